"""Comb-finger capacitance: the extractor of comb electrodes (netgen.geometry.combs) and the
extractor that puts it beside a plate extractor (MixedExtractor), so a proof mass's plates and
combs are sampled and fitted together, in port order.

Each face of a moving finger (a sidewall facing a fixed finger) contributes
    C_face(q) = int_0^L(q) SECTION(g(s; q), dz(s; q), cell) ds
over the overlap L(q) = L0 + e . u(tip) (e: the direction the moving fingers point), with the
local gap g = g0 - n . u(s) (n: the face normal toward the fixed finger) and the out-of-plane
offset dz = u_z(s) of the moving finger at the point s of the overlap, for the small-angle
rigid-body displacement u (netgen.mechanics.base.KINEMATICS; rot_z turns the fingers, so the gap
varies along the overlap: NODES Gauss points per face). Each finger end adds TIP at the tip
clearance (finger length - overlap, closed by e . u). C per electrode is the sum over its faces.

SECTION and TIP are the seam to the cross-section model ([electrostatics] comb_model, MODELS):
"field2d" (default) is netgen.electrostatics.comb_section (a 2-D field solve of the periodic
finger cell over the substrate, with fringe, out-of-plane offset and so the levitation force, and
a finger-end section); "textbook" is the parallel plate eps t / g per unit overlap and face (no
fringe, no out-of-plane dependence, no tip term, so no vertical force).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..core.errors import StructureError
from ..geometry.combs import CombShape
from ..geometry.shapes import Array, Basis, Electrode, Plate
from . import comb_section
from .base import ProbePoints

NODES = 4  # Gauss-Legendre points along each face's overlap (exact for the textbook form to ~1e-9)


@dataclass(frozen=True)
class CombCell:
    """What the cross-section model needs of one comb: finger width and thickness, `pitch` the
    centre distance of a moving finger and its neighbouring fixed finger (half the moving fingers'
    period, CombShape.pitch), the fixed fingers' bottom to the substrate (inf: none given),
    permittivity (F/m); netgen.electrostatics.comb_section's conventions."""

    width: float
    thickness: float
    pitch: float
    substrate_gap: float
    eps: float


def textbook_section(gap: np.ndarray, offset: np.ndarray, cell: CombCell) -> np.ndarray:
    """Capacitance per unit overlap of one face (F/m): the parallel plate eps t / g."""
    return cell.eps * cell.thickness / gap + 0.0 * offset


def textbook_tip(gap: np.ndarray, offset: np.ndarray, cell: CombCell) -> np.ndarray:
    """Capacitance of one finger end (F) at tip clearance `gap`: none in the textbook model."""
    return 0.0 * gap


@dataclass(frozen=True)
class CombModel:
    """A per-length face capacitance SECTION(gap, offset, cell) (F/m), a finger-end TIP (F) and
    the line the model report shows."""

    section: Callable[[np.ndarray, np.ndarray, CombCell], np.ndarray]
    tip: Callable[[np.ndarray, np.ndarray, CombCell], np.ndarray]
    description: str


# [electrostatics] comb_model -> the cross-section model (one line per model)
MODELS = {
    "field2d": CombModel(
        comb_section.section,
        comb_section.tip,
        "comb fingers: 2-D field solve of the periodic finger cell over the substrate per face and "
        "unit overlap + finger-end section (netgen.electrostatics.comb_section)",
    ),
    "textbook": CombModel(
        textbook_section,
        textbook_tip,
        "comb fingers: parallel plate eps t / g per face and unit overlap (textbook, no fringe)",
    ),
}


@dataclass(frozen=True)
class CombGeometry:
    """One comb electrode's faces and tips with the coordinates' motion there (per unit q)."""

    gap0: Array  # (F,) face gaps at rest
    overlap0: float
    close: Array  # (F, nc): n . u at the tip: gap closed
    slope: Array  # (F, nc): n . (e . grad) u: gap change per unit length back from the tip
    grow: Array  # (F, nc): e . u at the tip: overlap growth
    lift: Array  # (F, nc): u_z at the tip
    tilt: Array  # (F, nc): (e . grad) u_z
    clearance0: float  # finger length - overlap
    tip_close: Array  # (T, nc): e . u at each finger tip
    tip_lift: Array  # (T, nc)
    probe_gap: Array  # (P,) rest gaps of the stop candidates (face ends, tips; finger ends over the substrate)
    probe_phi: Array  # (P, nc) closing per unit q
    cell: CombCell
    model: CombModel


