"""The default [sampling] range narrows where the box's corners reach an electrode
(netgen.electrostatics.sampling.box_range, netgen.build.default_range). The reference is a hand
count: a cantilever's bending modes each touch first at the free tip, where every mode shape
peaks, so at the box corner of n modes the tip closes n times the gap each mode alone closes."""

from __future__ import annotations

import re

import pytest

from netgen.build import build
from netgen.electrostatics.sampling import CORNER_REACH, box_range, corner_closure
from netgen.structure import parse_structure
from tests.fixtures import ROOT
from tests.structures import PISTON_3

MODES = 7


def cantilever(range_line: str) -> str:
    """examples/cantilever.toml with MODES modes, the sparse design and the given range line."""
    src = (ROOT / "examples" / "cantilever.toml").read_text()
    src = re.sub(r"^range = 0\.6.*$", range_line, src, flags=re.M)
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
