"""A 2-D Laplace solver for conductor cross-sections: per-unit-length Maxwell capacitance matrices.

The domain is a box (netgen.electrostatics.mesh2d): each side is open (zero normal field: the box
is far enough that the truncated field is negligible, `Solution.levels` records the box check),
grounded (a conductor at 0 V, e.g. a substrate) or, for the left/right pair, periodic. Conductors
are rectangles, disks and zero-thickness strips, each a Dirichlet set of a named conductor.

The solve is scikit-fem P2 (default) or P1 on a graded mesh (mesh2d.sizing), one sparse LU
(scipy.sparse.linalg.splu) for all conductors' right-hand sides, and C_ij = u_i^T K u_j (the
field energies, equal to the residual charges). A solve remeshes with ever finer sizes (the
corner size shrinking fastest: geometric grading toward the singular corners and strip ends)
until the largest relative change of a matrix entry is below `tol`; the levels (elements,
dofs, matrix) are kept for the record.
2-D capacitances per unit length are scale free: coordinates are divided by a reference length
before meshing, so any unit (m, um) gives the same C' in F/m.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu
from skfem import Basis, BilinearForm, ElementTriP1, ElementTriP2, MeshTri, asm
from skfem.helpers import dot, grad

from ..core.constants import EPS0
from . import mesh2d
from .mesh2d import Disk, Shape

Array = np.ndarray
SIDES = ("bottom", "right", "top", "left")
GROUND = "ground"


@dataclass(frozen=True)
class Conductor:
    """A named conductor made of one or more shapes (mesh2d.Rect, Disk, Strip)."""

    name: str
    shapes: tuple[Shape, ...]


@dataclass(frozen=True)
class Problem:
    """A cross-section: conductors in the box (x0, y0, x1, y1) with side conditions.

    sides: per side "open" (zero normal field) or "ground" (0 V); `periodic` joins left and
    right (their conditions are then ignored). eps: permittivity in F/m. A conductor named
    "ground" is held at 0 V with the grounded sides and is not a row of the matrix.
    """

    conductors: tuple[Conductor, ...]
    box: tuple[float, float, float, float]
    sides: dict[str, str] = field(default_factory=lambda: dict.fromkeys(SIDES, "open"))
    periodic: bool = False
    eps: float = EPS0

    def names(self) -> tuple[str, ...]:
        """The conductors of the matrix, in order (ground excluded)."""
        return tuple(c.name for c in self.conductors if c.name != GROUND)

    def shapes(self) -> tuple[Shape, ...]:
        """All conductor shapes."""
        return tuple(s for c in self.conductors for s in c.shapes)


@dataclass(frozen=True)
class Level:
    """One mesh of a convergence run: its size and the matrix found on it."""

    elements: int
    dofs: int
    capacitance: Array


@dataclass
class Solution:
    """The converged per-unit-length Maxwell matrix (F/m) and how it was reached.

    capacitance[i, j]: charge on conductor i per volt on conductor j (others and ground at 0 V);
    change: the last level's largest relative entry change (the convergence measure);
    box_change: the relative change when the open box is doubled (None: not checked).
    """

    names: tuple[str, ...]
    capacitance: Array
    levels: list[Level]
    converged: bool
    change: float
    settings: dict
    box_change: float | None = None
    state: Discrete | None = None

    def mutual(self, a: str, b: str) -> float:
        """The two-terminal capacitance between conductors a and b: -C_ab (F/m)."""
        return -float(self.capacitance[self.names.index(a), self.names.index(b)])

    def to_ground(self, a: str) -> float:
        """Conductor a's capacitance to ground: the row sum of the matrix (F/m)."""
        return float(self.capacitance[self.names.index(a)].sum())

    def charge(self, on: str, excited: str, weight: Callable[[Array, Array], Array]) -> float:
        """Charge (C/m) on the part of conductor `on` that `weight(x, y)` selects (0..1 per
        degree of freedom) with 1 V on `excited`: the residual charges of the finest level, so
        weights that add to one on every dof split the matrix entry exactly."""
        return self.state.charge(self.names.index(on), self.names.index(excited), weight)


@dataclass
class Discrete:
    """The finest level's assembled system: reduced stiffness, solutions, dof positions, sets."""

    K: sp.csr_matrix
    U: Array
    x: Array
    y: Array
    sets: list[Array]
    scale: float

    def charge(self, on: int, excited: int, weight: Callable[[Array, Array], Array]) -> float:
        """See Solution.charge."""
        r = self.K @ self.U[:, excited]
        d = self.sets[on]
        return float((r[d] * weight(self.x[d] * self.scale, self.y[d] * self.scale)).sum())


def open_box(
    conductors: tuple[Conductor, ...], margin: float = 100.0, ground_bottom: float | None = None
) -> tuple[float, float, float, float]:
    """A box `margin` times the conductors' extent around them; with ground_bottom, the box's
    bottom is that y (a ground plane) and it extends margin * extent above the top."""
    pts = np.concatenate([mesh2d.boundary_samples(s, 8) for c in conductors for s in c.shapes])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    size = float(max(hi - lo))
    cx = 0.5 * (lo[0] + hi[0])
    y0 = ground_bottom if ground_bottom is not None else lo[1] - margin * size
    return (cx - margin * size, y0, cx + margin * size, hi[1] + margin * size)


