"""Shapes of the conductor and the fixed electrodes: plate outlines (disk, rectangle), boundary
pieces (segments, arcs), annular sectors and rectangles, with exact areas and Gauss rules over
their overlap with a plate (points, weights, boundary and edge points), and the facing-edge
length of two electrodes. Geometry is centred on the plate: the plate outline and annular
sectors share the origin. Units are SI (m). All areas are integrated with tensor Gauss-Legendre
rules on the exact overlap region, so the rules are exact to high order for smooth integrands.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Literal, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

DEFAULT_ORDER = 10
"""Gauss points per panel and direction for area rules.

Measured against closed forms for tilted sectors: ~1e-12 relative while the smallest local
gap stays >= 0.5 g, 2e-8 at 0.2 g, 4e-5 at 0.05 g (near contact 1/g_loc gets steep; raise
`order` there).  Rigid translation is exact to rounding.
"""

DEFAULT_EDGE_ORDER = 12
"""Gauss points per boundary piece (arcs: per quarter turn) for the fringe line integrals."""

Array = NDArray[np.float64]
Basis = Callable[[Array, Array], Array]
"""basis(x, y) -> (npts, ncoords): vertical displacement per unit generalized coordinate."""

Side = Literal["above", "below", "in_plane"]

# ----------------------------------------------------------------------------- quadrature helpers


@lru_cache(maxsize=64)
def gauss(n: int) -> tuple[Array, Array]:
    """Gauss-Legendre nodes and weights on [0, 1] (cached)."""
    x, w = np.polynomial.legendre.leggauss(n)
    return (x + 1.0) / 2.0, w / 2.0


def gauss_panels(breaks: Sequence[float], n: int) -> tuple[Array, Array]:
    """Composite Gauss rule with n points on each panel between consecutive breaks."""
    t, w = gauss(n)
    b = np.asarray(breaks, dtype=float)
    lo, length = b[:-1, None], np.diff(b)[:, None]
    return (lo + length * t).ravel(), (length * w).ravel()


def graded_breaks(lo: float, hi: float, singular: float, ratio: float = 4.0, max_panels: int = 16) -> list[float]:
    """Panel breaks on [lo, hi], refined geometrically toward a branch point at `singular` <= lo."""
    breaks, d = [hi], hi - singular
    for _ in range(max_panels - 1):
        d /= ratio
        if singular + d <= lo:
            break
        breaks.append(singular + d)
    return [lo] + breaks[::-1]


def empty() -> tuple[Array, Array, Array]:
    """Empty point set (electrode not over the plate)."""
    z = np.zeros(0)
    return z, z.copy(), z.copy()


def corner_radius(slot: float, span: float) -> float:
    """Radius where the two slot-offset side lines of a sector meet (0 without slots)."""
    if slot <= 0.0:
        return 0.0
    return slot / (2.0 * math.sin(span / 2.0)) if span < math.pi else slot / 2.0


# ----------------------------------------------------------------------------- plate outlines


@dataclass(frozen=True)
class DiskPlate:
    """Circular plate outline of given radius centred at the origin."""

    radius: float

    @property
    def size(self) -> float:
        """Reference length L for the edge fringe: the radius (the ln(R/g) of docs/bem.md)."""
        return self.radius

    @property
    def width(self) -> float:
        """The plate's width across (Palmer's fringe formula): the diameter."""
        return 2 * self.radius

    def area(self) -> float:
        """Exact plate area."""
        return math.pi * self.radius**2

    def area_rule(self, order: int) -> tuple[Array, Array, Array]:
        """Points and weights integrating smooth fields over the disk: Gauss-Legendre in r
        (`order` points), the trapezoidal rule in theta (2 `order` points, exact for its Fourier modes)."""
        g, w = np.polynomial.legendre.leggauss(order)
        r = 0.5 * self.radius * (g + 1)
        theta = 2 * np.pi * np.arange(2 * order) / (2 * order)
        rr, tt = np.meshgrid(r, theta, indexing="ij")
        weights = (0.5 * self.radius * w * r)[:, None] * np.full(theta.shape, 2 * np.pi / theta.size)[None, :]
        return (rr * np.cos(tt)).ravel(), (rr * np.sin(tt)).ravel(), weights.ravel()


@dataclass(frozen=True)
class RectPlate:
    """Rectangular plate outline [x0, x1] x [y0, y1]."""

    x0: float
    x1: float
    y0: float
    y1: float

    @property
    def size(self) -> float:
        """Reference length L for the edge fringe: the shorter side."""
        return min(self.x1 - self.x0, self.y1 - self.y0)

    @property
    def width(self) -> float:
        """The plate's width across (Palmer's fringe formula): the shorter side."""
        return self.size

    def area(self) -> float:
        """Exact plate area."""
        return (self.x1 - self.x0) * (self.y1 - self.y0)

    def area_rule(self, order: int) -> tuple[Array, Array, Array]:
        """Points and weights over the rectangle: `order` Gauss points along x, 8 along y (the
        fields integrated over suspended conductors are at most linear in y)."""
        g, w = np.polynomial.legendre.leggauss(order)
        gy, wy = np.polynomial.legendre.leggauss(8)
        hx, hy = 0.5 * (self.x1 - self.x0), 0.5 * (self.y1 - self.y0)
        x, y = np.meshgrid(hx * (g + 1) + self.x0, hy * (gy + 1) + self.y0, indexing="ij")
        weights = (hx * w)[:, None] * (hy * wy)[None, :]
        return x.ravel(), y.ravel(), weights.ravel()


Plate = DiskPlate | RectPlate


# ----------------------------------------------------------------------------- boundary pieces


@dataclass(frozen=True)
class Segment:
    """Straight boundary piece of an overlap region; rim=True if it is the plate's edge."""

    p0: tuple[float, float]
    p1: tuple[float, float]
    rim: bool = False

    @property
    def length(self) -> float:
        """Exact length."""
        return math.dist(self.p0, self.p1)

    def points(self, order: int) -> tuple[Array, Array, Array]:
        """Gauss points (x, y) and line weights ds along the segment."""
        t, w = gauss(order)
        (x0, y0), (x1, y1) = self.p0, self.p1
        return x0 + (x1 - x0) * t, y0 + (y1 - y0) * t, self.length * w

    def endpoints(self) -> tuple[Array, Array]:
        """End points, where extreme gaps of affine displacements occur."""
        return np.array([self.p0[0], self.p1[0]]), np.array([self.p0[1], self.p1[1]])


