"""The process laws evaluated at a point (tscale, escale, temp, etch, dg): a coordinate's mass,
stiffness and damping, its compressible-film branches, the strain energy's factor and the
capacitances, the same arithmetic the emitters render (netgen.model.process builds the laws)."""

from __future__ import annotations

from typing import Any

import numpy as np

from .etch_knots import ETCH_UNIT, knot_value
from .etch_state import TSCALE, cross_factor, state_factor
from .process_film import branches_at, film_ratio

LAW_KEYS = ("mass", "a", "b", "d_rest", "d_film")


def law_value(c: dict, key: str, tscale: float, etch: float, knots: tuple[float, ...] = ()) -> float:
    """Law part `key` of one coordinate's law at (tscale, etch): the tscale cubic times the etch ratio
    (with the etch record's `knots`, netgen.model.etch_knots)."""
    t = float(np.dot(c[key], [1.0, tscale, tscale**2, tscale**3]))
    if "etch" not in c:
        return t
    u = etch / ETCH_UNIT
    return t * (knot_value(c["etch"][key], u, knots) if knots else float(np.dot(c["etch"][key], [1.0, u, u**2, u**3])))


def ratio_value(coeffs: list[float], etch: float, knots: tuple[float, ...] = ()) -> float:
    """An etch ratio (cubic in etch / ETCH_UNIT, with the truncated powers of the etch record's `knots`
    where it has them: netgen.model.etch_knots) at `etch` (m)."""
    u = etch / ETCH_UNIT
    if len(coeffs) > 4:
        return knot_value(coeffs, u, knots)
    return float(np.dot(coeffs, [1.0, u, u**2, u**3]))


def capacitance_at(model: Any, x: np.ndarray, etch: float = 0.0, tscale: float = 1.0) -> np.ndarray:
    """A MacroModel's capacitances (npoints, nelectrodes) at scaled coordinates x, the etch bias and
    tscale: each electrode's fit at x + its shift etch / L_q, times its etch ratio (capacitance_laws)
    and a comb's state factor (netgen.model.etch_state) and, under both, its cross factor
    and its tscale ratio and state factor (thickness_capacitance; the arithmetic the emitters render)."""
    x = np.atleast_2d(x)
    laws = {r["electrode"]: r for r in (model.process.get("etch") or {}).get("capacitance", [])}
    names = [c.name for c in model.coordinates]
    out = model.capacitance(x)
    thick = {r["electrode"]: r for r in (model.process.get("tscale") or {}).get("capacitance_laws", [])}
    for k, f in enumerate(model.capacitances):
        law = laws.get(f.electrode)
        if law is None:
            continue
        moved = x.copy()
        for q, shift in law.get("shift", {}).items():
            v = names.index(q)
            moved[:, v] += shift * etch / model.coordinates[v].scale
        knots = tuple(model.process["etch"].get("knots", []))
        out[:, k] = ratio_value(law["ratio"], etch, knots) * model.capacitance(moved)[:, k]
        if "state" in law:  # the state-dependent factor 1 + u P1(x) + u^2 P2(x) (netgen.model.etch_state)
            out[:, k] *= state_factor(law["state"], x, etch)
        if "cross" in law:  # with tscale too: 1 + (tscale - 1) (u Q1(x) + u^2 Q2(x)) (netgen.model.etch_state)
            out[:, k] *= cross_factor(law["cross"], x, tscale, etch)
    for k, f in enumerate(model.capacitances):
        if f.electrode in thick:
            out[:, k] *= float(np.dot(thick[f.electrode]["ratio"], [1.0, tscale, tscale**2, tscale**3]))
            if "state" in thick[f.electrode]:  # a comb's state factor, u = tscale - 1
                out[:, k] *= state_factor(thick[f.electrode]["state"], x, tscale, TSCALE)
    return out


def modulus_factor(law: dict, escale: float, temp_c: float) -> float:
    """e = escale (1 + tc (T - T0)): the factor on the modulus part of the stiffness."""
    return escale * (1.0 + law["modulus_tc_per_K"] * (temp_c - law["temperature_C"]))


def energy_factor(
    law: dict, tscale: float = 1.0, escale: float = 1.0, temp_c: float | None = None, etch: float = 0.0
) -> float:
    """pu, the fitted strain energy's factor at the process point (energy_law: (e A(tscale) + B(tscale))
    R(etch), the arithmetic the emitters render); 1 without a strain-energy law."""
    u = law.get("strain_energy") or {}
    if not u:
        return 1.0
    temp_c = law["temperature_C"] if temp_c is None else temp_c
    powers = [1.0, tscale, tscale**2, tscale**3]
    pu = modulus_factor(law, escale, temp_c) * float(np.dot(u["a"], powers)) + float(np.dot(u["b"], powers))
    return pu * (ratio_value(u["etch"], etch) if "etch" in u and "etch" in law["parameters"] else 1.0)


def coordinate_values(
    law: dict,
    v: int,
    tscale: float = 1.0,
    escale: float = 1.0,
    temp_c: float | None = None,
    etch: float = 0.0,
    dg: dict[str, float] | None = None,
):
    """(mass, stiffness, damping) of coordinate v at the process point (`dg`: set -> gap offset, m),
    from the laws (the same arithmetic the emitters render)."""
    temp_c = law["temperature_C"] if temp_c is None else temp_c
    c = law["coordinates"][v]
    knots = tuple((law.get("etch") or {}).get("knots", ()))
    mass, a, b, d_rest, d_film = (law_value(c, k, tscale, etch, knots) for k in LAW_KEYS)
    visc = law["temp"]["viscosity"]
    ratio = (
        float(np.polynomial.polynomial.polyval((temp_c - law["temperature_C"]) / 100.0, visc["coeffs"]))
        if visc
        else 1.0
    )
    damp = d_rest + ratio * d_film * film_ratio(law, v, temp_c, dg or {})
    return mass, modulus_factor(law, escale, temp_c) * a + b, damp


def film_at(law: dict, v: int, film: tuple, temp_c: float | None = None, dg: dict[str, float] | None = None) -> tuple:
    """Coordinate v's compressible-film branches (Coordinate.film) at the process point: dampers times
    the viscosity ratio and a moved side's pg, corners times rg over that (process_film.branches_at)."""
    temp_c = law["temperature_C"] if temp_c is None else temp_c
    visc = law["temp"]["viscosity"]
    pv = (
        float(np.polynomial.polynomial.polyval((temp_c - law["temperature_C"]) / 100.0, visc["coeffs"]))
        if visc
        else 1.0
    )
    return branches_at(law, v, film, pv, temp_c, dg or {})
