"""The geometry stage: plate and electrode shapes with their Gauss rules (netgen.geometry.shapes),
and the layout a structure file describes (netgen.geometry.layout)."""
