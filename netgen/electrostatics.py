"""Plate-to-electrode capacitances C_i(q) of a vertically deforming plate between fixed electrodes.

Model (see design.md, "Measured: boundary-element check of the capacitance extractor"):
the plate surface moves only vertically, w(x, y; q) = sum_v q_v phi_v(x, y).  An electrode on
side s (+1 above, -1 below) at surface gap g sees the local gap g_loc = g - s w.  Its capacitance
to the plate is the parallel-plate integral over the overlap of electrode and plate plus an edge
fringe along the boundary of that overlap:

    C_i(q) = eps * [ integral_overlap dA / g_loc  +  integral_boundary f(g_loc) ds ],
    f(g)   = a + b ln(L / g)                       (EdgeFringe, dimensionless per unit length).

Both terms are analytic in q, so dC/dq (the electrostatic forces) follow exactly.  Gaps are
measured from the undeformed plate SURFACE to the electrode; plate thickness does not enter.
All areas are integrated with tensor Gauss-Legendre rules on the exact overlap region, so the
rules are exact to high order for smooth w (errors fall exponentially with the order).

Geometry is centred on the plate: the plate outline (DiskPlate, RectPlate) and annular sectors
share the origin.  Units are SI (m, F).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Callable, Iterator, Literal, Protocol, Sequence, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import quad

EPS0 = 8.8541878128e-12
"""Vacuum permittivity in F/m (CODATA 2018)."""

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

Side = Literal["above", "below"]


# ----------------------------------------------------------------------------- closed forms


def parallel_plate(eps: float, area: float, gap: ArrayLike) -> Array:
    """Ideal parallel-plate capacitance eps*A/g (no fringe): the zeroth-order reference."""
    return eps * area / np.asarray(gap, dtype=float)


def palmer_rectangle(eps: float, a: float, b: float, g: float) -> float:
    """Palmer (1937) capacitance of two equal, aligned, thin a-by-b rectangles at distance g."""
    fa = 1.0 + g / (math.pi * a) * (1.0 + math.log(2.0 * math.pi * a / g))
    fb = 1.0 + g / (math.pi * b) * (1.0 + math.log(2.0 * math.pi * b / g))
    return eps * a * b / g * fa * fb


def kirchhoff_disk(eps: float, radius: float, g: float) -> float:
    """Kirchhoff's capacitance of two thin coaxial disks of radius R at distance g << R."""
    return eps * math.pi * radius**2 / g + eps * radius * (math.log(16.0 * math.pi * radius / g) - 1.0)


def _cos_antiderivative(x: float, a: float, b: float) -> float:
    """Continuous antiderivative of 1/(a + b cos x) for a > |b| (Poisson-kernel form)."""
    c = math.sqrt(a * a - b * b)
    rho = b / (a + c)
    return (x - 2.0 * math.atan2(rho * math.sin(x), 1.0 + rho * math.cos(x))) / c


def tilted_sector_exact(
    eps: float,
    r_in: float,
    r_out: float,
    theta_start: float,
    theta_end: float,
    slot: float,
    gap: float,
    tilt: float,
    radius: float = math.inf,
) -> float:
    """Reference value of eps * integral dA / (gap - tilt*y) over a slotted annular sector.

    The angular integral is done in closed form, the radial one by adaptive scipy quad; the
    sector is clipped to r <= radius (plate rim).  Independent of the Gauss rules in this module.
    """
    h = slot / 2.0
    span = theta_end - theta_start
    lo = max(r_in, _corner_radius(slot, span))
    hi = min(r_out, radius)
    if hi <= lo:
        return 0.0
    if abs(tilt) * hi >= gap:
        raise ValueError("need |tilt| * min(r_out, radius) < gap (plate must not touch)")

    def ring(r: float) -> float:
        d = math.asin(min(1.0, h / r)) if h > 0 else 0.0
        b = -tilt * r  # gap - tilt r sin(phi) = gap + b cos(phi - pi/2)
        x0, x1 = theta_start + d - math.pi / 2, theta_end - d - math.pi / 2
        return r * (_cos_antiderivative(x1, gap, b) - _cos_antiderivative(x0, gap, b))

    value, _ = quad(ring, lo, hi, epsabs=0.0, epsrel=1e-13, limit=200)
    return eps * value


