"""netgen: macromodels of micromechanical multi-electrode structures for circuit simulators."""

__version__ = "0.1.0"
