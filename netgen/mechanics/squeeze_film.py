"""Squeeze-film damping of a plate in its gas gaps: the linearised Reynolds equation.

Model (incompressible, isothermal, small motion; valid for squeeze numbers
sigma = 12 mu_eff omega L^2 / (p_a g^2) << 1, see `squeeze_number`):

    div( g^3 / (12 mu_eff) grad p ) = dh/dt      on the gap region Omega,
    p = 0 (ambient)                              on the open edges of Omega,

with p the pressure excess over ambient and h the local gap. For the free disk the gap
region of each side is the plate disk itself (the electrode layer faces the whole plate at
the set's gap; slots between electrodes are neglected) and the gas escapes at the plate rim:
p = 0 there. A unit velocity of coordinate v closes the gap by phi_v(x, y) (its vertical
displacement shape), so p_v solves -lap p_v = 12 mu_eff phi_v / g^3 and the damping matrix is

    B_uv = int_Omega p_v phi_u dA = (12 mu_eff / g^3) <phi_u, (-lap)^-1 phi_v>,

symmetric positive definite, summed over both sides' gaps. Only its diagonal enters the
MacroModel (diagonal damping); `off_diagonal_ratio` reports what is dropped.

Rarefaction: Veijola's effective viscosity mu_eff = mu / (1 + 9.638 Kn^1.159) with
Kn = lambda / g and the mean free path lambda = lambda_0 p_0 / p (stated for Kn < 880).
Discretisation: scikit-fem P2 triangles; the load phi_v is evaluated at the quadrature points.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.sparse.linalg import eigsh, splu, spsolve
from skfem import Basis, BilinearForm, ElementTriP2, LinearForm, MeshTri, condense, solve
from skfem.helpers import dot, grad

from ..core.constants import ATMOSPHERE, K_B, Gas


def knudsen(gas: Gas, pressure: float, gap: float) -> float:
    """Knudsen number lambda(p) / g with lambda scaling as 1/p."""
    return gas.mean_free_path * ATMOSPHERE / pressure / gap


def effective_viscosity(gas: Gas, pressure: float, gap: float) -> float:
    """Veijola's rarefied-gas effective viscosity mu / (1 + 9.638 Kn^1.159)."""
    return gas.viscosity / (1.0 + 9.638 * knudsen(gas, pressure, gap) ** 1.159)


def squeeze_number(mu_eff: float, omega: float, length: float, pressure: float, gap: float) -> float:
    """sigma = 12 mu_eff omega L^2 / (p g^2); the incompressible model needs sigma << 1 (say < 1)."""
    return 12.0 * mu_eff * omega * length**2 / (pressure * gap**2)


Shapes = Callable[[np.ndarray, np.ndarray], np.ndarray]


def disk_mesh(radius: float, refine: int = 5) -> MeshTri:
    """Triangle mesh of a disk of the given radius (boundary vertices on the circle)."""
    return MeshTri.init_circle(refine).scaled(radius)


def rectangle_mesh(length: float, width: float, n: int = 32) -> MeshTri:
    """Structured triangle mesh of [0, length] x [0, width]."""
    return MeshTri.init_tensor(np.linspace(0, length, n + 1), np.linspace(0, width, n + 1))


def reynolds_matrix(mesh: MeshTri, shapes: Shapes, leak: float = 0.0) -> np.ndarray:
    """<phi_u, (-lap + leak)^-1 phi_v> over the mesh with p = 0 on its whole boundary (m^4 per
    unit^2); `leak` (1/m^2) = 1 / lambda^2 of a perforated plate (perforation_leak)."""
    basis = Basis(mesh, ElementTriP2())
    stiffness = BilinearForm(lambda u, v, w: dot(grad(u), grad(v)) + leak * u * v).assemble(basis)
    ncol = shapes(np.zeros(1), np.zeros(1)).shape[-1]
    loads = np.stack([_load(basis, shapes, k) for k in range(ncol)], axis=1)
    interior = basis.complement_dofs(basis.get_dofs())
    pressure = np.zeros_like(loads)
    for k in range(ncol):
        pressure[:, k] = solve(*condense(stiffness, loads[:, k], I=interior))
    return loads.T @ pressure


