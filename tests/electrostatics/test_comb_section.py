"""Comb cross-sections (netgen.electrostatics.comb_section) on coarse tables: mirror symmetries
of the cell, the levitation sign over a substrate, the spline against direct solves, the
parallel-plate limit, the disk cache."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from netgen.core.constants import EPS0
from netgen.electrostatics import comb_section
from tests.oracles import closed_forms

UM = 1e-6


@pytest.fixture
def coarse(monkeypatch, tmp_path):
    """Small grids and a private cache folder (the module's tables are rebuilt per test)."""
    monkeypatch.setenv("NETGEN_CACHE", str(tmp_path))
    monkeypatch.setattr(comb_section, "GRID", {"gaps": 5, "offsets": 4, "ends": 4})
    monkeypatch.setattr(comb_section, "SETTINGS", {"tol": 5e-3, "max_levels": 1, "mesh_scale": 1.5, "order": 2})
    monkeypatch.setattr(comb_section, "_TABLES", {})
    return tmp_path


def cell(thickness=4 * UM, substrate_gap=2 * UM):
    """Fingers 2 um wide, 2 um gaps (pitch 4 um)."""
    return SimpleNamespace(width=2 * UM, thickness=thickness, pitch=4 * UM, substrate_gap=substrate_gap, eps=EPS0)


def test_symmetric_cell_splits_evenly_and_free_space_is_even_in_offset(coarse):
    """At the nominal gap the moving finger's two halves carry equal mutual charge (mirror x);
    without a substrate an offset up or down gives the same C' (mirror y), with one the finger is
    pulled up (d side / d offset > 0 at 0: levitation) and sees the substrate."""
    g = comb_section.Geometry.of(cell(substrate_gap=None))
    right, left, ground = comb_section.solve_cell(g, g.gap, 0.0)
    # the split is read off one unstructured mesh, not mirror symmetric: the halves agree to the
    # solve's discretisation error (bounded by its convergence tol), 4.6e-6 measured, not to rounding
    assert right == pytest.approx(left, rel=comb_section.SETTINGS["tol"], abs=0) and ground == 0.0
    up, down = (comb_section.solve_cell(g, g.gap, s * UM)[0] for s in (1, -1))
    assert up == pytest.approx(down, rel=2e-3, abs=0)
    on = comb_section.Geometry.of(cell())
    up, mid, down = (comb_section.solve_cell(on, on.gap, s * 0.2 * UM)[0] for s in (1, 0, -1))
    assert up > mid > down
    assert comb_section.solve_cell(on, on.gap, 0.0)[2] > 0


def test_table_matches_direct_solves_and_is_cached(coarse, monkeypatch):
    """The spline between grid gaps within 1 % of a direct solve there, its gap derivative within
    3 % of a central difference of direct solves; a second use reads the disk and never solves."""
    c = cell()
    g = comb_section.Geometry.of(c)
    gap = 1.4 * UM  # between the grid's gaps 1.1 and 2.0 um
    off = float(comb_section.grids(g)[1][-1])  # on the offset grid (-1.6 .. +2 um)
    direct = comb_section.solve_cell(g, gap, off)[0]
    assert float(comb_section.section(gap, off, c)) == pytest.approx(direct, rel=1e-2, abs=0)
    h = 0.05 * UM
    fd = (comb_section.solve_cell(g, gap + h, off)[0] - comb_section.solve_cell(g, gap - h, off)[0]) / (2 * h)
    assert comb_section.section_gradient(gap, off, c)[0] == pytest.approx(fd, rel=3e-2, abs=0)
    assert len(list(coarse.glob("comb_sections/section-*.npz"))) == 1
    monkeypatch.setattr(comb_section, "_TABLES", {})
    monkeypatch.setattr(comb_section, "solve", lambda *a, **k: pytest.fail("re-solved a cached table"))
    monkeypatch.setattr(comb_section, "solve_cell", lambda *a, **k: pytest.fail("re-solved a cached table"))
    assert float(comb_section.section(gap, off, c)) == pytest.approx(direct, rel=1e-2, abs=0)
    with pytest.raises(ValueError, match="outside its table"):
        comb_section.section(5 * UM, 0.0, c)


def test_tip_falls_with_the_end_gap(coarse):
    """The finger-end C (F per end) is positive, falls as the end gap opens, and at a small end gap
    is at least the tip face's parallel plate eps t w / e."""
    c = cell()
    e = np.array([0.5, 2.0, 8.0, 30.0]) * UM
    tip = comb_section.tip(e, np.zeros(4), c)
    assert np.all(tip > 0) and np.all(np.diff(tip) < 0)
    assert tip[0] > EPS0 * c.thickness * c.width / e[0]
    assert np.all(comb_section.tip_gradient(e, np.zeros(4), c)[:, 0] < 0)


def test_parallel_plate_limit_of_the_cell():
    """Thick fingers t/g = 20 without substrate: per side eps t/g plus a fringe below the thin
    two-strip one's (closed_forms.parallel_strips less eps t/g: a neighbour on each side and the
    finger width shield the ends) and above zero; one direct converged solve."""
    c = cell(thickness=40 * UM, substrate_gap=None)
    g = comb_section.Geometry.of(c)
    side = comb_section.solve_cell(g, g.gap, 0.0)[0]
    plate = EPS0 * 20.0
    assert plate < side < closed_forms.parallel_strips(EPS0, 20.0, 1.0)
    assert side / plate == pytest.approx(1.0, abs=0.08)
