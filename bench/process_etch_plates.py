"""The etch on plates (netgen.model.etch_geometry.etched_plate): the figures quoted in docs/process.md
and CHANGELOG.md. The piston of tests/oracles/plate_etch (examples/piston.toml, fringe "none") against
its closed forms and full rebuilds, with its tilts against rebuilds, the rigid disk with its squeeze
film and the disk with its (2,0) mode against rebuilds, at the oracle's three etches.
Run from the repository root:
    .venv/bin/python bench/process_etch_plates.py
"""

from __future__ import annotations

import math
import time

import numpy as np
from support import plate_etch, process_balance

from netgen.build import build_model
from netgen.core.constants import EPS0
from netgen.model.process import capacitance_at, coordinate_values
from netgen.structure import parse_structure

ETCHES = plate_etch.ETCHES


def built(text: str):
    return build_model(parse_structure(text, "plate.toml"))


def box(model) -> np.ndarray:
    """The fit box's half-widths per coordinate (scaled)."""
    rng = model.sampling.get("coordinate_range", {})
    return np.array([rng.get(c.name, model.sampling["range"]) for c in model.coordinates])


def against_rebuilds(label: str, text, inner: float = 1.0) -> None:
    """Stated errors, then per etch: the largest |f_law / f_rebuilt - 1|, mass and damping likewise,
    and the capacitances at 100 points (inside `inner` of the box) at the same physical state."""
    model = built(text())
    law = model.process["etch"]
    fits = max(f.max_rel_error for f in model.capacitances)
    print(
        f"{label}: stated mechanics {law['max_rel_error']:.1e}, capacitance {law['capacitance_max_rel_error']:.1e}"
        f" (without state factors {law.get('capacitance_stateless_max_rel_error', law['capacitance_max_rel_error']):.1e}),"
        f" fit {fits:.1e}"
    )
    x = np.random.default_rng(3).uniform(-inner, inner, (100, model.ncoords)) * box(model)
    for e in ETCHES:
        ref = built(text(e, ""))
        f_err = m_err = d_err = 0.0
        for v, c in enumerate(ref.coordinates):
            mass, k, damp = coordinate_values(model.process, v, etch=e)
            m_err = max(m_err, abs(mass / c.mass - 1))
            d_err = max(d_err, abs(damp / c.damping - 1) if c.damping else 0.0)
            if c.frequency_hz:
                f_err = max(f_err, abs(math.sqrt(k / mass) / (2 * math.pi) / c.frequency_hz - 1))
        c_err = np.max(np.abs(capacitance_at(model, x, e) / ref.capacitance(x * model.scales / ref.scales) - 1))
        ref_fit = max(f.max_rel_error for f in ref.capacitances)
        print(
            f"  etch {e:+.1e}: f {f_err:.1e}, mass {m_err:.1e}, damping {d_err:.1e}, C at 100 points {c_err:.1e}"
            f" (rebuild's fit {ref_fit:.1e})"
        )


def piston_pull_in() -> None:
    """The piston's pull-in from the law against sqrt(8 k g^3 / (27 eps A')) and the rebuild's."""
    model = built(plate_etch.piston_text())
    for e in ETCHES:
        ref = built(plate_etch.piston_text(e, ""))
        v_law = process_balance.pull_in(
            process_balance.LawAt(model, e), [coordinate_values(model.process, 0, etch=e)[1]]
        )
        a = plate_etch.SIDE**2 * plate_etch.area_ratio(e)
        v_closed = math.sqrt(8 * plate_etch.STIFFNESS * plate_etch.GAP**3 / (27 * EPS0 * a))
        v_ref = process_balance.pull_in(ref, [ref.coordinates[0].stiffness])
        print(
            f"  etch {e:+.1e}: pull-in {v_law:.6f} V, closed form {v_law / v_closed - 1:+.1e},"
            f" rebuilt {v_law / v_ref - 1:+.1e}"
        )


def main() -> None:
    start = time.perf_counter()
    against_rebuilds("piston (fringe none)", plate_etch.piston_text)
    piston_pull_in()
    against_rebuilds("piston with tilts (box 0.3)", plate_etch.tilted_piston_text, 0.99)
    against_rebuilds("rigid disk with its squeeze film", plate_etch.disk_text, 0.99)
    against_rebuilds("disk with the (2,0) mode", plate_etch.modal_disk_text)
    print(f"{time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