@dataclass(frozen=True)
class Arc:
    """Circular boundary piece centred at the origin, from angle phi0 to phi1 (phi1 > phi0)."""

    radius: float
    phi0: float
    phi1: float
    rim: bool = False

    @property
    def length(self) -> float:
        """Exact length."""
        return self.radius * (self.phi1 - self.phi0)

    def points(self, order: int) -> tuple[Array, Array, Array]:
        """Gauss points and weights, one panel per quarter turn at most."""
        npan = max(1, math.ceil((self.phi1 - self.phi0) / (math.pi / 2) - 1e-9))
        phi, w = gauss_panels(np.linspace(self.phi0, self.phi1, npan + 1), order)
        return self.radius * np.cos(phi), self.radius * np.sin(phi), self.radius * w

    def endpoints(self) -> tuple[Array, Array]:
        """End points (plus the quarter points, a cheap guard for min-gap searches)."""
        phi = np.linspace(self.phi0, self.phi1, 5)
        return self.radius * np.cos(phi), self.radius * np.sin(phi)


Piece = Segment | Arc


def pieces_points(pieces: Sequence[Piece], order: int) -> tuple[Array, Array, Array]:
    """Concatenated boundary quadrature over several pieces."""
    if not pieces:
        return empty()
    parts = [p.points(order) for p in pieces]
    return tuple(np.concatenate([p[k] for p in parts]) for k in range(3))  # type: ignore[return-value]


# ----------------------------------------------------------------------------- electrode shapes