# ----------------------------------------------------------------------------- edge fringe


@dataclass(frozen=True)
class EdgeFringe:
    """Fringe capacitance per unit edge length, eps * (a + b ln(L/g)), at local gap g.

    The default (a=0.42, b=0.06) is design.md's boundary-element calibration for a plate
    between two electrodes (0.600 / 0.656 / 0.685 eps0 at g/L = 0.05 / 0.02 / 0.01; the
    defaults pass through the first two points and are 1.7 % high at the third).
    `length` None means "the plate's size" (DiskPlate: radius; RectPlate: shorter side).
    """

    a: float = 0.42
    b: float = 0.06
    length: float | None = None

    @classmethod
    def palmer(cls, width: float) -> EdgeFringe:
        """Per-edge fringe of Palmer's open two-plate formula for a plate of width `width`.

        Palmer's first-order term eps/pi (1 + ln(2 pi W/g)) per unit length covers BOTH
        edges of a strip of width W, so one edge carries (1/(2 pi)) (1 + ln(2 pi W/g)).
        """
        return cls(a=(1.0 + math.log(2.0 * math.pi)) / (2.0 * math.pi), b=1.0 / (2.0 * math.pi), length=width)

    @classmethod
    def kirchhoff(cls, radius: float) -> EdgeFringe:
        """Per-edge fringe reproducing Kirchhoff's two-disk formula on a disk rim of `radius`."""
        return cls(a=(math.log(16.0 * math.pi) - 1.0) / (2.0 * math.pi), b=1.0 / (2.0 * math.pi), length=radius)

    def resolved(self, length: float) -> EdgeFringe:
        """This fringe with its reference length filled in (kept if already set)."""
        return self if self.length is not None else EdgeFringe(self.a, self.b, length)

    def per_length(self, g: ArrayLike) -> Array:
        """f(g) = a + b ln(L/g): fringe capacitance per unit edge length in units of eps."""
        if self.length is None:
            raise ValueError("EdgeFringe.length unset: call resolved(length) first")
        return self.a + self.b * np.log(self.length / np.asarray(g, dtype=float))

    def derivative(self, g: ArrayLike) -> Array:
        """df/dg = -b/g, for the analytic force term."""
        return -self.b / np.asarray(g, dtype=float)


# ----------------------------------------------------------------------------- quadrature helpers


@lru_cache(maxsize=64)
def _gauss(n: int) -> tuple[Array, Array]:
    """Gauss-Legendre nodes and weights on [0, 1] (cached)."""
    x, w = np.polynomial.legendre.leggauss(n)
    return (x + 1.0) / 2.0, w / 2.0


def _gauss_panels(breaks: Sequence[float], n: int) -> tuple[Array, Array]:
    """Composite Gauss rule with n points on each panel between consecutive breaks."""
    t, w = _gauss(n)
    b = np.asarray(breaks, dtype=float)
    lo, length = b[:-1, None], np.diff(b)[:, None]
    return (lo + length * t).ravel(), (length * w).ravel()


def _graded_breaks(lo: float, hi: float, singular: float, ratio: float = 4.0, max_panels: int = 16) -> list[float]:
    """Panel breaks on [lo, hi], refined geometrically toward a branch point at `singular` <= lo."""
    breaks, d = [hi], hi - singular
    for _ in range(max_panels - 1):
        d /= ratio
        if singular + d <= lo:
            break
        breaks.append(singular + d)
    return [lo] + breaks[::-1]


def _empty() -> tuple[Array, Array, Array]:
    """Empty point set (electrode not over the plate)."""
    z = np.zeros(0)
    return z, z.copy(), z.copy()


def _corner_radius(slot: float, span: float) -> float:
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
        """Reference length L for the edge fringe: the radius (design.md's ln(R/g))."""
        return self.radius

    def area(self) -> float:
        """Exact plate area."""
        return math.pi * self.radius**2


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

    def area(self) -> float:
        """Exact plate area."""
        return (self.x1 - self.x0) * (self.y1 - self.y0)


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
        t, w = _gauss(order)
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
        phi, w = _gauss_panels(np.linspace(self.phi0, self.phi1, npan + 1), order)
        return self.radius * np.cos(phi), self.radius * np.sin(phi), self.radius * w

    def endpoints(self) -> tuple[Array, Array]:
        """End points (plus the quarter points, a cheap guard for min-gap searches)."""
        phi = np.linspace(self.phi0, self.phi1, 5)
        return self.radius * np.cos(phi), self.radius * np.sin(phi)


