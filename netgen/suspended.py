"""Suspended structures (the paper's u(x) = G(x) m case): a rigid plate on linear springs and
Euler-Bernoulli beams (clamped-clamped, cantilever) over rectangular electrodes.

Mechanics only; the capacitance extractor, the fit and the emitters are the free disk's.

- Piston: coordinates z (and tilt_x, tilt_y), masses m, I_x = m W^2/12, I_y = m L^2/12, springs
  from the structure file.
- Beams: Hermite-cubic finite elements of the Euler-Bernoulli beam (bending EI w'''' plus the
  geometric stiffness of the axial residual force N0 = sigma0 w t), generalized eigenproblem
  K phi = w^2 M phi; the first N modes are the coordinates, each normalised to a peak
  deflection of 1 (the amplitude is the peak deflection in metres), with modal mass phi^T M phi
  and modal stiffness phi^T K phi (M- and K-orthogonal: diagonal).
- Stress stiffening of a clamped-clamped beam (large deflection): the mid-plane stretches by
  dL = integral (sqrt(1 + w'^2) - 1) dx, storing U = E A dL^2 / (2 L) beyond the linear modal
  energy. U is sampled on a grid of the modal amplitudes and fitted as a polynomial (the
  paper's "inner potential energy ... fitted"); its gradient is the nonlinear restoring force.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import eigh
from scipy.optimize import minimize_scalar

from .fit import Polynomial, monomial_exponents, monomials, sampling_grid


# ------------------------------------------------------------------ beam finite elements

def _hermite(s: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Hermite cubic shape functions and their x-derivatives at local coordinates s in [0, 1]."""
    n = np.stack([1 - 3 * s**2 + 2 * s**3, h * (s - 2 * s**2 + s**3), 3 * s**2 - 2 * s**3, h * (-s**2 + s**3)], -1)
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
    vectors: np.ndarray              # (ndof, nmodes) nodal (w, w') values, peak-normalised
    elements: int

    def _locate(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        h = self.length / self.elements
        xr = np.clip(np.ravel(np.asarray(x, dtype=float)), 0.0, self.length)
        e = np.minimum((xr / h).astype(int), self.elements - 1)
        return e, xr / h - e, h

    def _eval(self, x: np.ndarray, derivative: bool) -> np.ndarray:
        e, s, h = self._locate(x)
        n, d = _hermite(s, h)
        f = d if derivative else n                                         # (npts, 4)
        dofs = 2 * e[:, None] + np.arange(4)[None, :]                       # (npts, 4)
        return np.einsum("pk,pkm->pm", f, self.vectors[dofs])

    def shape(self, x: np.ndarray) -> np.ndarray:
        """Deflection per unit modal amplitude, (npts, nmodes), at positions x (m) along the beam."""
        return self._eval(x, False)

    def slope(self, x: np.ndarray) -> np.ndarray:
        """dphi/dx (1/m), (npts, nmodes)."""
        return self._eval(x, True)


def beam_modes(kind: str, length: float, width: float, thickness: float, youngs_modulus: float,
               density: float, count: int, residual_stress: float = 0.0, elements: int = 60) -> BeamModes:
    """The first `count` bending modes of a clamped-clamped beam or a cantilever (Hermite FE)."""
    h = length / elements
    area, inertia = width * thickness, width * thickness**3 / 12.0
    ei, rho_a, n0 = youngs_modulus * inertia, density * area, residual_stress * area
    kb = ei / h**3 * np.array([[12, 6 * h, -12, 6 * h], [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                               [-12, -6 * h, 12, -6 * h], [6 * h, 2 * h * h, -6 * h, 4 * h * h]])
    kg = n0 / (30 * h) * np.array([[36, 3 * h, -36, 3 * h], [3 * h, 4 * h * h, -3 * h, -h * h],
                                   [-36, -3 * h, 36, -3 * h], [3 * h, -h * h, -3 * h, 4 * h * h]])
    me = rho_a * h / 420 * np.array([[156, 22 * h, 54, -13 * h], [22 * h, 4 * h * h, 13 * h, -3 * h * h],
                                     [54, 13 * h, 156, -22 * h], [-13 * h, -3 * h * h, -22 * h, 4 * h * h]])
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
    for k, i in enumerate(np.argmax(np.abs(shapes), axis=0)):             # refine the grid maximum
        lo, hi = xs[max(i - 1, 0)], xs[min(i + 1, len(xs) - 1)]
        best = minimize_scalar(lambda x: -abs(probe.shape(np.array([x]))[0, k]), bounds=(lo, hi),
                               method="bounded", options={"xatol": 1e-12 * length})
        peak[k] = probe.shape(np.array([best.x]))[0, k]
        peak[k] = peak[k] if abs(peak[k]) >= abs(shapes[i, k]) else shapes[i, k]
    vectors = vectors / peak[None, :]
    mass = np.einsum("im,ij,jm->m", vectors, M, vectors)
    stiff = np.einsum("im,ij,jm->m", vectors, K, vectors)
    # frequencies from the modal stiffness and mass (the Rayleigh quotients the model integrates;
    # eigh's eigenvalues of this ill-conditioned pencil agree within ~1e-7)
    return BeamModes(kind, length, np.sqrt(stiff / mass) / (2 * math.pi), mass, stiff, vectors, elements)


def euler_bernoulli_frequency(kind: str, length: float, width: float, thickness: float,
                              youngs_modulus: float, density: float) -> float:
    """Closed-form fundamental frequency (Hz): (beta L)^2 / (2 pi L^2) sqrt(E I / (rho A))."""
    beta_l = {"clamped_clamped_beam": 4.730040744862704, "cantilever": 1.875104068711961}[kind]
    ei, rho_a = youngs_modulus * width * thickness**3 / 12.0, density * width * thickness
    return beta_l**2 / (2 * math.pi * length**2) * math.sqrt(ei / rho_a)


# ------------------------------------------------------------------ stress stiffening

def stretching_energy(modes: BeamModes, axial_rigidity: float, q: np.ndarray, points: int = 400) -> np.ndarray:
    """Mid-plane stretching energy E A dL^2 / (2 L) (J) at modal amplitudes q (npts, nmodes), m;
    dL = integral (sqrt(1 + w'^2) - 1) dx by Gauss-Legendre quadrature over the beam."""
    t, w = np.polynomial.legendre.leggauss(points)
    x, w = (t + 1) * modes.length / 2, w * modes.length / 2
    slope = np.atleast_2d(q) @ modes.slope(x).T                               # (npts, nx)
    stretch = (np.sqrt(1.0 + slope * slope) - 1.0) @ w
    return axial_rigidity * stretch**2 / (2 * modes.length)


def fit_energy(energy, scales: np.ndarray, levels: int = 5, half_range: float = 1.0,
               degrees: tuple[int, ...] = (4,)) -> tuple[Polynomial, dict]:
    """Least-squares polynomial U(xs) (J) of the scaled coordinates xs = q / scale, with monomials
    of the given total degrees only, on a levels^n grid over +-half_range (and a check at random
    points). Returns the polynomial and its fit report."""
    n = len(scales)
    exps = monomial_exponents(n, max(degrees))
    exps = exps[np.isin(exps.sum(axis=1), degrees)]
    x = sampling_grid(n, levels, half_range)
    u = energy(x * scales)
    coef, *_ = np.linalg.lstsq(monomials(x, exps), u, rcond=None)
    keep = np.abs(coef) > 1e-9 * np.max(np.abs(coef)) if np.any(coef) else np.zeros(len(coef), bool)
    poly = Polynomial(exps[keep], coef[keep])                  # drop terms at rounding level (symmetry zeros)
    check = np.random.default_rng(7).uniform(-half_range, half_range, (200, n))
    ref = energy(check * scales)
    top = float(np.max(np.abs(u)))
    err = float(np.max(np.abs(poly(check) - ref))) / top if top > 0 else 0.0
    return poly, {"levels": levels, "range": half_range, "samples": int(len(x)),
                  "degrees": list(degrees), "max_error_rel_to_peak": err}


# ------------------------------------------------------------------ pipeline stage

def mechanics(s):
    """The Mechanics stage output (pipeline.Mechanics) of a piston or a beam structure."""
    from .pipeline import Mechanics
    c = s.conductor
    if c.kind == "piston":
        rigid = list(s.coordinates.rigid)
        inertia = {"z": c.mass, "tilt_x": c.mass * c.width**2 / 12, "tilt_y": c.mass * c.length**2 / 12}
        springs = {"z": c.stiffness, "tilt_x": c.tilt_stiffness, "tilt_y": c.tilt_stiffness}
        masses = np.array([inertia[r] for r in rigid])
        stiff = np.array([springs[r] for r in rigid])

        def basis(x: np.ndarray, y: np.ndarray) -> np.ndarray:
            cols = {"z": np.ones_like(x), "tilt_x": y, "tilt_y": -x}
            return np.stack([cols[r] for r in rigid], axis=-1)

        return Mechanics(rigid, ["translation" if r == "z" else "rotation" for r in rigid],
                         ["m" if r == "z" else "rad" for r in rigid], [""] * len(rigid), masses, stiff,
                         np.sqrt(stiff / masses) / (2 * math.pi), basis,
                         {"kind": "piston", "mass_kg": c.mass, "spring_N_per_m": c.stiffness,
                          "tilt_spring_N_m_per_rad": c.tilt_stiffness})
    count = s.coordinates.modes
    modes = beam_modes(c.kind, c.length, c.width, c.thickness, c.youngs_modulus, c.density, count,
                       c.residual_stress, c.elements)

    def basis(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return modes.shape(x)

    names = [f"m{k + 1}" for k in range(count)]
    ref = euler_bernoulli_frequency(c.kind, c.length, c.width, c.thickness, c.youngs_modulus, c.density)
    report = {"kind": c.kind, "mass_kg": c.mass, "elements": c.elements,
              "residual_stress_Pa": c.residual_stress, "axial_force_N": c.residual_stress * c.width * c.thickness,
              "euler_bernoulli_f1_unstressed_hz": ref, "mode_normalisation": "peak deflection 1"}
    m = Mechanics(names, ["mode"] * count, ["m"] * count, [str(k + 1) for k in range(count)],
                  modes.modal_mass, modes.modal_stiffness, modes.frequencies_hz, basis, report)
    m.beam = modes                       # for the stretching energy (assemble)
    return m


def nonlinear_stiffness(s, m, scales: np.ndarray) -> dict:
    """The fitted stretching energy of a clamped-clamped beam as the MacroModel's nonlinear
    stiffness entry ({} when there is none)."""
    c = s.conductor
    if getattr(c, "kind", "") != "clamped_clamped_beam" or not c.stretching or not hasattr(m, "beam"):
        return {}
    ea = c.youngs_modulus * c.width * c.thickness
    poly, report = fit_energy(lambda q: stretching_energy(m.beam, ea, q), scales)
    return energy_entry(poly, "mid-plane stretching of the clamped-clamped beam: U = E A dL^2 / (2 L), "
                        "dL = integral (sqrt(1 + w'^2) - 1) dx", report)


def energy_entry(poly: Polynomial, description: str, report: dict) -> dict:
    """The JSON-ready nonlinear stiffness entry: U(xs) in J as a polynomial of the scaled states."""
    return {"energy_J": {"exponents": poly.exponents.tolist(), "coeffs": [float(v) for v in poly.coeffs]},
            "variables": "xs (scaled coordinates q / scale)",
            "force": "F_v = -(1/scale_v) dU/dxs_v (N), added to -K q",
            "description": description, "fit": report}


# ------------------------------------------------------------------ geometry for the extractor

def plate_outline(s):
    """The conductor outline for the capacitance extractor."""
    from . import electrostatics as es
    return es.RectPlate(*s.conductor.outline())


def electrodes(s):
    """Extractor electrodes and model descriptions of a suspended structure, in port order."""
    from . import electrostatics as es
    from .model import Electrode
    plate = plate_outline(s)
    out, described = [], []
    for e in s.electrode_sets:
        ext = es.Electrode(es.Rectangle(e.name, e.x0, e.x1, e.y0, e.y1), e.side, e.gap)
        x, y, w = ext.shape.quadrature(plate)
        out.append(ext)
        described.append(Electrode(e.name, e.name, e.side, e.gap, float(np.sum(w))))
    return out, described
