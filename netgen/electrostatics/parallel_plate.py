"""The parallel-plate extractor: plate-to-electrode capacitances C_i(q) of a vertically deforming
plate between fixed electrodes (its accuracy: docs/bem.md, 'The field checks behind the analytic
extractor').

The plate surface moves only vertically, w(x, y; q) = sum_v q_v phi_v(x, y).  An electrode on
side s (+1 above, -1 below) at surface gap g sees the local gap g_loc = g - s w.  Its capacitance
to the plate is the parallel-plate integral over the overlap of electrode and plate plus an edge
fringe along the boundary of that overlap:

    C_i(q) = eps * [ integral_overlap dA / g_loc  +  integral_boundary f(g_loc) ds ],
    f(g)   = a + b ln(L / g)                       (EdgeFringe, dimensionless per unit length).

Both terms are analytic in q, so dC/dq (the electrostatic forces) follow exactly.  Gaps are
measured from the undeformed plate SURFACE to the electrode; plate thickness does not enter.

A dielectric layer of thickness t_d and relative permittivity eps_r on an electrode is a
capacitor in series with the air gap: D is continuous across the layer, so the potential drop
is D [(g_loc - t_d) / eps_m + t_d / eps_r] / eps0 and both terms use the effective gap
g_eff - s w, g_eff = g - t_d + t_d eps_m / eps_r (eps_m: the gap medium's relative permittivity,
Electrode.field_gap).  The fringe term takes the same effective gap (an approximation: the layer
is thin against the plate) and adds the layer's edge step (layer_step): to first order in t_d a
coat on a conductor is the conductor's surface moved out by h_s = t_d (1 - eps_m / eps_r) (the
field at a conductor is normal to it), so a layered electrode's edge is a step of height h_s, whose
extra fringe is Wheeler's thickness correction on the antisymmetric half-problem (layer_step).
min_gap() and the probe points measure the AIR gap g - t_d - s w
(Electrode.stop_gap): the plate touches the layer's surface, not the electrode.
A perforated plate (a proof mass's etch-hole grid) scales the plate term by its effective fill
factor at the local gap, eps F(g_loc) / g_loc (netgen.electrostatics.perforation: hole, pitch and the
plate's thickness); the edge fringe of the plate's outline is unchanged.
The Gauss rules come from netgen.geometry.shapes.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike

from ..core.constants import EPS0
from ..geometry.shapes import DEFAULT_EDGE_ORDER, DEFAULT_ORDER, Array, Basis, Electrode, Plate, shared_edge_length
from .base import ProbePoints
from .perforation import Perforation

# ----------------------------------------------------------------------------- edge fringe


@dataclass(frozen=True)
class EdgeFringe:
    """Fringe capacitance per unit edge length, eps * (a + b ln(L/g)), at local gap g.

    The default (a=0.42, b=0.06) is the boundary-element calibration for a plate
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


def layer_step(step: Array, g: Array) -> Array:
    """Extra fringe per unit edge length (in units of eps) of an electrode edge raised by `step`
    (a layer's h_s = t_d (1 - eps_m / eps_r)) at the effective gap g: (h_s / (4 pi g)) (1 + ln(g / h_s)).

    Two aligned sheets at +-V/2 have the mid-plane as an equipotential, so each edge is a strip
    edge at g / 2 over a ground plane; Wheeler's thickness correction (Wheeler 1977, IEEE
    Trans. MTT-25, 631: a wide strip of thickness t at height h widens by (t / pi)(1 + ln(2 h / t)),
    half per edge) with h = g / 2 raises that half's capacitance per edge by eps (h_s / (pi g))
    (1 + ln(g / h_s)), and the series pair's by a quarter of it (dC = dC_half (C / C_half)^2, C_half = 2 C).
    """
    safe = np.where(step > 0.0, step, 1.0)
    return np.where(step > 0.0, step / (4.0 * math.pi * g) * (1.0 + np.log(g / safe)), 0.0)


