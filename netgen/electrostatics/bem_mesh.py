"""Triangulations for the boundary-element extractor (netgen.electrostatics.bem), in numpy.

Every conductor is a set of flat triangles: electrodes and thin plates are open sheets, a plate
of finite thickness is a closed surface (top, bottom and rim band). Meshes are graded: the
element size is `h_edge` at every free edge (where the surface charge is singular) and grows
geometrically by `growth` up to `h_max` (set by the element-to-gap rule of
netgen.electrostatics.bem.quadrature_order). Polar shapes are triangulated in (r, arc length)
coordinates, where they are convex, by scipy's Delaunay, and mapped back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import Delaunay

from ..geometry.shapes import AnnularSector, Array, DiskPlate, Electrode, Plate, Rectangle, RectPlate, corner_radius


@dataclass(frozen=True)
class Sizes:
    """Element sizes of one mesh level (m): `h_edge` at free edges, at most `h_max` elsewhere."""

    h_edge: float
    h_max: float
    growth: float = 1.5

    def scaled(self, factor: float) -> Sizes:
        """The same grading with every size times `factor` (the next mesh level)."""
        return Sizes(self.h_edge * factor, self.h_max * factor, self.growth)


@dataclass(frozen=True)
class Surface:
    """Flat triangles of one conductor: vertices (nv, 3) in m and triangles (nt, 3) indices."""

    vertices: Array
    triangles: np.ndarray

    def moved(self, dz: Array) -> Surface:
        """The surface with vertex i shifted by dz[i] along z (a deformed plate)."""
        v = self.vertices.copy()
        v[:, 2] += dz
        return Surface(v, self.triangles)

    def areas(self) -> Array:
        """Area of every triangle."""
        p = self.vertices[self.triangles]
        return 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)


def graded(lo: float, hi: float, sizes: Sizes, ends: tuple[bool, bool] = (True, True)) -> Array:
    """Nodes from lo to hi: spacing h_edge at each graded end, growing by `growth` to h_max.

    The step sequence is built from the graded end(s) (mirrored about the middle when both
    are graded) and stretched uniformly so that the last node lands on hi.
    """
    length = hi - lo
    if length <= 0.0:
        raise ValueError("graded: need hi > lo")
    graded_ends = sum(ends)
    span = length / 2.0 if graded_ends == 2 else length
    first = sizes.h_edge if graded_ends else sizes.h_max
    steps, total = [], 0.0
    while total < span * (1.0 - 1e-9):
        step = min(first * sizes.growth ** len(steps), sizes.h_max)
        steps.append(step)
        total += step
    if len(steps) > 1 and total - span > 0.5 * steps[-1]:
        total -= steps.pop()
    steps = np.array(steps) * (span / total)
    if graded_ends == 2:
        steps = np.concatenate([steps, steps[::-1]])
    elif ends == (False, True):
        steps = steps[::-1]
    return lo + np.concatenate([[0.0], np.cumsum(steps)]) * (length / steps.sum())


def _delaunay(points: Array) -> np.ndarray:
    """Triangles of a point set of a convex region, zero-area slivers on the hull removed."""
    tri = Delaunay(points).simplices
    p = points[tri]
    a, b = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    area = 0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    return tri[area > 1e-12 * area.max()]


def sector_sheet(shape: AnnularSector, sizes: Sizes, z: float, wedges: int = 4) -> Surface:
    """An annular sector (with its slot trims) as a flat graded sheet at height z, symmetric about
    its bisector: one half is triangulated and reflected (sector_half), so that sectors equal by
    symmetry get congruent meshes and a mirror-symmetric layout a mirror-symmetric mesh (a full
    ring: dihedral of order 2 `wedges`, _ring_sheet)."""
    lo = max(shape.r_in, corner_radius(shape.slot, shape.span))
    radii = graded(lo, shape.r_out, sizes, ends=(lo > 0.0, True))
    if shape.full_ring:
        return _ring_sheet(radii, sizes, z, wedges)
    r, d, tri = sector_half(shape, radii, sizes)
    mid = d == 0.0  # nodes on the bisector: their own mirror images
    image = np.full(len(d), -1)
    image[mid] = np.flatnonzero(mid)
    image[~mid] = len(d) + np.arange(int((~mid).sum()))
    centre = 0.5 * (shape.theta_start + shape.theta_end)
    rr = np.concatenate([r, r[~mid]])
    theta = np.concatenate([centre - d, centre + d[~mid]])
    v = np.column_stack([rr * np.cos(theta), rr * np.sin(theta), np.full(len(rr), z)])
    return Surface(v, np.concatenate([tri, image[tri][:, ::-1]]))


def sector_half(shape: AnnularSector, radii: Array, sizes: Sizes) -> tuple[Array, Array, np.ndarray]:
    """The half of a slotted sector on the theta_start side of its bisector: node radii r, angular
    distances d from the bisector (0 on it) and triangles. Rings at graded radii; on each ring the
    arc length u from the slot side is graded towards both sides (graded() puts a node on the
    middle), and the half u <= w/2 is triangulated in (r, u), where it is convex."""
    h = shape.slot / 2.0
    pts, dist = [], []
    for r in radii:
        trim = math.asin(min(1.0, h / r)) if (shape.slot > 0.0 and r > 0.0) else 0.0
        width = max(shape.span - 2.0 * trim, 0.0)
        if r == 0.0 or width == 0.0:
            pts.append((r, 0.0))
            dist.append(0.0)
            continue
        u = graded(0.0, r * width, sizes)
        u = u[: len(u) // 2 + 1]
        u[-1] = 0.5 * r * width
        pts.extend((r, uk) for uk in u)
        dist.extend(0.5 * width - u / r)
        dist[-1] = 0.0
    uv = np.array(pts)
    return uv[:, 0], np.array(dist), _delaunay(uv)


def _ring_sheet(radii: Array, sizes: Sizes, z: float, wedges: int = 4, aspect: float = 10.0) -> Surface:
    """A full ring or disk (no slots) as rings of points, symmetric under the dihedral group of
    order 2 `wedges`: the wedge 0 <= theta <= pi / wedges is triangulated in the plane (convex) and
    reflected and rotated onto the rest, its seams sharing the nodes on the rays theta = k pi /
    wedges. Along a ring the spacing is h_max, or `aspect` times the local ring spacing where that
    is finer: near the rim the elements are long and thin, resolving the radial edge singularity."""
    wedge, dr = math.pi / wedges, np.diff(radii)
    counts, xy = [], []
    for k, r in enumerate(radii):
        if r == 0.0:
            counts.append(0)
            xy.append((0.0, 0.0))
            continue
        local = dr[min(k, len(dr) - 1)] if k == 0 else min(dr[k - 1], dr[min(k, len(dr) - 1)])
        n = max(math.ceil(4 / wedges), math.ceil(wedge * r / min(sizes.h_max, aspect * local)))
        counts.append(n)
        t = np.arange(n + 1) * (wedge / n)
        xy.extend(zip(r * np.cos(t), r * np.sin(t)))
    pts = np.array(xy)
    tri = _delaunay(pts)
    if radii[0] > 0.0:  # an annulus: drop the triangles over the hole
        c = pts[tri].mean(axis=1)
        tri = tri[np.hypot(c[:, 0], c[:, 1]) > radii[0]]
    return _dihedral_images(np.asarray(radii, dtype=float), counts, tri, wedges, z)


def _dihedral_images(radii: Array, counts: list[int], tri: np.ndarray, wedges: int, z: float) -> Surface:
    """The wedge's triangles (over nodes j = 0..n_k of ring k) mapped by the 2 `wedges` rotations
    and reflections onto full rings of 2 wedges n_k equally spaced nodes (a centre: one node)."""
    ring = np.repeat(np.arange(len(counts)), [n + 1 if n else 1 for n in counts])
    j = np.concatenate([np.arange(n + 1) if n else [0] for n in counts])
    full = np.array([2 * wedges * n if n else 1 for n in counts])
    offset = np.concatenate([[0], np.cumsum(full)[:-1]])
    n_k = np.array(counts)[ring]
    images = []
    for i in range(wedges):
        for sign in (1, -1):
            jj = np.mod(sign * j + 2 * i * n_k, full[ring])
            t = (offset[ring] + jj)[tri]
            images.append(t if sign > 0 else t[:, ::-1])
    theta = np.concatenate([np.arange(m) * (2.0 * math.pi / m) for m in full])
    r = np.repeat(radii, full)
    v = np.column_stack([r * np.cos(theta), r * np.sin(theta), np.full(len(r), z)])
    return Surface(v, np.concatenate(images))


def disk_sheet(radius: float, sizes: Sizes, z: float = 0.0, wedges: int = 4) -> Surface:
    """A flat disk graded towards its rim (rings of points, dihedral of order 2 `wedges`)."""
    return _ring_sheet(graded(0.0, radius, sizes, ends=(False, True)), sizes, z, wedges)


def rectangle_sheet(x0: float, x1: float, y0: float, y1: float, sizes: Sizes, z: float = 0.0) -> Surface:
    """A flat rectangle: a tensor grid graded towards all four edges, each cell two triangles."""
    x, y = graded(x0, x1, sizes), graded(y0, y1, sizes)
    X, Y = np.meshgrid(x, y, indexing="ij")
    nx, ny = len(x), len(y)
    idx = np.arange(nx * ny).reshape(nx, ny)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    tri = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return Surface(np.column_stack([X.ravel(), Y.ravel(), np.full(nx * ny, z)]), tri)


def plate_face(plate: Plate, sizes: Sizes, wedges: int = 4) -> Surface:
    """The plate outline as a flat sheet at z = 0 (a disk: dihedral of order 2 `wedges`)."""
    if isinstance(plate, DiskPlate):
        return disk_sheet(plate.radius, sizes, wedges=wedges)
    if isinstance(plate, RectPlate):
        return rectangle_sheet(plate.x0, plate.x1, plate.y0, plate.y1, sizes)
    raise NotImplementedError(f"no BEM mesh for plate {type(plate).__name__}")


def _rim(face: Surface) -> np.ndarray:
    """Vertex indices of the face's boundary loop, in order (edges used by one triangle)."""
    t = face.triangles
    edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(edges, axis=0, return_counts=True)
    boundary = uniq[count == 1]
    nxt: dict[int, list[int]] = {}
    for a, b in boundary:
        nxt.setdefault(int(a), []).append(int(b))
        nxt.setdefault(int(b), []).append(int(a))
    start = int(boundary[0, 0])
    loop, prev = [start], -1
    while True:
        cur = loop[-1]
        step = [n for n in nxt[cur] if n != prev]
        if not step or step[0] == start:
            break
        prev = cur
        loop.append(step[0])
    return np.array(loop)


