"""A rigid rectangular proof mass on flexures (kind "proof_mass"): any of the six rigid-body
coordinates x, y, z, rot_z, tilt_x, tilt_y with the mass and the inertia tensor of the
perforated rectangle and its moving comb fingers, and the flexure stiffness per coordinate
(netgen.mechanics.flexures: a 3-D frame solve of the named suspension, closed forms beside it in
the report; or given numbers; or none: a free body). The flexures' own mass is not added (reported
as a fraction of the moving mass).
Small-angle kinematics (netgen.mechanics.base.KINEMATICS). With [coordinates] modes = N the first
N internal modes of the plate (free edges, netgen.mechanics.plates) join them as m1, m2, ...:
vertical mode shapes that deform the plate electrodes' gaps (and move the comb fingers on the
edges vertically), M-orthogonal to the rigid motions over the plate; the moving comb fingers add
to each mode's mass (finger_modes: rigid, they turn with the edge at their roots), the flexures' vertical
springs at their attachment points to each mode's stiffness (first order: the Rayleigh quotient),
and the couplings both bring to the other modes, z and the tilts are dropped (their sizes are in
the report)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..core.errors import StructureError
from ..geometry.combs import Finger, moving_fingers
from ..structure import Structure, mode_name
from . import flexures
from .base import KINEMATICS, RIGID, Mechanics, RigidBasis, StrainEnergy, finger_rule, rigid_field
from .plates import PLATE_MODES
from .rect_plate import ELEMENTS, conductor_plate


def second_moments(c) -> tuple[float, float]:
    """(int x^2 dA, int y^2 dA) over the rectangle minus its centred square hole grid (m^4)."""
    ix, iy = c.width * c.length**3 / 12, c.length * c.width**3 / 12
    nx, ny = c.holes()
    if nx and ny:
        px = (np.arange(nx) - (nx - 1) / 2) * c.hole_pitch
        py = (np.arange(ny) - (ny - 1) / 2) * c.hole_pitch
        one = c.hole**4 / 12
        ix -= ny * float(np.sum(c.hole**2 * px**2) + nx * one)
        iy -= nx * float(np.sum(c.hole**2 * py**2) + ny * one)
    return ix, iy


def inertia(c, fingers: Sequence[Finger] = ()) -> dict[str, float]:
    """Mass (kg) and moments of inertia about the centre (kg m^2) per rigid-body coordinate of the
    perforated rectangle and the moving comb fingers on it (finger_inertia); the tilts include the
    thickness term m t^2 / 12."""
    rho_t = c.density * c.thickness
    ix, iy = second_moments(c)
    m = c.mass
    body = {
        "x": m,
        "y": m,
        "z": m,
        "rot_z": rho_t * (ix + iy),
        "tilt_x": rho_t * iy + m * c.thickness**2 / 12,
        "tilt_y": rho_t * ix + m * c.thickness**2 / 12,
    }
    extra = finger_inertia(c.density, fingers)
    return {k: v + extra[k] for k, v in body.items()}


def finger_inertia(density: float, fingers: Sequence[Finger]) -> dict[str, float]:
    """The moving fingers' mass rho t w L each and their inertias about the mass centre (each box's
    own (a^2 + b^2) / 12 plus the parallel-axis term of its centre; the tilts with t^2 / 12). Each
    finger is centred on the mass's mid-plane: exact for fingers of the full layer thickness (the
    default comb thickness: etched from the same layer, they span the same -t/2..t/2, so their first
    moment in z is 0 and their second rho w L t^3 / 12, as here); a thinner finger given its own
    `thickness` is taken as centred too (if it sits at the layer's bottom or top instead, the tilts
    miss its m (t - t_f)^2 / 4 and an x-z or y-z product of inertia)."""
    out = dict.fromkeys(RIGID, 0.0)
    for f in fingers:
        m = density * f.thickness * f.area
        a, b = f.x1 - f.x0, f.y1 - f.y0
        cx, cy = (f.x0 + f.x1) / 2, (f.y0 + f.y1) / 2
        own_x, own_y = m * (a * a / 12 + cx * cx), m * (b * b / 12 + cy * cy)  # int x^2 dm, int y^2 dm
        for k in ("x", "y", "z"):
            out[k] += m
        out["rot_z"] += own_x + own_y
        out["tilt_x"] += own_y + m * f.thickness**2 / 12
        out["tilt_y"] += own_x + m * f.thickness**2 / 12
    return out


def stiffness(c, moving: float) -> tuple[dict[str, float], dict]:
    """Spring per rigid-body coordinate and the report of its source, with the flexures' mass as a
    fraction of the `moving` mass (kg: the plate and its fingers, what the model's coordinates carry)."""
    f = c.flexure
    if f.type == "none":
        return {k: 0.0 for k in RIGID}, {"type": "none", "note": "a free body: no springs"}
    if f.type == "given":
        given = dict(f.given)
        keys = {"x": "k_x", "y": "k_y", "z": "k_z", "rot_z": "k_rot", "tilt_x": "k_tilt_x", "tilt_y": "k_tilt_y"}
        return {k: given.get(v, 0.0) for k, v in keys.items()}, {"type": "given", "given": given}
    half = (c.length / 2, c.width / 2)
    solved = flexures.frame_stiffness(f, *half, c.youngs_modulus, c.poisson_ratio)
    rigid = flexures.frame_stiffness(f, *half, c.youngs_modulus, c.poisson_ratio, rigid_truss=True)
    closed = flexures.closed_form(f, c.youngs_modulus, c.poisson_ratio)
    report = {
        "type": f.type,
        "source": "3-D Euler-Bernoulli frame solve of the suspension (netgen.mechanics.frame)",
        "frame_N_per_m": {k: solved[k] for k in flexures.AXES},
        "coupling_max": solved["coupling"],
        "closed_form_N_per_m": closed,
        "closed_form_source": flexures.SOURCES[f.type],
        "frame_rigid_truss_over_closed_form": {k: rigid[k] / closed[k] for k in closed},
        "flexure_mass_fraction": flexure_mass(c) / moving,
    }
    return {k: solved[k] for k in flexures.AXES}, report


def flexure_mass(c) -> float:
    """The beams' mass (kg): left out of the model, reported beside the proof mass."""
    f = c.flexure
    beams = {
        "clamped_guided": 4 * f.length * f.width,
        "folded": 8 * f.length * f.width,
        "crab_leg": 4 * (f.length * f.width + f.thigh_length * f.thigh_width),
    }.get(f.type, 0.0)
    return beams * f.thickness * c.density


class ModalBasis(RigidBasis):
    """The rigid-body fields followed by the plate's internal modes (vertical only: they move
    nothing in plane)."""

    def __init__(self, rigid: list[str], modes):
        super().__init__(list(rigid) + [mode_name(lab) for lab in modes.labels])
        self.rigid, self.modes = tuple(rigid), modes

    def __call__(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        x, y = np.asarray(x, float), np.asarray(y, float)
        shapes = self.modes.shape(x, y).reshape(x.shape + (-1,))
        rigid = [rigid_field(n, x, y) for n in self.rigid]
        return np.concatenate([np.stack(rigid, axis=-1), shapes], axis=-1) if rigid else shapes

    def in_plane(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        x = np.asarray(x, float)
        rigid = RigidBasis(self.rigid).in_plane(x, y) if self.rigid else np.zeros(x.shape + (2, 0))
        return np.concatenate([rigid, np.zeros(rigid.shape[:-1] + (len(self.modes.labels),))], axis=-1)


def flexure_springs(c, modes, rigid: list[str]) -> tuple[np.ndarray, float] | None:
    """The flexures' vertical springs at their attachment points (k_z shared equally, their
    rotational restraint left out) on the internal modes: the stiffness each mode gains,
    sum k phi^2, and the largest coupling sum k phi_mode phi_rigid to z and the tilts, relative to
    sqrt(K_mode K_rigid), which the diagonal model drops. None without attachment points."""
    f = c.flexure
    if f.type in ("none", "given"):
        return None
    frame = flexures.suspension(f, c.length / 2, c.width / 2, c.youngs_modulus, c.poisson_ratio)
    pts = np.array([frame.nodes[i][:2] for i in sorted(frame.tied)])
    k_tie = flexures.frame_stiffness(f, c.length / 2, c.width / 2, c.youngs_modulus, c.poisson_ratio)["z"] / len(pts)
    phi = modes.shape(pts[:, 0], pts[:, 1])
    gain = k_tie * np.sum(phi**2, axis=0)
    out_of_plane = [n for n in rigid if n in ("z", "tilt_x", "tilt_y")]
    if not out_of_plane:
        return gain, 0.0
    fields = np.stack([rigid_field(n, pts[:, 0], pts[:, 1]) for n in out_of_plane], axis=-1)
    k_rr = k_tie * np.sum(fields**2, axis=0)
    cross = k_tie * fields.T @ phi
    return gain, float(np.max(np.abs(cross) / np.sqrt(np.outer(k_rr, modes.modal_stiffness + gain))))


def finger_modes(
    c, modes, fingers: Sequence[Finger], rigid: list[str], inert: dict[str, float]
) -> tuple[np.ndarray, float]:
    """The moving fingers on the internal modes: a finger is a rigid box clamped to the plate's edge,
    so a point s beyond its root moves phi + s dphi/dn (RectPlateModes.shape, the basis the
    electrostatics use too), and mode v gains M_f,v = int rho t phi_v^2 dA over the fingers; and
    the largest mass coupling the fingers bring, int rho t phi_v phi_u over them to the other modes
    and to z and the tilts, relative to sqrt(M_v M_u), which the diagonal model drops (the modes are
    M-orthogonal over the plate alone)."""
    n = len(modes.labels)
    out_of_plane = [r for r in rigid if r in ("z", "tilt_x", "tilt_y")]
    mm, mr = np.zeros((n, n)), np.zeros((n, len(out_of_plane)))
    for x, y, w, rho_h, _ in finger_rule(c.density, fingers):
        phi = modes.shape(x, y)
        mm += rho_h * phi.T @ (w[:, None] * phi)
        if out_of_plane:
            mr += rho_h * phi.T @ (w[:, None] * np.stack([rigid_field(k, x, y) for k in out_of_plane], axis=-1))
    gain = np.diag(mm).copy()
    total = modes.modal_mass + gain
    rel = [np.abs(mm - np.diag(gain)) / np.sqrt(np.outer(total, total))]
    if out_of_plane:
        rel.append(np.abs(mr) / np.sqrt(np.outer(total, [inert[k] for k in out_of_plane])))
    return gain, float(max(np.max(r) for r in rel))


def modes_report(
    c, modes, springs: tuple[np.ndarray, float] | None, fingers: tuple[np.ndarray, float] | None = None
) -> dict:
    """What the internal modes are and how far to trust them."""
    eff = conductor_plate(c)
    flex = (
        f"none: no attachment points (flexure type {c.flexure.type})"
        if springs is None
        else {
            "stiffness_added_rel": [float(v) for v in springs[0] / modes.modal_stiffness],
            "coupling_to_z_and_tilts_max": springs[1],
            "model": "k_z / (attachment points) at each, added to each mode's stiffness; couplings dropped",
        }
    )
    out = {
        "source": "Kirchhoff plate, free edges, scikit-fem Bogner-Fox-Schmit elements (netgen.mechanics.rect_plate)",
        "elements_along_length": ELEMENTS,
        "labels": list(modes.labels),
        "free_plate_frequencies_hz": [float(v) for v in modes.frequencies_hz],
        "lambda2_leissa": [float(v) for v in modes.lambda2],
        "effective_plate": {
            "density_factor": eff.density_factor,
            "bending_stiffness_factor": eff.stiffness_factor,
            "model": "etch holes as an effective plate: mass fraction; D of a series strip",
        },
        "side_conditions": modes.orthogonality,
        "normalisation": "peak deflection 1 over the mesh nodes",
        "flexure_springs": flex,
    }
    if fingers is not None:
        out["comb_fingers"] = {
            "mass_added_rel": [float(v) for v in fingers[0] / modes.modal_mass],
            "coupling_to_modes_z_and_tilts_max": fingers[1],
            "model": "each moving finger turns with the plate's edge at its root (phi + s dphi/dn): int rho t "
            "phi^2 dA over the fingers added to each mode's mass; couplings dropped",
        }
    return out


def mechanics(s: Structure) -> Mechanics:
    """The proof mass's rigid-body coordinates with their inertias and flexure springs, and its
    first internal plate modes when [coordinates] modes asks for them."""
    c: Any = s.conductor
    rigid = list(s.coordinates.rigid)
    fingers = moving_fingers(s.electrode_sets, c.outline())
    inert = inertia(c, fingers)
    springs, spring_report = stiffness(c, inert["x"])
    count = s.coordinates.modes
    modes = PLATE_MODES[c.outline_shape](c, count) if count else None
    attached = flexure_springs(c, modes, rigid) if modes else None
    on_fingers = finger_modes(c, modes, fingers, rigid, inert) if modes and fingers else None
    modal = (modes.modal_stiffness + (attached[0] if attached else 0.0)) if modes else []
    modal_mass = (modes.modal_mass + (on_fingers[0] if on_fingers else 0.0)) if modes else []
    masses = np.array([inert[n] for n in rigid] + list(modal_mass))
    stiff = np.array([springs[n] for n in rigid] + list(modal))
    freqs = np.sqrt(stiff / masses) / (2 * math.pi)
    labels = list(modes.labels) if modes else []
    report = {
        "kind": "proof_mass",
        "mass_kg": inert["x"],
        "plate_mass_kg": c.mass,
        "moving_fingers": len(fingers),
        "holes": list(c.holes()),
        "inertia_kg_m2": {k: v for k, v in inert.items() if k in ("rot_z", "tilt_x", "tilt_y")},
        "flexure": spring_report,
        "kinematics": KINEMATICS,
    }
    if modes:
        report["internal_modes"] = modes_report(c, modes, attached, on_fingers)
    names = rigid + [mode_name(lab) for lab in labels]
    k_xy = flexure_coupling(c)
    energy = coupling_energy(s.source, k_xy, names, springs)
    if energy:
        spring_report["k_xy_N_per_m"] = k_xy  # the report's "flexure" entry
    return Mechanics(
        names,
        [RIGID[n][0] for n in rigid] + ["mode"] * count,
        [RIGID[n][1] for n in rigid] + ["m"] * count,
        [""] * len(rigid) + labels,
        masses,
        stiff,
        freqs,
        ModalBasis(rigid, modes) if modes else RigidBasis(rigid),
        report,
        energy,
    )


def flexure_coupling(c) -> float:
    """The suspension's x-y coupling stiffness k_xy (N/m; 0 without one)."""
    return float(c.flexure.k_xy)


def coupling_energy(source: str, k_xy: float, names: list[str], springs: dict[str, float]) -> StrainEnergy | None:
    """The flexure's x-y coupling k_xy x y as a strain energy (a quadratic, so the emitters' restoring
    force -dU/dq is exact): a gyroscope's quadrature force -k_xy x on y. Refused (exit 2, naming the
    structure file `source`) unless the spring matrix [[k_x, k_xy], [k_xy, k_y]] stays positive definite."""
    if not k_xy:
        return None
    limit = math.sqrt(springs["x"] * springs["y"])
    if abs(k_xy) >= limit:
        raise StructureError(
            source,
            "conductor.flexure.k_xy",
            f"|k_xy| = {abs(k_xy):g} N/m is not below sqrt(k_x k_y) = {limit:g} N/m: the suspension would be unstable",
            f"give |k_xy| well below {limit:g} N/m (a misalignment: a few per cent of k_x or less)",
        )
    ix, iy = names.index("x"), names.index("y")
    return StrainEnergy(
        lambda q: k_xy * q[:, ix] * q[:, iy],
        f"x-y coupling of the suspension, U = k_xy x y with k_xy = {k_xy:g} N/m ([conductor.flexure] k_xy)",
        (2,),
    )
