"""The etch laws' torsion knots (netgen.model.etch_knots): where an etched flexure width w - 2 etch passes
the layer thickness t, the frame's torsion constant (netgen.mechanics.frame.torsion_constant, Roark's
fit with A = max(w, t)) changes formula, and the law is a cubic plus truncated powers at that etch.

References (independent of the law): the torsion constant's two branches at the kink (their slopes in w,
0.2633 t^3 and 0.30 t^3 from differentiating Roark's formula by hand); the mechanics re-run at the
etched structure (examples/accelerometer_xyz with textbook combs, rewritten at the etched sizes:
tests/oracles/process_cases.xyz_text), whose 2 um legs on its 2 um layer put the kink at etch 0.

Tolerances:
- the slopes: the one-sided differences' truncation (their midpoint 1.5 h from the kink, h = 1e-6 t:
  1.5e-6 J'' t / J' <= 2e-6 with J'' = 0.35 t^2 on the wide side, 0.46 t^2 on the narrow) and their
  round-off (1e-16 J / (h J') ~ 1e-10): 1e-5.
- the law against the re-runs, stiffness and modal frequency of every coordinate at etches straddling
  the kink and across the range: the law's stated error (its largest residual at the 9 re-runs it is
  fitted to, relative to the stiffness or mass) times 3, the Lebesgue constant of cubic
  interpolation on 5 equispaced points per piece (2.2) rounded up: between fit points a least-squares
  piecewise cubic with one spare point per piece misses by at most that factor of its misfit at
  them (the re-runs' noise: the perforation's hole count). The issue's acceptance (modal 1e-4) is
  asserted beside it. One cubic across the kink missed the stiffness by 1.6e-3 at -0.05 um.
"""

from __future__ import annotations

import math

import pytest

from netgen.mechanics import mechanics
from netgen.mechanics.frame import torsion_constant
from netgen.model.etch_knots import etch_knots, knot_points
from netgen.model.process import coordinate_values
from netgen.structure import parse_structure
from tests.fixtures import shared_model as build_model
from tests.oracles.process_cases import perforated, xyz_etch_text, xyz_text

STRADDLE = (-0.1e-6, -0.02e-6, -0.005e-6, -0.001e-6, 0.001e-6, 0.005e-6, 0.02e-6, 0.04e-6, 0.1e-6)  # m


def test_torsion_constant_has_a_kink_at_w_equal_t():
    """Roark's J has slope 0.2633 t^3 on the wide side and 0.30 t^3 on the narrow side of w = t (14 %
    apart): a cubic in etch cannot follow it."""
    t, h = 2e-6, 2e-12
    wide = (torsion_constant(t + 2 * h, t) - torsion_constant(t + h, t)) / h
    narrow = (torsion_constant(t - h, t) - torsion_constant(t - 2 * h, t)) / h
    assert wide / t**3 == pytest.approx(1 / 3 - 0.07, rel=1e-5)
    assert narrow / t**3 == pytest.approx(1 - 0.84 + 0.14, rel=1e-5)


def test_knots_where_the_etched_widths_meet_the_thickness():
    """accelerometer_xyz (2 um legs, 2 um layer): one knot at etch 0, the re-runs five per piece; the
    perforated mass with 3 um legs: its knot at 0.5 um lies outside +-0.1 um (the plain cubic)."""
    s = parse_structure(xyz_etch_text(), "xyz.toml")
    assert etch_knots(s, -1e-7, 1e-7) == (0.0,)
    assert len(knot_points(-1e-7, 1e-7, (0.0,))) == 9
    px = parse_structure(perforated(process='[process]\nparameters = ["etch"]\n'), "px.toml")
    assert etch_knots(px, -1e-7, 1e-7) == ()
    model = build_model(px)
    assert "knots" not in model.process["etch"]
    assert all(len(r) == 4 for c in model.process["coordinates"] for r in c["etch"].values())


@pytest.fixture(scope="module")
def xyz():
    return build_model(parse_structure(xyz_etch_text(), "xyz.toml"))


@pytest.mark.parametrize("etch", STRADDLE)
def test_law_follows_the_kink(xyz, etch):
    """Stiffness and modal frequency of every coordinate against the re-run at the etched sizes."""
    law = xyz.process
    stated = law["etch"]["max_rel_error"]
    assert law["etch"]["knots"] == [0.0]
    ref = mechanics(parse_structure(xyz_text(etch), "xyz.toml"))
    for v in range(xyz.ncoords):
        m, k, _ = coordinate_values(law, v, etch=etch)
        assert k == pytest.approx(ref.stiffnesses[v], rel=3 * stated, abs=0)
        f = math.sqrt(k / m) / math.sqrt(ref.stiffnesses[v] / ref.masses[v]) - 1
        assert abs(f) <= min(3 * stated, 1e-4)
