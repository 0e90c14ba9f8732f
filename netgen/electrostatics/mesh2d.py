"""Graded triangle meshes of 2-D conductor cross-sections for netgen.electrostatics.field2d.

The domain is an axis-aligned box with holes (rectangular and round conductors) and embedded
zero-thickness strips. Points come from a quadtree whose cell size follows a sizing function
h(p) = min_f (h_f + grade * dist(p, f)) over the features f (conductor corners, edges, strips),
so the mesh is fine at the corners where the field is singular and coarse far away; the
conductor and box boundaries get their own points at the local h, scipy's Delaunay
triangulates, missing boundary segments are split until present (conforming Delaunay), and the
triangles inside conductors are dropped. A periodic box gets the same points on its left and
right sides, so uniform refinement (skfem's `refined`) keeps the two sides matched.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import Delaunay, cKDTree

Array = np.ndarray


@dataclass(frozen=True)
class Rect:
    """A solid rectangular conductor [x0, x1] x [y0, y1] (a hole in the mesh)."""

    x0: float
    y0: float
    x1: float
    y1: float

    def corners(self) -> Array:
        """The four corners, counter-clockwise from (x0, y0)."""
        return np.array([[self.x0, self.y0], [self.x1, self.y0], [self.x1, self.y1], [self.x0, self.y1]])

    def segments(self) -> list[tuple[Array, Array]]:
        """The four edges as (start, end) pairs."""
        c = self.corners()
        return [(c[i], c[(i + 1) % 4]) for i in range(4)]

    def inside(self, x: Array, y: Array) -> Array:
        """True strictly inside (the hole)."""
        return (x > self.x0) & (x < self.x1) & (y > self.y0) & (y < self.y1)

    def size(self) -> float:
        """The smaller side: the feature length of the sizing function."""
        return min(self.x1 - self.x0, self.y1 - self.y0)


@dataclass(frozen=True)
class Disk:
    """A solid round conductor of radius r centred at (cx, cy)."""

    cx: float
    cy: float
    r: float

    def corners(self) -> Array:
        """No corners: the field on a circle is smooth."""
        return np.zeros((0, 2))

    def segments(self) -> list[tuple[Array, Array]]:
        """No straight edges (the circle is handled by `distance` and `boundary_points`)."""
        return []

    def inside(self, x: Array, y: Array) -> Array:
        """True strictly inside."""
        return (x - self.cx) ** 2 + (y - self.cy) ** 2 < self.r**2

    def size(self) -> float:
        """The radius."""
        return self.r


@dataclass(frozen=True)
class Strip:
    """A zero-thickness conductor along the segment (x0, y0)-(x1, y1) (both faces in the domain)."""

    x0: float
    y0: float
    x1: float
    y1: float

    def corners(self) -> Array:
        """The two ends: edge singularities r^-1/2."""
        return np.array([[self.x0, self.y0], [self.x1, self.y1]])

    def segments(self) -> list[tuple[Array, Array]]:
        """The strip itself."""
        c = self.corners()
        return [(c[0], c[1])]

    def inside(self, x: Array, y: Array) -> Array:
        """A strip has no inside."""
        return np.zeros(np.shape(x), dtype=bool)

    def size(self) -> float:
        """The strip's length."""
        return float(math.hypot(self.x1 - self.x0, self.y1 - self.y0))


Shape = Rect | Disk | Strip


@dataclass(frozen=True)
class Sizing:
    """Mesh size h(p) = min(h_max, min_f (h_f + grade * dist(p, f))): h_corner at corners and
    strip ends, h_edge along edges and circles, growing by `grade` per unit distance."""

    h_corner: float
    h_edge: float
    grade: float
    h_max: float
    corners: Array  # (nc, 2)
    seg_a: Array  # (ns, 2) starts of straight edges
    seg_b: Array  # (ns, 2) ends
    circles: Array  # (nd, 3) cx, cy, r

    def __call__(self, p: Array) -> Array:
        """h at the points p (n, 2)."""
        h = np.full(p.shape[0], self.h_max)
        if self.corners.size:
            d = np.sqrt(((p[:, None, :] - self.corners[None]) ** 2).sum(-1)).min(axis=1)
            h = np.minimum(h, self.h_corner + self.grade * d)
        if self.seg_a.size:
            h = np.minimum(h, self.h_edge + self.grade * segment_distance(p, self.seg_a, self.seg_b))
        for cx, cy, r in self.circles:
            d = np.abs(np.hypot(p[:, 0] - cx, p[:, 1] - cy) - r)
            h = np.minimum(h, self.h_edge + self.grade * d)
        return h


