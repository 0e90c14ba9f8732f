"""The squeeze film's laws of the process parameters (netgen.model.process): its viscosity ratio under
temp (Sutherland, the mean free path in an open or a sealed cavity, Veijola's rarefaction) and its gap
law under dg_<set> (Reynolds' 12 mu_eff / g^3 at the moved gap), derived here once so that the
emitters (netgen.emit.process) only render them."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..core.constants import GASES
from ..mechanics import Mechanics
from ..mechanics import squeeze_film as sf
from ..mechanics.damping import squeeze_film_damping
from ..structure import Structure

KELVIN = 273.15
VISCOSITY_DEGREE = 4
VEIJOLA_POWER = 1.159  # mu_eff = mu / (1 + 9.638 Kn^1.159) (netgen.mechanics.squeeze_film)
# Sutherland constants S (K): White, Viscous Fluid Flow (3rd ed.), table 1-2 (air 111, N2 107,
# Ar 144); helium 79.4 K (Sutherland-law fits of Chapman and Cowling's data)
SUTHERLAND = {"air": 111.0, "nitrogen": 107.0, "argon": 144.0, "helium": 79.4}
GAP_SIDES = {"above": 1.0, "below": -1.0}  # +z towards the electrode


def viscosity_ratio(
    gas: str, pressure: float, gap: float, t0: float, t: np.ndarray, sealed: bool = False
) -> np.ndarray:
    """mu_eff(T) / mu_eff(T0) of the rarefied gas film (T, T0 in K): Sutherland's mu(T), the mean
    free path mu sqrt(T) / p (path_ratio: p fixed, or p ~ T in a sealed cavity), Veijola's effective
    viscosity."""
    s_k = SUTHERLAND[gas]
    t = np.asarray(t, dtype=float)
    mu = (t / t0) ** 1.5 * (t0 + s_k) / (t + s_k)
    kn0 = sf.knudsen(GASES[gas], pressure, gap)
    kn = kn0 * path_ratio(s_k, t0, t, sealed)
    return mu * (1.0 + 9.638 * kn0**1.159) / (1.0 + 9.638 * kn**1.159)


def path_ratio(s_k: float, t0: float, t: np.ndarray | float, sealed: bool = False) -> np.ndarray:
    """lambda(T) / lambda(T0) of the mean free path lambda = (mu / p) sqrt(pi k T / 2 m) with
    Sutherland's mu: (T / T0)^2 (T0 + S) / (T + S) at fixed pressure; in a sealed cavity (p = p0 T /
    T0, a fixed number density) (T / T0) (T0 + S) / (T + S), the collision cross-section's growth
    (1 + S / T) that Sutherland's law stands for (a hard-sphere gas, S = 0, would keep it constant)."""
    r = np.asarray(t, dtype=float) / t0
    return (r if sealed else r * r) * (t0 + s_k) / (r * t0 + s_k)


def film_gaps(s: Structure) -> dict[str, float]:
    """side -> its squeeze film's gap: to a dielectric layer's surface, the nearest set's (netgen.mechanics.
    damping.squeeze_film_damping)."""
    sides: dict[str, float] = {}
    for e in s.electrode_sets:
        if getattr(e, "side", None) in GAP_SIDES:
            sides[e.side] = min(sides.get(e.side, np.inf), e.gap - getattr(e, "dielectric_thickness", 0.0))
    return sides


