"""The adaptive design (netgen.fit.adaptive) on an analytic capacitance: a rigid square plate
over one electrode of the same size, z and both tilts, pure parallel plate. The reference is
the closed-form integral of eps / (g - w(x, y)) over the plate for the affine w = z + a x + b y,
itself checked against the extractor (Gauss quadrature of the local gap, fringe off)."""

from __future__ import annotations

import numpy as np
import pytest

from netgen.build import build
from netgen.core.constants import EPS0
from netgen.electrostatics.sampling import Samples, design_points
from netgen.fit.adaptive import SAFETY, adaptive_fits
from netgen.fit.capacitance import fit_all
from netgen.structure import parse_structure
from tests.structures import PISTON_3

SIDE, GAP = 200e-6, 2e-6
PISTON = (
    PISTON_3
    + """[sampling]
{sampling}
range = 0.3
[fit]
holdout = 300
[electrostatics]
fringe = "none"
"""
)


def plate_integral(c: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Exact integral of 1 / (c - a x - b y) over the square |x|, |y| <= SIDE / 2: the second
    difference of H(u) = u ln u - u over the corners, divided by a b (1-D forms where a or b
    vanish: 2 W atanh(a L / 2c) / a, and L W / c)."""
    h = SIDE / 2

    def big_h(u):
        return u * np.log(u) - u

    out = np.empty_like(c)
    for k in range(len(c)):
        ck, ak, bk = c[k], a[k], b[k]
        if abs(ak) * h < 1e-9 * ck and abs(bk) * h < 1e-9 * ck:
            out[k] = SIDE * SIDE / ck
        elif abs(ak) * h < 1e-9 * ck:
            out[k] = SIDE * 2 * np.arctanh(bk * h / ck) / bk
        elif abs(bk) * h < 1e-9 * ck:
            out[k] = SIDE * 2 * np.arctanh(ak * h / ck) / ak
        elif min(ck - ak * sx * h - bk * sy * h for sx in (-1, 1) for sy in (-1, 1)) <= 0:
            out[k] = np.nan  # a corner touches the electrode
        else:
            corners = [(sx, sy) for sx in (-1, 1) for sy in (-1, 1)]
            out[k] = sum(sx * sy * big_h(ck - ak * sx * h - bk * sy * h) for sx, sy in corners) / (ak * bk)
    return out


@pytest.fixture(scope="module")
def piston():
    """The grid build (its extractor, scales, basis) and an analytic sampler of C(x)."""
    b = build(parse_structure(PISTON.format(sampling="levels = 5"), "piston3.toml"))
    sign = b.electrodes[0].sign

    def analytic(x: np.ndarray) -> np.ndarray:
        q = x * b.scales  # z, tilt_x, tilt_y: w = z + tilt_x y - tilt_y x
        return EPS0 * plate_integral(GAP - sign * q[:, 0], sign * q[:, 2], -sign * q[:, 1])[:, None]

    return b, analytic


def test_the_closed_form_is_the_extractor_without_fringe(piston):
    b, analytic = piston
    x = np.random.default_rng(3).uniform(-0.3, 0.3, (60, 3))
    ref, ext = analytic(x), b.prepared.capacitance(x * b.scales)
    assert np.array_equal(np.isnan(ref), np.isnan(ext)) and np.isnan(ref).sum() < 20
    assert np.allclose(ref[~np.isnan(ref)], ext[~np.isnan(ext)], rtol=1e-4)


def test_adaptive_reaches_the_tolerance_with_fewer_points_than_the_grid(piston):
    """The adaptive design meets fit.tolerance on 300 held-out points of the closed form; the
    5-level grid (125 points) is the coarsest full grid that does (3 levels, 27 points, misses)."""
    b, analytic = piston

    def evaluate(x):  # touching points dropped, as the sampling does
        c = analytic(x)
        keep = ~np.isnan(c[:, 0])
        return Samples(x[keep], c[keep], int((~keep).sum()), x)

    s = parse_structure(PISTON.format(sampling='design = "adaptive"\npoints = 120'), "piston3.toml")
    hold_x = np.random.default_rng(9).uniform(-0.3, 0.3, (300, 3))
    holdout = evaluate(hold_x)
    start = evaluate(design_points(s.sampling, 3))
    result = adaptive_fits(s, b.electrodes, b.mechanics.basis, b.scales, start, evaluate, holdout)
    assert result.converged
    assert result.fits[0].max_rel_error <= s.fit.tolerance
    checked = [r["validation_max_rel_error"] for r in result.rounds if "validation_max_rel_error" in r]
    assert checked and checked[-1] <= SAFETY * s.fit.tolerance  # the stop was confirmed on fresh points
    grids = {}
    for levels in (3, 5):
        g = parse_structure(PISTON.format(sampling=f"levels = {levels}"), "piston3.toml")
        x = design_points(g.sampling, 3)
        grids[levels] = fit_all(g, b.electrodes, b.mechanics.basis, b.scales, evaluate(x), holdout)[0].max_rel_error
    assert grids[3] > s.fit.tolerance >= grids[5], grids
    assert len(result.samples.x) < 125, len(result.samples.x)
