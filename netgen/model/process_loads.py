"""The process laws of the inertial loads: under tscale (inertial_law: each entry's mid-plane rho t and
rotary rho t^3 / 12 parts) and under etch (netgen.model.process, the etch parameter): the a_in load G_v and
the inertial terms P, G, S, c (netgen.mechanics.inertial) are integrals of rho over the moving body,
as the mass is, so under an etch bias they follow the etched body (outline - 2 etch, holes + 2 etch,
comb fingers w - 2 etch), not the drawn one. Each is re-evaluated on the etched structure
(netgen.model.process.etched, its mechanics re-run there) at the etch points and fitted as a ratio
(a cubic in etch / 1 um, 1 at 0), as the mass law is:

- a_in: G(t, etch) = G t R(etch). G = int rho t phi dA is linear in the thickness t; R(etch) =
  G(etch) / G (for a rigid z translation G is the body's mass and R the mass's own ratio: the etched
  area (L - 2e)(W - 2e) - N (h + 2e)^2 is quadratic in e, the cubic exact).
- the inertial entries: X(t, etch) = X ((1 - f) t R1(etch) + f t^3 R3(etch)), the mid-plane (rho t)
  and the rotary (rho t^3 / 12) parts of the entry (inertial_law) each with its
  own ratio: the two are integrals of different moments of the etched body (its first and second
  area moments against its area), so one ratio could not carry both. A second area moment of an
  etched rectangle is quartic in the etch; the cubic's residual at the etch points is the stated
  error (about (etch / side)^4: round-off on a device).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..mechanics import Mechanics, participation
from ..mechanics import inertial as inertial_terms
from ..structure import Structure
from .process import ETCH_UNIT, ROUND_OFF, etch_points, etched, power_fit, ratio_value, scaled

INERTIAL_KINDS = ("participation", "gyroscopic", "centrifugal", "centrifugal_force")
PROBE_T = 2.0  # the thickness factor of the second evaluation separating the t and t^3 parts


def inertial_law(s: Structure, data: dict, terms) -> dict:
    """The tscale law of the inertial terms (MacroModel.inertial, netgen.mechanics.inertial): every
    entry is an integral over the plate of rho (A A + z^2 B B) (fields affine in z through the
    thickness, independent of it), so X(t) = X (1 - f) t + X f t^3 exactly, f the rotary
    (through-thickness, rho t^3 / 12) share; f per entry from `terms(structure)` -> inertial data at
    the nominal fields and the thickness PROBE_T times the nominal: X(2) = X (2 - 2 f + 8 f).
    escale leaves them (no modulus); etch moves each part by its own ratio (netgen.model.process_loads,
    stored under "etch" by the build). {} without tscale and etch."""
    wanted = s.process is not None and (s.process.wants("tscale") or s.process.wants("etch"))
    if not wanted or not any(data.get(k) for k in INERTIAL_KINDS):
        return {}
    probe = terms(scaled(s, PROBE_T))
    fractions = {k: {n: rotary_share(v, probe[k][n]) for n, v in data[k].items()} for k in INERTIAL_KINDS}
    return {
        "law": "X(tscale) = X ((1 - f) tscale + f tscale^3), f the entry's rotary share (exact)",
        "t3_fraction": fractions,
    }


def rotary_share(nominal, probe) -> list:
    """f = (X(2) - 2 X) / (6 X) per entry (0 where X = 0), snapped to 0 or 1 within ROUND_OFF."""
    x, x2 = np.asarray(nominal, dtype=float), np.asarray(probe, dtype=float)
    f = np.divide(x2 - PROBE_T * x, (PROBE_T**3 - PROBE_T) * x, out=np.zeros_like(x), where=x != 0.0)
    f[np.abs(f) < ROUND_OFF] = 0.0
    f[np.abs(f - 1.0) < ROUND_OFF] = 1.0
    return f.tolist()


IDENTITY = [1.0, 0.0, 0.0, 0.0]


def etched_runs(s: Structure, m: Mechanics, run) -> list[tuple[float, Structure, Mechanics]]:
    """(etch, etched structure, its mechanics) at the etch points (the nominal m reused at 0)."""
    out = []
    assert s.process is not None  # only a structure declaring etch has etch laws
    for e in etch_points(s.process):
        se = etched(s, e)
        out.append((e, se, m if e == 0.0 else run(se)))
    return out


def ratios(
    points: tuple[float, ...], values: np.ndarray, nominal: np.ndarray, scale: np.ndarray
) -> tuple[list[list[float]], float]:
    """Per column of `values` (points x entries) its ratio to `nominal` as a cubic in etch / 1 um (1 at
    0; IDENTITY where the nominal is 0) and the largest residual relative to `scale` (the entry the
    value is, or is a part of, at each point)."""
    u = tuple(e / ETCH_UNIT for e in points)
    coef, err = power_fit(u, values, scale, nominal=0.0)
    out = [[float(c / n) for c in row] if n != 0.0 else list(IDENTITY) for row, n in zip(coef, nominal)]
    return out, err


def acceleration_law(s: Structure, m: Mechanics, run, runs=None) -> dict:
    """The a_in load's etch law: per coordinate the ratio R_v(etch) = G_v(etch) / G_v (a cubic in
    etch / 1 um) of netgen.mechanics.participation on the etched body, and the cubic's residual."""
    runs = runs or etched_runs(s, m, run)
    points = tuple(e for e, _, _ in runs)
    values = np.array([participation(se, me) for _, se, me in runs])
    nominal = values[points.index(0.0)]
    law, err = ratios(points, values, nominal, np.abs(values))
    return {"ratio": law, "max_rel_error": err}