def layer_step_slope(step: Array, g: Array) -> Array:
    """d/dg of layer_step: -h_s ln(g / h_s) / (4 pi g^2), for the force term."""
    safe = np.where(step > 0.0, step, 1.0)
    return np.where(step > 0.0, -step * np.log(g / safe) / (4.0 * math.pi * g**2), 0.0)


@dataclass(frozen=True)
class PointFringe:
    """Per-point fringe coefficients: electrode i's EdgeFringe (a_i, b_i) repeated over its edge
    points, so each electrode keeps its own calibrated a + b ln(L/g) (netgen.electrostatics.calibration)."""

    a: Array
    b: Array
    length: float

    def per_length(self, g: ArrayLike) -> Array:
        """f(g) = a_p + b_p ln(L/g) at every edge point p (broadcast over samples)."""
        return self.a + self.b * np.log(self.length / np.asarray(g, dtype=float))

    def derivative(self, g: ArrayLike) -> Array:
        """df/dg = -b_p/g."""
        return -self.b / np.asarray(g, dtype=float)


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
            W[stops[i] : stops[i + 1], i] = w
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
    node, or at most the layer's share t_d eps_m / eps_r of the effective gap: the plate inside a
    dielectric layer) give nan for that electrode; check min_gap() to keep samples in range.
    """

    def __init__(
        self,
        electrodes: Sequence[Electrode],
        area: _PointSet,
        edge: _PointSet,
        probe: _PointSet,
        eps: float,
        fringe: EdgeFringe | PointFringe | None,
        chunk_elements: int,
        perforation: Perforation | None = None,
        step: bool = False,
    ) -> None:
        """Store the precomputed point sets; use ParallelPlateExtractor.prepare to build one."""
        self.electrodes = tuple(electrodes)
        self.area, self.edge, self.probe = area, edge, probe
        self.ncoords = area.phi.shape[1]
        self.eps = eps
        self.fringe = fringe if edge.gap.size else None
        self.perforation = perforation
        # each edge point's layer step h_s = g - g_eff (layer_step; None: no layer, or off)
        steps = [e.gap - e.field_gap(eps / EPS0) for e in self.electrodes]
        sizes = [sl.stop - sl.start for sl in edge.slices]
        self.step = np.repeat(steps, sizes) if step and any(steps) and edge.gap.size else None
        self.chunk = max(1, chunk_elements // max(1, area.gap.size + edge.gap.size))
        # the effective gap left when the plate touches a layer (None: no layer, the gap's own 0)
        layers = [e.field_gap(eps / EPS0) - e.stop_gap for e in self.electrodes]
        self.reserve = (
            (
                np.repeat(layers, [sl.stop - sl.start for sl in area.slices]),
                np.repeat(layers, [sl.stop - sl.start for sl in edge.slices]),
            )
            if any(layers)
            else None
        )

    def _blocks(self, q: Array) -> Iterator[tuple[slice, Array, Array, Array, Array | None]]:
        """Yield (sample slice, q chunk, area gaps, edge gaps, touching mask or None) per chunk."""
        for s in range(0, q.shape[0], self.chunk):
            qc = q[s : s + self.chunk]
            ga, ge = self.area.gaps(qc), self.edge.gaps(qc)
            touch = None
            aa, ae = (ga, ge) if self.reserve is None else (ga - self.reserve[0], ge - self.reserve[1])
            if (aa.size and aa.min() <= 0.0) or (ae.size and ae.min() <= 0.0):
                touch = np.minimum(self.area.per_electrode_min(aa), self.edge.per_electrode_min(ae)) <= 0.0
                # any finite positive stand-in keeps other electrodes' sums clean (0 * inf = nan)
                ga, ge = np.where(aa > 0.0, ga, 1.0), np.where(ae > 0.0, ge, 1.0)
            yield slice(s, s + qc.shape[0]), qc, ga, ge, touch

    def capacitance(self, Q: ArrayLike) -> Array:
        """Plate-to-electrode capacitances (nsamples, nelectrodes) in F; nan where touching."""
        q, single = _as_samples(Q, self.ncoords)
        out = np.empty((q.shape[0], len(self.electrodes)))
        for sl, _, ga, ge, touch in self._blocks(q):
            c = (self.areal(ga) / ga) @ self.area.weights
            if self.fringe is not None:
                c += self.fringe.per_length(ge) @ self.edge.weights
            if self.step is not None:
                c += layer_step(self.step, ge) @ self.edge.weights
            c *= self.eps
            if touch is not None:
                c[touch] = np.nan
            out[sl] = c
        return out[0] if single else out

    def gradient(self, Q: ArrayLike) -> Array:
        """Analytic dC_i/dq_v (nsamples, nelectrodes, ncoords); nan where touching.

        dC/dq_v = eps [ int s phi_v / g^2 dA + int s phi_v b / g ds ]  (s = +1 above, -1 below);
        a perforated plate's area term is int s phi_v (F / g^2 - F' / g) dA (areal_slope).
        """
        q, single = _as_samples(Q, self.ncoords)
        out = np.empty((q.shape[0], len(self.electrodes), self.ncoords))
        for sl, _, ga, ge, touch in self._blocks(q):
            ha = self.area.point_weight * self.areal_slope(ga)
            he = -self.fringe.derivative(ge) * self.edge.point_weight if self.fringe is not None else None
            if self.step is not None:
                hs = -layer_step_slope(self.step, ge) * self.edge.point_weight
                he = hs if he is None else he + hs
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

    def areal(self, g: Array) -> Array | float:
        """The plate term's fill factor at the local gaps g (1: a solid plate)."""
        return 1.0 if self.perforation is None else self.perforation.fill(g)

    def areal_slope(self, g: Array) -> Array:
        """-d/dg (F(g) / g) = F / g^2 - F' / g: the plate term's weight in dC/dq."""
        if self.perforation is None:
            return 1.0 / g**2
        return self.perforation.fill(g) / g**2 - self.perforation.derivative(g) / g

    def min_gap(self, Q: ArrayLike) -> Array:
        """Smallest local gap under each electrode (nsamples, nelectrodes); inf if no overlap.

        Taken over quadrature nodes and boundary vertices: exact for affine w on straight
        boundaries, within the node spacing on arcs.
        """
        q, single = _as_samples(Q, self.ncoords)
        out = np.empty((q.shape[0], len(self.electrodes)))
        for s in range(0, q.shape[0], self.chunk):
            out[s : s + self.chunk] = self.probe.per_electrode_min(self.probe.gaps(q[s : s + self.chunk]))
        return out[0] if single else out

    def probe_points(self) -> ProbePoints:
        """The points min_gap() watches: quadrature nodes, edge points and boundary vertices."""
        owner = np.concatenate(
            [np.full(sl.stop - sl.start, i) for i, sl in enumerate(self.probe.slices)] or [np.zeros(0, dtype=int)]
        ).astype(int)
        return ProbePoints(self.probe.gap, self.probe.phi, owner)