Piece = Segment | Arc


def _pieces_points(pieces: Sequence[Piece], order: int) -> tuple[Array, Array, Array]:
    """Concatenated boundary quadrature over several pieces."""
    if not pieces:
        return _empty()
    parts = [p.points(order) for p in pieces]
    return tuple(np.concatenate([p[k] for p in parts]) for k in range(3))  # type: ignore[return-value]


# ----------------------------------------------------------------------------- electrode shapes


@runtime_checkable
class Shape(Protocol):
    """Electrode outline: exact area, area and edge quadrature over its overlap with a plate."""

    name: str

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
        return max(self.r_in, _corner_radius(self.slot, self.span)), min(self.r_out, plate.radius)

    def area(self) -> float:
        """Exact area of the trimmed sector (unclipped), from integral of r*width(r) dr."""
        lo, hi = max(self.r_in, _corner_radius(self.slot, self.span)), self.r_out
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
            return _empty()
        breaks = _graded_breaks(lo, hi, self.slot / 2.0) if self.slot > 0.0 else [lo, hi]
        r, wr = _gauss_panels(breaks, order)
        npan = max(1, math.ceil(self.span / (math.pi / 2) - 1e-9))
        t, wt = _gauss_panels(np.linspace(0.0, 1.0, npan + 1), order)
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
        if lo > _corner_radius(self.slot, self.span) * (1 + 1e-12) and lo > 0.0:
            d_lo = float(self._trim(lo))
            pieces.append(Arc(lo, self.theta_start + d_lo, self.theta_end - d_lo))
        if not self.full_ring:
            pieces.append(self._side(self.theta_start, +1.0, lo, hi))
            pieces.append(self._side(self.theta_end, -1.0, lo, hi))
        return pieces

    def edge_points(self, plate: Plate, order: int = DEFAULT_EDGE_ORDER) -> tuple[Array, Array, Array]:
        """Gauss points and line weights along the overlap boundary (where the fringe lives)."""
        return _pieces_points(self.boundary(plate), order)


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
            return _empty()
        lx, ly = X1 - X0, Y1 - Y0
        nx, ny = (min(16, max(1, math.ceil(v / min(lx, ly) - 1e-9))) for v in (lx, ly))
        x, wx = _gauss_panels(np.linspace(X0, X1, nx + 1), order)
        y, wy = _gauss_panels(np.linspace(Y0, Y1, ny + 1), order)
        X, Y = np.meshgrid(x, y, indexing="ij")
        return X.ravel(), Y.ravel(), np.outer(wx, wy).ravel()

    def _quadrature_disk(self, plate: DiskPlate, order: int) -> tuple[Array, Array, Array]:
        """Rule over rectangle-disk overlap: panels in x between kinks, x = R sin t, Gauss in y."""
        R = plate.radius
        xa, xb = max(self.x0, -R), min(self.x1, R)
        if xb <= xa:
            return _empty()
        kinks = [s * math.sqrt(R * R - c * c) for c in (self.y0, self.y1) if abs(c) < R for s in (-1.0, 1.0)]
        breaks = sorted({xa, xb, *[k for k in kinks if xa < k < xb]})
        tb = np.arcsin(np.clip(np.asarray(breaks) / R, -1.0, 1.0))
        t, wt = _gauss_panels(tb, order)
        x, half = R * np.sin(t), R * np.cos(t)
        ylo, yhi = np.maximum(self.y0, -half), np.minimum(self.y1, half)
        width = np.maximum(yhi - ylo, 0.0)
        s, ws = _gauss(order)
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
        for c, a0, a1, vertical in ((self.y0, self.x0, self.x1, False), (self.y1, self.x0, self.x1, False),
                                    (self.x0, self.y0, self.y1, True), (self.x1, self.y0, self.y1, True)):
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
        return _pieces_points(self.boundary(plate), order)