def temperature_law(s: Structure, temp_range_c: tuple[float, float], m: Mechanics | None = None) -> dict:
    """The squeeze film's viscosity ratio as a polynomial in u = (T - T0) / 100 K, exactly 1 at T0 (and
    its misfit), fitted at the smallest film gap; per other side its rarefaction and shares
    (side_laws: the exact factor pw_<side> from the fitted gap's ratio to its own); {} without a
    squeeze film. T0 = the structure's damping temperature; `m` for the sides' shares."""
    d = s.damping
    t0 = d.temperature if d else 300.0
    if not (d and d.squeeze_film):
        return {}
    sides = film_gaps(s)
    gap = min(sides.values())
    lo, hi = (v + KELVIN for v in temp_range_c)
    t = np.linspace(lo, hi, 67)
    u = (t - t0) / 100.0
    sealed = s.process is not None and s.process.cavity == "sealed"
    ratio = viscosity_ratio(d.gas, d.pressure, gap, t0, t, sealed)
    # 1 at T0 exactly (the default temp gives the model's own damping, as every law at its nominal
    # point): least squares of ratio - 1 on u .. u^4; a free constant put 1 + 8e-7 there
    powers = np.vander(u, VISCOSITY_DEGREE + 1, increasing=True)[:, 1:]
    coef = np.concatenate([[1.0], np.linalg.lstsq(powers, ratio - 1.0, rcond=None)[0]])
    fine = np.linspace(lo, hi, 661)
    at_gap = viscosity_ratio(d.gas, d.pressure, gap, t0, fine, sealed)
    misfit = float(np.max(np.abs(np.polynomial.polynomial.polyval((fine - t0) / 100.0, coef) / at_gap - 1.0)))
    # a film at a larger gap on the other side is less rarefied: its ratio differs from the fitted one by
    # up to the spread (reported); side_laws gives it its own exactly
    spread = max(
        (
            float(np.max(np.abs(viscosity_ratio(d.gas, d.pressure, g, t0, fine, sealed) / at_gap - 1.0)))
            for g in sides.values()
        ),
        default=0.0,
    )
    others = {k: g for k, g in sides.items() if g != gap}
    laws, whole = side_laws(s, m, others) if others else ([], True)
    # pv = r (1 + e1), each side's pv pw_<side> = r_side (1 + e1) (pw exact); a compressible branch
    # of both sides gets pv alone: then |e1 - e2| / (1 + e2) <= (misfit + spread) / (1 - spread)
    error = misfit if whole else (misfit + spread) / (1.0 - spread)
    cavity = "sealed cavity, p ~ T" if sealed else "fixed pressure"
    return {
        "law": f"Sutherland (S = {SUTHERLAND[d.gas]:g} K) with Veijola's rarefaction at gap {gap:.4g} m, {cavity}",
        "gas": d.gas,
        "cavity": "sealed" if sealed else "open",
        "sutherland_K": SUTHERLAND[d.gas],
        "t0_K": t0,
        "coeffs": [float(c) for c in coef],
        "variable": "(T - T0) / 100 K",
        "gap_m": gap,
        "rarefaction": rarefaction(d, gap),
        "sides": laws,
        "max_rel_error": error,
        "polynomial_misfit": misfit,
        "sides_spread": spread,
    }


def rarefaction(d, gap: float) -> float:
    """Veijola's 9.638 Kn^1.159 of the damping's gas at `gap` and T0 (mu_eff = mu / (1 + that))."""
    return 9.638 * sf.knudsen(GASES[d.gas], d.pressure, gap) ** VEIJOLA_POWER


def side_laws(s: Structure, m: Mechanics | None, others: dict[str, float]) -> tuple[list[dict], bool]:
    """Per side whose film gap is not the fitted one: its gap, rarefaction, per coordinate its share of
    the film damping and (compressible) its branches, for pw_<side> = (1 + A_s) (1 + A pl^1.159) /
    ((1 + A) (1 + A_s pl^1.159)) = its ratio mu_eff(T) / mu_eff(T0) over the fitted gap's (exact: both
    Sutherland's mu(T), Kn ~ lambda(T) / g). Also False where a compressible branch is both sides'."""
    if m is None:
        return [], False
    film = squeeze_film_damping(s, m)
    whole = all(o is not None for own in film.get("owners", []) for o in own["branch"])
    out = []
    for side, gap in sorted(others.items()):
        row = {"side": side, "gap_m": gap, "rarefaction": rarefaction(s.damping, gap), "share": side_share(film, side)}
        if "owners" in film:
            row["branches"] = [[j for j, o in enumerate(own["branch"]) if o == side] for own in film["owners"]]
        out.append(row)
    return out, whole