@runtime_checkable
class Shape(Protocol):
    """Electrode outline: exact area, area and edge quadrature over its overlap with a plate
    (`name` read-only: the shapes are frozen dataclasses)."""

    @property
    def name(self) -> str: ...

    def area(self) -> float: ...
    def quadrature(self, plate: Plate, order: int = DEFAULT_ORDER) -> tuple[Array, Array, Array]: ...
    def boundary(self, plate: Plate) -> list[Piece]: ...
    def edge_points(self, plate: Plate, order: int = DEFAULT_EDGE_ORDER) -> tuple[Array, Array, Array]: ...

    @property
    def slot(self) -> float: ...


@dataclass(frozen=True)
class AnnularSector:
    """Annular sector r_in..r_out, theta_start..theta_end (rad), trimmed by straight slots.

    Each straight side lies slot/2 from the radial line at theta_start / theta_end (so two
    neighbouring sectors are separated by a slot of width `slot`); at radius r the electrode
    spans [theta_start + asin(slot/2r), theta_end - asin(slot/2r)].  slot=0 with a full
    2 pi span is a complete ring.  Only disk plates centred on the origin are supported.
    """

    name: str
    r_in: float
    r_out: float
    theta_start: float
    theta_end: float
    slot: float = 0.0

    def __post_init__(self) -> None:
        """Reject shapes the polar description cannot represent."""
        span = self.span
        if not (0.0 < span <= 2.0 * math.pi + 1e-12):
            raise ValueError(f"{self.name}: need 0 < theta_end - theta_start <= 2 pi")
        if not (0.0 <= self.r_in < self.r_out) or self.slot < 0.0:
            raise ValueError(f"{self.name}: need 0 <= r_in < r_out and slot >= 0")
        if self.slot > 0.0 and span > math.pi and self.r_in < self.slot / 2.0:
            raise ValueError(f"{self.name}: a slotted sector wider than pi needs r_in >= slot/2")

    @property
    def span(self) -> float:
        """Nominal angular span theta_end - theta_start."""
        return self.theta_end - self.theta_start

    @property
    def full_ring(self) -> bool:
        """True for a closed ring (full turn without a slot): no side edges."""
        return self.slot == 0.0 and self.span >= 2.0 * math.pi - 1e-12

    def _trim(self, r: ArrayLike) -> Array:
        """Angular trim asin(slot/2r) at each side."""
        r = np.asarray(r, dtype=float)
        if self.slot == 0.0:
            return np.zeros_like(r)
        return np.arcsin(np.minimum(1.0, self.slot / (2.0 * r)))

    def _radial_range(self, plate: Plate) -> tuple[float, float]:
        """Radii [lo, hi] of the overlap with a disk plate (hi <= lo: no overlap)."""
        if not isinstance(plate, DiskPlate):
            raise NotImplementedError("AnnularSector supports DiskPlate (origin-centred) only")
        return max(self.r_in, corner_radius(self.slot, self.span)), min(self.r_out, plate.radius)

    def area(self) -> float:
        """Exact area of the trimmed sector (unclipped), from integral of r*width(r) dr."""
        lo, hi = max(self.r_in, corner_radius(self.slot, self.span)), self.r_out
        h = self.slot / 2.0

        def prim(r: float) -> float:
            """Antiderivative of r * (span - 2 asin(h/r))."""
            if h == 0.0:
                return self.span * r * r / 2.0
            trim = r * r * math.asin(min(1.0, h / r)) + h * math.sqrt(max(0.0, r * r - h * h))
            return self.span * r * r / 2.0 - trim

        return prim(hi) - prim(lo)

    def quadrature(self, plate: Plate, order: int = DEFAULT_ORDER) -> tuple[Array, Array, Array]:
        """Gauss points (x, y) and area weights over the overlap with the plate (polar rule)."""
        lo, hi = self._radial_range(plate)
        if hi <= lo:
            return empty()
        breaks = graded_breaks(lo, hi, self.slot / 2.0) if self.slot > 0.0 else [lo, hi]
        r, wr = gauss_panels(breaks, order)
        npan = max(1, math.ceil(self.span / (math.pi / 2) - 1e-9))
        t, wt = gauss_panels(np.linspace(0.0, 1.0, npan + 1), order)
        d = self._trim(r)
        width = np.maximum(self.span - 2.0 * d, 0.0)
        phi = (self.theta_start + d)[:, None] + width[:, None] * t[None, :]
        w = (wr * r * width)[:, None] * wt[None, :]
        rr = np.broadcast_to(r[:, None], phi.shape)
        return (rr * np.cos(phi)).ravel(), (rr * np.sin(phi)).ravel(), w.ravel()

    def _side(self, theta: float, inward: float, lo: float, hi: float) -> Segment:
        """Straight slot edge parallel to the ray at theta, offset slot/2 toward the inside."""
        h = self.slot / 2.0
        u, n = np.array([math.cos(theta), math.sin(theta)]), np.array([-math.sin(theta), math.cos(theta)])
        p = [math.sqrt(max(0.0, r * r - h * h)) * u + inward * h * n for r in (lo, hi)]
        return Segment((float(p[0][0]), float(p[0][1])), (float(p[1][0]), float(p[1][1])))

    def boundary(self, plate: Plate) -> list[Piece]:
        """Boundary of the overlap: outer arc (plate rim if r_out > R), inner arc, slot sides."""
        lo, hi = self._radial_range(plate)
        if hi <= lo:
            return []
        d_hi = float(self._trim(hi))
        pieces: list[Piece] = [Arc(hi, self.theta_start + d_hi, self.theta_end - d_hi, rim=self.r_out > plate.radius)]
        if lo > corner_radius(self.slot, self.span) * (1 + 1e-12) and lo > 0.0:
            d_lo = float(self._trim(lo))
            pieces.append(Arc(lo, self.theta_start + d_lo, self.theta_end - d_lo))
        if not self.full_ring:
            pieces.append(self._side(self.theta_start, +1.0, lo, hi))
            pieces.append(self._side(self.theta_end, -1.0, lo, hi))
        return pieces

    def edge_points(self, plate: Plate, order: int = DEFAULT_EDGE_ORDER) -> tuple[Array, Array, Array]:
        """Gauss points and line weights along the overlap boundary (where the fringe lives)."""
        return pieces_points(self.boundary(plate), order)


