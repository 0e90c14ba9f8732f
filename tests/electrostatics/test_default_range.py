"""The default [sampling] range narrows where the box's corners reach an electrode
(netgen.electrostatics.sampling.box_range, netgen.build.default_range). The reference is a hand
count: a cantilever's bending modes each touch first at the free tip, where every mode shape
peaks, so at the box corner of n modes the tip closes n times the gap each mode alone closes."""

from __future__ import annotations

import re

import numpy as np
import pytest

from netgen.build import build
from netgen.electrostatics.sampling import CORNER_REACH, box_range, corner_closure
from netgen.structure import StructureError, parse_structure
from tests.fixtures import ROOT
from tests.structures import PISTON_3

MODES = 7


def cantilever(range_line: str) -> str:
    """examples/cantilever.toml with MODES modes, the sparse design and the given range line."""
    src = (ROOT / "examples" / "cantilever.toml").read_text()
    src = re.sub(r"^range = .*$", range_line, src, flags=re.M)
    src = re.sub(r"^modes = 3 .*$", f"modes = {MODES}", src, flags=re.M)
    return re.sub(r"^levels = .*$", 'design = "sparse"', src, flags=re.M)


@pytest.fixture(scope="module")
def narrowed():
    """The cantilever built without a range key."""
    return build(parse_structure(cantilever(""), "cantilever7.toml"))


def test_corner_closure_of_n_cantilever_modes_is_n(narrowed):
    assert corner_closure(narrowed.prepared, narrowed.scales) == pytest.approx(MODES, rel=1e-6)


def test_range_without_a_key_shrinks_so_the_corners_just_reach(narrowed):
    expected = int(100 * CORNER_REACH / MODES) / 100  # 1/7 rounded down to two digits: 0.14
    assert narrowed.model.sampling["range"] == expected == 0.14
    assert narrowed.model.sampling["range_narrowed_from"] == 0.2
    assert abs(narrowed.holdout.x).max() <= expected  # the held-out points follow the box


def test_a_given_range_is_kept(narrowed):
    s = parse_structure(cantilever("range = 0.2"), "cantilever7.toml")
    assert s.sampling.range_given
    assert box_range(narrowed.prepared, narrowed.scales, 0.2) == 0.14  # what the default would be
    b = build(s)
    assert b.model.sampling["range"] == 0.2 and "range_narrowed_from" not in b.model.sampling


PISTON = (
    PISTON_3
    + """[sampling]
levels = 3
[electrostatics]
fringe = "none"
"""
)


def test_a_box_whose_corners_stay_clear_keeps_the_default():
    """A square plate over an electrode of its size, z and two tilts: each alone touches first at
    the plate's corner, so a corner of the box closes 3 gaps per unit range there."""
    b = build(parse_structure(PISTON, "piston3.toml"))
    assert corner_closure(b.prepared, b.scales) == pytest.approx(3.0, rel=1e-6)
    assert b.model.sampling["range"] == 0.2 and "range_narrowed_from" not in b.model.sampling
    assert box_range(b.prepared, b.scales, 0.5) == 0.33


# --------------------------------------------------------------- a range per coordinate

# Euler-Bernoulli cantilever modes (Blevins, Formulas for natural frequency and mode shape, table
# 8-1): beta_n L and sigma_n; with the shapes normalised to mean square 1 the tip value is 2 and
# integral phi_n dx = 2 L sigma_n / (beta_n L).
BETA_L = (1.87510407, 4.69409113, 7.85475744)
SIGMA = (0.734095514, 1.018467319, 0.999224497)


def static_share(n: int) -> float:
    """Mode n's static amplitude under a uniform load over the whole beam, in units of its
    touching amplitude (the tip closes the gap), over mode 1's: (F_n / k_n) / (F_1 / k_1) with
    F_n ~ integral phi_n, k_n ~ (beta_n L)^4 and the same tip value |phi_n(L)| = 2 for every n."""
    share = [(-1) ** k * SIGMA[k] / BETA_L[k] ** 5 for k in range(3)]
    return share[n - 1] / share[0]


@pytest.fixture(scope="module")
def cantilever_example():
    """examples/cantilever.toml as committed: range = {m1 = 0.6, m2 = 0.1, m3 = 0.05}."""
    return build(parse_structure((ROOT / "examples" / "cantilever.toml").read_text(), "cantilever.toml"))


def test_each_coordinate_samples_its_own_range(cantilever_example):
    """The design and the held-out points fill each coordinate's own half-width; the JSON names them."""
    b = cantilever_example
    half = np.array([0.6, 0.1, 0.05])
    assert np.abs(b.grid.x).max(axis=0) == pytest.approx(half, rel=1e-12, abs=0)
    assert np.all(np.abs(b.holdout.x) <= half)
    assert np.abs(b.holdout.x).max(axis=0) == pytest.approx(half, rel=0.05)  # 500 uniform points reach the edges
    assert b.model.sampling["range"] == 0.6
    assert b.model.sampling["coordinate_range"] == {"m1": 0.6, "m2": 0.1, "m3": 0.05}


def test_the_higher_modes_box_covers_their_static_reach_and_the_fit_meets_its_tolerance(cantilever_example):
    """The model's own static shares at rest, (dC/dxs_v / (k_v L_v^2)) over mode 1's, equal the
    Euler-Bernoulli ratio (-1.41 % and +0.106 %) within 5 %: a full-length electrode at rest pulls
    with a uniform pressure (no fringing), and the 60-element beam's modes and the fit's slopes (its
    held-out error is a few 1e-4 of C, so a slope of 1.4 % of mode 1's is known to a few per cent)
    carry the rest. m1 at 0.6 then drives m2 and m3 statically to 0.6 x share, which their boxes
    (0.1, 0.05) cover 12x and 80x over; and the fit meets fit.tolerance, which the even box of
    0.6 missed 65-fold (corners 1.8 gaps into the electrode)."""
    m = cantilever_example.model
    fit = m.capacitances[0]
    n, h = len(m.coordinates), 1e-4
    slope = []
    for v in range(n):
        e = np.zeros((1, n))
        e[0, v] = h
        slope.append((fit.value(e)[0] - fit.value(-e)[0]) / (2 * h))
    reach = np.array(slope) / np.array([c.stiffness * c.scale**2 for c in m.coordinates])
    for k in (2, 3):
        assert reach[k - 1] / reach[0] == pytest.approx(static_share(k), rel=0.05)
        assert m.sampling["coordinate_range"][f"m{k}"] > 10 * 0.6 * abs(static_share(k))
    assert fit.max_rel_error <= m.sampling["tolerance"]


@pytest.mark.parametrize(
    "line,words",
    [
        ("range = {}", ["sampling.range", "empty"]),
        ("range = { m1 = 0.6, m9 = 0.1 }", ["sampling.range", "unknown coordinate 'm9'"]),
        ("range = { m1 = 0.6, m2 = 0.95 }", ["sampling.range.m2", "touch"]),
        ('range = { m1 = "wide" }', ["sampling.range.m1"]),
    ],
)
def test_a_bad_range_table_is_named(line, words):
    src = re.sub(r"^range = .*$", line, (ROOT / "examples" / "cantilever.toml").read_text(), flags=re.M)
    with pytest.raises(StructureError) as info:
        parse_structure(src, "bad.toml")
    message = str(info.value)
    assert message.startswith("bad.toml") and "fix:" in message
    for w in words:
        assert w in message, message