def scaled(problem: Problem, s: float) -> Problem:
    """The problem with every length divided by s (capacitances per length are unchanged)."""

    def shape(q: Shape) -> Shape:
        if isinstance(q, Disk):
            return Disk(q.cx / s, q.cy / s, q.r / s)
        return type(q)(q.x0 / s, q.y0 / s, q.x1 / s, q.y1 / s)

    conductors = tuple(Conductor(c.name, tuple(shape(q) for q in c.shapes)) for c in problem.conductors)
    return Problem(conductors, tuple(b / s for b in problem.box), problem.sides, problem.periodic, problem.eps)


def reference_length(problem: Problem) -> float:
    """The smallest conductor size or gap: the unit lengths are divided by."""
    shapes = problem.shapes()
    L = min([q.size() for q in shapes if q.size() > 0] + [mesh2d.min_gap(shapes), box_clearance(problem)])
    if not L > 0:
        raise ValueError("field2d: conductors touch each other or a grounded side (no gap to mesh)")
    return L


def box_clearance(problem: Problem) -> float:
    """Smallest distance of a conductor to a grounded side of the box (inf if none is grounded)."""
    pts = np.concatenate([mesh2d.boundary_samples(q, 8) for q in problem.shapes()])
    x0, y0, x1, y1 = problem.box
    d = {"bottom": pts[:, 1] - y0, "top": y1 - pts[:, 1], "left": pts[:, 0] - x0, "right": x1 - pts[:, 0]}
    grounded = [float(d[k].min()) for k, v in problem.sides.items() if v == "ground"]
    return min(grounded, default=math.inf)


def initial_mesh(problem: Problem, scale: float = 1.0, grade: float = 0.25) -> MeshTri:
    """The graded starting mesh of a (scaled) problem."""
    h = mesh2d.sizing(problem.shapes(), problem.box, scale, grade)
    m = mesh2d.build(problem.shapes(), problem.box, h, problem.periodic)
    return MeshTri(m.p.T.copy(), m.t.T.copy())


def on_shape(q: Shape, x: Array, y: Array, tol: float) -> Array:
    """True for points on the boundary of shape q (within tol)."""
    if isinstance(q, Disk):
        return np.abs(np.hypot(x - q.cx, y - q.cy) - q.r) < tol
    pts = np.c_[np.ravel(x), np.ravel(y)]
    d = mesh2d.segment_distance(pts, np.array([a for a, _ in q.segments()]), np.array([b for _, b in q.segments()]))
    return (d < tol).reshape(np.shape(x))


@BilinearForm
def laplace(u, v, w):
    """The Laplace stiffness form grad u . grad v (the permittivity multiplies the result)."""
    return dot(grad(u), grad(v))


def dof_sets(problem: Problem, basis: Basis, tol: float) -> tuple[list[Array], Array]:
    """Dirichlet dofs of each named conductor (Problem.names order) and of ground."""
    mesh = basis.mesh

    def dofs(test: Callable[[Array], Array]) -> Array:
        facets = mesh.facets_satisfying(test)
        return np.unique(basis.get_dofs(facets=facets).all()) if facets.size else np.zeros(0, dtype=int)

    ends = mesh.p[:, mesh.facets]  # (2, 2 ends, nfacets)
    boundary = np.zeros(mesh.nfacets, dtype=bool)
    boundary[mesh.boundary_facets()] = True
    sets = {}
    for c in problem.conductors:
        hit = np.zeros(mesh.nfacets, dtype=bool)
        mid = 0.5 * (ends[:, 0] + ends[:, 1])
        for q in c.shapes:
            if isinstance(q, Disk):  # chords of the circle: both ends on it, on the mesh boundary
                hit |= boundary & on_shape(q, ends[0, 0], ends[1, 0], tol) & on_shape(q, ends[0, 1], ends[1, 1], tol)
            else:
                hit |= on_shape(q, mid[0], mid[1], tol)
        f = np.flatnonzero(hit)
        sets[c.name] = np.unique(basis.get_dofs(facets=f).all()) if f.size else np.zeros(0, dtype=int)
    x0, y0, x1, y1 = problem.box
    where = {
        "bottom": lambda x: np.abs(x[1] - y0) < tol,
        "top": lambda x: np.abs(x[1] - y1) < tol,
        "left": lambda x: np.abs(x[0] - x0) < tol,
        "right": lambda x: np.abs(x[0] - x1) < tol,
    }
    ground = [sets.pop(GROUND, np.zeros(0, dtype=int))]
    for side, kind in problem.sides.items():
        if kind == "ground" and not (problem.periodic and side in ("left", "right")):
            ground.append(dofs(where[side]))
    return [sets[n] for n in problem.names()], np.unique(np.concatenate(ground)).astype(int)


