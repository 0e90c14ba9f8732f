"""Analytic capacitance functions C(x) fitted to sampled capacitances.

A fit is a polynomial P of total degree d in the scaled coordinates x; the capacitance is
C = c_ref / P(x) ("inverse": 1/C is nearly affine in the coordinates of a gap electrode),
C = c_ref * P(x) ("direct"), or C = c_ref sum_k 1/P_k(x) ("plates": K effective parallel plates,
refined until the held-out error meets the tolerance). Derivatives are analytic.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares
from tqdm import tqdm

from ..core.constants import EPS0
from ..core.errors import StructureError
from ..electrostatics.sampling import Samples
from ..geometry.layout import plate_outline
from ..geometry.shapes import Electrode
from ..structure import Structure
from .polynomial import Polynomial, fit_polynomial, monomial_exponents, monomials, span

MAX_NFEV = 60  # Levenberg-Marquardt evaluations per plate fit (netgen.fit.cost uses it too)
# Work (evaluations x samples x coefficients^2) a plate fit may spend converging (settled): the
# beams' and the calibrated disk's fits (2e5..2e6 per run of MAX_NFEV) converge within it, the
# reference disk's (1.3e8..6.8e8 per run) keep their single capped run.
SETTLE_WORK = 5e7
# Levenberg-Marquardt's ftol, xtol and gtol in settled: scipy's 1e-8 stops a fit whose cost still
# falls along its ill-determined directions (cond(J) 2.7e4 on the clamped-clamped beam), where the
# stopping point is the rounding's: its dC/dxs moved 5.9e-17 F between two BLAS kernels, five times
# what tests/staleness.py allows. At 1e-14, near eps times the conditioning's reach, both kernels
# stop within 1.5e-19 F and C within 4.4e-9 relative (the gradient falls from 3e-7 to 4e-12). A fit
# too large for a second run (the reference disk's) keeps scipy's: at 1e-14 its one capped run would end at
# max_nfev, where rounding puts it (tests/pipeline/test_import: the imported samples' fit then differs).
SETTLE_TOL = 1e-14
REST_WEIGHT = 3.0  # the rest residuals weigh as REST_WEIGHT^2 times all the samples together


@dataclass(frozen=True)
class CapacitanceFit:
    """One fitted capacitance between the moving conductor and an electrode.

    target "plates": C = c_ref * sum_k 1 / P_k(x) (K effective parallel plates; K = 1 is the
    plain fit of 1/C); "inverse": the same with K = 1; "direct": C = c_ref * P_0(x). An optional
    `factor` F multiplies either form, C = F(x) c_ref ...: a process point's state factor
    (netgen.sweep.point, netgen.model.etch_state); the fits a build makes have none.
    """

    electrode: str
    c_ref: float  # F, capacitance at x = 0 (sampled)
    target: str
    polys: tuple[Polynomial, ...]
    max_rel_error: float  # on held-out random points inside the sampled box and its corners (at_corners)
    rms_rel_error: float
    grid_max_rel_error: float  # on the sampling grid itself
    factor: Polynomial | None = None  # C = factor(x) * the form above (None: 1)

    def value(self, x: np.ndarray) -> np.ndarray:
        """C(x) in farad."""
        if self.target == "direct":
            return self.factored(x, self.c_ref * self.polys[0](x))
        return self.factored(x, self.c_ref * sum((1.0 / p(x) for p in self.polys), np.zeros(len(x))))

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """dC/dx in farad per unit of scaled coordinate, shape (npoints, ncoords)."""
        if self.target == "direct":
            return self.factored_gradient(x, self.c_ref * self.polys[0](x), self.c_ref * self.polys[0].gradient(x))
        out = np.zeros(x.shape)
        for p in self.polys:
            v = p(x)
            out = out - p.gradient(x) / (v * v)[:, None]
        c = self.c_ref * sum((1.0 / p(x) for p in self.polys), np.zeros(len(x)))
        return self.factored_gradient(x, c, self.c_ref * out)

    def factored(self, x: np.ndarray, c: np.ndarray) -> np.ndarray:
        """The form's value c (npoints,) at x times the factor."""
        return c if self.factor is None else self.factor(x) * c

    def factored_gradient(self, x: np.ndarray, c: np.ndarray, g: np.ndarray) -> np.ndarray:
        """d(F C)/dx = F dC/dx + C dF/dx from the form's value c (npoints,) and gradient g (npoints, ncoords)."""
        if self.factor is None:
            return g
        return self.factor(x)[:, None] * g + c[:, None] * self.factor.gradient(x)

    @property
    def degree(self) -> int:
        return int(max(p.exponents.sum(axis=1).max() for p in self.polys))


