"""The z shift of a perforated plate electrode's capacitance law under etch (netgen.model.process.
capacitance_laws): the etch widens the proof mass's holes by 2 etch, and the fill factor F(g) the
plate sees (netgen.electrostatics.perforation: 1 - (1 - phi) ((h - 2 d(g)) / p)^2, the rims' fringe
d growing with the gap g) changes by an amount that itself depends on the gap. A constant ratio
pc(etch) is then exact at rest only (accelerometer_xyz's z plates: 4.9e-4 .. 5.3e-4 off at the fit
box's ends at etch -+0.1 um, against the fit's 1.7e-4).

The etched plate's C(z; etch) is read instead as pc(etch) C(z + k etch; 0): k chosen so that the
law's log-slope d ln C / dz at rest matches the etched extractor's, to first order in the shift,
s(etch) = (D_e - D_0) / D_0' (D the log-slope, D_0' its derivative, central differences over the
half box dz), k the least-squares slope of s(etch) over the range's two ends. The remaining error
is of second order in z (2e-5 there). The shift is an effective one (the gap does not move): the
contact stops do not follow it (the law is marked "fill"). Not offered with dg declared: a gap offset
reads the same state xs_z. A plate conductor (piston, free disk: netgen.model.etch_geometry.etched_plate)
with an edge fringe gets the same shift: the fringe's share of C changes with the etched outline, and
with the gap; with fringe "none" its log-slope does not change and it gets none."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

FLOOR = 1e-6  # m of shift per m of etch: 0.1 pm at 0.1 um, far below any gap's 1e-6 relative


def fill_shifts(
    s: Any,
    extract: Callable,
    etched: Callable,
    coords: list[str],
    plates: list[int],
    etches: tuple[float, float],
    dz: float,
) -> dict[int, float]:
    """electrode index -> k (the z shift per metre of etch) for the plate electrodes `plates` of `s`,
    from `extract(structure, 0, offset)` (netgen.build.capacitance_sampler) at rest moved along z, on
    `etched(s, etch)` (netgen.model.process.etched); an electrode whose log-slope has no curvature or
    a non-finite value is left out. {} without plates or coordinate z."""
    if not plates or dz <= 0.0 or "z" not in coords:
        return {}

    def at(etch: float, z: float) -> np.ndarray:
        offset = np.zeros(len(coords))
        offset[coords.index("z")] = z
        return np.asarray(extract(etched(s, etch) if etch else s, 0, offset)[0], dtype=float)

    drawn = np.log(np.array([at(0.0, z) for z in (-dz, 0.0, dz)]))
    slope0 = (drawn[2] - drawn[0]) / (2 * dz)
    curve0 = (drawn[2] - 2 * drawn[1] + drawn[0]) / dz**2
    shifts = []
    for e in etches:
        lo, hi = np.log(at(e, -dz)), np.log(at(e, dz))
        with np.errstate(divide="ignore", invalid="ignore"):  # a comb's C without z: 0 / 0, left out below
            shifts.append(((hi - lo) / (2 * dz) - slope0) / curve0)
    ends = np.array(etches)[:, None]
    k = np.sum(np.array(shifts) * ends, axis=0) / np.sum(ends * ends)
    # |k| <= FLOOR is the extractor's round-off (an unperforated plate's log-slope does not change)
    return {i: float(k[i]) for i in plates if np.isfinite(k[i]) and curve0[i] != 0.0 and abs(k[i]) > FLOOR}
