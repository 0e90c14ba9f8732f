"""Quadrilateral panels for the multipole extractor (netgen.electrostatics.fastcap), in numpy.

FastCap collocates a constant charge per flat panel, so panels need not meet edge to edge: every
radial band of a disk or sector and every row of a rectangle is divided on its own, with panels
of at most `aspect` to one. Sizes follow bem_mesh.Sizes (in metres, set from the smallest gap):
h_edge at every free edge (where the charge density is singular), growing by `growth` up to
h_max inside, so the panels facing a gap are a fixed number of gaps wide and those at its edges a
fraction of a gap. A band whose inner radius is 0 is closed by triangles (one corner repeated).
The plate's face is graded the same way towards the facing electrodes' outlines in projection
(disk_face: ring radii and slot sides), where its charge changes within a gap, and the electrodes
towards the plate's rim.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..geometry.shapes import AnnularSector, Array, DiskPlate, Electrode, Plate, Rectangle, RectPlate, corner_radius
from ..structure import grid_count
from .bem_mesh import Sizes, graded

ASPECT = 4.0  # longest panel side over its radial (or shortest) side


@dataclass(frozen=True)
class Panels:
    """Flat panels of one conductor: corners (n, 4, 3) in m; a triangle repeats its last corner."""

    corners: Array

    def moved(self, dz: Array) -> Panels:
        """The panels with corner (i, k) shifted by dz[i, k] along z (a moved or deformed plate)."""
        c = self.corners.copy()
        c[:, :, 2] += dz
        return Panels(c)

    def __len__(self) -> int:
        """The number of panels."""
        return len(self.corners)

    def areas(self) -> Array:
        """Area of every panel (two triangles, exact for flat panels)."""
        c = self.corners
        t1 = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
        t2 = np.cross(c[:, 2] - c[:, 0], c[:, 3] - c[:, 0])
        return 0.5 * (np.linalg.norm(t1, axis=1) + np.linalg.norm(t2, axis=1))


def _band_nodes(length: float, sizes: Sizes, dr: float, aspect: float, graded_ends: bool) -> Array:
    """Fractions 0..1 along a band of `length`: panels at most aspect * dr (and h_max) long,
    graded to h_edge at both ends when they are free edges."""
    top = min(sizes.h_max, aspect * dr)
    if not graded_ends:
        n = max(1, math.ceil(length / top))
        return np.linspace(0.0, 1.0, n + 1)
    s = Sizes(min(sizes.h_edge, top), top, sizes.growth)
    return (graded(0.0, length, s) - 0.0) / length


def graded_through(lo: float, hi: float, cuts, sizes: Sizes, ends: tuple[bool, bool] = (True, True)) -> Array:
    """Nodes from lo to hi graded towards both ends (as `ends` says) and towards every cut strictly
    inside (the projection of another conductor's edge): graded pieces between consecutive cuts."""
    tol = 1e-9 * (hi - lo)
    inner = sorted({float(c) for c in cuts if lo + tol < c < hi - tol})
    breaks = [lo, *inner, hi]
    parts = [
        graded(a, b, sizes, ends=(ends[0] if k == 0 else True, ends[1] if k == len(breaks) - 2 else True))
        for k, (a, b) in enumerate(zip(breaks[:-1], breaks[1:]))
    ]
    return np.concatenate([parts[0]] + [p[1:] for p in parts[1:]])


def polar_panels(
    r_lo: float,
    r_hi: float,
    theta0: float,
    span: float,
    slot: float,
    sizes: Sizes,
    z: float,
    aspect: float = ASPECT,
    cuts: tuple[float, ...] = (),
) -> Panels:
    """An annulus, disk or slotted annular sector at height z: radial bands graded towards every
    free radius (and every radius in `cuts`: the plate's rim above an electrode), each band's arc
    divided on its own (graded towards the slot sides, if any)."""
    full = slot == 0.0 and span >= 2.0 * math.pi - 1e-12
    radii = graded_through(r_lo, r_hi, cuts, sizes, ends=(r_lo > 0.0, True))
    quads = []
    for r0, r1 in zip(radii[:-1], radii[1:]):
        rm = 0.5 * (r0 + r1)
        trims = [math.asin(min(1.0, slot / (2.0 * r))) if (slot > 0.0 and r > 0.0) else 0.0 for r in (r0, r1)]
        width = span - 2.0 * math.asin(min(1.0, slot / (2.0 * rm))) if slot > 0.0 else span
        u = _band_nodes(max(rm * width, 1e-30), sizes, r1 - r0, aspect, graded_ends=not full)
        if full:
            u = np.linspace(0.0, 1.0, max(8, len(u)))
        t0 = [theta0 + tr + u * (span - 2.0 * tr) for tr in trims]  # angles of the nodes at r0 and r1
        p0 = np.stack([r0 * np.cos(t0[0]), r0 * np.sin(t0[0])], axis=1)
        p1 = np.stack([r1 * np.cos(t0[1]), r1 * np.sin(t0[1])], axis=1)
        q = np.stack([p0[:-1], p1[:-1], p1[1:], p0[1:]], axis=1)
        if r0 == 0.0:  # the centre: triangles, the repeated corner last
            q = np.stack([p1[:-1], p1[1:], p0[:-1], p0[:-1]], axis=1)
        quads.append(q)
    xy = np.concatenate(quads)
    return Panels(np.concatenate([xy, np.full(xy.shape[:2] + (1,), z)], axis=2))


def _sector_edges(shapes) -> tuple[list[float], list[tuple[float, float, float, float]]]:
    """The annular-sector electrodes' outlines in projection: their radii, and their straight sides
    as (theta, offset, r_lo, r_hi): the side at angle theta + asin(offset / r) for r_lo <= r <= r_hi."""
    radii: set[float] = set()
    lines: dict[tuple[float, float], tuple[float, float, float, float]] = {}
    for s in shapes:
        if not isinstance(s, AnnularSector):
            continue
        lo = max(s.r_in, corner_radius(s.slot, s.span))
        radii.update({lo, s.r_out})
        if s.full_ring:
            continue
        for theta, offset in ((s.theta_start, s.slot / 2.0), (s.theta_end, -s.slot / 2.0)):
            key = (round(theta % (2.0 * math.pi), 12), round(offset * 1e9, 3))
            old = lines.get(key)
            r0, r1 = (lo, s.r_out) if old is None else (min(lo, old[2]), max(s.r_out, old[3]))
            lines[key] = (theta, offset, r0, r1)
    return sorted(radii), list(lines.values())


def _side_angle(line: tuple[float, float, float, float], r: float) -> float:
    """Angle of a straight sector side (_sector_edges) at radius r."""
    return line[0] + math.asin(max(-1.0, min(1.0, line[1] / r)))


def disk_face(radius: float, shapes, sizes: Sizes, aspect: float = ASPECT) -> Panels:
    """A disk plate's face at z = 0, graded towards its rim and towards the outlines of the annular-
    sector electrodes facing it (their radii and slot sides, in projection): the panels facing a
    slot between rings or sectors are a fraction of a gap wide, as the electrodes' own are."""
    cuts, lines = _sector_edges(shapes)
    radii = graded_through(0.0, radius, cuts, sizes, ends=(False, True))
    quads = []
    for r0, r1 in zip(radii[:-1], radii[1:]):
        rm = 0.5 * (r0 + r1)
        active = sorted(
            (ln for ln in lines if ln[2] <= rm <= ln[3] and abs(ln[1]) < r0),
            key=lambda ln: _side_angle(ln, rm) % (2.0 * math.pi),
        )
        if not active:  # a full band: equal arcs, triangles at the centre
            n = max(8, math.ceil(2.0 * math.pi * rm / min(sizes.h_max, aspect * (r1 - r0))))
            t = np.linspace(0.0, 2.0 * math.pi, n + 1)
            pieces = [(t, t)]
        else:
            pieces = []
            for a, b in zip(active, active[1:] + active[:1]):
                width = (_side_angle(b, rm) - _side_angle(a, rm)) % (2.0 * math.pi)
                if len(active) == 1:
                    width = 2.0 * math.pi
                u = _band_nodes(max(rm * width, 1e-30), sizes, r1 - r0, aspect, graded_ends=True)
                ends = [
                    _side_angle(a, r)
                    + u
                    * max(
                        width + (_side_angle(b, r) - _side_angle(a, r)) - (_side_angle(b, rm) - _side_angle(a, rm)), 0.0
                    )
                    for r in (r0, r1)
                ]
                pieces.append((ends[0], ends[1]))
        for t0, t1 in pieces:
            p0 = np.stack([r0 * np.cos(t0), r0 * np.sin(t0)], axis=1)
            p1 = np.stack([r1 * np.cos(t1), r1 * np.sin(t1)], axis=1)
            if r0 == 0.0:
                quads.append(np.stack([p1[:-1], p1[1:], p0[:-1], p0[:-1]], axis=1))
            else:
                quads.append(np.stack([p0[:-1], p1[:-1], p1[1:], p0[1:]], axis=1))
    xy = np.concatenate(quads)
    return Panels(np.concatenate([xy, np.zeros(xy.shape[:2] + (1,))], axis=2))


def rect_panels(
    x0: float, x1: float, y0: float, y1: float, sizes: Sizes, z: float, cuts: tuple[tuple, tuple] = ((), ())
) -> Panels:
    """A rectangle at height z: a tensor grid graded towards all four edges (and towards the x and
    y positions in `cuts`: other conductors' edges in projection)."""
    x, y = graded_through(x0, x1, cuts[0], sizes), graded_through(y0, y1, cuts[1], sizes)
    X, Y = np.meshgrid(x, y, indexing="ij")
    P = np.stack([X, Y, np.full(X.shape, z)], axis=-1)
    c = np.stack([P[:-1, :-1], P[1:, :-1], P[1:, 1:], P[:-1, 1:]], axis=2).reshape(-1, 4, 3)
    return Panels(c)


def _rim_band(outline: Array, thickness: float, sizes: Sizes) -> Panels:
    """The side wall of a plate of `thickness` along a closed outline (m, 2) of points: layers of
    about h_edge in z (graded towards both faces), panels between consecutive outline points."""
    zs = graded(-thickness / 2.0, thickness / 2.0, Sizes(sizes.h_edge, sizes.h_edge * 4.0, sizes.growth))
    a, b = outline, np.roll(outline, -1, axis=0)
    out = []
    for z0, z1 in zip(zs[:-1], zs[1:]):

        def at(p, z):
            return np.column_stack([p, np.full(len(p), z)])

        out.append(np.stack([at(a, z0), at(b, z0), at(b, z1), at(a, z1)], axis=1))
    return Panels(np.concatenate(out))


def hole_edges(lo: float, hi: float, hole: float, pitch: float) -> Array:
    """The holes' edges (n, 2) along one side lo..hi: a centred row of grid_count(length, pitch)
    cells (the count ProofMass.holes, its mass and inertia use), a hole centred in each."""
    n = grid_count(hi - lo, pitch)
    centres = 0.5 * (lo + hi) + (np.arange(n) - (n - 1) / 2.0) * pitch
    return np.column_stack([centres - hole / 2.0, centres + hole / 2.0])


def _nodes(lo: float, hi: float, cuts: Array, sizes: Sizes) -> tuple[Array, Array]:
    """Nodes from lo to hi graded towards every cut (hole edge) and end; and whether each cell
    between consecutive nodes lies inside a hole (cuts (n, 2): each hole's two edges)."""
    breaks = np.concatenate([[lo], cuts.ravel(), [hi]])
    parts = [graded(a, b, sizes) for a, b in zip(breaks[:-1], breaks[1:])]
    nodes = np.concatenate([parts[0]] + [p[1:] for p in parts[1:]])
    inside = np.concatenate([np.full(len(p) - 1, k % 2 == 1) for k, p in enumerate(parts)])
    return nodes, inside


def perforated_face(plate: RectPlate, hole: float, pitch: float, sizes: Sizes) -> tuple[Panels, Array, Array, list]:
    """A rectangular plate's face at z = 0 with its square etch-hole grid cut out: a tensor grid
    graded towards the outline and every hole's edges, the cells inside holes dropped; also the
    x and y nodes and each hole's outline (on the grid's nodes, for the holes' walls)."""
    cx, cy = hole_edges(plate.x0, plate.x1, hole, pitch), hole_edges(plate.y0, plate.y1, hole, pitch)
    x, in_x = _nodes(plate.x0, plate.x1, cx, sizes)
    y, in_y = _nodes(plate.y0, plate.y1, cy, sizes)
    X, Y = np.meshgrid(x, y, indexing="ij")
    P = np.stack([X, Y, np.zeros(X.shape)], axis=-1)
    c = np.stack([P[:-1, :-1], P[1:, :-1], P[1:, 1:], P[:-1, 1:]], axis=2)
    keep = ~np.logical_and.outer(in_x, in_y)
    rings = []
    for a, b in cx:
        xs = x[(x >= a - 1e-9 * pitch) & (x <= b + 1e-9 * pitch)]
        for lo, hi in cy:
            ys = y[(y >= lo - 1e-9 * pitch) & (y <= hi + 1e-9 * pitch)]
            rings.append(_rectangle_outline(xs, ys))
    return Panels(c[keep]), x, y, rings


def _rectangle_outline(x: Array, y: Array) -> Array:
    """The closed outline (m, 2) of the rectangle x[0]..x[-1] by y[0]..y[-1] through the given nodes."""
    return np.concatenate(
        [
            np.column_stack([x[:-1], np.full(len(x) - 1, y[0])]),
            np.column_stack([np.full(len(y) - 1, x[-1]), y[:-1]]),
            np.column_stack([x[::-1][:-1], np.full(len(x) - 1, y[-1])]),
            np.column_stack([np.full(len(y) - 1, x[0]), y[::-1][:-1]]),
        ]
    )


def plate_panels(
    plate: Plate,
    thickness: float,
    sizes: Sizes,
    aspect: float = ASPECT,
    holes: tuple[float, float] | None = None,
    facing: tuple = (),
) -> Panels:
    """The plate: one sheet at z = 0 (thickness 0), or top and bottom faces at +-thickness/2 and
    the rim wall (a closed surface); holes = (side, pitch): a rectangular plate's square etch-hole
    grid cut out of the faces, each hole walled through the thickness; facing: the electrodes'
    shapes, whose outlines the faces are graded towards (disk_face; a rectangle's x and y edges)."""
    rings: list[Array] = []
    if holes is not None:
        if not isinstance(plate, RectPlate):
            raise NotImplementedError(f"no etch holes in a {type(plate).__name__} (a proof mass is rectangular)")
        face, x, y, rings = perforated_face(plate, holes[0], holes[1], sizes)
        outline = _rectangle_outline(x, y)
    elif isinstance(plate, DiskPlate):
        face = disk_face(plate.radius, facing, sizes, aspect)
        n = max(8, math.ceil(2.0 * math.pi * plate.radius / min(sizes.h_max, aspect * sizes.h_edge)))
        t = np.arange(n) * (2.0 * math.pi / n)
        outline = plate.radius * np.column_stack([np.cos(t), np.sin(t)])
    elif isinstance(plate, RectPlate):
        rects = [f for f in facing if isinstance(f, Rectangle)]
        cuts = (tuple(v for f in rects for v in (f.x0, f.x1)), tuple(v for f in rects for v in (f.y0, f.y1)))
        face = rect_panels(plate.x0, plate.x1, plate.y0, plate.y1, sizes, 0.0, cuts)
        outline = _rectangle_outline(graded(plate.x0, plate.x1, sizes), graded(plate.y0, plate.y1, sizes))
    else:
        raise NotImplementedError(f"no panels for plate {type(plate).__name__}")
    if thickness <= 0.0:
        return face
    top, bottom = (
        face.moved(np.full(face.corners.shape[:2], thickness / 2.0)),
        face.moved(np.full(face.corners.shape[:2], -thickness / 2.0)),
    )
    wall = [_rim_band(r, thickness, sizes).corners for r in (outline, *rings)]
    return Panels(np.concatenate([top.corners, bottom.corners, *wall]))


def electrode_panels(
    e: Electrode, sizes: Sizes, z: float, aspect: float = ASPECT, plate: Plate | None = None
) -> Panels:
    """A fixed electrode's outline as a flat panel sheet at height z, graded towards its own edges
    and towards the plate's rim where that lies over it (plate: the moving plate's outline)."""
    s = e.shape
    if isinstance(s, AnnularSector):
        lo = max(s.r_in, corner_radius(s.slot, s.span))
        cuts = (plate.radius,) if isinstance(plate, DiskPlate) else ()
        return polar_panels(lo, s.r_out, s.theta_start, s.span, s.slot, sizes, z, aspect, cuts)
    if isinstance(s, Rectangle):
        edges = ((plate.x0, plate.x1), (plate.y0, plate.y1)) if isinstance(plate, RectPlate) else ((), ())
        return rect_panels(s.x0, s.x1, s.y0, s.y1, sizes, z, edges)
    raise NotImplementedError(f"no panels for electrode shape {type(s).__name__}")


# ----------------------------------------------------------------------------- dielectric layers


@dataclass(frozen=True)
class Layered:
    """An electrode under a dielectric layer (Electrode.dielectric_thickness): FastCap2 refuses a thin
    conductor on a dielectric interface, so the electrode is a closed box of the layer's thickness
    below its face. face: the conductor's face under the layer; rest: its back face and walls (in
    the gap medium); interface: the layer's free surface (top face and walls), with one reference
    point inside the layer per panel (refs, (n, 3)); eps_r: the layer's relative permittivity."""

    face: Panels
    rest: Panels
    interface: Panels
    refs: Array
    eps_r: float

    def __len__(self) -> int:
        """The panels of the conductor and the interface."""
        return len(self.face) + len(self.rest) + len(self.interface)

    def arrays(self) -> list[Array]:
        """The arrays that identify it (a sample store's fingerprint)."""
        return [self.face.corners, self.rest.corners, self.interface.corners, self.refs, np.array([self.eps_r])]


def _arc(r: float, a0: float, a1: float, h: float) -> Array:
    """Points on the arc of radius r from angle a0 to a1 (both ends), at most h apart."""
    n = max(1, math.ceil(abs(a1 - a0) * r / h)) if r > 0.0 else 1
    t = np.linspace(a0, a1, n + 1)
    return r * np.column_stack([np.cos(t), np.sin(t)])


def _line(a: Array, b: Array, h: float) -> Array:
    """Points on the segment a..b (both ends), at most h apart."""
    n = max(1, math.ceil(float(np.hypot(*(b - a))) / h))
    return a + np.linspace(0.0, 1.0, n + 1)[:, None] * (b - a)


def outlines(e: Electrode, sizes: Sizes) -> list[Array]:
    """The electrode's boundary as closed polygons (m, 2), the electrode to the left of every
    edge (outer boundary counter-clockwise, an annulus's inner circle clockwise); points at most
    h_edge apart (rectangles: the graded face's own edge nodes)."""
    s, h = e.shape, sizes.h_edge
    if isinstance(s, Rectangle):
        x, y = graded(s.x0, s.x1, sizes), graded(s.y0, s.y1, sizes)
        return [
            np.concatenate(
                [
                    np.column_stack([x[:-1], np.full(len(x) - 1, s.y0)]),
                    np.column_stack([np.full(len(y) - 1, s.x1), y[:-1]]),
                    np.column_stack([x[::-1][:-1], np.full(len(x) - 1, s.y1)]),
                    np.column_stack([np.full(len(y) - 1, s.x0), y[::-1][:-1]]),
                ]
            )
        ]
    if not isinstance(s, AnnularSector):
        raise NotImplementedError(f"no outline for electrode shape {type(s).__name__}")
    lo = max(s.r_in, corner_radius(s.slot, s.span))
    if s.slot == 0.0 and s.span >= 2.0 * math.pi - 1e-12:
        rings = [_arc(s.r_out, 0.0, 2.0 * math.pi, h)[:-1]]
        return rings + ([_arc(lo, 2.0 * math.pi, 0.0, h)[:-1]] if lo > 0.0 else [])

    def trim(r: float) -> float:
        return math.asin(min(1.0, s.slot / (2.0 * r))) if (s.slot > 0.0 and r > 0.0) else 0.0

    a0, a1 = s.theta_start, s.theta_start + s.span
    outer = _arc(s.r_out, a0 + trim(s.r_out), a1 - trim(s.r_out), h)
    inner = _arc(lo, a1 - trim(lo), a0 + trim(lo), h)
    end = _line(outer[-1], inner[0], h)
    start = _line(inner[-1], outer[0], h)
    parts = [outer[:-1], end[:-1], *([inner[:-1]] if lo > 0.0 else []), start[:-1]]
    return [np.concatenate(parts)]


def walls(outline: Array, z0: float, z1: float, h: float) -> tuple[Panels, Array]:
    """The wall along a closed outline between heights z0 and z1 (rows at most h tall), and a
    point just inside (to the left of every edge, a tenth of the shorter panel side) per panel."""
    zs = np.linspace(z0, z1, max(1, math.ceil(abs(z1 - z0) / h)) + 1)
    a, b = outline, np.roll(outline, -1, axis=0)
    d = b - a
    length = np.hypot(d[:, 0], d[:, 1])
    inward = np.column_stack([-d[:, 1], d[:, 0]]) / length[:, None]
    quads, refs = [], []
    for lo, hi in zip(zs[:-1], zs[1:]):

        def at(p: Array, z: float) -> Array:
            return np.column_stack([p, np.full(len(p), z)])

        quads.append(np.stack([at(a, lo), at(b, lo), at(b, hi), at(a, hi)], axis=1))
        step = 0.1 * np.minimum(length, abs(hi - lo))
        refs.append(at(0.5 * (a + b) + inward * step[:, None], 0.5 * (lo + hi)))
    return Panels(np.concatenate(quads)), np.concatenate(refs)


def layered_panels(
    e: Electrode, sizes: Sizes, z: float, toward: float, aspect: float = ASPECT, plate: Plate | None = None
) -> Layered:
    """An electrode with its face at height z under a layer (dielectric_thickness) towards the
    plate (toward = +1: the plate is above, -1: below); the box below the face is as thick as the
    layer. The layer's panels are the face's, moved to its surface."""
    t = e.dielectric_thickness
    face = electrode_panels(e, sizes, z, aspect, plate)
    back = face.moved(np.full(face.corners.shape[:2], -toward * t))
    top = face.moved(np.full(face.corners.shape[:2], toward * t))
    h = min(sizes.h_edge, t)
    rest, interface, refs = [back.corners], [top.corners], [top.corners.mean(axis=1) - [0.0, 0.0, toward * t / 2.0]]
    for ring in outlines(e, sizes):
        w, _ = walls(ring, z - toward * t, z, h)
        rest.append(w.corners)
        w, r = walls(ring, z, z + toward * t, h)
        interface.append(w.corners)
        refs.append(r)
    return Layered(
        face,
        Panels(np.concatenate(rest)),
        Panels(np.concatenate(interface)),
        np.concatenate(refs),
        e.dielectric_permittivity,
    )
