"""The inertial terms of the coordinates in an accelerating, rotating frame (the device frame):
frame acceleration a (m/s^2) and rotation rate Omega (rad/s), both along the frame's axes.

Every coordinate q_v moves the body's points by Phi_v(r) q_v (small motions: the kinematics of
netgen.mechanics.base, with the rigid rotations' through-thickness part e_v x z e_z). Newton's law
of each point in the moving frame, rho (r'' + a + 2 Omega x r' + Omega x (Omega x r) + Omega' x r),
projected on Phi_v (Lagrange's equations with the kinetic energy T = 1/2 int rho |v_frame + r' +
Omega x r|^2 over the body give the same terms) is

    M q'' + ... = F - sum_i P_i a_i - sum_k Omega_k G_k q' - sum_{k<=l} Omega_k Omega_l (S_kl q + c_kl)

with, over the body (rho including a perforation's fill factor, r = rest position + Phi q):
    participation  P_i[v]     = int rho Phi_v . e_i
    Coriolis       G_k[v, w]  = 2 int rho Phi_v . (e_k x Phi_w)             (antisymmetric)
    centrifugal    S_kk[v, w] = int rho Phi_v,k Phi_w,k - int rho Phi_v . Phi_w  (a stiffness change)
                   S_kl[v, w] = int rho (Phi_v,k Phi_w,l + Phi_v,l Phi_w,k)      (k < l, symmetric)
    and its constant force c_kl: S_kl with Phi_w replaced by the rest position r0.
All follow from the one array W[a, b, i, j] = int rho Phi_a,i Phi_b,j over the coordinates' fields
and r0, evaluated through the thickness exactly (fields affine in z) and by the plate's area rule.

The rigid rotations' second-order kinematics (rotation vector: r = s + theta x s + 1/2 theta x
(theta x s)) add to the centrifugal stiffness (`rotation_stiffness`); in the Coriolis terms they are
a total time derivative (no force). Dropped, with the reason in the build report (`report`): the
Euler term Omega' x r (the rate inputs are taken as slowly varying: no angular-acceleration port),
the modes' through-thickness in-plane motion -z grad(phi) (Kirchhoff rotary inertia, relative size
(h / wavelength)^2 / 12) and their second-order (membrane) kinematics."""

from __future__ import annotations

import math

import numpy as np

from ..structure import Structure
from .base import RIGID, Mechanics, mass_rule

AXES = "xyz"
RATE_PAIRS = ("xx", "yy", "zz", "xy", "xz", "yz")  # the centrifugal products Omega_k Omega_l, k <= l
ZERO = 1e-9  # entries below ZERO sqrt(M_v M_w) are round-off of terms zero by symmetry: set to 0
EPS = np.zeros((3, 3, 3))
for _i, _j, _k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
    EPS[_i, _j, _k], EPS[_i, _k, _j] = 1.0, -1.0