def reference(x: np.ndarray, c: np.ndarray) -> float:
    """Sampled capacitance nearest the origin: the fit's natural unit."""
    return float(c[np.argmin(np.sum(x * x, axis=1))])


def with_errors(
    fit: CapacitanceFit, x: np.ndarray, c: np.ndarray, x_check: np.ndarray, c_check: np.ndarray
) -> CapacitanceFit:
    """The same fit with its held-out and grid errors filled in."""
    held = np.abs(fit.value(x_check) / c_check - 1.0)
    grid = np.abs(fit.value(x) / c - 1.0)
    return replace(
        fit,
        max_rel_error=float(held.max()),
        rms_rel_error=float(np.sqrt(np.mean(held**2))),
        grid_max_rel_error=float(grid.max()),
    )


def at_corners(fits: list[CapacitanceFit], corners: Samples | None) -> list[CapacitanceFit]:
    """The fits with max_rel_error over the box's corners too (netgen.electrostatics.sampling.sample_corners),
    where a polynomial's misfit peaks and random held-out points rarely fall; the fits and their rms
    (a mean over the random points) stay as they are."""
    if corners is None:
        return fits
    return [with_corners(f, corners.x, corners.c[:, i]) for i, f in enumerate(fits)]


def with_corners(fit: CapacitanceFit, x: np.ndarray, c: np.ndarray) -> CapacitanceFit:
    """The fit with max_rel_error the larger of its own and its max relative error at the points x
    (the box's corners) against the capacitances c."""
    if len(x) == 0:
        return fit
    return replace(fit, max_rel_error=max(fit.max_rel_error, float(np.max(np.abs(fit.value(x) / c - 1.0)))))


def fit_capacitance(
    name: str, x: np.ndarray, c: np.ndarray, degree: int, target: str, x_check: np.ndarray, c_check: np.ndarray
) -> CapacitanceFit:
    """Fit one capacitance as a single polynomial of C or of 1/C; report held-out errors."""
    c_ref = reference(x, c)
    if target == "direct":
        poly = fit_polynomial(x, c / c_ref, degree)
    else:
        poly = fit_polynomial(x, c_ref / c, degree)
    draft = CapacitanceFit(name, c_ref, "direct" if target == "direct" else "inverse", (poly,), 0.0, 0.0, 0.0)
    return with_errors(draft, x, c, x_check, c_check)


