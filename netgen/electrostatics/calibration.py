"""Calibration of the analytic extractor against a field solution at a few points.

A field solver (the BEM extractor, or a user's Maxwell-matrix file: netgen.electrostatics.coupling_file)
gives the full Maxwell capacitance matrix M(q) at a few generalized coordinates q: conductors in
the order [plate, electrode_1, ..., electrode_n], in F, M_ii > 0 and M_ij = -C_ij <= 0 off the
diagonal. From it:

- the plate-electrode capacitances C_i(q) = -M[0, i] fit, per electrode, the two coefficients of
  the parallel-plate extractor's edge fringe, C_i = eps [int dA/g + a_i int ds + b_i int ln(L/g) ds]
  (netgen.electrostatics.parallel_plate): C is linear in (a_i, b_i), so the fit is one small least
  squares per electrode over the values at the points and their central differences along each
  coordinate (the forces are derivatives of C);
- the constant electrode-electrode coupling matrix is the mean of -M[i, j] over the points, with
  its spread (standard deviation, min, max) recorded: the couplings barely move with the plate
  (docs/bem.md, 'A disk between 8 + 8 sector electrodes').

Points (`design`): the centre, then +-h along each coordinate in turn (h = `span` x touching
amplitude), then seeded random points in that box.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..geometry.shapes import Array, Basis, Electrode, Plate
from .parallel_plate import EdgeFringe, ParallelPlateExtractor

# q (ncoords,) in SI -> Maxwell matrix (1 + nel, 1 + nel) in F, conductors [plate, *electrodes]
MaxwellSource = Callable[[np.ndarray], np.ndarray]
SEED = 20261201  # the random points beyond the star design


@dataclass(frozen=True)
class Calibration:
    """The result: points (npts, ncoords) SI, each point's Maxwell matrix, the fitted per-electrode
    fringes, the coupling matrix (mean over the points) and its spread, and the comparison of
    the uncalibrated and calibrated analytic extractor against the field solution."""

    source: str
    points: Array
    maxwell: Array  # (npts, 1 + nel, 1 + nel)
    fringes: tuple[EdgeFringe, ...]
    coupling: Array  # (nel, nel), zero diagonal
    spread: Array  # (nel, nel) standard deviation over the points
    comparison: dict

    def record(self, names: Sequence[str]) -> dict:
        """The MacroModel's calibration entry (netgen.model.validate.check_calibration)."""
        n = len(names)
        spread = [
            {
                "pair": [names[i], names[j]],
                "mean": float(self.coupling[i, j]),
                "std": float(self.spread[i, j]),
                "min": float(-self.maxwell[:, 1 + i, 1 + j].max()),
                "max": float(-self.maxwell[:, 1 + i, 1 + j].min()),
            }
            for i in range(n)
            for j in range(i + 1, n)
            if self.coupling[i, j]
        ]
        return {
            "source": self.source,
            "points": int(len(self.points)),
            "fringe": [
                {"electrode": e, "a": float(f.a), "b": float(f.b), "length": float(f.length)}
                for e, f in zip(names, self.fringes)
            ],
            "coupling_spread": spread,
        }


def design(n: int, scales: Array, span: float) -> Array:
    """n calibration points (n, ncoords) in SI: the centre, +-span x touching amplitude along each
    coordinate in turn, then seeded uniform random points inside that box; a coordinate with an
    infinite amplitude (one that moves no plate towards an electrode, e.g. in-plane beside combs)
    stays at 0."""
    if n < 1:
        raise ValueError("calibration needs at least one point")
    nc = len(scales)
    finite = np.isfinite(np.asarray(scales, dtype=float))  # an in-plane coordinate never closes a plate gap:
    h = np.where(finite, span * np.asarray(scales, dtype=float), 0.0)  # it stays at 0 (nothing to fit along it)
    star = [np.zeros(nc)] + [s * h[v] * np.eye(nc)[v] for v in range(nc) if finite[v] for s in (1.0, -1.0)]
    extra = np.random.default_rng(SEED).uniform(-1.0, 1.0, (max(0, n - len(star)), nc)) * h
    return np.vstack(star[:n] + list(extra))


def plate_capacitances(m: Array) -> Array:
    """Plate-electrode capacitances (..., nel) = -M[plate, electrode] of Maxwell matrices (..., 1+nel, 1+nel)."""
    return -m[..., 0, 1:]


def electrode_couplings(m: Array) -> Array:
    """Electrode-electrode two-terminal capacitances (..., nel, nel) = -M[i, j], zero diagonal."""
    c = -m[..., 1:, 1:].copy()
    idx = np.arange(c.shape[-1])
    c[..., idx, idx] = 0.0
    return c


def pairs(points: Array) -> list[tuple[int, int, int, float]]:
    """(coordinate v, index of +h, index of -h, 2h) for every pair of points that differ only along v
    by +-h around a common point: the central differences of the design."""
    out = []
    for k in range(len(points)):
        for j in range(k + 1, len(points)):
            d = points[k] - points[j]
            nz = np.flatnonzero(d)
            if len(nz) == 1 and np.allclose(points[k] + points[j], 2 * points[0]):
                v = int(nz[0])
                out.append((v, k, j, float(d[v])))
    return out