def thick_plate(plate: Plate, thickness: float, sizes: Sizes, wedges: int = 4) -> Surface:
    """A closed plate surface: top face at +thickness/2, bottom at -thickness/2, and a rim band
    of about thickness/h_edge layers joining their boundary loops (a disk's face: plate_face)."""
    face = plate_face(plate, sizes, wedges)
    if thickness <= 0.0:
        return face
    nv = len(face.vertices)
    loop = _rim(face)
    layers = max(1, math.ceil(thickness / sizes.h_edge))
    zs = np.linspace(-thickness / 2.0, thickness / 2.0, layers + 1)
    top = face.vertices.copy()
    top[:, 2] = zs[-1]
    bot = face.vertices.copy()
    bot[:, 2] = zs[0]
    inner = [np.column_stack([face.vertices[loop, :2], np.full(len(loop), z)]) for z in zs[1:-1]]
    v = np.concatenate([top, bot, *inner]) if inner else np.concatenate([top, bot])
    ring_ids = [loop + nv] + [2 * nv + k * len(loop) + np.arange(len(loop)) for k in range(len(inner))] + [loop]
    band = []
    for lo_ids, hi_ids in zip(ring_ids[:-1], ring_ids[1:]):
        a, b = lo_ids, np.roll(lo_ids, -1)
        c, d = np.roll(hi_ids, -1), hi_ids
        band += [np.column_stack([a, b, c]), np.column_stack([a, c, d])]
    tri = np.concatenate([face.triangles, face.triangles[:, ::-1] + nv, *band])
    return Surface(v, tri)