def side_share(film: dict, side: str) -> list[float]:
    """Per coordinate the side's part of the film damping the law scales (d_film): its Reynolds part of
    the film's, or (compressible, netgen.mechanics.damping.compressible_film) of the remainder damper."""
    if "owners" in film:
        parts = [o["remainder"].get(side, 0.0) for o in film["owners"]]
    else:
        parts = film["sides"][side]["diagonal"]
    return [float(b / t) if t > 0 else 0.0 for b, t in zip(parts, film["diagonal"])]


def film_law(s: Structure, m: Mechanics, gap_set: dict, dg_max: float = 0.0, solved: dict | None = None) -> dict:
    """{"film": ...} for a gap set whose side's squeeze film it alone faces: the film's gap g (to a
    dielectric's surface), Veijola's 9.638 Kn^1.159 there at T0 and per coordinate the side's share
    of the film damping; the emitters scale that share by mu_eff(g + dg) g^3 / (mu_eff(g) (g + dg)^3)
    (netgen.emit.process_film.film_factors). The share is exact for any tscale and etch: both sides' films
    solve one Reynolds problem on one plate, b_side = 12 mu_eff(g_side) / g_side^3 R(shapes). A
    perforated mass's holes leak ~ 1 / g^3, which is no factor: there the ratio is fitted per
    coordinate (perforated_fit). The compressible film: compressible_law. {} where no law holds: no
    film or more sets on the side (the film has one gap). `solved`: squeeze_film_damping(s, m) if done."""
    d = s.damping
    if not (d and d.squeeze_film):
        return {}
    side = set_side(gap_set)
    facing = {e.name for e in s.electrode_sets if getattr(e, "side", None) == side}
    if facing != {gap_set["set"]}:
        return {}
    film = solved or squeeze_film_damping(s, m)
    row = film["sides"][side]
    if d.film_model == "compressible":
        return {"film": compressible_law(film, side)}
    out = {"gap_m": row["gap_m"], "rarefaction": 9.638 * row["knudsen"] ** 1.159, "share": side_share(film, side)}
    if float(getattr(s.conductor, "hole", 0.0)) > 0.0 and dg_max > 0.0:
        out["fit"] = perforated_fit(s, m, side, dg_max, np.asarray(row["diagonal"]))
    return {"film": out}


def compressible_law(film: dict, side: str) -> dict:
    """The compressible film's law for the side's gap set (netgen.mechanics.damping.compressible_film,
    its branches one side's each): Veijola's 9.638 Kn^1.159 at the side's gap, per coordinate the
    indices of the side's branches and its share of the remainder damper. Exact in g: a branch's
    damper r_j = c (phi, psi_j)^2 / lambda_j and the remainder ~ c = 12 mu_eff / g^3, its gas spring
    r_j w_j = (phi, psi_j)^2 p_a / g (the Dirichlet eigenpairs of the gap region do not depend on g),
    so at g + dg the dampers are times pg = mu_eff(g + dg) g^3 / (mu_eff(g) (g + dg)^3) and the
    corners times g / ((g + dg) pg) (netgen.emit.process_film.branch_law)."""
    row, owners = film["sides"][side], film["owners"]
    share = side_share(film, side)
    branches = [[j for j, s in enumerate(o["branch"]) if s == side] for o in owners]
    return {
        "gap_m": row["gap_m"],
        "rarefaction": 9.638 * row["knudsen"] ** 1.159,
        "share": share,
        "branches": branches,
    }


