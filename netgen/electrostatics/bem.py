"""The boundary-element extractor: the full Maxwell capacitance matrix of the moving plate and
every fixed electrode, from bempp-cl's Laplace single layer (Galerkin, piecewise constants).

Each conductor is a graded triangulation (netgen.electrostatics.bem_mesh): the plate is moved
by its generalized coordinates q (rigid motion and mode shapes, w = basis(x, y) q, applied to
every plate vertex), electrodes are sheets at their gaps. One dense matrix A (V sigma = u), one
LU factorisation (blocked Cholesky above LU_LIMIT unknowns: dense_solve), one right-hand side
per conductor: C = eps B^T A^-1 B, B the element areas of each conductor.

Accuracy (docs/bem.md, 'Quadrature and element size'): bempp uses one quadrature rule for
all non-touching element pairs, so the element size facing a gap g sets the order: elements up
to 2g need order 4, 4g order 8, 8g order 12 (QUADRATURE). Every solve runs on two mesh levels
(sizes in the ratio BemSettings.refinement) and Richardson-extrapolates; the correction is the
error estimate. A finer level is added while the estimate exceeds the tolerance and the dense
matrix fits BemSettings.memory_budget; past that BemBudgetError says so and stops.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike
from scipy.linalg import cholesky, lu_factor, lu_solve, solve_triangular

from ..core.constants import EPS0
from ..core.errors import SimulationError, SimulatorNotFound, StructureError
from ..geometry.shapes import Array, Basis, Electrode, Plate
from .base import ProbePoints
from .bem_mesh import Sizes, Surface, dihedral_order, electrode_sheet, estimate_elements, thick_plate
from .parallel_plate import ParallelPlateExtractor, PreparedParallelPlate

BEM_INSTALL = "pip install 'netgen[bem]'  (or: pip install bempp-cl==0.4.2)"
# largest element facing a gap, in gaps -> bempp's regular quadrature order (docs/bem.md); a rule
# holds up to SLACK times its limit (a sample point closing a gap by a few % keeps its order)
QUADRATURE: tuple[tuple[float, int], ...] = ((2.0, 4), (4.0, 8), (8.0, 12))
SLACK = 1.1
BYTES_PER_ENTRY = 10.0  # the dense matrix (factorised in place) and bempp's assembly buffers
# largest system for LAPACK's LU (dense_solve). Measured with scipy 1.17.1 (OpenBLAS 0.3.31), 2
# threads: getrf segfaults at 22k unknowns (random and BEM matrices), works at 20k and with one
# thread; an earlier OpenBLAS's threaded potrf segfaulted at 20k (docs/bem.md, 'Costs'). Above it
# the blocked Cholesky, whose threaded parts are matrix products only.
LU_LIMIT = 16000
# bem_mesh.estimate_elements is within this factor of the mesher's count (measured 0.89..1.25 on
# disks, sectors and rectangles, thin and thick plates: bench/bem_estimate.py): a level is refused
# before meshing only when even estimate / ESTIMATE_FACTOR elements exceed the memory budget
ESTIMATE_FACTOR = 1.5


class BemBudgetError(SimulationError):
    """The requested accuracy needs a denser matrix than the memory budget allows."""


class BemSolveError(SimulationError):
    """The dense system could not be factorised (not positive definite)."""


def quadrature_order(ratio: float) -> int:
    """bempp's regular quadrature order for elements `ratio` times the gap they face."""
    for limit, order in QUADRATURE:
        if ratio <= limit * SLACK:
            return order
    raise BemBudgetError(
        f"BEM: elements {ratio:.2f} times the gap they face exceed the largest quadrature "
        f"rule ({QUADRATURE[-1][0] * SLACK:g} gaps, order {QUADRATURE[-1][1]}); lower "
        "BemSettings.element_to_gap"
    )


