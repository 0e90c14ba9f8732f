"""Euler-Bernoulli beams (clamped-clamped, cantilever) over rectangular electrodes: the paper's
u(x) = G(x) m case.

- Hermite-cubic finite elements of the Euler-Bernoulli beam (bending EI w'''' plus the geometric
  stiffness of the axial residual force N0 = sigma0 w t), generalized eigenproblem
  K phi = w^2 M phi; the first N modes are the coordinates, each normalised to a peak
  deflection of 1 (the amplitude is the peak deflection in metres), with modal mass phi^T M phi
  and modal stiffness phi^T K phi (M- and K-orthogonal: diagonal).
- Stress stiffening of a clamped-clamped beam (large deflection): the mid-plane stretches by
  dL = integral (sqrt(1 + w'^2) - 1) dx, storing U = E A dL^2 / (2 L) beyond the linear modal
  energy: the Mechanics' strain energy, which the build fits as a polynomial over the sampled
  box (the paper's "inner potential energy ... fitted"; netgen.fit.energy).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache, partial

import numpy as np
from scipy.linalg import eigh
from scipy.optimize import minimize_scalar

from ..structure import Structure, mode_name
from .base import Mechanics, StrainEnergy


def _hermite(s: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Hermite cubic shape functions and their x-derivatives at local coordinates s in [0, 1]."""
    n = np.stack([1 - 3 * s**2 + 2 * s**3, h * (s - 2 * s**2 + s**3), 3 * s**2 - 2 * s**3, h * (-(s**2) + s**3)], -1)
    d = np.stack([(-6 * s + 6 * s**2) / h, 1 - 4 * s + 3 * s**2, (6 * s - 6 * s**2) / h, -2 * s + 3 * s**2], -1)
    return n, d


