"""The BEM extractor (netgen.electrostatics.bem) against independent solutions: two coaxial
disks against Love's integral equation (solved by Nystrom in closed_forms.love_disks), two
squares against Palmer's formula and the earlier converged BEM (docs/bem.md, 'Two 1 mm squares'), a sphere against
4 pi eps R; the Maxwell matrix's symmetry and row sums; monotone capacitance under a rigid
translation; the memory budget. Coarse meshes (two levels + Richardson) that meet the stated
tolerances; the converged runs are in bench/bem_reference_disk.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("bempp_cl")

from netgen.core.constants import EPS0
from netgen.electrostatics import EXTRACTORS, bem  # noqa: E402
from netgen.electrostatics.bem_mesh import Surface, disk_sheet, icosphere, rectangle_sheet  # noqa: E402
from netgen.geometry.shapes import AnnularSector, DiskPlate, Electrode  # noqa: E402
from tests.oracles.closed_forms import kirchhoff_disk, love_disks, palmer_rectangle  # noqa: E402

COARSE = bem.BemSettings(
    element_to_gap=4.0, edge_to_gap=0.25, element_to_size=0.125, levels=2, max_levels=2, tolerance=1.0
)
MM, UM = 1e-3, 1e-6


def two_disks(kappa: float) -> bem.MaxwellMatrix:
    """Two coaxial unit disks at distance kappa (eps = 1)."""

    def meshes(k):
        s = COARSE.sizes(kappa, k, 1.0)
        return [disk_sheet(1.0, s), disk_sheet(1.0, s, kappa)]

    return bem.converged(meshes, ["a", "b"], 1.0, kappa, COARSE, h_max=COARSE.sizes(kappa, 0, 1.0).h_max)


@pytest.mark.slow
@pytest.mark.parametrize("kappa", [0.1, 0.2])
def test_two_disks_against_love(kappa):
    """C11 - C12 (disks at +1/-1) and C11 + C12 (both at +1) within 0.5 % of Love's equation
    (d/a = 0.05, a minute of CPU, is bench/bem_love.py)."""
    m = two_disks(kappa)
    assert m.settings["solves"][0]["order"] <= 8  # elements up to 4 gaps
    c = m.matrix
    assert (c[0, 0] - c[0, 1]) == pytest.approx(love_disks(kappa), rel=5e-3)
    assert (c[0, 0] + c[0, 1]) == pytest.approx(love_disks(kappa, same_potential=True), rel=5e-3)


def test_love_reference_is_converged():
    """The Nystrom solution of Love's equation changes by < 1e-6 when its rule is doubled, and
    tends to Kirchhoff's asymptotic formula as kappa -> 0 (0.27 % at 0.05, 0.06 % at 0.02)."""
    for kappa in (0.05, 0.1, 0.2):
        base = love_disks(kappa)
        fine = love_disks(kappa, panels=2 * math.ceil(4.0 / kappa), order=24)
        assert abs(base / fine - 1.0) < 1e-6
    gaps = [abs(love_disks(k) / 2.0 / kirchhoff_disk(1.0, 1.0, k) - 1.0) for k in (0.05, 0.02)]
    assert gaps[1] < gaps[0] < 3e-3 and gaps[1] < 1e-3


@pytest.mark.parametrize("g, best, palmer_tol", [(50 * UM, 23.40, 0.025), (20 * UM, 53.75, 0.015)])
def test_two_squares_against_palmer(g, best, palmer_tol):
    """Two 1 mm squares: Palmer's first-order formula is +2.1 % / +1.2 % above the converged BEM
    (docs/bem.md, 'Two 1 mm squares') at g = 50 / 20 um (its neglected corner terms); the coarse BEM
    is within that of Palmer, below it, and within 0.5 % of the converged value (eps0*mm)."""

    def meshes(k):
        s = COARSE.sizes(g, k, MM)
        return [rectangle_sheet(0, MM, 0, MM, s), rectangle_sheet(0, MM, 0, MM, s, g)]

    c = bem.converged(meshes, ["a", "b"], EPS0, g, COARSE, h_max=COARSE.sizes(g, 0, MM).h_max).matrix
    two_terminal = (c[0, 0] - c[0, 1]) / 2.0  # Q at +-1/2 V
    palmer = palmer_rectangle(EPS0, MM, MM, g)
    assert 0.0 < 1.0 - two_terminal / palmer < palmer_tol
    assert two_terminal / (EPS0 * MM) == pytest.approx(best, rel=5e-3)


def test_sphere():
    """A sphere (icosphere levels 2 and 3, Richardson with order 2): 4 pi eps R within 0.1 %."""
    R = 1e-4
    st = bem.BemSettings(refinement=2.0, levels=2, max_levels=2, tolerance=1.0)
    m = bem.converged(lambda k: [icosphere(R, 2 + k)], ["s"], EPS0, R, st, h_max=R)
    assert m.matrix[0, 0] == pytest.approx(4 * math.pi * EPS0 * R, rel=1e-3, abs=0)


def rigid_z(x, y):
    """The basis of a rigid vertical translation."""
    return np.ones((np.size(x), 1))