def motion(basis: Basis, pts: np.ndarray, nc: int) -> tuple[np.ndarray, np.ndarray]:
    """In-plane (npts, 2, nc) and vertical (npts, nc) displacement per unit coordinate at pts;
    a basis without `in_plane` (a conductor without in-plane coordinates) moves nothing in plane."""
    x, y = pts[:, 0], pts[:, 1]
    w = np.asarray(basis(x, y), dtype=float).reshape(len(pts), nc)
    u = basis.in_plane(x, y) if hasattr(basis, "in_plane") else np.zeros((len(pts), 2, nc))
    return np.asarray(u, dtype=float), w


def geometry(shape: CombShape, basis: Basis, nc: int, eps: float, model: CombModel) -> CombGeometry:
    """Evaluate the basis at the faces' tips and one unit back along the fingers (the motion is
    affine in position for rigid bodies, so the difference is the exact gradient)."""
    faces = shape.faces()
    tip = np.array([f.tip for f in faces])
    n = np.array([f.normal for f in faces])
    e = shape.engage
    u0, w0 = motion(basis, tip, nc)
    u1, w1 = motion(basis, tip + e[None, :], nc)
    tips = shape.finger_tips()
    ut, wt = motion(basis, tips, nc)
    close = np.einsum("fk,fkv->fv", n, u0)
    roots = tip - e[None, :] * shape.overlap
    ur, _ = motion(basis, roots, nc)
    tip_close = np.einsum("k,tkv->tv", e, ut)
    clearance = shape.length - shape.overlap
    probe_gap = np.concatenate([[f.gap for f in faces] * 2, np.full(len(tips), clearance)])
    probe_phi = np.concatenate([close, np.einsum("fk,fkv->fv", n, ur), tip_close])
    if shape.substrate_gap:  # the fingers' tips and roots bottom out on the substrate
        _, wr = motion(basis, tips - e[None, :] * shape.length, nc)
        probe_gap = np.concatenate([probe_gap, np.full(2 * len(tips), shape.substrate_gap)])
        probe_phi = np.concatenate([probe_phi, -wt, -wr])
    return CombGeometry(
        np.array([f.gap for f in faces]),
        shape.overlap,
        close,
        np.einsum("fk,fkv->fv", n, u1 - u0),
        np.einsum("k,fkv->fv", e, u0),
        w0,
        w1 - w0,
        clearance,
        tip_close,
        wt,
        probe_gap,
        probe_phi,
        CombCell(shape.width, shape.thickness, shape.pitch / 2, shape.substrate_gap or float("inf"), eps),
        model,
    )


def comb_capacitance(g: CombGeometry, q: np.ndarray) -> np.ndarray:
    """C (nsamples,) of one comb at coordinates q (nsamples, nc) in SI; nan where a gap closes,
    the fingers bottom out or disengage."""
    t, w = np.polynomial.legendre.leggauss(NODES)
    t, w = (t + 1) / 2, w / 2
    length = g.overlap0 + q @ g.grow.T  # (ns, F)
    close, slope = q @ g.close.T, q @ g.slope.T
    lift, tilt = q @ g.lift.T, q @ g.tilt.T
    c = np.zeros(q.shape[0])
    bad = np.any(length <= 0, axis=1)
    for tk, wk in zip(t, w):
        back = (1 - tk) * length  # distance back from the tip
        gap = g.gap0[None, :] - close + back * slope
        bad |= np.any(gap <= 0, axis=1)
        c += np.sum(wk * length * g.model.section(np.where(gap > 0, gap, 1.0), lift - back * tilt, g.cell), axis=1)
    clearance = g.clearance0 - q @ g.tip_close.T
    bad |= np.any(clearance <= 0, axis=1)
    c += 2 * np.sum(g.model.tip(np.where(clearance > 0, clearance, 1.0), q @ g.tip_lift.T, g.cell), axis=1)
    return np.where(bad, np.nan, c)


def as_samples(Q: ArrayLike, nc: int) -> tuple[np.ndarray, bool]:
    """Q as (nsamples, nc) and whether it was one 1-D sample."""
    q = np.asarray(Q, dtype=float)
    single = q.ndim == 1
    q = np.atleast_2d(q)
    if q.shape[1] != nc:
        raise ValueError(f"Q must have shape (nsamples, {nc}), got {np.shape(Q)}")
    return q, single