@dataclass(frozen=True)
class BemSettings:
    """How the BEM meshes and solves (all lengths in units of the smallest plate-electrode gap).

    element_to_gap: largest element (sets the quadrature order, QUADRATURE); edge_to_gap:
    element size at free edges; growth: size ratio of neighbouring elements; refinement: size
    ratio between mesh levels; levels / max_levels: levels always solved / at most; tolerance:
    relative error estimate to reach; richardson_order: convergence order assumed for the
    extrapolation (None: report the finest level, error = last change); memory_budget: bytes
    for the dense matrix of the finest level; singular_order: quadrature of touching pairs;
    element_to_size: largest element in units of the plate's size (radius, shorter side);
    quadrature_order: the regular order (None: the QUADRATURE rule; from_structure refuses one
    below the rule). A structure file sets them in [electrostatics.bem] (netgen.structure.bem_table).
    """

    element_to_gap: float = 4.0
    edge_to_gap: float = 0.5
    growth: float = 1.5
    refinement: float = math.sqrt(2.0)
    levels: int = 2
    max_levels: int = 3
    tolerance: float = 5e-3
    richardson_order: float | None = 2.0
    memory_budget: float = 4e9
    singular_order: int = 4
    element_to_size: float = 0.2
    quadrature_order: int | None = None  # regular quadrature order; None: QUADRATURE's rule for element_to_gap

    def sizes(self, gap: float, level: int, size: float = math.inf) -> Sizes:
        """Element sizes (m) of mesh level `level` (0 = coarsest) for the smallest gap `gap` and
        a plate of `size` (radius or shorter side): elements are also at most element_to_size
        times the plate, so that a wide gap does not leave its outline unresolved."""
        f = 1.0 / self.refinement**level
        h_max = min(self.element_to_gap * gap, self.element_to_size * size)
        return Sizes(min(self.edge_to_gap * gap, h_max / 2.0) * f, h_max * f, self.growth)


@dataclass(frozen=True)
class MaxwellMatrix:
    """One BEM solve: the Maxwell (short-circuit) matrix, Q = matrix @ V, in F; conductor 0 is
    the moving plate, then the electrodes in the order given."""

    names: tuple[str, ...]
    matrix: Array  # (n+1, n+1) best estimate (Richardson-extrapolated)
    coarse: Array  # (n+1, n+1) the next coarser level's solution
    error: float  # estimated relative error of plate_electrode (max over electrodes)
    settings: dict = field(default_factory=dict)

    @property
    def plate_electrode(self) -> Array:
        """(n,) two-terminal plate-electrode capacitances, -matrix[0, 1:]."""
        return -self.matrix[0, 1:]

    @property
    def coupling(self) -> Array:
        """(n, n) electrode-electrode two-terminal capacitances (zero diagonal): the convention
        of CapacitanceExtractor.coupling."""
        c = -self.matrix[1:, 1:].copy()
        np.fill_diagonal(c, 0.0)
        return c

    @property
    def to_infinity(self) -> Array:
        """(n+1,) each conductor's capacitance to infinity (the row sums)."""
        return self.matrix.sum(axis=1)


def _bempp():
    """bempp_cl.api, or SimulatorNotFound saying how to install it."""
    try:
        import bempp_cl.api as bempp
    except ImportError:
        raise SimulatorNotFound(f"the BEM extractor needs bempp-cl; install it with: {BEM_INSTALL}") from None
    return bempp


def check_budget(unknowns: int, budget: float, what: str = "") -> None:
    """BemBudgetError when the dense system of `unknowns` does not fit `budget` bytes."""
    need = BYTES_PER_ENTRY * unknowns * unknowns
    if need > budget:
        raise BemBudgetError(
            f"BEM{what}: {unknowns} unknowns need {need / 1e9:.1f} GB for the dense matrix, above "
            f"the memory budget of {budget / 1e9:.1f} GB; raise BemSettings.memory_budget, "
            "loosen tolerance or element_to_gap, or use a calibrated analytic extractor"
        )


