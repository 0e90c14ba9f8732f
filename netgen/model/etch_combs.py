"""The effective across-the-fingers shift of a transverse comb's capacitance law under etch
(netgen.model.process.capacitance_laws). The etched comb's fingers are 2 etch narrower and both
their gaps 2 etch wider; moving the drawn fingers 2 etch away (the geometric shift, which the
contact stops follow) gives the near gap exactly but narrows the far side's gap where the etch
widens it, and keeps the drawn finger width in the fringe. With the 2-D cell
(netgen.electrostatics.comb_section, which counts both) the ratio C(q; etch) / C(q + shift etch; 0)
then depends on the local gap: in accelerometer_xyz's combs the log-ratio has a slope along x and
rot_z alike (both close the same local gap) of 1e-2 per unit scaled coordinate at etch -+0.1 um,
4.5e-3 of spread over the fit box, while along y, z and the tilts it is 2e-4 .. 7e-4.

A ratio fitted jointly over etch and the local gap is, to first order, an extra shift along the gap:
pc(etch) C(q + (shift + d n) etch; 0) = pc(etch) C(q + shift etch; 0) (1 + d etch dlnC/dx_n), the
fit's own gap dependence carrying the coordinate dependence for x and rot_z together, and the
emitted forms unchanged (a constant shift per metre of etch, as the geometric one). d minimises, over
the four etch points and FIT_POINTS points of the fit box (not the points the law's error is then
checked at), the largest departure of the log-ratio from its value at rest (the ratio is fitted at
rest), linearised in d (one central difference of ln C along n at the geometric shift: d etch is
15 nm at 0.1 um, the linearisation's own error ~1e-5). What it leaves is even in the out-of-plane
offset (z and the tilts: the narrower finger's fringe), 5e-4 .. 7e-4 at the box's ends along each,
which no shift carries (netgen.model.etch_state's factor does).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar

FIT_POINTS = 128  # fit-box points the shift is fitted at, drawn after the points the law is checked at
FLOOR = 1e-6  # m of shift per m of etch: below it the form is exact (textbook eps t / g) to round-off
STEP = 1e-9  # m: the central difference of ln C along the gap (1e-3 of a micrometre gap)
SPREAD = 1e-9  # a log-ratio spread below this at every etch: nothing for a shift to carry


def gap_shifts(
    s: Any,
    extract: Callable,
    etched: Callable,
    combs: dict[int, tuple[np.ndarray, np.ndarray]],
    etches: tuple[float, ...],
    skip: int,
) -> dict[int, float]:
    """electrode index -> d (m per m of etch, along n) for the transverse combs `combs` (index ->
    (geometric shift vector per metre of etch, unit vector n of the across coordinate)) of `s`, from
    `extract(structure, n, offset)` (netgen.build.capacitance_sampler: rest and n fixed points; the
    rows after `skip` + 1 are used with rest) at `etched(s, etch)` for the nonzero `etches`; combs
    whose law is exact (log-ratio spread below SPREAD) or whose d is below FLOOR are left out; points
    where a gap closes (nan) are left out of the fit."""
    if not combs:
        return {}
    rows = np.r_[0, np.arange(skip + 1, skip + 1 + FIT_POINTS)]
    points = [e for e in etches if e != 0.0]
    moved = {e: extract(etched(s, e), skip + FIT_POINTS)[rows] for e in points}
    out: dict[int, float] = {}
    for k, (v, n) in combs.items():

        def log_c(offset: np.ndarray) -> np.ndarray:
            return np.log(extract(s, skip + FIT_POINTS, offset)[rows, k])

        with np.errstate(divide="ignore", invalid="ignore"):  # touching points: nan, left out below
            lr = np.array([np.log(moved[e][:, k]) - log_c(v * e) for e in points])
            ok = np.all(np.isfinite(lr), axis=0)
            if not ok[0] or np.max(np.ptp(lr[:, ok], axis=1)) < SPREAD:
                continue
            de = np.array([e * (log_c(v * e + STEP * n) - log_c(v * e - STEP * n)) / (2 * STEP) for e in points])
        ok &= np.all(np.isfinite(de), axis=0)
        lr, de = lr[:, ok], de[:, ok]
        fit = minimize_scalar(
            lambda x: spread(lr - x * de), bounds=(-2.0, 2.0), method="bounded", options={"xatol": 1e-6}
        )
        if abs(fit.x) > FLOOR:
            out[k] = float(fit.x)
    return out


def spread(lr: np.ndarray) -> float:
    """The largest departure of the log-ratios at each etch (rows) from their value at rest (column 0):
    the law's error there, its ratio being exact at rest (netgen.model.process.capacitance_laws)."""
    return float(np.max(np.abs(lr - lr[:, :1])))