def centred_rectangle_mesh(length: float, width: float, n: int = 32) -> MeshTri:
    """Structured triangle mesh of [-length/2, length/2] x [-width/2, width/2]."""
    return MeshTri.init_tensor(np.linspace(-length / 2, length / 2, n + 1), np.linspace(-width / 2, width / 2, n + 1))


def perforation_leak(gap: float, thickness: float, hole: float, pitch: float) -> float:
    """1 / lambda^2 (1/m^2) of square etch holes (side `hole` on a `pitch` grid, through the plate
    `thickness`) in the Reynolds equation, -lap p + p / lambda^2 = 12 mu v / g^3: each hole a
    Poiseuille duct, Q = hole^4 dp / (28.45 mu t) (square section), smeared over its cell, so
    1 / lambda^2 = 12 hole^4 / (28.45 g^3 t pitch^2) (Bao, "Micro Mechanical Transducers" (2000),
    sec. 3.7's perforated-plate model without the hole-end corrections; valid for many holes
    across the plate and hole >~ gap)."""
    return 12.0 * hole**4 / (28.45 * gap**3 * thickness * pitch**2)


def rectangular_plate_leaky_series(
    mu: float, length: float, width: float, gap: float, leak: float, terms: int = 200
) -> float:
    """Rigid rectangular plate, -lap p + leak p = 12 mu v / g^3, p = 0 on the edges: the double sine
    series b = (12 mu / g^3) sum_{m,n odd} 64 L W / (pi^4 m^2 n^2 (pi^2 (m^2/L^2 + n^2/W^2) + leak))."""
    m = np.arange(1, 2 * terms, 2, dtype=float)[:, None]
    n = np.arange(1, 2 * terms, 2, dtype=float)[None, :]
    lam = math.pi**2 * (m**2 / length**2 + n**2 / width**2) + leak
    return 12.0 * mu / gap**3 * float(np.sum(64.0 * length * width / (math.pi**4 * m**2 * n**2 * lam)))


def _load(basis: Basis, shapes: Shapes, k: int) -> np.ndarray:
    """Load vector int phi_k psi_i dA with phi_k evaluated at the quadrature points."""

    def form(v, w):
        x, y = w.x[0], w.x[1]
        return shapes(x.ravel(), y.ravel())[..., k].reshape(x.shape) * v

    return LinearForm(form).assemble(basis)


def damping_matrix(mesh: MeshTri, shapes: Shapes, gap: float, mu_eff: float) -> np.ndarray:
    """Squeeze-film damping matrix B (N s/m per unit^2 of the coordinates) of one gap."""
    return 12.0 * mu_eff / gap**3 * reynolds_matrix(mesh, shapes)


def off_diagonal_ratio(b: np.ndarray) -> float:
    """Largest |B_uv| / sqrt(B_uu B_vv), u != v: the coupling dropped by a diagonal model."""
    d = np.sqrt(np.clip(np.diag(b), 1e-300, None))
    r = np.abs(b) / np.outer(d, d)
    np.fill_diagonal(r, 0.0)
    return float(r.max()) if r.size else 0.0


def circular_plate_closed_form(mu: float, radius: float, gap: float) -> float:
    """b = 3 pi mu a^4 / (2 g^3): rigid disk, incompressible film, p = 0 at the rim."""
    return 3.0 * math.pi * mu * radius**4 / (2.0 * gap**3)


def rectangular_plate_series(mu: float, length: float, width: float, gap: float, terms: int = 400) -> float:
    """Blech's incompressible limit: b = 768 mu L W / (pi^6 g^3) sum_{m,n odd} 1 / (m^2 n^2 (m^2/L^2 + n^2/W^2))."""
    m = np.arange(1, 2 * terms, 2, dtype=float)[:, None]
    n = np.arange(1, 2 * terms, 2, dtype=float)[None, :]
    s = np.sum(1.0 / (m**2 * n**2 * (m**2 / length**2 + n**2 / width**2)))
    return 768.0 * mu * length * width / (math.pi**6 * gap**3) * float(s)


def thermal_force_psd(damping: float, temperature: float) -> float:
    """One-sided thermal force noise S_F = 4 k_B T b (N^2/Hz), fluctuation-dissipation."""
    return 4.0 * K_B * temperature * damping