@dataclass(frozen=True)
class Rectangle:
    """Axis-aligned rectangular electrode [x0, x1] x [y0, y1]."""

    name: str
    x0: float
    x1: float
    y0: float
    y1: float

    def __post_init__(self) -> None:
        """Reject degenerate rectangles."""
        if not (self.x0 < self.x1 and self.y0 < self.y1):
            raise ValueError(f"{self.name}: need x0 < x1 and y0 < y1")

    @property
    def slot(self) -> float:
        """Rectangles carry no slot width (coupling neighbours need an explicit max gap)."""
        return 0.0

    def area(self) -> float:
        """Exact area."""
        return (self.x1 - self.x0) * (self.y1 - self.y0)

    def _overlap_rect(self, plate: RectPlate) -> tuple[float, float, float, float]:
        """Intersection rectangle with a rectangular plate (may be empty)."""
        return max(self.x0, plate.x0), min(self.x1, plate.x1), max(self.y0, plate.y0), min(self.y1, plate.y1)

    def quadrature(self, plate: Plate, order: int = DEFAULT_ORDER) -> tuple[Array, Array, Array]:
        """Gauss points and weights over the overlap (tensor rule; x = R sin t on disks)."""
        if isinstance(plate, DiskPlate):
            return self._quadrature_disk(plate, order)
        X0, X1, Y0, Y1 = self._overlap_rect(plate)
        if X1 <= X0 or Y1 <= Y0:
            return empty()
        lx, ly = X1 - X0, Y1 - Y0
        nx, ny = (min(16, max(1, math.ceil(v / min(lx, ly) - 1e-9))) for v in (lx, ly))
        x, wx = gauss_panels(np.linspace(X0, X1, nx + 1), order)
        y, wy = gauss_panels(np.linspace(Y0, Y1, ny + 1), order)
        X, Y = np.meshgrid(x, y, indexing="ij")
        return X.ravel(), Y.ravel(), np.outer(wx, wy).ravel()

    def _quadrature_disk(self, plate: DiskPlate, order: int) -> tuple[Array, Array, Array]:
        """Rule over rectangle-disk overlap: panels in x between kinks, x = R sin t, Gauss in y."""
        R = plate.radius
        xa, xb = max(self.x0, -R), min(self.x1, R)
        if xb <= xa:
            return empty()
        kinks = [s * math.sqrt(R * R - c * c) for c in (self.y0, self.y1) if abs(c) < R for s in (-1.0, 1.0)]
        breaks = sorted({xa, xb, *[k for k in kinks if xa < k < xb]})
        tb = np.arcsin(np.clip(np.asarray(breaks) / R, -1.0, 1.0))
        t, wt = gauss_panels(tb, order)
        x, half = R * np.sin(t), R * np.cos(t)
        ylo, yhi = np.maximum(self.y0, -half), np.minimum(self.y1, half)
        width = np.maximum(yhi - ylo, 0.0)
        s, ws = gauss(order)
        y = ylo[:, None] + width[:, None] * s[None, :]
        w = (wt * half * width)[:, None] * ws[None, :]
        return np.broadcast_to(x[:, None], y.shape).ravel(), y.ravel(), w.ravel()

    def boundary(self, plate: Plate) -> list[Piece]:
        """Boundary of the overlap with the plate, plate-rim pieces flagged rim=True."""
        if isinstance(plate, DiskPlate):
            return self._boundary_disk(plate)
        X0, X1, Y0, Y1 = self._overlap_rect(plate)
        if X1 <= X0 or Y1 <= Y0:
            return []
        return [
            Segment((X0, Y0), (X1, Y0), rim=plate.y0 > self.y0),
            Segment((X1, Y0), (X1, Y1), rim=plate.x1 < self.x1),
            Segment((X1, Y1), (X0, Y1), rim=plate.y1 < self.y1),
            Segment((X0, Y1), (X0, Y0), rim=plate.x0 > self.x0),
        ]

    def _inside(self, x: float, y: float) -> bool:
        """Strictly inside the rectangle."""
        return self.x0 < x < self.x1 and self.y0 < y < self.y1

    def _boundary_disk(self, plate: DiskPlate) -> list[Piece]:
        """Rectangle sides clipped to the disk, plus the rim arcs lying inside the rectangle."""
        R = plate.radius
        pieces: list[Piece] = []
        for c, a0, a1, vertical in (
            (self.y0, self.x0, self.x1, False),
            (self.y1, self.x0, self.x1, False),
            (self.x0, self.y0, self.y1, True),
            (self.x1, self.y0, self.y1, True),
        ):
            if abs(c) >= R:
                continue
            m = math.sqrt(R * R - c * c)
            lo, hi = max(a0, -m), min(a1, m)
            if hi > lo:
                pieces.append(Segment((c, lo), (c, hi)) if vertical else Segment((lo, c), (hi, c)))
        cuts = []
        for c in (self.x0, self.x1):
            if abs(c) < R:
                cuts += [math.acos(c / R), -math.acos(c / R)]
        for c in (self.y0, self.y1):
            if abs(c) < R:
                cuts += [math.asin(c / R), math.pi - math.asin(c / R)]
        cuts = sorted({a % (2.0 * math.pi) for a in cuts})
        if not cuts:
            return pieces + ([Arc(R, 0.0, 2.0 * math.pi, rim=True)] if self._inside(R, 0.0) else [])
        for a, b in zip(cuts, cuts[1:] + [cuts[0] + 2.0 * math.pi]):
            mid = (a + b) / 2.0
            if b > a and self._inside(R * math.cos(mid), R * math.sin(mid)):
                pieces.append(Arc(R, a, b, rim=True))
        return pieces

    def edge_points(self, plate: Plate, order: int = DEFAULT_EDGE_ORDER) -> tuple[Array, Array, Array]:
        """Gauss points and line weights along the overlap boundary."""
        return pieces_points(self.boundary(plate), order)