@dataclass(frozen=True)
class ParallelPlateExtractor:
    """Parallel plate over the local gap plus edge fringe; constant slot coupling between electrodes.

    eps: permittivity (F/m).  fringe: EdgeFringe or None (off).  fringes: one EdgeFringe per
    electrode, in the order prepare() gets them (a calibration's, netgen.electrostatics.calibration;
    overrides `fringe`).  coupling: a given constant coupling matrix (nel, nel) in F (a calibration's
    or a file's, netgen.electrostatics.coupling_file; overrides coupling_per_length).  coupling_per_length: F/m of
    shared slot edge between neighbouring coplanar electrodes (a calibration value, e.g. from
    one BEM run; docs/bem.md finds 5-15 % of the disk-sector capacitance, nearly position
    independent).  neighbour_gap: largest edge separation counted as "neighbouring"
    (None: the larger slot of the two shapes).  order / edge_order: Gauss points per panel.
    chunk_elements: samples are processed in chunks of about this many (sample, point) pairs.
    perforation: the plate's etch-hole grid (None: solid), its fill factor F(g) on the plate term.
    layer_step: add a layered electrode's edge step (layer_step) while an edge fringe is on.
    """

    description: ClassVar[str] = "parallel-plate over the local gap + edge fringe"
    eps: float = EPS0
    fringe: EdgeFringe | None = field(default_factory=EdgeFringe)
    coupling_per_length: float = 0.0
    neighbour_gap: float | None = None
    fringes: tuple[EdgeFringe, ...] | None = None
    coupling_matrix: tuple[tuple[float, ...], ...] | None = None
    order: int = DEFAULT_ORDER
    edge_order: int = DEFAULT_EDGE_ORDER
    chunk_elements: int = 2**21
    perforation: Perforation | None = None
    layer_step: bool = True

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
        # the plate terms see the series gap of air and layer; min_gap the air gap to the layer
        medium = self.eps / EPS0
        field_gaps = [e.field_gap(medium) for e in electrodes]
        stop_gaps = [e.stop_gap for e in electrodes]
        nc, k, sets = phi.shape[1], 0, []
        for g in groups:
            group_gaps = stop_gaps if g is probe else field_gaps
            blocks = []
            for e, pts in zip(electrodes, g):
                blocks.append(e.sign * phi[k : k + pts[0].size])
                k += pts[0].size
            weights = [p[2] if len(p) == 3 else np.zeros(p[0].size) for p in g]
            sets.append(_PointSet.build(group_gaps, blocks, weights, nc))
        fringe = self.fringe.resolved(plate.size) if self.fringe is not None else None
        if self.fringes is not None:
            fringe = self.point_fringe(edge, plate)
        at, ed, pr = sets
        step = self.layer_step and fringe is not None
        return PreparedParallelPlate(
            electrodes, at, ed, pr, self.eps, fringe, self.chunk_elements, self.perforation, step
        )

    def point_fringe(self, edge: list, plate: Plate) -> PointFringe:
        """The per-electrode fringes as per-point coefficients over the electrodes' edge points."""
        fringes = [f.resolved(plate.size) for f in self.fringes]
        lengths = {f.length for f in fringes}
        if len(lengths) != 1:
            raise ValueError(f"per-electrode fringes need one reference length, got {sorted(lengths)}")
        sizes = [pts[0].size for pts in edge]
        if len(sizes) != len(fringes):
            raise ValueError(f"{len(fringes)} per-electrode fringes for {len(sizes)} electrodes")
        return PointFringe(
            np.repeat([f.a for f in fringes], sizes), np.repeat([f.b for f in fringes], sizes), lengths.pop()
        )

    def coupling(self, electrodes: Sequence[Electrode], plate: Plate) -> Array:
        """Electrode-to-electrode capacitances (nel, nel) in F: coupling_per_length x shared slot edge.

        Positive two-terminal capacitances (zero diagonal) between coplanar electrodes (same
        side and gap), proportional to the length of their facing edges over the plate.
        """
        n = len(electrodes)
        if self.coupling_matrix is not None:
            given = np.array(self.coupling_matrix, dtype=float)
            if given.shape != (n, n):
                raise ValueError(f"the given coupling matrix is {given.shape}, the structure has {n} electrodes")
            return given
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


def from_structure(s, plate: Plate) -> ParallelPlateExtractor:
    """The extractor the structure's [electrostatics] options choose (s: a netgen.structure.Structure)."""
    o = s.electrostatics
    if o.fringe == "none":
        fringe = None
    elif o.fringe == "palmer":
        fringe = EdgeFringe.palmer(plate.width)
    else:
        fringe = EdgeFringe(o.fringe_a, o.fringe_b, plate.size)
    hole, pitch = float(getattr(s.conductor, "hole", 0.0)), float(getattr(s.conductor, "hole_pitch", 0.0))
    thickness = float(getattr(s.conductor, "thickness", 0.0))
    return ParallelPlateExtractor(
        eps=EPS0 * o.relative_permittivity,
        fringe=fringe,
        coupling_per_length=o.coupling_per_length,
        perforation=Perforation(hole, pitch, thickness=thickness) if hole else None,
    )