def single_layer(surfaces: Sequence[Surface], order: int, singular_order: int = 4) -> tuple[Array, Array]:
    """bempp's dense Galerkin P0 single-layer matrix (N, N) of the triangulated conductors at
    regular quadrature `order` (symmetrised), and B (N, n): element areas in their conductor's column."""
    bempp = _bempp()
    from bempp_cl.api.utils.parameters import DefaultParameters

    offsets = np.cumsum([0] + [len(s.vertices) for s in surfaces])
    verts = np.concatenate([s.vertices for s in surfaces]).T
    tris = np.concatenate([s.triangles + o for s, o in zip(surfaces, offsets)]).T.astype(np.uint32)
    dom = np.concatenate([np.full(len(s.triangles), i) for i, s in enumerate(surfaces)]).astype(np.uint32)
    grid = bempp.Grid(verts, tris, dom)
    space = bempp.function_space(grid, "DP", 0)
    params = DefaultParameters()
    params.quadrature.regular, params.quadrature.singular = order, singular_order
    op = bempp.operators.boundary.laplace.single_layer(
        space, space, space, parameters=params, assembler="dense", device_interface="numba", precision="double"
    )
    A = symmetrised(np.asarray(op.weak_form().to_dense()))
    # element i of the grid is element i of the concatenation (bempp keeps the given order)
    areas, owner = np.asarray(grid.volumes), np.asarray(grid.domain_indices)
    B = np.zeros((len(areas), len(surfaces)))
    B[np.arange(len(areas)), owner] = areas
    return A, B


def solve_surfaces(
    surfaces: Sequence[Surface], eps: float, order: int, singular_order: int = 4, budget: float = 4e9
) -> tuple[Array, dict]:
    """Maxwell matrix (n, n) in F of conductors given as triangulated surfaces, with bempp's
    dense single layer at quadrature `order`; and what the solve cost (elements, seconds)."""
    n_el = sum(len(s.triangles) for s in surfaces)
    check_budget(n_el, budget)
    t0 = time.perf_counter()
    A, B = single_layer(surfaces, order, singular_order)
    t1 = time.perf_counter()
    X = dense_solve(A, B)
    C = eps * (B.T @ X)
    t2 = time.perf_counter()
    return C, {"elements": int(n_el), "order": int(order), "assembly_s": t1 - t0, "solve_s": t2 - t1}


def dense_solve(A: Array, B: Array, limit: int = LU_LIMIT, block: int = 2048) -> Array:
    """A^-1 B for the symmetric single-layer matrix A (C order, destroyed): LAPACK's LU up to
    `limit` unknowns; above it a blocked Cholesky on matrix products (cholesky_blocked), since
    OpenBLAS's threaded getrf and potrf segfault on larger matrices (LU_LIMIT)."""
    if len(A) <= limit:
        # A.T is Fortran-ordered: getrf factorises it in place (no copy); trans=1 then solves A X = B
        return lu_solve(lu_factor(A.T, overwrite_a=True, check_finite=False), B, trans=1, check_finite=False)
    return cholesky_solve(cholesky_blocked(A, block), B, block)


def cholesky_blocked(A: Array, block: int = 2048) -> Array:
    """A = L L^T in place (L in the lower triangle; the upper is left as it was), right-looking by
    column blocks: LAPACK potrf only on block x block diagonal blocks, the panel by a triangular
    solve, the trailing update by matrix products row block by row block (at most block x N of
    temporaries); BemSolveError if A is not positive definite."""
    n = len(A)
    for k in range(0, n, block):
        e = min(k + block, n)
        try:
            lkk = cholesky(A[k:e, k:e], lower=True, check_finite=False)
        except np.linalg.LinAlgError:
            raise BemSolveError(
                f"BEM: the single-layer matrix is not positive definite ({n} unknowns, block "
                f"at {k}): a mesh with overlapping or touching conductors; check the gaps"
            ) from None
        A[k:e, k:e] = lkk
        if e == n:
            break
        panel = solve_triangular(lkk, A[e:, k:e].T, lower=True, check_finite=False).T
        A[e:, k:e] = panel
        for j in range(e, n, block):
            f = min(j + block, n)
            A[j:f, e:f] -= panel[j - e : f - e] @ panel[: f - e].T
    return A


def cholesky_solve(L: Array, B: Array, block: int = 2048) -> Array:
    """X = (L L^T)^-1 B by block forward and back substitution on cholesky_blocked's lower triangle."""
    n = len(L)
    Y = np.array(B, dtype=float)
    starts = list(range(0, n, block))
    for k in starts:
        e = min(k + block, n)
        Y[k:e] = solve_triangular(L[k:e, k:e], Y[k:e] - L[k:e, :k] @ Y[:k], lower=True, check_finite=False)
    for k in reversed(starts):
        e = min(k + block, n)
        Y[k:e] = solve_triangular(L[k:e, k:e], Y[k:e] - L[e:, k:e].T @ Y[e:], lower=True, trans=1, check_finite=False)
    return Y