# ----------------------------------------------------------------------------- electrodes


@dataclass(frozen=True)
class Electrode:
    """A fixed flat electrode: its outline, side of the plate, and gap to the plate surface;
    `group` names the set it belongs to (the model's Electrode.group)."""

    shape: Shape
    side: Side
    gap: float
    group: str = ""
    dielectric_thickness: float = 0.0  # m, a layer on the electrode's face (0: none)
    dielectric_permittivity: float = 1.0  # its relative permittivity

    def __post_init__(self) -> None:
        """Validate side, gap and layer."""
        if self.side not in ("above", "below", "in_plane"):
            raise ValueError(f"side must be 'above', 'below' or 'in_plane' (comb fingers), not {self.side!r}")
        if not self.gap > 0.0:
            raise ValueError("gap must be positive")
        if not (0.0 <= self.dielectric_thickness < self.gap and self.dielectric_permittivity >= 1.0):
            raise ValueError("need 0 <= dielectric_thickness < gap and dielectric_permittivity >= 1")

    @property
    def stop_gap(self) -> float:
        """Plate surface to the layer's surface, where the plate stops: g - t_d."""
        return self.gap - self.dielectric_thickness

    def field_gap(self, medium: float = 1.0) -> float:
        """The parallel plate's effective gap in a gap medium of relative permittivity `medium`:
        air and layer in series, g - t_d + t_d medium / eps_r (g itself without a layer)."""
        t = self.dielectric_thickness
        return self.gap if t == 0.0 else self.gap - t + t * medium / self.dielectric_permittivity

    @property
    def name(self) -> str:
        """The shape's name."""
        return self.shape.name

    @property
    def sign(self) -> float:
        """+1 above (local gap g - w), -1 below (local gap g + w), 0 in plane (comb fingers:
        their gaps close in the plane, netgen.electrostatics.comb)."""
        return {"above": 1.0, "below": -1.0}.get(self.side, 0.0)


