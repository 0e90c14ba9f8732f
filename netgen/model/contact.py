"""Pull-in and contact: what keeps a closing gap from blowing up the simulator.

Two parts, both stored in the MacroModel's `contact` dict and emitted by every dialect:

1. Clamped plate terms. Each fitted term 1/P_k(xs) is a parallel plate whose gap fraction
   is t = P_k(xs) / P_k(0). The fit extrapolates outside the sampled box and P_k may reach 0
   (infinite C and force) before the plate really touches (on the reference example at
   xs_z = 0.82). Below the knee t1 = KNEE the term uses
       P_eff = max(P, P_f + (P_1 - P_f) exp(min(P - P_1, 0) / (P_1 - P_f))),
   P_1 = t1 P_k(0), P_f = FLOOR P_k(0): identical to P above the knee (so the model is
   unchanged in its fitted range), C1 at the knee, monotone, and never below the floor. Forces
   stay the exact derivative of the clamped capacitance (dP_eff/dP = min(1, (P_eff - P_f) /
   (P_1 - P_f))), so charge and energy remain consistent; the force is bounded (at most about
   1/(4 FLOOR (KNEE - FLOOR)) times its value at xs = 0).

2. Stop points. The local gap at any point of an electrode is affine in the coordinates:
   g_j(xs) = gap_j (1 - a_j . xs). A set of probe points (the extractor's quadrature nodes and
   boundary vertices) is reduced to the points where each lone coordinate touches first (so a
   lone coordinate stops at exactly xs = +-1, its touching amplitude; at most 2 points per
   coordinate, which keeps ngspice fast: a greedy cover of all directions within 5 % needed 65
   points on the reference example and made transients 7x slower). Combined motions may reach
   a probe point first and then stop late; the worst case over DIRECTIONS random directions is
   stored as `late_contact_max` (fraction of the travel). At each point a penalty spring-damper acts on the
   penetration depth d_j = gap_j p_j, p_j = a_j . xs - 1:
       F_j = k gap_j pen(p_j) + c gap_j w(p_j) dp_j/dt,
       pen(p) = min(max(p, 0), delta)^2 / (2 delta) + max(p - delta, 0),  w(p) = min(max(p, 0), delta) / delta,
   a C1 ramp over delta = SMOOTH of the gap, with generalized forces -F_j gap_j a_jv / L_v.
   k = m (RATIO w_s)^2 and c = 2 m RATIO w_s (critically damped against the moving mass m, the
   conductor's and a proof mass's comb fingers' (netgen.mechanics.base.body_mass), which a
   translation's stop decelerates, with a contact frequency RATIO times the model time scale).

A dielectric layer on an electrode (netgen.structure.electrodes.read_dielectric) moves the stop
to the layer's surface: the probe points' gap_j is the air gap g - t_d (Electrode.stop_gap), so a
lone coordinate stops at xs = +-1 with the plate on the layer, while the plate terms' effective
gap g - t_d + t_d / eps_r still has t_d / eps_r left there (a contact capacitance
g_eff / (t_d / eps_r) times the rest value). The clamp's FLOOR (0.02) lies below that only when
t_d / eps_r > 0.02 g_eff; a thinner or higher-eps_r layer (0.2 um of nitride under 2 um: 68 x)
has the clamp cap the contact capacitance at 1 / FLOOR = 50 x.

Limits: the stop is a rigid electrode (or layer) surface without stand-off bumps; the
clamp is a numerical safeguard, not a model of the contact capacitance (C near contact is
only as good as the fit's extrapolation, within the floor); adhesion, friction and the
plate's deformation at contact are not modelled; a plate driven by a force larger than
k * gap penetrates visibly (the penetration at rest is F / (k n) for n points in contact).
"""

from __future__ import annotations

import numpy as np

KNEE = 0.05  # gap fraction P/P(0) where the clamp starts
FLOOR = 0.02  # gap fraction the clamped term never goes below
SMOOTH = 1e-3  # penalty onset ramp, fraction of the local gap
RATIO = 10.0  # contact frequency / model time scale
DIRECTIONS = 2000  # random directions over which the late contact of combined motions is measured
SEED = 0


def clamp(p: np.ndarray, knee: np.ndarray, floor: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Clamped P and dP_eff/dP, elementwise (knee, floor broadcast against p)."""
    span = knee - floor
    pe = np.maximum(p, floor + span * np.exp(np.minimum(p - knee, 0.0) / span))
    return pe, np.minimum(1.0, (pe - floor) / span)


def penetration(p: np.ndarray, delta: float) -> tuple[np.ndarray, np.ndarray]:
    """C1 penalty ramp pen(p) and its slope w(p) (p: penetration as a fraction of the gap)."""
    r = np.minimum(np.maximum(p, 0.0), delta)
    return r * r / (2 * delta) + np.maximum(p - delta, 0.0), r / delta


def stop_points(a: np.ndarray) -> list[int]:
    """Indices of the probe points (rows of a: gap closed per unit xs) where each lone coordinate
    touches first, for either sign (at most 2 per coordinate, ties to the lowest index)."""
    a = np.round(a, 9)  # rounding-level differences must not change the choice
    ends = set(np.argmax(a, axis=0).tolist()) | set(np.argmin(a, axis=0).tolist())
    return sorted(j for j in ends if np.any(a[j] != 0.0))


def cover_miss(a: np.ndarray, chosen: list[int]) -> float:
    """Worst late contact of the chosen points over DIRECTIONS random directions of motion:
    1 - (first chosen touch) / (first touch of any probe point), as a fraction of the travel."""
    d = np.random.default_rng(SEED).normal(size=(DIRECTIONS, a.shape[1]))
    m = a @ d.T
    best = m.max(axis=0)
    touching = best > 0  # directions that reach an electrode at all (one-sided: not all do)
    if not touching.any():
        return 0.0
    # a direction that no stop point approaches counts as 1 (never stopped), not as more
    return float(np.max(1.0 - np.maximum(m[chosen][:, touching].max(axis=0), 0.0) / best[touching]))


def contact_model(
    gap: np.ndarray, phi: np.ndarray, owner: list[str], scales: np.ndarray, mass: float, ws: float
) -> dict:
    """The MacroModel's contact dict from probe points (gap, signed basis phi, electrode names)."""
    a = np.round(phi * scales[None, :] / gap[:, None], 9)  # 1e-9 of the gap: no last-bit noise in the JSON
    chosen = stop_points(a)
    points = [{"electrode": owner[j], "gap": float(gap[j]), "a": [float(v) for v in a[j]]} for j in chosen]
    return {
        "model": "clamped plate terms + penalty spring-damper at stop points (netgen.model.contact)",
        "knee": KNEE,
        "floor": FLOOR,
        "smoothing": SMOOTH,
        "stiffness": mass * (RATIO * ws) ** 2,
        "damping": 2 * mass * RATIO * ws,
        "late_contact_max": round(cover_miss(a, chosen), 6),
        "points": points,
    }