def dihedral_order(electrodes: tuple[Electrode, ...], largest: int = 8) -> int:
    """The largest m <= `largest` whose dihedral group (rotations by 2 pi / m, the mirror y -> -y)
    maps the electrode layout onto itself (1 if none): a disk plate's mesh gets that symmetry
    (disk_sheet's wedges), so electrodes equal by symmetry see congruent plate meshes."""

    def layout(angle: float, mirror: bool) -> set | None:
        """Every electrode's footprint after the mirror (if asked) and the rotation by angle."""
        keys = [_footprint(e, angle, mirror) for e in electrodes]
        return None if any(k is None for k in keys) else set(keys)

    base = layout(0.0, False)
    if base is None or base != layout(0.0, True):
        return 1
    return next((m for m in range(largest, 1, -1) if layout(2.0 * math.pi / m, False) == base), 1)


def _footprint(e: Electrode, angle: float, mirror: bool) -> tuple | None:
    """A hashable description of electrode e mirrored (y -> -y, if asked) then rotated by angle,
    lengths in pm and angles in nrad (None: a shape without a polar or rectangular description)."""
    pm = lambda x: round(x * 1e12)  # noqa: E731
    s, common = e.shape, (e.side, pm(e.gap), pm(e.dielectric_thickness), e.dielectric_permittivity)
    if isinstance(s, AnnularSector):
        a = -s.theta_end if mirror else s.theta_start
        a = 0.0 if s.full_ring else math.remainder(a + angle, 2.0 * math.pi) % (2.0 * math.pi)
        a = 0.0 if abs(a - 2.0 * math.pi) < 1e-9 else a
        return ("sector", *common, pm(s.r_in), pm(s.r_out), pm(s.slot), round(a * 1e9), round(s.span * 1e9))
    if isinstance(s, Rectangle):
        c, sn, f = math.cos(angle), math.sin(angle), -1.0 if mirror else 1.0
        pts = [(x, f * y) for x in (s.x0, s.x1) for y in (s.y0, s.y1)]
        return ("rect", *common, frozenset((pm(c * x - sn * y), pm(sn * x + c * y)) for x, y in pts))
    return None


