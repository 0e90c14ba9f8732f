"""The 2-D field solver (netgen.electrostatics.field2d) against exact per-unit-length capacitances
(netgen.electrostatics.closed_forms): coplanar strips, a wire over a ground plane, a finger pair
in its parallel-plate limit. Coarse settings (seconds); the converged table is
bench/field2d_convergence.py's."""

from __future__ import annotations

import math

import pytest

from netgen.core.constants import EPS0
from netgen.electrostatics.field2d import Conductor, Problem, open_box, solve
from netgen.electrostatics.mesh2d import Disk, Strip
from tests.oracles import closed_forms

OPEN = {"bottom": "open", "right": "open", "top": "open", "left": "open"}
GROUNDED = {**OPEN, "bottom": "ground"}


def coplanar(width: float, gap: float) -> Problem:
    """Two zero-thickness strips of `width`, inner edges `gap` apart, in open space."""
    a = Conductor("a", (Strip(-gap / 2 - width, 0.0, -gap / 2, 0.0),))
    b = Conductor("b", (Strip(gap / 2, 0.0, gap / 2 + width, 0.0),))
    return Problem((a, b), open_box((a, b)), OPEN)


def wire(radius: float, height: float) -> Problem:
    """A round wire with its centre at `height` over a grounded plane (the box's bottom)."""
    w = Conductor("wire", (Disk(0.0, height, radius),))
    return Problem((w,), open_box((w,), ground_bottom=0.0), GROUNDED)


def finger_pair(thickness: float, gap: float) -> Problem:
    """Two thin fingers (zero-width strips of height `thickness`) face to face across `gap`."""
    a = Conductor("a", (Strip(-gap / 2, 0.0, -gap / 2, thickness),))
    b = Conductor("b", (Strip(gap / 2, 0.0, gap / 2, thickness),))
    return Problem((a, b), open_box((a, b)), OPEN)


@pytest.mark.parametrize("width,gap", [(1.0, 1.0), (3.0, 0.5)])
def test_coplanar_strips(width, gap):
    """Two coplanar thin strips (w, s): C' = eps K(k')/K(k), k = s/(s+2w), within 0.3 %; the
    matrix is a two-conductor one (rows sum to zero: no ground in 2-D open space)."""
    sol = solve(coplanar(width * 1e-6, gap * 1e-6), tol=2e-3, max_levels=3)
    exact = closed_forms.coplanar_strips(EPS0, width, gap)
    assert sol.mutual("a", "b") == pytest.approx(exact, rel=3e-3, abs=0)
    assert abs(sol.to_ground("a")) < 1e-3 * exact
    assert sol.converged and sol.levels[-1].elements > sol.levels[0].elements


@pytest.mark.parametrize("height", [1.5, 4.0])
def test_wire_over_ground(height):
    """A round wire (r = 1) at centre height h over ground: C' = 2 pi eps / acosh(h/r) within 0.3 %."""
    sol = solve(wire(1.0, height), tol=2e-3, max_levels=3)
    assert sol.capacitance[0, 0] == pytest.approx(closed_forms.wire_over_plane(EPS0, 1.0, height), rel=3e-3, abs=0)


@pytest.mark.parametrize("ratio", [20.0, 50.0])
def test_finger_pair_parallel_plate_limit(ratio):
    """Thin fingers of height t across g, t/g = 20 and 50: the exact two-strip C' (Palmer's
    conformal map, closed_forms.parallel_strips) within 0.3 %; that is eps t/g plus Maxwell's
    fringe (1 + ln(2 pi t/g)) eps/pi to 0.15 %, and the fringe is 8.5 % (t/g = 20) of the total."""
    sol = solve(finger_pair(ratio, 1.0), tol=2e-3, max_levels=3)
    exact = closed_forms.parallel_strips(EPS0, ratio, 1.0)
    assert sol.mutual("a", "b") == pytest.approx(exact, rel=3e-3, abs=0)
    assert closed_forms.palmer_strips(EPS0, ratio, 1.0) == pytest.approx(exact, rel=1.5e-3, abs=0)
    assert sol.mutual("a", "b") > EPS0 * ratio * 1.04


def test_exact_two_strips_against_its_asymptote():
    """closed_forms.parallel_strips tends to Palmer's two-term asymptote as W/g grows (the relative
    gap shrinks ~5x from W/g = 20 to 50) and is above eps W/g + eps/pi everywhere."""
    gaps = [
        abs(closed_forms.palmer_strips(1.0, r, 1.0) / closed_forms.parallel_strips(1.0, r, 1.0) - 1) for r in (20, 50)
    ]
    assert gaps[1] < gaps[0] / 4
    assert all(closed_forms.parallel_strips(1.0, r, 1.0) > r + 1 / math.pi for r in (1.0, 5.0, 20.0))