def segment_distance(p: Array, a: Array, b: Array) -> Array:
    """Distance of each point p (n, 2) to the nearest of the segments a-b (m, 2): (n,)."""
    ab = b - a
    L2 = np.maximum((ab**2).sum(-1), 1e-300)
    s = np.clip(((p[:, None, :] - a[None]) * ab[None]).sum(-1) / L2, 0.0, 1.0)
    q = a[None] + s[..., None] * ab[None]
    return np.sqrt(((p[:, None, :] - q) ** 2).sum(-1)).min(axis=1)


def sizing(
    shapes: tuple[Shape, ...], box: tuple[float, float, float, float], scale: float = 1.0, grade: float = 0.25
) -> Sizing:
    """The sizing of a level `scale` (1, 1/2, 1/4, ...): h_corner = scale^3 L/100 (the corner and
    strip-end singularities need the geometric grading to reach far down), h_edge = scale L/6,
    grade * sqrt(scale), where L is the smallest conductor size or conductor-to-conductor gap;
    h_max a tenth of the box."""
    L = min([s.size() for s in shapes if s.size() > 0] + [min_gap(shapes)])
    corners = [s.corners() for s in shapes]
    segs = [seg for s in shapes for seg in s.segments()]
    circles = [(s.cx, s.cy, s.r) for s in shapes if isinstance(s, Disk)]
    x0, y0, x1, y1 = box
    return Sizing(
        scale**3 * L / 100.0,
        scale * L / 6.0,
        grade * math.sqrt(scale),
        max(x1 - x0, y1 - y0) / 10.0,
        np.concatenate(corners) if corners else np.zeros((0, 2)),
        np.array([a for a, _ in segs]).reshape(-1, 2),
        np.array([b for _, b in segs]).reshape(-1, 2),
        np.array(circles).reshape(-1, 3),
    )


def min_gap(shapes: tuple[Shape, ...]) -> float:
    """Smallest distance between two conductors (sampled on their boundaries); inf for one."""
    pts = [boundary_samples(s) for s in shapes]
    best = math.inf
    for i in range(len(pts)):
        for j in range(i + 1, len(pts)):
            d = np.sqrt(((pts[i][:, None, :] - pts[j][None]) ** 2).sum(-1)).min()
            best = min(best, float(d))
    return best


def boundary_samples(s: Shape, n: int = 64) -> Array:
    """n points per edge on a conductor's boundary (for gap estimates)."""
    if isinstance(s, Disk):
        a = np.linspace(0.0, 2 * math.pi, 4 * n, endpoint=False)
        return np.c_[s.cx + s.r * np.cos(a), s.cy + s.r * np.sin(a)]
    u = np.linspace(0.0, 1.0, n)[:, None]
    return np.concatenate([a + u * (b - a) for a, b in s.segments()])


def split_line(a: Array, b: Array, h: Sizing) -> Array:
    """Points from a to b (both included) with spacing at most the local h: dyadic bisection."""
    out = [np.asarray(a, float), np.asarray(b, float)]
    for _ in range(40):
        pts = np.array(out)
        mid = 0.5 * (pts[:-1] + pts[1:])
        long = np.hypot(*(pts[1:] - pts[:-1]).T) > h(mid)
        if not long.any():
            return pts
        new = []
        for k in range(len(pts) - 1):
            new.append(pts[k])
            if long[k]:
                new.append(mid[k])
        new.append(pts[-1])
        out = new
    return np.array(out)


def circle_points(d: Disk, h: Sizing) -> Array:
    """Points on a circle at the local h (at least 16), counter-clockwise."""
    p = np.c_[d.cx + d.r * np.ones(1), d.cy * np.ones(1)]
    n = max(16, int(math.ceil(2 * math.pi * d.r / float(h(p)[0]))))
    a = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    return np.c_[d.cx + d.r * np.cos(a), d.cy + d.r * np.sin(a)]