def fields(names: list[str], basis: np.ndarray, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mid-plane displacement A (npts, n+1, 3) and its through-thickness slope B (displacement
    = A + z B) per coordinate, the rest position r0 as the last field. Rigid coordinates: their
    exact small-motion fields (translation e_i, rotation e_i x r); modes: vertical phi_v (basis)."""
    n, zero, one = len(names), np.zeros_like(x), np.ones_like(x)
    a, b = np.zeros((len(x), n + 1, 3)), np.zeros((len(x), n + 1, 3))
    axis = {"x": 0, "y": 1, "z": 2, "tilt_x": 0, "tilt_y": 1, "rot_z": 2}
    for v, name in enumerate(names):
        if name in RIGID and RIGID[name][0] == "translation":
            a[:, v, axis[name]] = 1.0
        elif name in RIGID:  # e_i x (x, y, z)
            e = np.eye(3)[axis[name]]
            a[:, v] = np.cross(e, np.stack([x, y, zero], axis=-1))
            b[:, v] = np.cross(e, [0.0, 0.0, 1.0])
        else:
            a[:, v, 2] = basis[:, v]
    a[:, n] = np.stack([x, y, zero], axis=-1)
    b[:, n] = np.stack([zero, zero, one], axis=-1)
    return a, b


def moments(s: Structure, m: Mechanics, order: int = 96) -> tuple[np.ndarray, np.ndarray, float]:
    """W[a, b, i, j] = int rho Phi_a,i Phi_b,j dV and P[a, i] = int rho Phi_a,i dV over the body
    (a, b: the coordinates and r0 last; the plate and the moving fingers, netgen.mechanics.base.mass_rule:
    an internal mode turns a finger with the plate's edge at its root, as in its modal mass), and the
    body's mass."""
    n = len(m.names)
    big_w, p, total = np.zeros((n + 1, n + 1, 3, 3)), np.zeros((n + 1, 3)), 0.0
    for x, y, w, rho_h, h in mass_rule(s, order):
        a, b = fields(m.names, m.basis(x, y), x, y)
        wt = rho_h * w
        big_w = big_w + np.einsum("p,pai,pbj->abij", wt, a, a) + h * h / 12.0 * np.einsum("p,pai,pbj->abij", wt, b, b)
        p, total = p + np.einsum("p,pai->ai", wt, a), total + float(np.sum(wt))
    return big_w, p, total


def terms(s: Structure, m: Mechanics, inputs: tuple[str, ...]) -> dict:
    """The MacroModel's inertial data (netgen.model.inertial.Inertial.from_dict) for the chosen
    inputs (netgen.structure.schema.INERTIAL_INPUTS; a_z is the a_in port, kept apart)."""
    big_w, p, total = moments(s, m)
    n = len(m.names)
    mass3 = np.einsum("abii->ab", big_w)
    root = np.sqrt(np.diag(mass3)[:n])
    scale = np.outer(root, root)
    accel = {k: clean(p[:n, AXES.index(k[-1])], root * math.sqrt(total)) for k in inputs if k in ("a_x", "a_y")}
    rates = [k[-1] for k in inputs if k.startswith("w_")]
    gyro, cent, const = {}, {}, {}
    for k in rates:
        g = 2.0 * np.einsum("ij,abij->ab", EPS[:, AXES.index(k), :], big_w)
        gyro[k] = clean(0.5 * (g[:n, :n] - g[:n, :n].T), scale)
    for pair in RATE_PAIRS:
        if pair[0] not in rates or pair[1] not in rates:
            continue
        i, j = AXES.index(pair[0]), AXES.index(pair[1])
        sk = big_w[:, :, i, i] - mass3 if i == j else big_w[:, :, i, j] + big_w[:, :, j, i]
        sk[:n, :n] += rotation_stiffness(m.names, big_w[n, n], i, j)
        cent[pair] = clean(0.5 * (sk[:n, :n] + sk[:n, :n].T), scale)
        const[pair] = clean(sk[:n, n], root * math.sqrt(float(mass3[n, n])))
    return {
        "participation": accel,
        "gyroscopic": gyro,
        "centrifugal": cent,
        "centrifugal_force": {k: v for k, v in const.items() if any(v)},
    }


def rotation_stiffness(names: list[str], j: np.ndarray, k: int, m: int) -> np.ndarray:
    """The centrifugal stiffness of the rigid rotations' second-order kinematics, coefficient of
    Omega_k Omega_m (both orders when k != m): with r = s + theta x s + 1/2 theta x (theta x s) (the
    rotation vector), T0 = 1/2 int rho |Omega x r|^2 gains 1/2 theta^T E theta, E_ab = |Omega|^2 J_ab
    - Omega_a (J Omega)_b - delta_ab (|Omega|^2 tr J - Omega^T J Omega) (symmetrized; J = int rho s s^T),
    and the stiffness -E. Without it a tilt about the rotation axis itself would feel a softening."""
    axis = {"tilt_x": 0, "tilt_y": 1, "rot_z": 2}
    out = np.zeros((len(names), len(names)))

    def e(a: int, b: int, p: int, q: int) -> float:
        d = np.eye(3)
        return (
            d[p, q] * j[a, b]
            - 0.5 * (d[a, p] * j[b, q] + d[b, p] * j[a, q])
            - d[a, b] * d[p, q] * np.trace(j)
            + d[a, b] * j[p, q]
        )

    for v, nv in enumerate(names):
        for w, nw in enumerate(names):
            if nv in axis and nw in axis:
                a, b = axis[nv], axis[nw]
                out[v, w] = -(e(a, b, k, m) + (e(a, b, m, k) if k != m else 0.0))
    return out


def clean(values: np.ndarray, scale: np.ndarray) -> list:
    """Entries as plain floats (nested lists for matrices), round-off below ZERO * scale set to 0."""
    out = np.where(np.abs(values) < ZERO * scale, 0.0, values)
    return out.tolist()


def report(names: list[str], kinds: list[str], data: dict, stiffness: np.ndarray, inputs: tuple[str, ...]) -> dict:
    """The build report's account of the inertial terms: what each input couples, where the
    centrifugal stiffness reaches 1 % of a spring, and what was dropped and why."""
    out: dict = {"inputs": list(inputs), "dropped": dropped(kinds)}
    idle = [k for k in inputs if k.startswith("w_") and not couples(data, k[-1])]
    idle += [k for k, p in data["participation"].items() if not any(p)]
    if idle:
        out["uncoupled"] = idle
        out["uncoupled_note"] = (
            f"the input(s) {', '.join(idle)} move no coordinate of this device (every term zero by its "
            "symmetry or its coordinates' directions); the port(s) stay, reading nothing"
        )
    rate_1pct: dict[str, float] = {}
    for pair, sk in data["centrifugal"].items():
        if pair[0] == pair[1]:
            for v, name in enumerate(names):
                if sk[v][v] and stiffness[v] > 0:
                    rate_1pct.setdefault(name, math.inf)
                    rate_1pct[name] = min(rate_1pct[name], math.sqrt(0.01 * stiffness[v] / abs(sk[v][v])))
    if rate_1pct:
        out["centrifugal_1pct_rate_rad_s"] = {k: float(v) for k, v in rate_1pct.items()}
    return out


def couples(data: dict, axis: str) -> bool:
    """Does a rate about `axis` produce any force (Coriolis, centrifugal, constant)?"""
    mats = [data["gyroscopic"].get(axis, [])]
    mats += [v for k, v in data["centrifugal"].items() if axis in k]
    mats += [v for k, v in data["centrifugal_force"].items() if axis in k]
    return any(np.any(np.asarray(m_) != 0.0) for m_ in mats)


def dropped(kinds: list[str]) -> list[str]:
    """The terms left out of the inertial model, each with its reason."""
    out = [
        "Euler term -rho Omega' x r: the rate inputs are taken as slowly varying (no angular-acceleration "
        "port); it is below the Coriolis term by |Omega'| / (2 |Omega| omega) at the motion's frequency omega",
        "second-order kinematics of the rigid rotations in the Coriolis terms: a total time derivative in "
        "the Lagrangian (no force; in the centrifugal stiffness they are kept)",
    ]
    if "mode" in kinds:
        out.append(
            "the modes' through-thickness in-plane motion -z grad(phi) (Kirchhoff rotary inertia): "
            "relative size (h / wavelength)^2 / 12 of the modal terms; and the modes' second-order "
            "(membrane) kinematics in the centrifugal stiffness: relative size (q / wavelength)^2"
        )
    return out