def fit_plates(name: str, data: FitData, initial: np.ndarray, degree: int, max_nfev: int = MAX_NFEV) -> CapacitanceFit:
    """Fit C = c_ref sum_k 1/P_k(x) to data.x, data.c by least squares on the relative error
    (data.x_check, data.c_check: the held-out errors).

    `initial` (K, 1 + ncoords) holds affine first guesses of the P_k (from physical patches
    of the electrode); higher-degree coefficients start at zero. The Jacobian is analytic.
    data.rest (C(0), dC/dx(0)): n + 1 more residuals, weighted REST_WEIGHT sqrt(samples), so the fit
    matches the capacitance and its slopes at rest (netgen.electrostatics.sampling.rest_of).
    """
    x, c, x_check, c_check, rest = data.x, data.c, data.x_check, data.c_check, data.rest
    c_ref = reference(x, c)
    exps = monomial_exponents(x.shape[1], degree)
    sp = span(x)
    basis = monomials(x / sp, exps)  # well-scaled design matrix
    k_terms, nterm = initial.shape[0], exps.shape[0]
    start = np.zeros((k_terms, nterm))
    start[:, : 1 + x.shape[1]] = initial * np.concatenate([[1.0], sp])[None, :]

    def residual(a: np.ndarray) -> np.ndarray:
        out = c_ref * np.sum(1.0 / (basis @ a.reshape(k_terms, nterm).T), axis=1) / c - 1.0
        return out if rest is None else np.concatenate([out, rest_residual(a.reshape(k_terms, nterm))])

    def jacobian(a: np.ndarray) -> np.ndarray:
        p = basis @ a.reshape(k_terms, nterm).T  # (npts, K)
        w = -c_ref / (p * p) / c[:, None]  # d residual / d P_k
        jac = (w[:, :, None] * basis[:, None, :]).reshape(len(c), k_terms * nterm)
        return jac if rest is None else np.concatenate([jac, rest_jacobian(a.reshape(k_terms, nterm))])

    lin = 1 + np.arange(x.shape[1])  # the linear monomials' columns (graded order)
    weight = REST_WEIGHT * math.sqrt(len(c))

    def rest_residual(a: np.ndarray) -> np.ndarray:
        """C(0) and dC/dx(0) against the extractor's, relative to C(0); in the basis x / span."""
        assert rest is not None  # residual calls it only with a rest
        c0, g0 = rest
        a0 = a[:, 0]
        grad = -c_ref * np.sum(a[:, lin] / (a0 * a0)[:, None], axis=0) / sp
        return weight * np.concatenate([[c_ref * np.sum(1.0 / a0) / c0 - 1.0], (grad - g0) / c0])

    def rest_jacobian(a: np.ndarray) -> np.ndarray:
        assert rest is not None  # jacobian calls it only with a rest
        c0, _ = rest
        a0 = a[:, 0]
        jac = np.zeros((1 + len(lin), k_terms, nterm))
        jac[0, :, 0] = -c_ref / (a0 * a0) / c0
        jac[1:, :, 0] = (2.0 * c_ref * a[:, lin] / (a0**3)[:, None] / sp[None, :] / c0).T
        for j, col in enumerate(lin):
            jac[1 + j, :, col] = -c_ref / (a0 * a0) / sp[j] / c0
        return weight * jac.reshape(1 + len(lin), k_terms * nterm)

    sol = settled(residual, jacobian, start.ravel(), len(c), max_nfev)
    scale = np.prod(sp[None, :] ** exps, axis=1)
    polys = tuple(Polynomial(exps, row / scale) for row in sol.x.reshape(k_terms, nterm))
    return with_errors(CapacitanceFit(name, c_ref, "plates", polys, 0.0, 0.0, 0.0), x, c, x_check, c_check)


def settled(residual, jacobian, start: np.ndarray, samples: int, max_nfev: int):
    """Levenberg-Marquardt in runs of max_nfev evaluations, each from where the last one stopped,
    until one converges or the next would pass SETTLE_WORK (evaluations x samples x coefficients^2,
    the cost of the steps). One capped run meets the error budget, but where a fit still moves fast
    along its ill-determined directions, where it stops depends on rounding (the clamped-clamped
    beam's 16 coefficients: C moved by twice its own error between two 1e-12 changes of the
    samples); a converged fit is a property of the samples, not of the CPU (tests/staleness.py).
    A fit too large to converge within the budget keeps its one capped run, whose rounding
    stability bench/fit_function_change.py measures."""
    per_run = max_nfev * samples * start.size**2
    # only a fit that may run again is taken to its minimum; one that gets a single capped run keeps
    # scipy's tolerances, as before (where 1e-14 would stop it at max_nfev, a rounding-chosen point)
    tight = 2 * per_run <= SETTLE_WORK
    tols = {"ftol": SETTLE_TOL, "xtol": SETTLE_TOL, "gtol": SETTLE_TOL} if tight else {}
    sol = least_squares(residual, start, jac=jacobian, method="lm", max_nfev=max_nfev, **tols)
    work = per_run
    while sol.status == 0 and work + per_run <= SETTLE_WORK:  # status 0: stopped at max_nfev
        sol = least_squares(residual, sol.x, jac=jacobian, method="lm", max_nfev=max_nfev, **tols)
        work += per_run
    return sol