# ------------------------------------------------------------------ compressible film (frequency domain)
#
# Isothermal, linearised, compressible: -lap p + i kappa p = (12 mu_eff / g^3) phi_v with
# kappa = 12 mu_eff omega / (g^2 p_a) (= sigma / L^2). The complex admittance per unit velocity
# B(omega) = int p phi dA = b(omega) - i k(omega) / omega: damping b and gas-spring stiffness k.
# With the Dirichlet eigenpairs (lambda_j, psi_j) of -lap on the gap region it is exactly
#   B(omega) = sum_j r_j / (1 + i omega / omega_j),  r_j = c (phi, psi_j)^2 / lambda_j,
#   omega_j = lambda_j g^2 p_a / (12 mu_eff),        c = 12 mu_eff / g^3,
# a pole-residue model: one damper r_j in series with a spring r_j omega_j (Maxwell) per pole.


@dataclass(frozen=True)
class PoleResidue:
    """B(omega) = remainder + sum_j residues_j / (1 + i omega / poles_j) for one coordinate
    (N s/m, rad/s); `remainder` = B(0) - sum residues: the truncated fast poles as a plain damper."""

    residues: np.ndarray
    poles: np.ndarray
    remainder: float = 0.0
    # per branch its residue from each parallel film (combine; rows sum to residues), and each
    # film's part of the remainder: which side of the plate a branch belongs to (None: one film)
    parts: np.ndarray | None = None
    remainder_parts: tuple[float, ...] = ()

    def admittance(self, omega: float | np.ndarray) -> np.ndarray:
        """Complex B(omega); Re = damping, -omega Im = gas-spring stiffness."""
        w = np.asarray(omega, dtype=float)[..., None]
        return self.remainder + np.sum(self.residues / (1.0 + 1j * w / self.poles), axis=-1)


def _p2_matrices(mesh: MeshTri) -> tuple[Basis, object, object, np.ndarray]:
    """P2 basis, stiffness and mass matrices, and the interior (non-boundary) DOFs."""
    basis = Basis(mesh, ElementTriP2())
    stiffness = BilinearForm(lambda u, v, w: dot(grad(u), grad(v))).assemble(basis)
    mass = BilinearForm(lambda u, v, w: u * v).assemble(basis)
    return basis, stiffness, mass, basis.complement_dofs(basis.get_dofs())


def compressible_admittance(
    mesh: MeshTri, shapes: Shapes, k: int, gap: float, mu_eff: float, pressure: float, omega: float
) -> complex:
    """B(omega) of coordinate k from the complex Reynolds solve (N s/m per unit^2)."""
    basis, stiffness, mass, interior = _p2_matrices(mesh)
    load = _load(basis, shapes, k)
    kappa = 12.0 * mu_eff * omega / (gap**2 * pressure)
    a = (stiffness + 1j * kappa * mass).tocsr()[interior][:, interior]
    p = spsolve(a.tocsc(), load[interior].astype(complex))
    return complex(12.0 * mu_eff / gap**3 * load[interior] @ p)


def pole_residue(
    mesh: MeshTri, shapes: Shapes, k: int, gap: float, mu_eff: float, pressure: float, poles: int = 40
) -> PoleResidue:
    """The `poles` slowest terms of the exact eigen-expansion of B(omega) for coordinate k
    (`pole_residues` of all coordinates, this one taken)."""
    return pole_residues(mesh, shapes, gap, mu_eff, pressure, poles)[k]


def rectangular_plate_blech_complex(
    mu: float, length: float, width: float, gap: float, pressure: float, omega: float, terms: int = 200
) -> complex:
    """Blech's compressible rectangular-plate series as complex B(omega) (rigid plate, p = 0 at edges)."""
    m = np.arange(1, 2 * terms, 2, dtype=float)[:, None]
    n = np.arange(1, 2 * terms, 2, dtype=float)[None, :]
    lam = math.pi**2 * (m**2 / length**2 + n**2 / width**2)
    kappa = 12.0 * mu * omega / (gap**2 * pressure)
    s = np.sum(64.0 * length * width / (math.pi**4 * m**2 * n**2 * (lam + 1j * kappa)))
    return complex(12.0 * mu / gap**3 * s)