def electrode_sheet(e: Electrode, sizes: Sizes, z: float, wedges: int = 4) -> Surface:
    """A fixed electrode's full outline as a flat sheet at height z (a full ring: dihedral of
    order 2 `wedges`, the layout's dihedral_order)."""
    s = e.shape
    if isinstance(s, AnnularSector):
        return sector_sheet(s, sizes, z, wedges)
    if isinstance(s, Rectangle):
        return rectangle_sheet(s.x0, s.x1, s.y0, s.y1, sizes, z)
    raise NotImplementedError(f"no BEM mesh for electrode shape {type(s).__name__}")


def icosphere(radius: float, level: int) -> Surface:
    """A sphere as the level-times subdivided icosahedron, vertices projected onto the sphere."""
    p = (1.0 + math.sqrt(5.0)) / 2.0
    v = [
        (-1, p, 0),
        (1, p, 0),
        (-1, -p, 0),
        (1, -p, 0),
        (0, -1, p),
        (0, 1, p),
        (0, -1, -p),
        (0, 1, -p),
        (p, 0, -1),
        (p, 0, 1),
        (-p, 0, -1),
        (-p, 0, 1),
    ]
    f = [
        (0, 11, 5),
        (0, 5, 1),
        (0, 1, 7),
        (0, 7, 10),
        (0, 10, 11),
        (1, 5, 9),
        (5, 11, 4),
        (11, 10, 2),
        (10, 7, 6),
        (7, 1, 8),
        (3, 9, 4),
        (3, 4, 2),
        (3, 2, 6),
        (3, 6, 8),
        (3, 8, 9),
        (4, 9, 5),
        (2, 4, 11),
        (6, 2, 10),
        (8, 6, 7),
        (9, 8, 1),
    ]
    verts = [np.array(x, dtype=float) / np.linalg.norm(x) for x in v]
    faces = f
    for _ in range(level):
        cache: dict[tuple[int, int], int] = {}

        def mid(a: int, b: int) -> int:
            """Index of the (projected) midpoint of edge a-b, created once."""
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                cache[key] = len(verts) - 1
            return cache[key]

        new = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    return Surface(radius * np.array(verts), np.array(faces))