# ------------------------------------------------------------------ the stage: one fit per electrode

PATCH_GRIDS = [(1, 1), (1, 2), (2, 2), (2, 3), (3, 3), (3, 4), (4, 4), (4, 5), (5, 5)]


@dataclass(frozen=True)
class FitData:
    """One electrode's samples for its fit: training (x, c), held out (x_check, c_check), and its
    value and gradient at rest (rest_of)."""

    x: np.ndarray
    c: np.ndarray
    x_check: np.ndarray
    c_check: np.ndarray
    rest: tuple[float, np.ndarray] | None = None

    @classmethod
    def of(cls, train: Samples, check: Samples, i: int) -> FitData:
        """Electrode i's columns of the training and held-out samples."""
        return cls(train.x, train.c[:, i], check.x, check.c[:, i], rest_of(train, i))


def fit_electrode(
    s: Structure, e: Electrode, basis, scales: np.ndarray, data: FitData, first: int = 0, oversample: float = 1.0
) -> tuple[CapacitanceFit, int]:
    """Fit one electrode's capacitance in the chosen form; 'plates' refines its patch count,
    starting at PATCH_GRIDS[first], until the held-out error meets the tolerance (or the
    term limit is reached: at most len(x) / oversample coefficients). Returns the fit and the
    index of the grid used."""
    o, name, x, c, x_check, c_check = s.fit, e.name, data.x, data.c, data.x_check, data.c_check
    if o.target != "plates":
        return fit_capacitance(name, x, c, o.degree, o.target, x_check, c_check), 0
    best: CapacitanceFit | None = None
    used, best_ok = first, False
    for k in range(first, len(PATCH_GRIDS)):
        grid = PATCH_GRIDS[k]
        if grid[0] * grid[1] > o.max_terms or grid[0] * grid[1] * math.comb(
            x.shape[1] + o.degree, o.degree
        ) * oversample > len(x):
            break  # more plate terms than the samples determine
        init = patch_guess(s, e, basis, scales, grid, float(c[np.argmin(np.sum(x * x, axis=1))]))
        fit = fit_plates(name, data, init, o.degree)
        ok = physical(fit, x, x_check)
        if best is None or (ok, -fit.max_rel_error) > (best_ok, -best.max_rel_error):
            best, used, best_ok = fit, k, ok
        if ok and fit.max_rel_error <= o.tolerance:
            break
    # check_determined and the adaptive start design (centre, axis ends and 16 (n + 1) Sobol points)
    # give the first grid enough samples
    assert best is not None, f"{name}: too few samples for {PATCH_GRIDS[first]} plate patches"
    return best, used


def physical(fit: CapacitanceFit, x: np.ndarray, x_check: np.ndarray) -> bool:
    """Every plate term 1/P_k positive at every sample and check point. A term that turns negative
    (a least-squares run with many plates over a box whose corners close the gap) puts a pole,
    P_k = 0, between the samples: held-out errors of tens of percent (lhs n = 11: 7.2e-1)."""
    pts = np.concatenate([x, x_check])
    return all(float(np.min(p(pts))) > 0.0 for p in fit.polys)


def refuse_unphysical(s: Structure, fits: list[CapacitanceFit], x: np.ndarray, x_check: np.ndarray) -> None:
    """Refuse a model whose chosen plate fit has a term 1/P_k that is not positive at a sample or
    check point (no physical patch grid was found): it has a pole inside the sampled box."""
    bad = [f.electrode for f in fits if f.target == "plates" and not physical(f, x, x_check)]
    if bad:
        raise StructureError(
            s.source,
            "sampling.range",
            f"the capacitance fit of electrode {bad[0]}"
            f"{f' (and {len(bad) - 1} more)' if len(bad) > 1 else ''} has a plate term 1/P_k that "
            f"turns negative inside the sampled box (+-{s.sampling.range:g}): a pole between the samples",
            "narrow [sampling] range (without the key the build narrows it where the box's corners "
            "reach an electrode), or use fewer coordinates",
        )