class PreparedComb:
    """CombExtractor bound to its electrodes and the basis (see the module docstring)."""

    def __init__(self, electrodes: Sequence[Electrode], geoms: list[CombGeometry], nc: int, source: str = ""):
        self.electrodes, self.geoms, self.ncoords, self.source = tuple(electrodes), geoms, nc, source
        self.capacitance(np.zeros(nc))  # the cross-section tables loaded or solved now, not in a timed sample

    def capacitance(self, Q: ArrayLike) -> Array:
        """Comb capacitances (nsamples, nelectrodes) in F; nan where touching."""
        q, single = as_samples(Q, self.ncoords)
        out = np.stack([self.one(e, g, q) for e, g in zip(self.electrodes, self.geoms)], axis=1)
        return out[0] if single else out

    def one(self, e: Electrode, g: CombGeometry, q: np.ndarray) -> np.ndarray:
        """comb_capacitance of one comb; a motion outside the 2-D section tables is a StructureError
        naming the electrode (the tables span netgen.electrostatics.comb_section's ranges)."""
        try:
            return comb_capacitance(g, q)
        except comb_section.OutsideTable as err:
            raise StructureError(
                self.source,
                f"electrode {e.name}",
                f"the sampled motion leaves the comb's 2-D section tables ({err})",
                'narrow [sampling] range, or set [electrostatics] comb_model = "textbook"',
            ) from None

    def gradient(self, Q: ArrayLike) -> Array:
        """dC/dq (nsamples, nelectrodes, ncoords) by central differences (steps 1e-6 of each
        coordinate's smallest stop distance)."""
        q, single = as_samples(Q, self.ncoords)
        out = np.empty((q.shape[0], len(self.geoms), self.ncoords))
        phi = np.concatenate([g.probe_phi / g.probe_gap[:, None] for g in self.geoms])
        for v in range(self.ncoords):
            reach = np.max(np.abs(phi[:, v]))
            h = np.zeros(self.ncoords)
            h[v] = 1e-6 / reach if reach > 0 else 1e-9
            out[:, :, v] = (self.capacitance(q + h) - self.capacitance(q - h)) / (2 * h[v])
        return out[0] if single else out

    def min_gap(self, Q: ArrayLike) -> Array:
        """Smallest local gap of each comb in units of its finger gap (nsamples, nelectrodes): a
        stop candidate at rest gap g_j closing by phi_j . q reads gap (1 - phi_j . q / g_j), so a
        tip clearance longer than the finger gap counts as the distance it really has to go."""
        q, single = as_samples(Q, self.ncoords)
        out = np.stack(
            [
                e.gap * np.min(1.0 - (q @ g.probe_phi.T) / g.probe_gap[None, :], axis=1)
                for e, g in zip(self.electrodes, self.geoms)
            ],
            axis=1,
        )
        return out[0] if single else out

    def probe_points(self) -> ProbePoints:
        """Face ends (at rest), finger tips and, over a substrate, the fingers' two ends going down
        onto it: the contact model's stop candidates (and the sampling's touching amplitudes)."""
        owner = np.concatenate([np.full(len(g.probe_gap), i) for i, g in enumerate(self.geoms)]).astype(int)
        return ProbePoints(
            np.concatenate([g.probe_gap for g in self.geoms]), np.concatenate([g.probe_phi for g in self.geoms]), owner
        )


@dataclass(frozen=True)
class CombExtractor:
    """Capacitances of comb electrodes (netgen.geometry.combs.CombShape) from the cross-section
    model `model` names in MODELS (the 2-D field solve by default, the textbook as an option)."""

    eps: float
    model: str = "field2d"
    source: str = ""  # the structure file, for errors

    @property
    def description(self) -> str:
        """The chosen model's line for the model report."""
        return MODELS[self.model].description

    def prepare(self, electrodes: Sequence[Electrode], plate: Plate, basis: Basis) -> PreparedComb:
        """The faces and tips of every comb with the basis evaluated there."""
        nc = np.asarray(basis(np.zeros(1), np.zeros(1))).reshape(1, -1).shape[1]
        model = MODELS[self.model]
        return PreparedComb(
            electrodes, [geometry(e.shape, basis, nc, self.eps, model) for e in electrodes], nc, self.source
        )

    def coupling(self, electrodes: Sequence[Electrode], plate: Plate) -> Array:
        """No constant comb-to-comb or comb-to-plate couplings in this model."""
        return np.zeros((len(electrodes), len(electrodes)))