def pole_residues(
    mesh: MeshTri, shapes: Shapes, gap: float, mu_eff: float, pressure: float, poles: int = 40
) -> list[PoleResidue]:
    """`pole_residue` of every coordinate of `shapes`, sharing one Dirichlet eigen-solve."""
    basis, stiffness, mass, interior = _p2_matrices(mesh)
    kk = stiffness.tocsr()[interior][:, interior].tocsc()
    mm = mass.tocsr()[interior][:, interior].tocsc()
    v0 = np.ones(kk.shape[0])  # seeded: same input, same output
    lam, psi = eigsh(kk, k=poles, M=mm, sigma=0.0, which="LM", v0=v0)
    lu = splu(kk)
    c = 12.0 * mu_eff / gap**3
    out = []
    for k in range(shapes(np.zeros(1), np.zeros(1)).shape[-1]):
        load = _load(basis, shapes, k)[interior]
        residues = c * (psi.T @ load) ** 2 / lam
        static = c * float(load @ lu.solve(load))
        out.append(PoleResidue(residues, lam * gap**2 * pressure / (12.0 * mu_eff), static - float(residues.sum())))
    return out


def combine(models: list[PoleResidue], rel: float = 1e-6) -> PoleResidue:
    """The sum of parallel films (both sides of the plate); equal poles (same gap on both sides,
    degenerate cos/sin eigenpairs) within `rel` merge into one branch with the summed residue."""
    poles = np.concatenate([m.poles for m in models])
    residues = np.concatenate([m.residues for m in models])
    source = np.concatenate([np.full(len(m.poles), i) for i, m in enumerate(models)])
    order = np.argsort(poles, kind="stable")
    merged_p: list[float] = []
    merged_r: list[float] = []
    parts: list[np.ndarray] = []
    for w, r, i in zip(poles[order], residues[order], source[order]):
        if not (merged_p and abs(w - merged_p[-1]) <= rel * merged_p[-1]):
            merged_p.append(float(w))
            merged_r.append(0.0)
            parts.append(np.zeros(len(models)))
        merged_r[-1] += float(r)
        parts[-1][i] += float(r)
    return PoleResidue(
        np.array(merged_r),
        np.array(merged_p),
        float(sum(m.remainder for m in models)),
        np.array(parts).reshape(len(merged_p), len(models)),
        tuple(float(m.remainder) for m in models),
    )


def max_relative_error(model: PoleResidue, reference: PoleResidue, omega_max: float, points: int = 200) -> float:
    """max |B - B_ref| / |B_ref| over a log grid from 1e-3 of the slowest pole to omega_max."""
    start = min(float(reference.poles.min()) * 1e-3, omega_max / 10)
    w = np.geomspace(start, omega_max, points)
    ref = reference.admittance(w)
    return float(np.max(np.abs(model.admittance(w) - ref) / np.abs(ref)))


def maxwell_network(
    full: PoleResidue, omega_max: float, tol: float = 0.01, max_branches: int = 8
) -> tuple[PoleResidue, float]:
    """The fewest Maxwell branches (largest residues first) that reproduce `full` within `tol`
    up to omega_max; the dropped poles join the plain damper (exact at omega << their pole).
    Returns the reduced network and its error (the last tried if `max_branches` is not enough)."""
    order = np.argsort(-full.residues, kind="stable")
    total = float(full.residues.sum())
    best = None
    for n in range(0, min(max_branches, len(order)) + 1):
        keep = np.sort(order[:n])
        drop = np.setdiff1d(np.arange(len(order)), keep)
        reduced = PoleResidue(full.residues[keep], full.poles[keep], full.remainder + float(full.residues[drop].sum()))
        if full.parts is not None:  # each film's kept residues and its remainder with its dropped poles
            rest = tuple(float(r) for r in np.asarray(full.remainder_parts) + full.parts[drop].sum(axis=0))
            reduced = dataclasses.replace(reduced, parts=full.parts[keep], remainder_parts=rest)
        err = max_relative_error(reduced, full, omega_max)
        best = (reduced, err)
        if err <= tol or total <= 0:
            break
    return best