# ----------------------------------------------------------------------------- neighbour edges


def shared_edge_length(a: Shape, b: Shape, plate: Plate, max_gap: float) -> float:
    """Length of facing, parallel electrode edges of a and b over the plate, at most max_gap apart."""
    tol = max_gap * (1.0 + 1e-9) + 1e-15
    total = 0.0
    for p in (p for p in a.boundary(plate) if not p.rim):
        for r in (r for r in b.boundary(plate) if not r.rim):
            if isinstance(p, Segment) and isinstance(r, Segment):
                total += _segment_overlap(p, r, tol)
            elif isinstance(p, Arc) and isinstance(r, Arc) and abs(p.radius - r.radius) <= tol:
                total += _arc_overlap(p, r) * (p.radius + r.radius) / 2.0
    return total


def _segment_overlap(p: Segment, r: Segment, tol: float) -> float:
    """Overlap length of two parallel segments within distance tol (0 otherwise)."""
    a0, a1, b0, b1 = (np.asarray(v, dtype=float) for v in (p.p0, p.p1, r.p0, r.p1))
    u = (a1 - a0) / np.linalg.norm(a1 - a0)
    v = b1 - b0
    if abs(u[0] * v[1] - u[1] * v[0]) > 1e-9 * np.linalg.norm(v):
        return 0.0
    if abs(u[0] * (b0 - a0)[1] - u[1] * (b0 - a0)[0]) > tol:
        return 0.0
    s = sorted((float(u @ (b0 - a0)), float(u @ (b1 - a0))))
    return max(0.0, min(float(u @ (a1 - a0)), s[1]) - max(0.0, s[0]))


def _arc_overlap(p: Arc, r: Arc) -> float:
    """Angular overlap (rad) of two arcs, angles taken modulo 2 pi."""
    total = 0.0
    for shift in (-2.0 * math.pi, 0.0, 2.0 * math.pi):
        total += max(0.0, min(p.phi1, r.phi1 + shift) - max(p.phi0, r.phi0 + shift))
    return min(total, p.phi1 - p.phi0, r.phi1 - r.phi0)