def flatten(data: dict) -> np.ndarray:
    """The inertial entries of every kind and key (INERTIAL_KINDS, the keys' order) as one vector."""
    return np.concatenate([np.ravel(np.asarray(v, dtype=float)) for k in INERTIAL_KINDS for v in data[k].values()])


def unflatten(flat: list, like: dict) -> dict:
    """`flat` (one item per entry, flatten's order) in the nesting of `like` ({kind: {key: array}})."""
    out: dict[str, Any] = {}
    i = 0
    for k in INERTIAL_KINDS:
        out[k] = {}
        for key, v in like[k].items():
            shape = np.shape(v)
            n = int(np.prod(shape))
            items = flat[i : i + n]
            out[k][key] = (
                items if len(shape) == 1 else [items[r * shape[1] : (r + 1) * shape[1]] for r in range(shape[0])]
            )
            i += n
    return out


def inertial_etch_law(s: Structure, m: Mechanics, run, inputs: tuple[str, ...], runs=None) -> dict:
    """The inertial entries' etch laws: per entry the ratios R1 (its rho t part) and R3 (its rho t^3 / 12
    part) as cubics in etch / 1 um, from netgen.mechanics.inertial.terms on the etched body at
    thickness 1 and PROBE_T (X(2) = 2 X1 + 8 X3 separates the parts), nested as the model's inertial
    data ("t", "t3"); the entry's own ratio R = X(etch) / X ("total": the law at thickness 1, used
    where tscale is not declared, e.g. with combs); and the largest residual relative to the entry."""
    runs = runs or etched_runs(s, m, run)
    points = tuple(e for e, _, _ in runs)
    like, part1, part3 = None, [], []
    for _, se, me in runs:
        x1 = inertial_terms.terms(se, me, inputs)
        x2 = inertial_terms.terms(scaled(se, PROBE_T), me, inputs)
        like = like or x1
        f1, f2 = flatten(x1), flatten(x2)
        x3 = (f2 - PROBE_T * f1) / (PROBE_T**3 - PROBE_T)
        part1.append(f1 - x3)
        part3.append(x3)
    p1, p3 = np.array(part1), np.array(part3)
    one = points.index(0.0)
    total = np.abs(p1 + p3)
    n1 = np.where(np.abs(p1[one]) > 1e-9 * total[one], p1[one], 0.0)
    n3 = np.where(np.abs(p3[one]) > 1e-9 * total[one], p3[one], 0.0)
    r1, e1 = ratios(points, p1, n1, total)
    r3, e3 = ratios(points, p3, n3, total)
    r, e = ratios(points, p1 + p3, p1[one] + p3[one], total)
    assert like is not None
    return {
        "t": unflatten(r1, like),
        "t3": unflatten(r3, like),
        "total": unflatten(r, like),
        "max_rel_error": max(e1, e3, e),
    }


def acceleration_at(model: Any, tscale: float, etch: float) -> list[float]:
    """The a_in participation at a process point, as the emitters render it: G_v tscale R_v(etch)."""
    law = ((model.process.get("etch") or {}).get("acceleration") or {}).get("ratio")
    if not law or not etch:
        return [g * tscale for g in model.acceleration]
    return [g * tscale * ratio_value(r, etch) for g, r in zip(model.acceleration, law)]