def quadtree_points(box: tuple[float, float, float, float], h: Sizing) -> Array:
    """Corners of the leaves of a quadtree refined until every cell is no larger than h at its centre."""
    x0, y0, x1, y1 = box
    size = min(x1 - x0, y1 - y0, h.h_max)
    nx, ny = max(1, int(math.ceil((x1 - x0) / size))), max(1, int(math.ceil((y1 - y0) / size)))
    sx, sy = (x1 - x0) / nx, (y1 - y0) / ny
    ix, iy = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    cells = np.c_[x0 + (ix.ravel() + 0.5) * sx, y0 + (iy.ravel() + 0.5) * sy]
    half = np.array([sx, sy]) / 2
    leaves = []
    for _ in range(40):
        split = 2 * half.max() > h(cells)
        leaves.append((cells[~split], half.copy()))
        cells = cells[split]
        if not cells.size:
            break
        half = half / 2
        cells = np.concatenate([cells + half * np.array(o) for o in ((-1, -1), (1, -1), (-1, 1), (1, 1))])
    pts = [c + hh * np.array(o) for c, hh in leaves for o in ((-1, -1), (1, -1), (-1, 1), (1, 1))]
    return np.concatenate(pts)


@dataclass(frozen=True)
class MeshData:
    """A triangulation: points (n, 2), triangles (m, 3) counter-clockwise."""

    p: Array
    t: Array


def build(
    shapes: tuple[Shape, ...], box: tuple[float, float, float, float], h: Sizing, periodic: bool = False
) -> MeshData:
    """The graded conforming triangulation of the box minus the conductors (see the module docstring)."""
    x0, y0, x1, y1 = box
    tol = 1e-9 * max(x1 - x0, y1 - y0)
    segs = boundary_segments(shapes, box, h, periodic)
    bpts = np.concatenate([np.concatenate(chain) for chain in segs])
    inner = quadtree_points(box, h)
    keep = np.ones(len(inner), dtype=bool)
    for s in shapes:
        keep &= ~s.inside(inner[:, 0], inner[:, 1])
    keep &= distance_to_chains(inner, segs) > 0.8 * h(inner)
    pts = unique(np.concatenate([bpts, inner[keep]]), tol)
    chains = [list(chain) for chain in segs]
    for _ in range(30):
        tri = Delaunay(pts)
        missing = missing_segments(tri.simplices, pts, chains, tol)
        if not missing:
            break
        pts = recover(pts, chains, missing, shapes, tol)
    else:
        raise RuntimeError("mesh2d.build: boundary segments not recovered after 30 passes")
    t = tri.simplices
    c = pts[t].mean(axis=1)
    keep = np.ones(len(t), dtype=bool)
    for s in shapes:
        keep &= ~s.inside(c[:, 0], c[:, 1])
    t = t[keep]
    area = cross(pts[t[:, 1]] - pts[t[:, 0]], pts[t[:, 2]] - pts[t[:, 0]])
    longest = np.max([((pts[t[:, i]] - pts[t[:, (i + 1) % 3]]) ** 2).sum(-1) for i in range(3)], axis=0)
    flat = np.abs(area) <= 1e-10 * longest
    t, area = t[~flat], area[~flat]
    t[area < 0] = t[area < 0][:, [0, 2, 1]]
    used = np.unique(t)
    index = np.full(len(pts), -1)
    index[used] = np.arange(len(used))
    return MeshData(pts[used], index[t])


def cross(a: Array, b: Array) -> Array:
    """z-component of the cross product of 2-D vectors, row by row."""
    return a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]


def unique(p: Array, tol: float) -> Array:
    """The points with duplicates (within tol) removed, first occurrence kept."""
    key = np.round(p / (10 * tol)).astype(np.int64)
    _, first = np.unique(key, axis=0, return_index=True)
    return p[np.sort(first)]