def sandwich() -> bem.PreparedBem:
    """A 100 um disk between a full disk above and an 8-slot-split pair of half rings below."""
    plate = DiskPlate(100 * UM)
    els = [
        Electrode(AnnularSector("top", 0.0, 100 * UM, 0.0, 2 * math.pi), "above", 10 * UM),
        Electrode(AnnularSector("b1", 20 * UM, 110 * UM, 0.0, math.pi, 8 * UM), "below", 10 * UM),
        Electrode(AnnularSector("b2", 20 * UM, 110 * UM, math.pi, 2 * math.pi, 8 * UM), "below", 10 * UM),
    ]
    ext = bem.BemExtractor(eps=EPS0, thickness=4 * UM, settings=bem.BemSettings(edge_to_gap=1.0, tolerance=1.0))
    return ext.prepare(els, plate, rigid_z)


@pytest.fixture(scope="module")
def prepared() -> bem.PreparedBem:
    return sandwich()


def test_maxwell_symmetric_and_rows(prepared):
    """Symmetric to 1e-6 relative; diagonal positive, off-diagonal negative; the rows sum to the
    capacitances to infinity: their total is the capacitance of all conductors joined into one,
    solved as one conductor (one right-hand side, an independent solve)."""
    m = prepared.maxwell(np.zeros(1))
    c = m.matrix
    assert np.abs(c - c.T).max() < 1e-6 * np.abs(c).max()
    assert (np.diag(c) > 0).all() and (c[~np.eye(len(c), dtype=bool)] < 0).all()
    assert (m.to_infinity > 0).all() and np.allclose(m.to_infinity, c.sum(axis=1))
    st = prepared.settings
    joined = []
    for k in range(2):
        parts = prepared.surfaces(np.zeros(1), k)
        off = np.cumsum([0] + [len(p.vertices) for p in parts])
        joined.append(
            [
                Surface(
                    np.concatenate([p.vertices for p in parts]),
                    np.concatenate([p.triangles + o for p, o in zip(parts, off)]),
                )
            ]
        )
    # the same mesh levels and quadrature rule as prepared.maxwell (its h_max sets the rule): a
    # different rule moves C by ~6e-6, the same one leaves only rounding
    h_max = st.sizes(prepared.gap, 0, prepared.plate_size).h_max
    gap = min(prepared.local_gap(np.zeros(1)), prepared.gap)
    whole = bem.converged(lambda k: joined[k], ["all"], EPS0, gap, st, h_max=h_max)
    assert whole.matrix[0, 0] == pytest.approx(c.sum(), rel=1e-9, abs=0)
    # electrode-electrode coupling of the two slotted halves is what the extractor's coupling gives
    assert m.coupling[1, 2] == pytest.approx(-c[2, 3], abs=0) and m.coupling[1, 2] > 0


def test_translation_toward_electrode_is_monotone(prepared):
    """Moving the plate up (toward 'top') raises C(top) and lowers both lower electrodes' C."""
    zs = np.array([-0.3, 0.0, 0.15, 0.3]) * prepared.gap
    c = prepared.capacitance(zs[:, None])
    assert (np.diff(c[:, 0]) > 0).all()
    assert (np.diff(c[:, 1]) < 0).all() and (np.diff(c[:, 2]) < 0).all()
    # the two halves are mirror images, meshed apart: they agree to the solve's discretisation
    # error (its Richardson estimate), not to rounding (3.6e-5 apart at z = -0.3 g)
    error = prepared.maxwell(zs[:1]).error
    assert c[0, 1] == pytest.approx(c[0, 2], rel=error, abs=0)


def test_memory_budget_stops_with_a_clear_error():
    """A budget smaller than the coarse dense matrix: BemBudgetError naming the unknowns and budget."""
    st = bem.BemSettings(memory_budget=1e5)
    with pytest.raises(bem.BemBudgetError, match=r"unknowns need .* memory budget of 0\.0 GB"):
        bem.converged(lambda k: [disk_sheet(1.0, st.sizes(0.1, k))], ["d"], 1.0, 0.1, st)
    assert bem.BemBudgetError.exit_code == 1


def test_registry_and_quadrature_rule():
    """[electrostatics] extractor = "bem" is registered; the quadrature order follows the
    element-to-gap rule of docs/bem.md, 'Quadrature and element size', and refuses elements over 8 gaps."""
    assert EXTRACTORS["bem"] is bem.from_structure
    assert [bem.quadrature_order(r) for r in (1.0, 2.0, 3.0, 4.0, 4.3, 4.5, 8.0)] == [4, 4, 8, 8, 8, 12, 12]
    with pytest.raises(bem.BemBudgetError, match="element_to_gap"):
        bem.quadrature_order(9.0)


@pytest.mark.parametrize("n,block", [(700, 64), (1000, 300)])
def test_blocked_cholesky_equals_lapack_lu(n, block):
    """The blocked Cholesky (used above bem.LU_LIMIT unknowns, where OpenBLAS's threaded getrf
    segfaults) against LAPACK's LU on a symmetric positive definite system, blocks not dividing n."""
    from scipy.linalg import lu_factor, lu_solve

    rng = np.random.default_rng(3)
    M = rng.standard_normal((n, n))
    A = M @ M.T / n + np.eye(n)
    B = rng.standard_normal((n, 4))
    ref = lu_solve(lu_factor(A), B)
    X = bem.dense_solve(A.copy(), B, limit=0, block=block)
    assert np.abs(X - ref).max() <= 1e-10 * np.abs(ref).max()


def test_blocked_cholesky_refuses_an_indefinite_matrix():
    """A matrix with a negative eigenvalue is not a single-layer matrix: a clear BemSolveError."""
    A = np.diag([1.0, 2.0, -1.0, 3.0])
    with pytest.raises(bem.BemSolveError, match="not positive definite"):
        bem.dense_solve(A, np.ones((4, 1)), limit=0, block=2)