def symmetrised(A: Array, block: int = 1024) -> Array:
    """(A + A^T) / 2 in place, block by block (no second N x N array). The Galerkin single layer
    is symmetric; bempp's quadrature of the pairs (i, j) and (j, i) differs by a few 1e-6 of C,
    and the symmetric part is the better of the two approximations."""
    n = len(A)
    for i in range(0, n, block):
        for j in range(i, n, block):
            m = 0.5 * (A[i : i + block, j : j + block] + A[j : j + block, i : i + block].T)
            A[i : i + block, j : j + block] = m
            A[j : j + block, i : i + block] = m.T
    return A


def extrapolate(levels: Sequence[Array], ratio: float, order: float | None) -> tuple[Array, float]:
    """Best estimate from solutions on successively finer levels (size ratio `ratio`) and its
    relative error: Richardson with `order` (or, from three levels, the observed order when it
    is between 0.5 and 4); without an order, the finest level and its last change."""
    fine, coarse = levels[-1], levels[-2]
    p = order
    if order is not None and len(levels) >= 3:
        d1, d2 = levels[-2] - levels[-3], fine - coarse
        mask = np.abs(d2) > 1e-9 * np.abs(fine).max()
        if mask.any():
            r = np.median(np.abs(d1[mask] / d2[mask]))
            if r > 1.0:
                observed = math.log(r) / math.log(ratio)
                p = observed if 0.5 <= observed <= 4.0 else order
    best = fine if p is None else fine + (fine - coarse) / (ratio**p - 1.0)
    return best, p


def relative_change(a: Array, b: Array) -> float:
    """Largest |a - b| / |a| over the watched entries: the plate-electrode capacitances a[0, 1:]
    (a single conductor: its capacitance)."""
    ra, rb = (a[0, 1:], b[0, 1:]) if len(a) > 1 else (a[0], b[0])
    keep = np.abs(ra) > 1e-6 * np.abs(ra).max()
    return float(np.max(np.abs(ra[keep] - rb[keep]) / np.abs(ra[keep]))) if keep.any() else 0.0


def converged(
    meshes: Callable[[int], Sequence[Surface]],
    names: Sequence[str],
    eps: float,
    gap: float,
    settings: BemSettings,
    h_max: float | None = None,
    order: int | None = None,
) -> MaxwellMatrix:
    """The Maxwell matrix on `settings.levels` or more mesh levels (meshes(level): the surfaces,
    level 0 coarsest, its largest element h_max (default element_to_gap * gap); `gap`: the
    smallest gap they face), extrapolated; BemBudgetError if the tolerance needs more than the
    memory budget or max_levels. `order` overrides the quadrature rule (differences of solves
    on the same meshes need the same rule)."""
    sols: list[Array] = []
    info: list[dict] = []
    order = order or settings.quadrature_order or quadrature_order((h_max or settings.element_to_gap * gap) / gap)
    err, best, p = math.inf, None, settings.richardson_order
    for level in range(settings.max_levels):
        try:
            C, cost = solve_surfaces(meshes(level), eps, order, settings.singular_order, settings.memory_budget)
        except BemBudgetError as exc:
            if len(sols) < 2:
                raise
            raise BemBudgetError(
                f"{exc} (the error estimate is {err:.2%} after {len(sols)} levels, tolerance {settings.tolerance:.2%})"
            ) from None
        sols.append(C)
        info.append(cost)
        if len(sols) >= settings.levels:
            best, p = extrapolate(sols, settings.refinement, settings.richardson_order)
            err = relative_change(best, sols[-1]) if p is not None else relative_change(sols[-1], sols[-2])
            if err <= settings.tolerance:
                break
    else:
        raise BemBudgetError(
            f"BEM: the error estimate {err:.2%} is above the tolerance {settings.tolerance:.2%} "
            f"after {settings.max_levels} mesh levels; raise BemSettings.max_levels (and the "
            "memory budget) or loosen the tolerance"
        )
    record = {**asdict(settings), "gap": gap, "solves": info, "richardson_order": p}
    return MaxwellMatrix(tuple(names), best, sols[-2], err, record)