FIT_SPAN = (-1.0, -0.5, 0.0, 0.5, 1.0)  # the dg points (of dg_max) the perforated film's cubic is fitted at
CHECK_SPAN = (-0.75, -0.25, 0.25, 0.75)  # and checked at, between them


def perforated_fit(s: Structure, m: Mechanics, side: str, dg_max: float, nominal: np.ndarray) -> dict:
    """The side's film damping ratio b(g + dg) / b(g) per coordinate of a perforated mass (the Reynolds
    solve with its holes' leak, netgen.mechanics.squeeze_film.perforation_leak, re-run with the side's
    electrodes moved by dg) as cubics in dg / 1 um, 1 at 0; the stated error the largest misfit at
    FIT_SPAN and CHECK_SPAN. At the nominal thickness and etch, the mean free path at T0."""

    def ratio(dg: float) -> np.ndarray:
        sets = tuple(
            dataclasses.replace(e, gap=e.gap + dg) if getattr(e, "side", None) == side else e for e in s.electrode_sets
        )
        moved = squeeze_film_damping(dataclasses.replace(s, electrode_sets=sets), m)["sides"][side]
        return np.asarray(moved["diagonal"]) / np.where(nominal > 0, nominal, 1.0)

    u = np.array([f * dg_max * 1e6 for f in FIT_SPAN])
    values = np.array([ratio(f * dg_max) if f else np.ones_like(nominal) for f in FIT_SPAN])
    powers = np.vander(u, 4, increasing=True)[:, 1:]
    coef = np.linalg.lstsq(powers, values - 1.0, rcond=None)[0]
    coeffs = np.vstack([np.ones((1, len(nominal))), coef]).T  # per coordinate c0 = 1, c1..c3
    err = 0.0
    for f in FIT_SPAN + CHECK_SPAN:
        x = f * dg_max * 1e6
        law = coeffs @ np.array([1.0, x, x * x, x**3])
        err = max(err, float(np.max(np.abs(law / ratio(f * dg_max) - 1.0)))) if f else err
    return {"variable": "dg / 1 um", "coeffs": [[float(c) for c in row] for row in coeffs], "max_rel_error": err}


def kelvin(temp_c: float) -> float:
    """degC -> K."""
    return temp_c + KELVIN


def film_ratio(law: dict, v: int, temp_c: float, dg: dict[str, float]) -> float:
    """The factor on coordinate v's squeeze-film damping from the gap sets' offsets `dg` (set -> m) and
    the sides' own viscosity laws: 1 + sum over sides of share (pw pg - 1), pg = mu_eff(g + dg) g^3 /
    (mu_eff(g) (g + dg)^3) with the mean free path at temp, a perforated film's cubic times
    rarefaction_shift in its place (film_law), pw the side's ratio to the fitted gap's (side_factors;
    netgen.emit.process_film.film_share renders the same)."""
    out = 1.0
    factors = gap_factors(law, temp_c, dg)
    pw = side_factors(law, temp_c)
    for g in law["gaps"]:
        f = g.get("film")
        w = pw.get(set_side(g), (1.0, 0.0))[0]
        if f and "fit" in f:  # a perforated mass's fitted ratio (perforated_fit) at T0, times its shift at temp
            x = dg.get(g["set"], 0.0) * 1e6
            cubic = float(np.dot(f["fit"]["coeffs"][v], [1.0, x, x * x, x**3]))
            out += f["share"][v] * (w * cubic * rarefaction_shift(f, *factors[g["set"]]) - 1.0)
        elif f:
            out += f["share"][v] * (w * factors[g["set"]][1] - 1.0)
    moved = {set_side(g) for g in law["gaps"] if g.get("film")}
    for side, (w, row) in pw.items():
        out += row["share"][v] * (w - 1.0) if side not in moved else 0.0
    return out


def set_side(gap_set: dict) -> str:
    """The side ("above", "below") a gap set's electrodes face."""
    return next(k for k, v in GAP_SIDES.items() if v == gap_set["sign"])