def patch_guess(
    s: Structure, e: Electrode, basis, scales: np.ndarray, grid: tuple[int, int], c_ref: float
) -> np.ndarray:
    """Affine first guesses P_k(x) for K = nr x nt patches of the electrode (equal-area bins in
    r and theta): each patch a parallel plate at its mean local displacement."""
    px, py, w = e.shape.quadrature(plate_outline(s))
    r, theta = np.hypot(px, py), np.unwrap(np.arctan2(py, px))
    phi = basis(px, py) * scales[None, :] * e.sign  # gap closed per unit x
    ids = _bins(r, w, grid[0]) * grid[1] + _bins(theta, w, grid[1])
    if s.conductor.one_dimensional:
        ids = _bins(px, w, grid[0] * grid[1])  # beams: all patches along the beam axis
    eps = EPS0 * s.electrostatics.relative_permittivity
    rows, caps = [], []
    for k in range(grid[0] * grid[1]):
        sel = ids == k
        area = float(np.sum(w[sel]))
        if area <= 0:
            continue
        mean_phi = np.sum(w[sel, None] * phi[sel], axis=0) / area
        gap = e.field_gap(s.electrostatics.relative_permittivity)  # the series gap of a dielectric layer
        rows.append(np.concatenate([[gap], -mean_phi]) / (eps * area))
        caps.append(eps * area / gap)
    lam = c_ref / sum(caps)  # absorbs the edge fringe
    return np.array(rows) * c_ref / lam


def _bins(values: np.ndarray, weights: np.ndarray, n: int) -> np.ndarray:
    """Bin index of each point so that the n bins hold equal total weight."""
    order = np.argsort(values, kind="stable")
    cum = np.cumsum(weights[order]) / np.sum(weights)
    ids = np.empty(len(values), dtype=int)
    ids[order] = np.minimum((cum * n - 1e-12).astype(int), n - 1)
    return ids


def rest_of(samples: Samples, i: int) -> tuple[float, np.ndarray] | None:
    """Electrode i's capacitance and gradient at rest, if the samples carry them."""
    return None if samples.rest is None else (float(samples.rest.c[i]), samples.rest.grad[i])


def check_determined(s: Structure, x: np.ndarray) -> None:
    """Refuse a design whose samples cannot determine the fit's polynomial terms (rank of the
    monomial matrix below the term count), e.g. a degree-2 fit on a level-1 sparse grid."""
    degree = s.fit.degree if s.fit.target != "plates" else 1  # a plate term: affine in x
    exps = monomial_exponents(x.shape[1], degree)
    rank = np.linalg.matrix_rank(monomials(x / span(x), exps)) if len(x) else 0
    if rank < len(exps):
        raise StructureError(
            s.source,
            "fit.degree",
            f"the {len(x)} samples of the {s.sampling.design} design "
            f"determine only {rank} of the {len(exps)} terms of a polynomial of total degree {degree} "
            f"in {x.shape[1]} coordinates",
            "lower [fit] degree or use a richer design ([sampling] levels, level or points; a "
            "level-L sparse grid determines total degree L)",
        )


def fit_all(
    s: Structure,
    electrodes: list[Electrode],
    basis,
    scales: np.ndarray,
    grid: Samples,
    holdout: Samples,
    progress: bool = False,
) -> list[CapacitanceFit]:
    """One capacitance fit per electrode, in port order (refused when the samples cannot
    determine the fit's terms)."""
    check_determined(s, grid.x)
    fits: list[CapacitanceFit] = []
    start: dict[str, int] = {}
    for i, e in enumerate(tqdm(electrodes, desc="fits", unit="el", disable=not progress, file=sys.stderr, leave=False)):
        ring = e.name.rsplit("s", 1)[0]  # electrodes of one ring share a patch grid
        fit, start[ring] = fit_electrode(s, e, basis, scales, FitData.of(grid, holdout, i), start.get(ring, 0))
        fits.append(fit)
    refuse_unphysical(s, fits, grid.x, holdout.x)
    return fits