def central_differences(
    Q: ArrayLike, step: Array, nel: int, solve_at: Callable[[Array], Callable[[Array], MaxwellMatrix]]
) -> Array:
    """dC_i/dq_v (nsamples, nel, ncoords) by central differences of Maxwell solves; `solve_at(row)`
    is the solve for one sample's neighbours (the field solvers' gradient: BEM and FastCap)."""
    q = np.atleast_2d(np.asarray(Q, dtype=float))
    out = np.empty((q.shape[0], nel, len(step)))
    for i, row in enumerate(q):
        solve = solve_at(row)
        for v in range(len(step)):
            dq = np.zeros(len(step))
            dq[v] = step[v]
            out[i, :, v] = (solve(row + dq).plate_electrode - solve(row - dq).plate_electrode) / (2 * step[v])
    return out[0] if np.ndim(Q) == 1 else out


@dataclass(frozen=True)
class _Level:
    """One mesh level of a prepared structure: the undeformed plate, its basis at the plate
    vertices (nv, ncoords) and the electrode sheets."""

    plate: Surface
    phi: Array
    electrodes: tuple[Surface, ...]


def surely_over(elements: float, budget: float) -> bool:
    """Does a mesh of about `elements` (bem_mesh.estimate_elements) exceed the budget even
    at the low end of the estimate's factor?"""
    return BYTES_PER_ENTRY * (elements / ESTIMATE_FACTOR) ** 2 > budget


def refusal(
    settings: BemSettings, elements: float, culprit: str, source: str | None
) -> SimulationError | StructureError:
    """The error for settings whose always-solved levels cannot fit the budget: a StructureError
    at the culprit key when they came from a structure file, else BemBudgetError."""
    need = BYTES_PER_ENTRY * elements**2
    problem = (
        f"edge_to_gap = {settings.edge_to_gap:g}, element_to_gap = {settings.element_to_gap:g} give about "
        f"{elements:.3g} elements on mesh level {settings.levels - 1} (estimated before meshing, within a factor "
        f"{ESTIMATE_FACTOR:g}), {need / 1e9:.3g} GB for the dense matrix, above the memory budget of "
        f"{settings.memory_budget / 1e9:g} GB"
    )
    fix = (
        f"raise {culprit} (edge_to_gap = 0.5 and element_to_gap = 4 are the defaults), or raise memory_budget_gb, "
        "or use a calibrated analytic extractor"
    )
    if source is None:
        return BemBudgetError(f"BEM: {problem}; {fix}")
    return StructureError(source, f"electrostatics.bem.{culprit}", problem, fix)