def side_factors(law: dict, temp_c: float) -> dict[str, tuple[float, dict]]:
    """side -> (pw, its record) of each side with its own viscosity law (temperature_law's sides) where
    temp is declared: pw = (1 + A_s) (1 + A pl^1.159) / ((1 + A) (1 + A_s pl^1.159)), A the fitted gap's
    rarefaction, A_s the side's, pl the mean free path's ratio at temp."""
    visc = law["temp"].get("viscosity") or {}
    if not (visc.get("sides") and "temp" in law["parameters"]):
        return {}
    pl = float(path_ratio(visc["sutherland_K"], visc["t0_K"], kelvin(temp_c), visc["cavity"] == "sealed"))
    a, e = visc["rarefaction"], VEIJOLA_POWER
    return {
        r["side"]: ((1.0 + r["rarefaction"]) * (1.0 + a * pl**e) / ((1.0 + a) * (1.0 + r["rarefaction"] * pl**e)), r)
        for r in visc["sides"]
    }


def rarefaction_shift(film: dict, rg: float, pg: float) -> float:
    """pg over its value at T0 (the mean free path's ratio pl = 1): mu_eff(g + dg, T) mu_eff(g, T0) /
    (mu_eff(g, T) mu_eff(g + dg, T0)), what a perforated film's cubic in dg (fitted at T0) and the
    viscosity ratio pv (at the drawn gap) leave out. Exact for the Reynolds film with holes: their leak
    12 h^4 / (28.45 g^3 t p^2) is a ratio of two conductances with one viscosity (netgen.mechanics.
    squeeze_film.perforation_leak), so b(g, T) = 12 mu_eff(g, T) / g^3 R(g), R free of T."""
    a = film["rarefaction"]
    return pg * (1.0 + a * rg**VEIJOLA_POWER) / (rg**3 * (1.0 + a))


def gap_factors(law: dict, temp_c: float, dg: dict[str, float]) -> dict[str, tuple[float, float]]:
    """set -> (rg, pg) of each gap set with a film law: rg = g / (g + dg), pg = rg^3 (1 + A pl^1.159) /
    (1 + A (pl rg)^1.159) with the mean free path's ratio pl at temp (film_law)."""
    visc = law["temp"].get("viscosity") or {}
    pl = 1.0
    if visc and "temp" in law["parameters"]:
        pl = float(path_ratio(visc["sutherland_K"], visc["t0_K"], kelvin(temp_c), visc["cavity"] == "sealed"))
    out = {}
    for g in law["gaps"]:
        if f := g.get("film"):
            r, a = f["gap_m"] / (f["gap_m"] + dg.get(g["set"], 0.0)), f["rarefaction"]
            out[g["set"]] = (r, r**3 * (1.0 + a * pl**1.159) / (1.0 + a * (pl * r) ** 1.159))
    return out


def branches_at(
    law: dict, v: int, film: tuple, pv: float, temp_c: float, dg: dict[str, float]
) -> tuple[tuple[float, float], ...]:
    """Coordinate v's compressible-film branches (r_j, w_j) at the process point: r_j times pv (the
    viscosity ratio, under temp), its side's pw (side_factors) and its moved side's pg, w_j times rg over that (compressible_law; the
    emitters' netgen.emit.process_film.branch_law)."""
    factors = gap_factors(law, temp_c, dg)
    owner = {j: g["set"] for g in law["gaps"] if g.get("film") for j in g["film"].get("branches", [[]] * (v + 1))[v]}
    pw = {j: w for w, row in side_factors(law, temp_c).values() for j in (row.get("branches") or [[]] * (v + 1))[v]}
    out = []
    for j, (r, w) in enumerate(film):
        rg, pg = factors.get(owner.get(j, ""), (1.0, 1.0))
        d = pv * pg * pw.get(j, 1.0)
        out.append((r * d, w * rg / d))
    return tuple(out)