def terms(
    base: ParallelPlateExtractor, electrodes: Sequence[Electrode], plate: Plate, basis: Basis, q: Array
) -> tuple[Array, Array, Array]:
    """The three parts of the analytic capacitance at the points q, each (npts, nel) in F:
    eps int F dA/g (no fringe; F: a perforated plate's fill factor, 1 when solid), eps int ds (a = 1,
    b = 0 minus that), eps int ln(L/g) ds (a = 0, b = 1). A layered electrode's edge step
    (parallel_plate.layer_step) is known, not fitted: it goes with the first part."""
    length = (base.fringe.length if base.fringe is not None else None) or plate.size

    def part(fringe, step=False):
        ext = ParallelPlateExtractor(
            eps=base.eps,
            fringe=fringe,
            order=base.order,
            edge_order=base.edge_order,
            perforation=base.perforation,
            layer_step=step,
        )
        return ext.prepare(electrodes, plate, basis).capacitance(q)

    area = part(None)
    stepped = part(EdgeFringe(0.0, 0.0, length), base.layer_step)
    return stepped, part(EdgeFringe(1.0, 0.0, length)) - area, part(EdgeFringe(0.0, 1.0, length)) - area


def fit_fringe(area: Array, edge: Array, log: Array, c: Array, diffs: list, b_default: float) -> tuple[float, float]:
    """(a, b) of one electrode: least squares of the relative residuals of C at the points and of
    its central differences (each scaled by the largest field-solution difference along that
    coordinate); with too few independent rows b keeps `b_default` and only a is fitted."""
    rows, rhs = [np.stack([edge, log], axis=1) / c[:, None]], [(c - area) / c]
    for v in sorted({d[0] for d in diffs}):
        ks = [(k, j) for vv, k, j, _ in diffs if vv == v]
        dc = np.array([c[k] - c[j] for k, j in ks])
        scale = np.abs(dc).max()
        if scale > 1e-9 * np.abs(c).max():
            da = np.array([area[k] - area[j] for k, j in ks])
            dl = np.array([log[k] - log[j] for k, j in ks])
            rows.append(np.stack([np.zeros_like(dl), dl], axis=1) / scale)
            rhs.append((dc - da) / scale)
    a_mat, y = np.vstack(rows), np.concatenate(rhs)
    if np.linalg.matrix_rank(a_mat, tol=1e-9 * np.abs(a_mat).max()) < 2:
        a = float(np.sum(a_mat[:, 0] * (y - b_default * a_mat[:, 1])) / np.sum(a_mat[:, 0] ** 2))
        return a, b_default
    sol, *_ = np.linalg.lstsq(a_mat, y, rcond=None)
    return float(sol[0]), float(sol[1])


def calibrate(
    source: MaxwellSource | None,
    electrodes: Sequence[Electrode],
    plate: Plate,
    basis: Basis,
    points: Array,
    base: ParallelPlateExtractor,
    name: str,
    maxwell: Array | None = None,
) -> Calibration:
    """Calibrate `base` at `points` (npts, ncoords) SI against `source` (or the given Maxwell
    matrices, e.g. from a file): per-electrode fringes, couplings, and the comparison report."""
    q = np.atleast_2d(np.asarray(points, dtype=float))
    m = np.stack([np.asarray(source(p), dtype=float) for p in q]) if maxwell is None else np.asarray(maxwell, float)
    nel = len(electrodes)
    if m.shape != (len(q), nel + 1, nel + 1):
        raise ValueError(
            f"the field solution gave Maxwell matrices of shape {m.shape[1:]}, expected "
            f"{(nel + 1, nel + 1)} (the plate and {nel} electrodes)"
        )
    c = plate_capacitances(m)
    area, edge, log = terms(base, electrodes, plate, basis, q)
    diffs = pairs(q)
    b0 = base.fringe.b if base.fringe is not None else EdgeFringe().b
    length = (base.fringe.length if base.fringe is not None else None) or plate.size
    fringes = tuple(
        EdgeFringe(*fit_fringe(area[:, i], edge[:, i], log[:, i], c[:, i], diffs, b0), length) for i in range(nel)
    )
    cc = electrode_couplings(m)
    mean, spread = cc.mean(axis=0), cc.std(axis=0)
    calibrated = ParallelPlateExtractor(
        eps=base.eps,
        fringes=fringes,
        order=base.order,
        edge_order=base.edge_order,
        perforation=base.perforation,
        layer_step=base.layer_step,
    )
    prepared = [e.prepare(electrodes, plate, basis) for e in (base, calibrated)]
    report = comparison([p.capacitance(q) for p in prepared], c, diffs, [e.name for e in electrodes], mean)
    return Calibration(name, q, m, fringes, mean, spread, report)


def comparison(analytic: list[Array], c: Array, diffs: list, names: list[str], coupling: Array) -> dict:
    """Per electrode: the relative error of C at the points and of its central difference along each
    coordinate, for the uncalibrated and the calibrated extractor; the couplings over C_i at the
    first point (the design's centre; a file's first point)."""
    out = {}
    for i, name in enumerate(names):
        row = {"c_field_F": c[:, i].tolist()}
        for label, a in zip(("analytic", "calibrated"), analytic):
            row[f"{label}_c_rel_error"] = ((a[:, i] - c[:, i]) / c[:, i]).tolist()
            per = {}
            for v, k, j, _ in diffs:
                dc = c[k, i] - c[j, i]
                if abs(dc) > 1e-6 * abs(c[0, i]):
                    per.setdefault(str(v), []).append(float(((a[k, i] - a[j, i]) - dc) / dc))
            row[f"{label}_dc_rel_error"] = per
        row["coupling_over_c0"] = {
            names[j]: float(coupling[i, j] / c[0, i]) for j in range(len(names)) if coupling[i, j]
        }
        out[name] = row
    return out
