"""The capacitance laws' checks and the (tscale, etch) cross factor (netgen.model.process): the states a
law is checked at (check_sets), its misfit there, and with tscale and etch both moving a comb the product
law's correction at the box's corners (cross_capacitance, netgen.model.etch_state.cross_laws)."""

from __future__ import annotations

import numpy as np

from ..electrostatics.sampling import CORNER_CHECKS, box_corners, check_points
from ..structure import Structure
from ..structure.schema import Process
from .etch_geometry import etched, scaled
from .etch_state import FIT_POINTS as STATE_FIT_POINTS
from .etch_state import TSCALE, cross_factor, cross_laws, state_factor
from .process_values import ratio_value

ROUND_OFF = 1e-12  # a law's residual below this is the re-runs' round-off: stated as 0 (exact)


CAPACITANCE_POINTS = 32  # random points of the fit box the capacitance ratios are checked at (and rest)


def check_sets(s: Structure, ncoords: int) -> list[tuple[np.ndarray, bool]]:
    """The scaled states a capacitance law is checked at, each with whether they are the box's corners
    (netgen.build.capacitance_sampler's `corners`): rest and CAPACITANCE_POINTS random points of the
    fit box, and the box's 2^n corners up to CORNER_CHECKS coordinates (as the fits' own check,
    netgen.electrostatics.sampling.sample_corners): a state polynomial's misfit peaks there (held-out
    random points found 9.6e-4 against 8.1e-4 on the random checks alone, accelerometer_xyz's etch)."""
    out = [(check_points(s.sampling, CAPACITANCE_POINTS, ncoords), False)]
    return out + ([(box_corners(s.sampling, ncoords), True)] if ncoords <= CORNER_CHECKS else [])


def cross_capacitance(
    s: Structure, p: Process, extract, names: list[str], coords: list[str], thick: dict, etch: dict
) -> dict:
    """With tscale and etch both moving the capacitances (combs, etch holes): the product of the two
    laws, C(q; t, e) = pc_t(t) S_t(xs; t) pc_e(e) S_e(xs; e) C(q + shift e; 1, 0), each fitted with the
    other parameter nominal, misses what moves with both (a field2d finger's fringe share depends on
    its width and thickness together; the etch factor was fitted at t = 1). Each electrode whose
    product misfits by FLOOR or more at the four corners of the (tscale, etch) box gets the cross factor
    1 + (tscale - 1) (u Q1(xs) + u^2 Q2(xs)) ("cross" on its etch law, netgen.model.etch_state.cross_laws),
    fitted at the corners on the state fit's points. Stated (updating the etch record): the largest
    |law / extractor - 1| at the corners over rest, the CAPACITANCE_POINTS check points and the box's
    corners (held out of the fit) folded into capacitance_max_rel_error, and apart
    (capacitance_cross_max_rel_error; the plain product's capacitance_product_max_rel_error)."""
    elaws = {r["electrode"]: r for r in etch["capacitance"]}
    tlaws = {r["electrode"]: r for r in thick["capacitance_laws"]}
    knots, n = tuple(etch.get("knots", ())), CAPACITANCE_POINTS + STATE_FIT_POINTS
    fit = np.arange(CAPACITANCE_POINTS + 1, n + 1)  # the state laws' fit points (netgen.model.etch_state)
    every = check_points(s.sampling, n, len(coords))
    corners = [(t, e) for t in p.tscale_range for e in p.etch_range]
    memo: dict[tuple, np.ndarray] = {}

    def drawn(offset: np.ndarray, count: int, at_corners: bool) -> np.ndarray:
        """The drawn structure's capacitances moved by `offset` (one extraction per distinct offset)."""
        key = (count, at_corners, *offset.tolist())
        if key not in memo:
            memo[key] = extract(s, count, offset, corners=at_corners)
        return memo[key]

    def law(t: float, e: float, x: np.ndarray, count: int, at_corners: bool) -> np.ndarray:
        """The product law at (t, e) at the states x (rows of extract(., count, corners=at_corners))."""
        return product_law(lambda v: drawn(v, count, at_corners), names, coords, elaws, tlaws, knots, t, e, x)

    with np.errstate(divide="ignore", invalid="ignore"):  # touching points: nan, left out
        residuals = {
            c: extract(etched(scaled(s, c[0]), c[1]), n)[fit] / law(*c, every, n, False)[fit] - 1.0 for c in corners
        }
    fitted = cross_laws(every[fit], residuals)
    plain = worst = 0.0
    for t, e in corners:
        for x, at in check_sets(s, len(coords)):
            count = 0 if at else CAPACITANCE_POINTS
            ref, got = extract(etched(scaled(s, t), e), count, corners=at), law(t, e, x, count, at)
            plain = max(plain, misfit(got, ref))
            for k, f in fitted.items():
                got[:, k] *= cross_factor(f, x, t, e)
            worst = max(worst, misfit(got, ref))
    for k, f in fitted.items():
        if names[k] in elaws:
            elaws[names[k]]["cross"] = f
    worst = worst if worst > ROUND_OFF else 0.0
    return {
        "capacitance_max_rel_error": max(etch["capacitance_max_rel_error"], worst),
        "capacitance_cross_max_rel_error": worst,
        "capacitance_product_max_rel_error": plain if plain > ROUND_OFF else 0.0,
    }


def product_law(
    drawn,
    names: list[str],
    coords: list[str],
    elaws: dict,
    tlaws: dict,
    knots: tuple[float, ...],
    t: float,
    e: float,
    xs,
) -> np.ndarray:
    """The electrodes' capacitances at the scaled states `xs` by the product of the etch and the tscale
    laws at (t, e), `drawn(offset)` the drawn structure's extractor there moved by each etch shift."""
    out = np.empty((len(xs), len(names)))
    for k, name in enumerate(names):
        le, lt = elaws.get(name, {}), tlaws.get(name)
        v = np.array([le.get("shift", {}).get(q, 0.0) for q in coords])
        c = drawn(v * e)[:, k]
        if le:
            c = c * ratio_value(le["ratio"], e, knots) * (state_factor(le["state"], xs, e) if "state" in le else 1.0)
        if lt:
            c = c * float(np.dot(lt["ratio"], [1.0, t, t * t, t**3]))
            c = c * (state_factor(lt["state"], xs, t, TSCALE) if "state" in lt else 1.0)
        out[:, k] = c
    return out


def misfit(got: np.ndarray, ref: np.ndarray) -> float:
    """The largest |got / ref - 1| where both are finite (a touching point is nan)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        r = got / ref - 1.0
    return float(np.max(np.abs(r[np.isfinite(r)]), initial=0.0))