def graded_steps(length: float, sizes: Sizes, graded_ends: int) -> float:
    """Closed-form step count of graded() over `length` (before its rounding): a geometric run
    h_edge * growth^k from each graded end until it reaches h_max, then steps of h_max."""
    if graded_ends == 0:
        return max(1.0, length / sizes.h_max)
    span, g = (length / 2.0 if graded_ends == 2 else length), sizes.growth
    run = max(0.0, math.log(sizes.h_max / sizes.h_edge) / math.log(g))  # steps until h_max
    run_length = sizes.h_edge * (g**run - 1.0) / (g - 1.0)
    n = (
        math.log1p(span * (g - 1.0) / sizes.h_edge) / math.log(g)
        if run_length >= span
        else run + (span - run_length) / sizes.h_max
    )
    return graded_ends * max(1.0, n)


def _rect_estimate(width: float, height: float, sizes: Sizes) -> tuple[float, float]:
    """(triangles, boundary nodes) of rectangle_sheet."""
    nx, ny = graded_steps(width, sizes, 2), graded_steps(height, sizes, 2)
    return 2.0 * nx * ny, 2.0 * (nx + ny)


def _rim_points(radius: float, sizes: Sizes, aspect: float = 10.0) -> float:
    """Points on _ring_sheet's rings next to one graded rim: rings at spacings h_edge growth^j,
    each of 2 pi r / (aspect h_edge growth^j) points while that is finer than h_max."""
    fine = max(0.0, math.log(sizes.h_max / (aspect * sizes.h_edge)) / math.log(sizes.growth))
    return (
        2.0
        * math.pi
        * radius
        / (aspect * sizes.h_edge)
        * (1.0 - sizes.growth ** -(fine + 1.0))
        / (1.0 - 1.0 / sizes.growth)
    )


def _ring_estimate(r_in: float, r_out: float, sizes: Sizes) -> tuple[float, float]:
    """(triangles, outer-rim points) of _ring_sheet: the rim rings plus an interior of spacing h_max."""
    rim = _rim_points(r_out, sizes) + (_rim_points(r_in, sizes) if r_in > 0.0 else 0.0)
    interior = math.pi * (r_out**2 - r_in**2) / sizes.h_max**2
    outer = max(8.0, 2.0 * math.pi * r_out / min(sizes.h_max, 10.0 * sizes.h_edge))  # the rim ring alone
    return 2.0 * (rim + interior + 8.0 * graded_steps(r_out - r_in, sizes, 2 if r_in > 0 else 1)), outer


def _sector_estimate(s: AnnularSector, sizes: Sizes) -> float:
    """Triangles of sector_sheet: rings graded in r, each ring's arc graded towards both sides."""
    lo = max(s.r_in, corner_radius(s.slot, s.span))
    if s.full_ring:
        return _ring_estimate(lo, s.r_out, sizes)[0]
    rings = graded_steps(s.r_out - lo, sizes, 2 if lo > 0.0 else 1) + 1.0
    arc = graded_steps(max(0.5 * (lo + s.r_out) * s.span, sizes.h_edge), sizes, 2) + 1.0
    return 2.0 * rings * arc


def estimate_elements(plate: Plate, thickness: float, electrodes: tuple[Electrode, ...], sizes: Sizes) -> float:
    """Triangles of one mesh level (plate, closed if thick, and every electrode sheet), in closed
    form from the sizes, without meshing: it lets a memory budget refuse a mesh before it is built
    (netgen.electrostatics.bem.PreparedBem). Checked against the mesher in tests/trust/test_bem_estimate.py."""
    if isinstance(plate, DiskPlate):
        face, loop = _ring_estimate(0.0, plate.radius, sizes)
    elif isinstance(plate, RectPlate):
        face, loop = _rect_estimate(plate.x1 - plate.x0, plate.y1 - plate.y0, sizes)
    else:
        raise NotImplementedError(f"no BEM mesh for plate {type(plate).__name__}")
    total = face
    if thickness > 0.0:
        total = 2.0 * face + 2.0 * loop * math.ceil(thickness / sizes.h_edge)
    for e in electrodes:
        s = e.shape
        if isinstance(s, AnnularSector):
            total += _sector_estimate(s, sizes)
        elif isinstance(s, Rectangle):
            total += _rect_estimate(s.x1 - s.x0, s.y1 - s.y0, sizes)[0]
    return total