def periodic_map(problem: Problem, doflocs: Array, tol: float) -> Array:
    """For each dof the dof it is identified with: right-side dofs -> the left-side dof at the same y."""
    x0, _, x1, _ = problem.box
    master = np.arange(doflocs.shape[1])
    if not problem.periodic:
        return master
    left = np.flatnonzero(np.abs(doflocs[0] - x0) < tol)
    right = np.flatnonzero(np.abs(doflocs[0] - x1) < tol)
    ol, orr = left[np.argsort(doflocs[1, left])], right[np.argsort(doflocs[1, right])]
    if len(ol) != len(orr) or np.abs(doflocs[1, ol] - doflocs[1, orr]).max(initial=0.0) > tol:
        raise RuntimeError("field2d: the periodic sides' dofs do not match")
    master[orr] = ol
    return master


def discrete_solve(problem: Problem, mesh: MeshTri, order: int, scale: float) -> tuple[Array, Discrete]:
    """Maxwell matrix (F/m) on one mesh: one LU of the free block, every conductor's right-hand side."""
    basis = Basis(mesh, ElementTriP2() if order == 2 else ElementTriP1())
    tol = 1e-9 * max(problem.box[2] - problem.box[0], problem.box[3] - problem.box[1])
    K = asm(laplace, basis).tocsr() * problem.eps
    master = periodic_map(problem, basis.doflocs, tol)
    keep, ridx = np.unique(master, return_inverse=True)
    P = sp.csr_matrix((np.ones(len(master)), (np.arange(len(master)), ridx)), shape=(len(master), len(keep)))
    Kr = (P.T @ K @ P).tocsr()
    sets, ground = dof_sets(problem, basis, tol)
    sets = [np.unique(ridx[s]) for s in sets]
    fixed = np.unique(np.concatenate(sets + [ridx[ground]])).astype(int)
    free = np.setdiff1d(np.arange(len(keep)), fixed)
    G = np.zeros((len(keep), len(sets)))
    for i, s in enumerate(sets):
        G[s, i] = 1.0
    lu = splu(Kr[free][:, free].tocsc())
    U = G.copy()
    U[free] = lu.solve(-(Kr[free][:, fixed] @ G[fixed]))
    C = U.T @ (Kr @ U)
    x, y = basis.doflocs[0, keep], basis.doflocs[1, keep]
    return 0.5 * (C + C.T), Discrete(Kr, U, x, y, sets, scale)


def relative_change(C: Array, prev: Array) -> float:
    """Largest entry change relative to the entry (floored at 1 % of the largest diagonal)."""
    floor = 1e-2 * np.abs(np.diag(C)).max()
    return float((np.abs(C - prev) / np.maximum(np.abs(C), floor)).max())


def doubled_box(problem: Problem) -> Problem:
    """The problem with every open side moved twice as far from the conductors."""
    pts = np.concatenate([mesh2d.boundary_samples(q, 8) for q in problem.shapes()])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    x0, y0, x1, y1 = problem.box

    def grow(side: str, v: float, edge: float) -> float:
        return v + (v - edge) if problem.sides.get(side) == "open" else v

    if problem.periodic:
        box = (x0, y0, x1, grow("top", y1, hi[1]))
        box = (x0, grow("bottom", y0, lo[1]), x1, box[3])
    else:
        box = (grow("left", x0, lo[0]), grow("bottom", y0, lo[1]), grow("right", x1, hi[0]), grow("top", y1, hi[1]))
    return Problem(problem.conductors, box, problem.sides, problem.periodic, problem.eps)


def solve(
    problem: Problem,
    tol: float = 1e-3,
    order: int = 2,
    max_levels: int = 4,
    mesh_scale: float = 1.0,
    grade: float = 0.25,
    check_box: bool = False,
) -> Solution:
    """The Maxwell matrix of `problem`: meshes of scale mesh_scale * 2^-k (mesh2d.sizing: the
    corner size shrinks 8x, the edge size 2x per level) until the largest relative entry change
    is below tol (at most max_levels meshes); check_box also solves the first level in the
    doubled box and records the relative change."""
    L = reference_length(problem)
    p = scaled(problem, L)
    levels: list[Level] = []
    prev, change, state = None, math.inf, None
    for k in range(max_levels):
        mesh = initial_mesh(p, mesh_scale * 0.5**k, grade)
        C, state = discrete_solve(p, mesh, order, L)
        levels.append(Level(int(mesh.nelements), int(state.K.shape[0]), C))
        if prev is not None:
            change = relative_change(C, prev)
            if change < tol:
                break
        prev = C
    box_change = None
    if check_box:
        big = scaled(doubled_box(problem), L)
        Cb, _ = discrete_solve(big, initial_mesh(big, mesh_scale, grade), order, L)
        box_change = relative_change(Cb, levels[0].capacitance)
    settings = {
        "order": order,
        "tol": tol,
        "max_levels": max_levels,
        "mesh_scale": mesh_scale,
        "grade": grade,
        "reference_length": L,
        "box": problem.box,
        "periodic": problem.periodic,
        "sides": dict(problem.sides),
    }
    return Solution(problem.names(), levels[-1].capacitance, levels, change < tol, change, settings, box_change, state)