# ----------------------------------------------------------------------------- electrodes


@dataclass(frozen=True)
class Electrode:
    """A fixed flat electrode: its outline, side of the plate, and gap to the plate surface."""

    shape: Shape
    side: Side
    gap: float

    def __post_init__(self) -> None:
        """Validate side and gap."""
        if self.side not in ("above", "below"):
            raise ValueError(f"side must be 'above' or 'below', not {self.side!r}")
        if not self.gap > 0.0:
            raise ValueError("gap must be positive")

    @property
    def name(self) -> str:
        """The shape's name."""
        return self.shape.name

    @property
    def sign(self) -> float:
        """+1 above (local gap g - w), -1 below (local gap g + w)."""
        return 1.0 if self.side == "above" else -1.0


def rigid_basis() -> Basis:
    """Rigid-body basis (z, tilt about x, tilt about y): phi = 1, y, -x (small angles)."""

    def basis(x: Array, y: Array) -> Array:
        return np.column_stack([np.ones_like(x), y, -x])

    return basis


# ----------------------------------------------------------------------------- extractor interface


@runtime_checkable
class PreparedExtractor(Protocol):
    """Capacitances of a fixed electrode set for many coordinate samples Q (nsamples, ncoords)."""

    electrodes: tuple[Electrode, ...]

    def capacitance(self, Q: ArrayLike) -> Array: ...
    def gradient(self, Q: ArrayLike) -> Array: ...
    def min_gap(self, Q: ArrayLike) -> Array: ...


@runtime_checkable
class CapacitanceExtractor(Protocol):
    """Builds a PreparedExtractor: geometry and basis are evaluated once, samples are cheap."""

    def prepare(self, electrodes: Sequence[Electrode], plate: Plate, basis: Basis) -> PreparedExtractor: ...
    def coupling(self, electrodes: Sequence[Electrode], plate: Plate) -> Array: ...


@dataclass(frozen=True)
class _PointSet:
    """Points of all electrodes, concatenated electrode by electrode, with signed basis values.

    `phi` (npts, nc) is sign * basis for gradient contractions; `phi_t` is its contiguous
    transpose, which makes the (nsamples, nc) @ (nc, npts) gap product one fast BLAS call.
    `weights` (npts, nel) holds each point's weight in its electrode's column (block sparse,
    kept dense: nel is small) so per-electrode sums are one matrix product too.
    """

    gap: Array  # (npts,) undeformed gap of the point's electrode
    phi: Array  # (npts, nc)
    weights: Array  # (npts, nel)
    slices: tuple[slice, ...]  # points of each electrode
    phi_t: Array = field(init=False)
    point_weight: Array = field(init=False)  # (npts,) each point's own weight

    def __post_init__(self) -> None:
        """Cache the contiguous transpose and the per-point weights."""
        object.__setattr__(self, "phi_t", np.ascontiguousarray(self.phi.T))
        object.__setattr__(self, "point_weight", self.weights.sum(axis=1))

    @classmethod
    def build(cls, gaps: Sequence[float], phis: Sequence[Array], weights: Sequence[Array], ncoords: int) -> _PointSet:
        """Concatenate per-electrode blocks (signed basis values and weights)."""
        sizes = [w.size for w in weights]
        stops = np.cumsum([0] + sizes)
        W = np.zeros((int(stops[-1]), len(sizes)))
        for i, w in enumerate(weights):
            W[stops[i]:stops[i + 1], i] = w
        phi = np.concatenate(phis) if phis else np.zeros((0, ncoords))
        gap = np.repeat(np.asarray(gaps, dtype=float), sizes)
        return cls(gap, phi.reshape(-1, ncoords), W, tuple(slice(a, b) for a, b in zip(stops[:-1], stops[1:])))

    def gaps(self, q: Array) -> Array:
        """Local gaps (nsamples, npts) for coordinate samples q (nsamples, nc)."""
        return self.gap - q @ self.phi_t

    def per_electrode_min(self, g: Array) -> Array:
        """Smallest value of g (nsamples, npts) over each electrode's points; inf if none."""
        out = np.full((g.shape[0], len(self.slices)), np.inf)
        for i, sl in enumerate(self.slices):
            if sl.stop > sl.start:
                out[:, i] = g[:, sl].min(axis=1)
        return out