class PreparedBem:
    """BemExtractor bound to electrodes, plate and basis: meshes and basis values are computed
    once per level (numpy only, so it pickles to executor workers); every q is a BEM solve."""

    def __init__(
        self,
        electrodes: Sequence[Electrode],
        plate: Plate,
        basis: Basis,
        eps: float,
        thickness: float,
        settings: BemSettings,
        source: str | None = None,
    ):
        """Mesh every level that can fit the memory budget (estimated first: refused before any
        meshing when an always-solved level cannot); the parallel-plate geometry answers min_gap
        and probe_points. `source`: the structure file the settings came from."""
        self.electrodes = tuple(electrodes)
        self.eps, self.thickness, self.settings = eps, thickness, settings
        self.geometry: PreparedParallelPlate = ParallelPlateExtractor(eps=eps, fringe=None).prepare(
            electrodes, plate, basis
        )
        self.ncoords = self.geometry.ncoords
        self.gap = min(e.gap for e in electrodes)
        self.plate_size = plate.size
        self.names = ("plate",) + tuple(e.name for e in electrodes)
        self.estimates = [self._estimate(plate, settings, k) for k in range(settings.max_levels)]
        if surely_over(self.estimates[settings.levels - 1], settings.memory_budget):
            edge_only = self._estimate(
                plate, replace(settings, edge_to_gap=max(settings.edge_to_gap, 0.5)), settings.levels - 1
            )
            culprit = "element_to_gap" if surely_over(edge_only, settings.memory_budget) else "edge_to_gap"
            raise refusal(settings, self.estimates[settings.levels - 1], culprit, source)
        self.levels: list[_Level | None] = [
            None if surely_over(n, settings.memory_budget) else self._level(plate, basis, k)
            for k, n in enumerate(self.estimates)
        ]

    def _estimate(self, plate: Plate, settings: BemSettings, k: int) -> float:
        """Elements of mesh level k, from the sizes alone (bem_mesh.estimate_elements)."""
        return estimate_elements(plate, self.thickness, self.electrodes, settings.sizes(self.gap, k, plate.size))

    def _level(self, plate: Plate, basis: Basis, k: int) -> _Level:
        """Meshes of level k: the plate (closed if thick) and each electrode at its height."""
        sizes = self.settings.sizes(self.gap, k, plate.size)
        m = dihedral_order(self.electrodes)
        p = thick_plate(plate, self.thickness, sizes, m)
        phi = np.asarray(basis(p.vertices[:, 0], p.vertices[:, 1]), dtype=float).reshape(len(p.vertices), -1)
        half = self.thickness / 2.0
        sheets = tuple(electrode_sheet(e, sizes, e.sign * (half + e.gap), m) for e in self.electrodes)
        return _Level(p, phi, sheets)

    def surfaces(self, q: ArrayLike, level: int) -> list[Surface]:
        """The conductors at coordinates q on mesh level `level`: the moved plate, then the electrodes."""
        lv = self.levels[level]
        if lv is None:  # not meshed: even the low end of its estimate is over the budget
            n = self.estimates[level]
            raise BemBudgetError(
                f"BEM: mesh level {level} would have about {n:.3g} elements (estimated before meshing), "
                f"{BYTES_PER_ENTRY * n * n / 1e9:.3g} GB for the dense matrix, above the memory budget of "
                f"{self.settings.memory_budget / 1e9:.1f} GB; raise BemSettings.memory_budget, loosen tolerance "
                "or element_to_gap, or use a calibrated analytic extractor"
            )
        return [lv.plate.moved(lv.phi @ np.asarray(q, dtype=float)), *lv.electrodes]

    def local_gap(self, q: ArrayLike) -> float:
        """Smallest local plate-electrode gap at q (m)."""
        g = self.geometry.min_gap(np.asarray(q, dtype=float))
        return float(np.min(g[np.isfinite(g)])) if np.isfinite(g).any() else self.gap

    def maxwell(self, q: ArrayLike, order: int | None = None) -> MaxwellMatrix:
        """The converged Maxwell matrix at generalized coordinates q (ncoords,); `order`: the
        quadrature order (default: from the element-to-gap rule at q's smallest local gap)."""
        q = np.asarray(q, dtype=float).reshape(self.ncoords)
        gap = self.local_gap(q)
        if gap <= 0.0:
            raise ValueError("the plate touches an electrode at this q")
        t0 = time.perf_counter()
        m = converged(
            lambda k: self.surfaces(q, k),
            self.names,
            self.eps,
            min(gap, self.gap),
            self.settings,
            h_max=self.settings.sizes(self.gap, 0, self.plate_size).h_max,
            order=order,
        )
        m.settings["seconds"] = time.perf_counter() - t0
        return m

    def capacitance(self, Q: ArrayLike) -> Array:
        """Plate-electrode capacitances (nsamples, nelectrodes) in F; nan where the plate touches."""
        q = np.atleast_2d(np.asarray(Q, dtype=float))
        out = np.full((q.shape[0], len(self.electrodes)), np.nan)
        for i, row in enumerate(q):
            if self.local_gap(row) > 0.0:
                out[i] = self.maxwell(row).plate_electrode
        return out[0] if np.ndim(Q) == 1 else out

    def gradient(self, Q: ArrayLike) -> Array:
        """dC_i/dq_v (nsamples, nelectrodes, ncoords) by central differences of BEM solves on the
        same meshes (a step closing 1 % of the smallest gap), each sample's quadrature order fixed."""
        amp = np.abs(self.geometry.probe.phi).max(axis=0)
        step = 0.01 * self.gap / np.where(amp > 0, amp, 1.0)
        h_max = self.settings.sizes(self.gap, 0, self.plate_size).h_max

        def solve_at(row: Array) -> Callable[[Array], MaxwellMatrix]:
            order = self.settings.quadrature_order or quadrature_order(h_max / min(self.local_gap(row), self.gap))
            return lambda x: self.maxwell(x, order)

        return central_differences(Q, step, len(self.electrodes), solve_at)

    def min_gap(self, Q: ArrayLike) -> Array:
        """Smallest local gap under each electrode (the parallel-plate geometry's)."""
        return self.geometry.min_gap(Q)

    def probe_points(self) -> ProbePoints:
        """The contact model's stop candidates (the parallel-plate geometry's)."""
        return self.geometry.probe_points()