@dataclass(frozen=True)
class BeamModes:
    """The first bending modes of a beam: shapes (peak 1), modal mass/stiffness, frequencies."""

    kind: str
    length: float
    frequencies_hz: np.ndarray
    modal_mass: np.ndarray
    modal_stiffness: np.ndarray
    vectors: np.ndarray  # (ndof, nmodes) nodal (w, w') values, peak-normalised
    elements: int

    def _locate(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        h = self.length / self.elements
        xr = np.clip(np.ravel(np.asarray(x, dtype=float)), 0.0, self.length)
        e = np.minimum((xr / h).astype(int), self.elements - 1)
        return e, xr / h - e, h

    def _eval(self, x: np.ndarray, derivative: bool) -> np.ndarray:
        e, s, h = self._locate(x)
        n, d = _hermite(s, h)
        f = d if derivative else n  # (npts, 4)
        dofs = 2 * e[:, None] + np.arange(4)[None, :]  # (npts, 4)
        return np.einsum("pk,pkm->pm", f, self.vectors[dofs])

    def shape(self, x: np.ndarray) -> np.ndarray:
        """Deflection per unit modal amplitude, (npts, nmodes), at positions x (m) along the beam."""
        return self._eval(x, False)

    def slope(self, x: np.ndarray) -> np.ndarray:
        """dphi/dx (1/m), (npts, nmodes)."""
        return self._eval(x, True)


def beam_modes(c, count: int) -> BeamModes:
    """The first `count` bending modes of the clamped-clamped beam or cantilever `c` (the structure's
    beam conductor: kind, length, width, thickness, youngs_modulus, density, residual_stress and its
    `elements`; Hermite FE)."""
    kind, length, width, thickness = c.kind, c.length, c.width, c.thickness
    youngs_modulus, density, residual_stress, elements = c.youngs_modulus, c.density, c.residual_stress, c.elements
    h = length / elements
    area, inertia = width * thickness, width * thickness**3 / 12.0
    ei, rho_a, n0 = youngs_modulus * inertia, density * area, residual_stress * area
    kb = (
        ei
        / h**3
        * np.array(
            [
                [12, 6 * h, -12, 6 * h],
                [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                [-12, -6 * h, 12, -6 * h],
                [6 * h, 2 * h * h, -6 * h, 4 * h * h],
            ]
        )
    )
    kg = (
        n0
        / (30 * h)
        * np.array(
            [
                [36, 3 * h, -36, 3 * h],
                [3 * h, 4 * h * h, -3 * h, -h * h],
                [-36, -3 * h, 36, -3 * h],
                [3 * h, -h * h, -3 * h, 4 * h * h],
            ]
        )
    )
    me = (
        rho_a
        * h
        / 420
        * np.array(
            [
                [156, 22 * h, 54, -13 * h],
                [22 * h, 4 * h * h, 13 * h, -3 * h * h],
                [54, 13 * h, 156, -22 * h],
                [-13 * h, -3 * h * h, -22 * h, 4 * h * h],
            ]
        )
    )
    ndof = 2 * elements + 2
    K, M = np.zeros((ndof, ndof)), np.zeros((ndof, ndof))
    for e in range(elements):
        i = slice(2 * e, 2 * e + 4)
        K[i, i] += kb + kg
        M[i, i] += me
    fixed = [0, 1] + ([ndof - 2, ndof - 1] if kind == "clamped_clamped_beam" else [])
    free = np.array([i for i in range(ndof) if i not in fixed])
    _, v = eigh(K[np.ix_(free, free)], M[np.ix_(free, free)], subset_by_index=[0, count - 1])
    vectors = np.zeros((ndof, count))
    vectors[free] = v
    probe = BeamModes(kind, length, np.zeros(count), np.zeros(count), np.zeros(count), vectors, elements)
    xs = np.linspace(0.0, length, 40 * elements + 1)
    shapes = probe.shape(xs)
    peak = np.empty(count)
    for k, i in enumerate(first_peaks(shapes)):  # refine the grid maximum
        lo, hi = xs[max(i - 1, 0)], xs[min(i + 1, len(xs) - 1)]
        best = minimize_scalar(
            lambda x: -abs(probe.shape(np.array([x]))[0, k]),
            bounds=(lo, hi),
            method="bounded",
            options={"xatol": 1e-12 * length},
        )
        peak[k] = probe.shape(np.array([best.x]))[0, k]
        peak[k] = peak[k] if abs(peak[k]) >= abs(shapes[i, k]) else shapes[i, k]
    vectors = vectors / peak[None, :]
    mass = np.einsum("im,ij,jm->m", vectors, M, vectors)
    stiff = np.einsum("im,ij,jm->m", vectors, K, vectors)
    # frequencies from the modal stiffness and mass (the Rayleigh quotients the model integrates;
    # eigh's eigenvalues of this ill-conditioned pencil agree within ~1e-7)
    return BeamModes(kind, length, np.sqrt(stiff / mass) / (2 * math.pi), mass, stiff, vectors, elements)


def first_peaks(shapes: np.ndarray, share: float = 1e-6) -> np.ndarray:
    """Per column, the first grid point whose |value| is within `share` of the column's largest, so the
    sign comes from a fixed place: an antisymmetric mode's two equal lobes were ordered by rounding,
    and the clamped-clamped beam's second mode flipped its sign under another CPU's BLAS kernels."""
    big = np.abs(shapes) >= (1.0 - share) * np.max(np.abs(shapes), axis=0)
    return np.argmax(big, axis=0)


def euler_bernoulli_frequency(
    kind: str, length: float, width: float, thickness: float, youngs_modulus: float, density: float
) -> float:
    """Closed-form fundamental frequency (Hz): (beta L)^2 / (2 pi L^2) sqrt(E I / (rho A))."""
    beta_l = {"clamped_clamped_beam": 4.730040744862704, "cantilever": 1.875104068711961}[kind]
    ei, rho_a = youngs_modulus * width * thickness**3 / 12.0, density * width * thickness
    return beta_l**2 / (2 * math.pi * length**2) * math.sqrt(ei / rho_a)


@lru_cache(maxsize=4)
def gauss_legendre(points: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights on [-1, 1], computed once per count (numpy's leggauss solves a
    points x points eigenproblem: 0.1 s at 400, on every energy evaluation of the fits and re-runs)."""
    t, w = np.polynomial.legendre.leggauss(points)
    t.flags.writeable = w.flags.writeable = False
    return t, w


def stretching_energy(modes: BeamModes, axial_rigidity: float, q: np.ndarray, points: int = 400) -> np.ndarray:
    """Mid-plane stretching energy E A dL^2 / (2 L) (J) at modal amplitudes q (npts, nmodes), m;
    dL = integral (sqrt(1 + w'^2) - 1) dx by Gauss-Legendre quadrature over the beam."""
    t, w = gauss_legendre(points)
    x, w = (t + 1) * modes.length / 2, w * modes.length / 2
    slope = np.atleast_2d(q) @ modes.slope(x).T  # (npts, nx)
    stretch = (np.sqrt(1.0 + slope * slope) - 1.0) @ w
    return axial_rigidity * stretch**2 / (2 * modes.length)


# ------------------------------------------------------------------ the stage

STRETCHING = (
    "mid-plane stretching of the clamped-clamped beam: U = E A dL^2 / (2 L), dL = integral (sqrt(1 + w'^2) - 1) dx"
)


def mechanics(s: Structure) -> Mechanics:
    """The first bending modes of a beam as generalized coordinates m1, m2, ...; a
    clamped-clamped beam with `stretching` also carries its stretching energy."""
    c = s.conductor
    count = s.coordinates.modes
    modes = beam_modes(c, count)

    def basis(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return modes.shape(x)

    names = [mode_name(str(k + 1)) for k in range(count)]
    ref = euler_bernoulli_frequency(c.kind, c.length, c.width, c.thickness, c.youngs_modulus, c.density)
    report = {
        "kind": c.kind,
        "mass_kg": c.mass,
        "elements": c.elements,
        "residual_stress_Pa": c.residual_stress,
        "axial_force_N": c.residual_stress * c.width * c.thickness,
        "euler_bernoulli_f1_unstressed_hz": ref,
        "mode_normalisation": "peak deflection 1",
    }
    energy = None
    if c.kind == "clamped_clamped_beam" and c.stretching:
        energy = StrainEnergy(partial(stretching_energy, modes, c.youngs_modulus * c.width * c.thickness), STRETCHING)
    return Mechanics(
        names,
        ["mode"] * count,
        ["m"] * count,
        [str(k + 1) for k in range(count)],
        modes.modal_mass,
        modes.modal_stiffness,
        modes.frequencies_hz,
        basis,
        report,
        energy,
    )