def boundary_segments(
    shapes: tuple[Shape, ...], box: tuple[float, float, float, float], h: Sizing, periodic: bool
) -> list[list[Array]]:
    """Chains of boundary points (each a list of point arrays along one edge or circle, closed
    circles repeat their first point): conductor edges, strips and the four box sides."""
    x0, y0, x1, y1 = box
    chains: list[list[Array]] = []
    for s in shapes:
        if isinstance(s, Disk):
            c = circle_points(s, h)
            chains.append([np.vstack([c, c[:1]])])
        else:
            chains += [[split_line(a, b, h)] for a, b in s.segments()]
    corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    bottom, top = split_line(corners[0], corners[1], h), split_line(corners[3], corners[2], h)
    left, right = split_line(corners[0], corners[3], h), split_line(corners[1], corners[2], h)
    if periodic:
        ys = np.union1d(left[:, 1], right[:, 1])
        left, right = np.c_[np.full_like(ys, x0), ys], np.c_[np.full_like(ys, x1), ys]
    chains += [[bottom], [top], [left], [right]]
    return chains


def distance_to_chains(p: Array, chains: list[list[Array]]) -> Array:
    """Distance of each point to the nearest boundary point of the chains (the chains are
    spaced at the local h, so this is the segment distance within half a spacing)."""
    d, _ = cKDTree(np.concatenate([c for chain in chains for c in chain])).query(p)
    return d


def edge_set(t: Array) -> set[tuple[int, int]]:
    """The undirected edges of a triangulation as sorted index pairs."""
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    e.sort(axis=1)
    return set(map(tuple, np.unique(e, axis=0).tolist()))


def missing_segments(t: Array, pts: Array, chains: list[list[Array]], tol: float) -> list[tuple[int, int]]:
    """(chain, segment) indices of boundary segments that are not triangulation edges."""
    edges = edge_set(t)
    key = {tuple(np.round(q / (10 * tol)).astype(np.int64)): i for i, q in enumerate(pts)}
    out = []
    for ci, chain in enumerate(chains):
        c = chain[0]
        ids = [key[tuple(np.round(q / (10 * tol)).astype(np.int64))] for q in c]
        for k in range(len(c) - 1):
            a, b = sorted((ids[k], ids[k + 1]))
            if (a, b) not in edges:
                out.append((ci, k))
    return out


def recover(
    pts: Array, chains: list[list[Array]], missing: list[tuple[int, int]], shapes: tuple[Shape, ...], tol: float
) -> Array:
    """Split the missing boundary segments at their midpoints (on the arc for circles) and drop
    the free points inside their diametral circles; returns the new point set (chains updated)."""
    by_chain: dict[int, list[int]] = {}
    for ci, k in missing:
        by_chain.setdefault(ci, []).append(k)
    disks = [s for s in shapes if isinstance(s, Disk)]
    centres, radii = [], []
    for ci, ks in by_chain.items():
        c = chains[ci][0]
        new = []
        for k in range(len(c) - 1):
            new.append(c[k])
            if k in ks:
                m = 0.5 * (c[k] + c[k + 1])
                for d in disks:
                    r = math.hypot(m[0] - d.cx, m[1] - d.cy)
                    if abs(math.hypot(c[k][0] - d.cx, c[k][1] - d.cy) - d.r) < 1e-6 * d.r and r > 0:
                        m = np.array([d.cx, d.cy]) + (m - [d.cx, d.cy]) * d.r / r
                new.append(m)
                centres.append(0.5 * (c[k] + c[k + 1]))
                radii.append(0.5 * math.hypot(*(c[k + 1] - c[k])))
        new.append(c[-1])
        chains[ci][0] = np.array(new)
    bpts = np.concatenate([chain[0] for chain in chains])
    bkey = {tuple(np.round(q / (10 * tol)).astype(np.int64)) for q in bpts}
    free = np.array([tuple(np.round(q / (10 * tol)).astype(np.int64)) not in bkey for q in pts])
    drop = np.zeros(len(pts), dtype=bool)
    tree = cKDTree(pts)
    for c, r in zip(centres, radii):
        drop[tree.query_ball_point(c, 1.05 * r)] = True
    drop &= free
    return unique(np.concatenate([bpts, pts[free & ~drop]]), tol)