@dataclass(frozen=True)
class BemExtractor:
    """Boundary-element capacitances (bempp-cl): eps (F/m), plate thickness (m; 0: a sheet),
    settings (BemSettings)."""

    eps: float = EPS0
    thickness: float = 0.0
    settings: BemSettings = field(default_factory=BemSettings)
    source: str | None = None  # the structure file of the settings (errors name it)

    @property
    def description(self) -> str:
        """What it computes and with which settings (the model report's extractor line)."""
        st = self.settings
        order = st.quadrature_order or "by element_to_gap"
        return (
            f"boundary elements (bempp-cl, Galerkin P0, {st.levels}..{st.max_levels} mesh levels + Richardson): "
            f"element_to_gap {st.element_to_gap:g}, edge_to_gap {st.edge_to_gap:g}, refinement {st.refinement:.3g}, "
            f"tolerance {st.tolerance:g}, quadrature {order}/{st.singular_order}, "
            f"memory budget {st.memory_budget / 1e9:g} GB"
        )

    def prepare(self, electrodes: Sequence[Electrode], plate: Plate, basis: Basis) -> PreparedBem:
        """Mesh the structure once (every level); each sample is then a solve."""
        return PreparedBem(electrodes, plate, basis, self.eps, self.thickness, self.settings, self.source)

    def coupling(self, electrodes: Sequence[Electrode], plate: Plate) -> Array:
        """Electrode-electrode capacitances (nel, nel) in F at the undeformed position."""
        prepared = self.prepare(electrodes, plate, lambda x, y: np.zeros((np.size(x), 1)))
        return prepared.maxwell(np.zeros(1)).coupling


def settings_of(s) -> BemSettings:
    """BemSettings from the structure's [electrostatics.bem] table (netgen.structure.bem_table:
    types and ranges checked there), with the limits of the quadrature rules checked here: a
    StructureError naming the file, the key and the fix."""
    given = dict(getattr(s.electrostatics, "bem", ()))
    if "memory_budget_gb" in given:
        given["memory_budget"] = given.pop("memory_budget_gb") * 1e9
    st = BemSettings(**given)
    where = "electrostatics.bem"
    limit = QUADRATURE[-1][0] * SLACK
    if st.element_to_gap > limit:
        raise StructureError(
            s.source,
            f"{where}.element_to_gap",
            f"element_to_gap = {st.element_to_gap:g}: no "
            f"quadrature rule is measured for elements above {limit:g} gaps (QUADRATURE)",
            f"write element_to_gap = {QUADRATURE[-1][0]:g} or less",
        )
    need = quadrature_order(st.element_to_gap)
    if st.quadrature_order is not None and st.quadrature_order < need:
        raise StructureError(
            s.source,
            f"{where}.quadrature_order",
            f"quadrature_order = {st.quadrature_order} is below "
            f"the order {need} that elements of {st.element_to_gap:g} gaps need (coarse quadrature "
            "overestimates C by 3-23 %)",
            f"write quadrature_order = {need} or more, or lower element_to_gap, or drop quadrature_order",
        )
    return st


def from_structure(s, plate: Plate) -> BemExtractor:
    """The extractor for a structure (s: netgen.structure.Structure): its permittivity, thickness
    and [electrostatics.bem] settings."""
    eps = EPS0 * s.electrostatics.relative_permittivity
    thickness = float(getattr(s.conductor, "thickness", 0.0))
    return BemExtractor(eps=eps, thickness=thickness, settings=settings_of(s), source=str(s.source))
