"""Writes examples/calibrated_disk_maxwell.json: the example Maxwell-matrix file of
examples/calibrated_disk.toml, in the format a field solver's export is converted to
(netgen.electrostatics.coupling_file). The values are synthetic, not a field solution: the
plate-electrode entries are the parallel-plate extractor with Palmer's edge fringe, adjacent
sectors couple at 10 % of the sector capacitance (docs/bem.md, 'A disk between 8 + 8 sector
electrodes': 5-15 %), varying by
+-1 % with z, and every conductor has 1 fF to infinity; 5 points (rest, +-z, +-tilt_x), printed
to 6 significant digits as a solver would. Run from the repository root:

    .venv/bin/python examples/calibrated_disk_maxwell.py
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from netgen.electrostatics.calibration import design
from netgen.electrostatics.parallel_plate import EdgeFringe, ParallelPlateExtractor
from netgen.electrostatics.sampling import coordinate_scales
from netgen.geometry.layout import electrodes, plate_outline
from netgen.mechanics import mechanics
from netgen.structure import parse_structure

HERE = Path(__file__).parent


def main() -> None:
    """Compute the five matrices and write the JSON."""
    text = (HERE / "calibrated_disk.toml").read_text()  # its geometry, without the file it names
    s = parse_structure(text.replace('extractor = "calibrated"', "").split("couplings =")[0], "calibrated_disk.toml")
    m, plate, els = mechanics(s), plate_outline(s), electrodes(s)
    ext = ParallelPlateExtractor(fringe=EdgeFringe.palmer(plate.size)).prepare(els, plate, m.basis)
    scales = coordinate_scales(ext, m.names, np.array([e.gap for e in els]))
    q = design(5, scales, s.sampling.range)
    c = ext.capacitance(q)
    n = len(els)
    points = []
    for k in range(len(q)):
        mx = np.zeros((n + 1, n + 1))
        mx[0, 1:] = mx[1:, 0] = -c[k]
        for i in range(n):
            for j in range(i + 1, n):
                if els[i].side == els[j].side and (j - i) % 4 in (1, 3):
                    mx[1 + i, 1 + j] = mx[1 + j, 1 + i] = -0.1 * c[0, i] * (1 + 0.05 * q[k, 0] / scales[0])
        np.fill_diagonal(mx, 0.0)
        np.fill_diagonal(mx, -mx.sum(axis=1) + 1e-15)
        points.append(
            {
                "q": {name: float(f"{v:.6g}") for name, v in zip(m.names, q[k]) if v},
                "maxwell": [[float(f"{v:.6g}") for v in row] for row in mx],
            }
        )
    doc = {
        "description": "synthetic example (examples/calibrated_disk_maxwell.py), not a field solution",
        "unit": "F",
        "conductors": ["plate"] + [e.name for e in els],
        "points": points,
    }
    (HERE / "calibrated_disk_maxwell.json").write_text(json.dumps(doc, indent=1) + "\n")


if __name__ == "__main__":
    main()