def _as_samples(Q: ArrayLike, ncoords: int) -> tuple[Array, bool]:
    """Q as a 2-D (nsamples, ncoords) float array, and whether it was a single 1-D sample."""
    q = np.asarray(Q, dtype=float)
    single = q.ndim == 1
    q = np.atleast_2d(q)
    if q.ndim != 2 or q.shape[1] != ncoords:
        raise ValueError(f"Q must have shape (nsamples, {ncoords}), got {np.shape(Q)}")
    return q, single


class PreparedParallelPlate:
    """ParallelPlateExtractor bound to electrodes, plate and basis (see module docstring).

    Samples where the plate touches or crosses an electrode (a local gap <= 0 at a quadrature
    node) give nan for that electrode; check min_gap() to keep samples in range.
    """

    def __init__(self, electrodes: Sequence[Electrode], area: _PointSet, edge: _PointSet, probe: _PointSet,
                 eps: float, fringe: EdgeFringe | None, chunk_elements: int) -> None:
        """Store the precomputed point sets; use ParallelPlateExtractor.prepare to build one."""
        self.electrodes = tuple(electrodes)
        self.area, self.edge, self.probe = area, edge, probe
        self.ncoords = area.phi.shape[1]
        self.eps = eps
        self.fringe = fringe if edge.gap.size else None
        self.chunk = max(1, chunk_elements // max(1, area.gap.size + edge.gap.size))

    def _blocks(self, q: Array) -> Iterator[tuple[slice, Array, Array, Array, Array | None]]:
        """Yield (sample slice, q chunk, area gaps, edge gaps, touching mask or None) per chunk."""
        for s in range(0, q.shape[0], self.chunk):
            qc = q[s:s + self.chunk]
            ga, ge = self.area.gaps(qc), self.edge.gaps(qc)
            touch = None
            if (ga.size and ga.min() <= 0.0) or (ge.size and ge.min() <= 0.0):
                touch = np.minimum(self.area.per_electrode_min(ga), self.edge.per_electrode_min(ge)) <= 0.0
                # any finite positive stand-in keeps other electrodes' sums clean (0 * inf = nan)
                ga, ge = np.where(ga > 0.0, ga, 1.0), np.where(ge > 0.0, ge, 1.0)
            yield slice(s, s + qc.shape[0]), qc, ga, ge, touch

    def capacitance(self, Q: ArrayLike) -> Array:
        """Plate-to-electrode capacitances (nsamples, nelectrodes) in F; nan where touching."""
        q, single = _as_samples(Q, self.ncoords)
        out = np.empty((q.shape[0], len(self.electrodes)))
        for sl, _, ga, ge, touch in self._blocks(q):
            c = (1.0 / ga) @ self.area.weights
            if self.fringe is not None:
                c += self.fringe.per_length(ge) @ self.edge.weights
            c *= self.eps
            if touch is not None:
                c[touch] = np.nan
            out[sl] = c
        return out[0] if single else out

    def gradient(self, Q: ArrayLike) -> Array:
        """Analytic dC_i/dq_v (nsamples, nelectrodes, ncoords); nan where touching.

        dC/dq_v = eps [ int s phi_v / g^2 dA + int s phi_v b / g ds ]  (s = +1 above, -1 below).
        """
        q, single = _as_samples(Q, self.ncoords)
        out = np.empty((q.shape[0], len(self.electrodes), self.ncoords))
        for sl, _, ga, ge, touch in self._blocks(q):
            ha = self.area.point_weight / ga**2
            he = -self.fringe.derivative(ge) * self.edge.point_weight if self.fringe is not None else None
            for i in range(len(self.electrodes)):
                a = self.area.slices[i]
                d = ha[:, a] @ self.area.phi[a]
                if he is not None:
                    e = self.edge.slices[i]
                    d += he[:, e] @ self.edge.phi[e]
                out[sl, i] = self.eps * d
            if touch is not None:
                out[sl][touch] = np.nan
        return out[0] if single else out

    def min_gap(self, Q: ArrayLike) -> Array:
        """Smallest local gap under each electrode (nsamples, nelectrodes); inf if no overlap.

        Taken over quadrature nodes and boundary vertices: exact for affine w on straight
        boundaries, within the node spacing on arcs.
        """
        q, single = _as_samples(Q, self.ncoords)
        out = np.empty((q.shape[0], len(self.electrodes)))
        for s in range(0, q.shape[0], self.chunk):
            out[s:s + self.chunk] = self.probe.per_electrode_min(self.probe.gaps(q[s:s + self.chunk]))
        return out[0] if single else out


@dataclass(frozen=True)
class ParallelPlateExtractor:
    """Parallel plate over the local gap plus edge fringe; constant slot coupling between electrodes.

    eps: permittivity (F/m).  fringe: EdgeFringe or None (off).  coupling_per_length: F/m of
    shared slot edge between neighbouring coplanar electrodes (a calibration value, e.g. from
    one BEM run; design.md finds 5-15 % of the disk-sector capacitance, nearly position
    independent).  neighbour_gap: largest edge separation counted as "neighbouring"
    (None: the larger slot of the two shapes).  order / edge_order: Gauss points per panel.
    chunk_elements: samples are processed in chunks of about this many (sample, point) pairs.
    """

    eps: float = EPS0
    fringe: EdgeFringe | None = field(default_factory=EdgeFringe)
    coupling_per_length: float = 0.0
    neighbour_gap: float | None = None
    order: int = DEFAULT_ORDER
    edge_order: int = DEFAULT_EDGE_ORDER
    chunk_elements: int = 2**21

    def prepare(self, electrodes: Sequence[Electrode], plate: Plate, basis: Basis) -> PreparedParallelPlate:
        """Build quadrature for all electrodes and evaluate the basis once at all points."""
        area, edge, probe = [], [], []
        for e in electrodes:
            area.append(e.shape.quadrature(plate, self.order))
            edge.append(e.shape.edge_points(plate, self.edge_order))
            ends = [p.endpoints() for p in e.shape.boundary(plate)]
            probe.append(tuple(np.concatenate([area[-1][k], edge[-1][k], *[v[k] for v in ends]]) for k in (0, 1)))
        groups = (area, edge, probe)
        x = np.concatenate([p[0] for g in groups for p in g])
        y = np.concatenate([p[1] for g in groups for p in g])
        phi = np.asarray(basis(x, y), dtype=float)
        phi = phi[:, None] if phi.ndim == 1 else phi
        if phi.shape[0] != x.size:
            raise ValueError(f"basis returned {phi.shape[0]} rows for {x.size} points")
        nc, gaps, k, sets = phi.shape[1], [e.gap for e in electrodes], 0, []
        for g in groups:
            blocks = []
            for e, pts in zip(electrodes, g):
                blocks.append(e.sign * phi[k:k + pts[0].size])
                k += pts[0].size
            weights = [p[2] if len(p) == 3 else np.zeros(p[0].size) for p in g]
            sets.append(_PointSet.build(gaps, blocks, weights, nc))
        fringe = self.fringe.resolved(plate.size) if self.fringe is not None else None
        return PreparedParallelPlate(electrodes, *sets, self.eps, fringe, self.chunk_elements)

    def coupling(self, electrodes: Sequence[Electrode], plate: Plate) -> Array:
        """Electrode-to-electrode capacitances (nel, nel) in F: coupling_per_length x shared slot edge.

        Positive two-terminal capacitances (zero diagonal) between coplanar electrodes (same
        side and gap), proportional to the length of their facing edges over the plate.
        """
        n = len(electrodes)
        out = np.zeros((n, n))
        if self.coupling_per_length == 0.0:
            return out
        for i in range(n):
            for j in range(i + 1, n):
                ei, ej = electrodes[i], electrodes[j]
                if ei.side != ej.side or not math.isclose(ei.gap, ej.gap, rel_tol=1e-9):
                    continue
                gap = self.neighbour_gap if self.neighbour_gap is not None else max(ei.shape.slot, ej.shape.slot)
                out[i, j] = out[j, i] = self.coupling_per_length * shared_edge_length(ei.shape, ej.shape, plate, gap)
        return out


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
