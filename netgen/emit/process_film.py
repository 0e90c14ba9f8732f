"""The squeeze film's process laws as netlist text (netgen.model.process_film): the gap sets' factors
pg_<set> / pq_<set>, the sides' own viscosity laws pw_<side>, a coordinate's film factor, the
compressible branches' factors and the header's statements; split from netgen.emit.process, which
re-exports what the emitters ask it for. No physics here: every number comes from the model."""

from __future__ import annotations

from ..model import MacroModel
from ..model.process_film import set_side
from .common import num
from .process_base import declared, enabled, poly

KELVIN = 273.15


def film_sets(model: MacroModel) -> list[dict]:
    """The gap sets whose side's squeeze film follows their dg (netgen.model.process_film.film_law)."""
    return [g for g in model.process.get("gaps", []) if g.get("film")] if enabled(model) else []


VEIJOLA_POWER = 1.159  # mu_eff = mu / (1 + 9.638 Kn^1.159) (netgen.mechanics.squeeze_film)


def film_factors(model: MacroModel, temp: str) -> list[tuple[str, str]]:
    """(name, expression) of each film gap set's damping ratio pg_<set> = r^3 (1 + A pl^1.159) / (1 + A
    (pl r)^1.159), r = g / (g + dg_<set>), A = 9.638 Kn^1.159 at T0 (Reynolds' 12 mu_eff / g^3 with
    Veijola's rarefaction at the moved gap; exact), and pl = lambda(T) / lambda(T0) (netgen.model.
    process_film.path_ratio, rational in T) where temp is declared; a perforated film's (its cubic:
    film_pg) pq_<set> = pg_<set> at pl over pg_<set> at 1 there (netgen.model.process_film.
    rarefaction_shift); each side's own viscosity law pw_<side> (side_factors). [] without either."""
    visc = model.process["temp"].get("viscosity") or {}
    pl = "pl*" if declared(model, "temp") and visc else ""
    sets = [g for g in film_sets(model) if pl or "fit" not in g["film"]]
    sides = pw_sides(model)
    if not (sets or sides):
        return []
    out = []
    if pl:
        r, t0, s_k = f"(({temp} + {num(KELVIN)})/{num(visc['t0_K'])})", visc["t0_K"], visc["sutherland_K"]
        sq = r if visc["cavity"] == "sealed" else f"{r}*{r}"  # lambda ~ T / (T + S) sealed, T^2 / (T + S) open
        out.append(("pl", f"{sq}*{num(t0 + s_k)}/({temp} + {num(KELVIN + s_k)})"))
    out += side_factors(model)
    for g in sets:
        f, rg = g["film"], f"rg_{g['set']}"
        a = num(f["rarefaction"])
        out.append((rg, f"{num(f['gap_m'])}/({num(f['gap_m'])} + dg_{g['set']})"))
        top = f"(1 + {a}*pow(pl, {VEIJOLA_POWER}))" if pl else num(1.0 + f["rarefaction"])
        if "fit" in f:  # rg^3 cancels: (1 + A pl^e) (1 + A r^e) / ((1 + A) (1 + A (pl r)^e))
            shift = f"{top}*(1 + {a}*pow({rg}, {VEIJOLA_POWER}))/({num(1.0 + f['rarefaction'])}*(1 + {a}*pow(pl*{rg}, {VEIJOLA_POWER})))"
            out.append((f"pq_{g['set']}", shift))
            continue
        out.append((f"pg_{g['set']}", f"{rg}*{rg}*{rg}*{top}/(1 + {a}*pow({pl}{rg}, {VEIJOLA_POWER}))"))
    return out


def pw_sides(model: MacroModel) -> list[dict]:
    """The sides with their own viscosity law (netgen.model.process_film.side_laws: a film gap other
    than the fitted one) where temp is declared; [] otherwise."""
    visc = model.process["temp"].get("viscosity") or {} if enabled(model) else {}
    return list(visc.get("sides") or []) if declared(model, "temp") else []


def side_factors(model: MacroModel) -> list[tuple[str, str]]:
    """(name, expression) of pw_<side> = (1 + A_s) (1 + A pl^1.159) / ((1 + A) (1 + A_s pl^1.159)): the
    side's film viscosity ratio over the fitted gap's, exact (netgen.model.process_film.side_factors)."""
    visc, e = model.process["temp"].get("viscosity") or {}, VEIJOLA_POWER
    a = visc.get("rarefaction", 0.0)
    return [
        (
            f"pw_{r['side']}",
            f"{num(1.0 + r['rarefaction'])}*(1 + {num(a)}*pow(pl, {e}))/"
            f"({num(1.0 + a)}*(1 + {num(r['rarefaction'])}*pow(pl, {e})))",
        )
        for r in pw_sides(model)
    ]


def film_share(model: MacroModel, v: int) -> str:
    """The text multiplying coordinate v's squeeze-film damping for the gap sets' films and the sides'
    own viscosity laws: 1 + sum of share (pw_<side> pg_<set> - 1) (the factor alone for a share of 1);
    "" where nothing moves it."""
    pws = {r["side"]: r for r in pw_sides(model)}
    terms, moved = [], set()
    for g in film_sets(model):
        side = set_side(g)
        moved.add(side)
        if g["film"]["share"][v] > 0:
            terms.append(("*".join([f"pw_{side}"] * (side in pws) + [film_pg(model, g, v)]), g["film"]["share"][v]))
    terms += [(f"pw_{k}", r["share"][v]) for k, r in pws.items() if k not in moved and r["share"][v] > 0]
    if not terms:
        return ""
    if len(terms) == 1 and terms[0][1] == 1.0:
        return f"*{terms[0][0]}"
    return "*(1 + " + " + ".join(f"{num(w)}*({pg} - 1)" for pg, w in terms) + ")"


def film_pg(model: MacroModel, g: dict, v: int) -> str:
    """Gap set g's film ratio for coordinate v: pg_<set>, or a perforated film's cubic in 1e6 dg_<set>
    (times pq_<set> under temp, film_factors)."""
    fit = g["film"].get("fit")
    if not fit:
        return f"pg_{g['set']}"
    shift = f"*pq_{g['set']}" if declared(model, "temp") and (model.process["temp"].get("viscosity") or {}) else ""
    return poly(fit["coeffs"][v], f"(1e6*dg_{g['set']})") + shift


def sides_text(visc: dict) -> str:
    """The header's note on a film at another gap (netgen.model.process_film.temperature_law): its own
    law pw_<side>, or the spread a branch of both sides leaves in the error; "" with one gap."""
    own = ", ".join(f"pw_{r['side']} at {r['gap_m']:.4g} m" for r in visc.get("sides") or [])
    if own and visc["max_rel_error"] == visc["polynomial_misfit"]:
        return f" (fitted at gap {visc['gap_m']:.4g} m; the other side's film times its own exact ratio {own})"
    if visc.get("sides_spread"):
        return f" (fitted at the smaller gap; the other side's film differs by up to {visc['sides_spread']:.1e})"
    return ""


def joint_error(model: MacroModel, g: dict) -> float | None:
    """A perforated film's law under dg and temp (its cubic, pv, pq_<set>: film_factors) against the re-run:
    within e_v + e_c + e_v e_c, the viscosity polynomial's and the cubic's stated errors; None without
    temp or a cubic."""
    fit, visc = (g.get("film") or {}).get("fit"), model.process["temp"].get("viscosity") or {}
    if not (fit and visc and declared(model, "temp")):
        return None
    e_v, e_c = visc["max_rel_error"], fit["max_rel_error"]
    return e_v + e_c + e_v * e_c


def film_text(g: dict, joint: float | None = None) -> str:
    """The header's statement of what a gap offset does to the damping (netgen.model.process_film.film_law);
    `joint`: a perforated film's error under dg and temp (joint_error)."""
    if not (f := g.get("film")):
        return "damping unchanged (no squeeze film of this set's own: given damping, or a side several sets share)"
    if "branches" in f:  # the compressible film (netgen.model.process_film.compressible_law)
        return (
            f"its side's compressible-film branches: dampers and the remainder damper's share times pg_{g['set']} "
            f"= mu_eff(g + dg) g^3 / (mu_eff(g) (g + dg)^3), gas springs times rg_{g['set']} = g / (g + dg) "
            f"(corners times rg / pg), g = {f['gap_m']:.4g} m, Veijola's 9.638 Kn^1.159 = {f['rarefaction']:.4g} "
            "at T0 (exact)"
        )
    if f.get("fit"):
        return (
            "its side's squeeze-film damping (a perforated mass's, with its holes' leak) times a cubic in dg "
            f"per coordinate from the film re-run at the moved gap, within {f['fit']['max_rel_error']:.1e} "
            "(at the nominal thickness and etch, the mean free path at T0)"
            + (
                f"; under temp also times pq_{g['set']} = mu_eff(g + dg, T) mu_eff(g, T0) / (mu_eff(g, T) "
                f"mu_eff(g + dg, T0)), Veijola's 9.638 Kn^1.159 = {f['rarefaction']:.4g} at g = {f['gap_m']:.4g} m "
                f"and T0 (exact: the holes' leak does not depend on T); with pv within {joint:.1e}"
                if joint is not None
                else ""
            )
        )
    return (
        f"its side's squeeze-film damping times pg_{g['set']} = mu_eff(g + dg) g^3 / (mu_eff(g) (g + dg)^3), "
        f"g = {f['gap_m']:.4g} m, Veijola's 9.638 Kn^1.159 = {f['rarefaction']:.4g} at T0 (exact)"
    )


def branch_law(model: MacroModel, v: int, j: int) -> tuple[str, str] | None:
    """(damper factor, moved-gap set) of coordinate v's compressible-film branch j: the damper r_j times
    pv under temp (and its side's pw_<side>, film_factors) and pg_<set> where its side's set has a gap offset (netgen.model.process_film.
    compressible_law), its corner times rg_<set> over that factor (the gas spring ~ p_a / g); None
    where nothing moves it. The set is "" without one."""
    moved = [g["set"] for g in film_sets(model) if j in g["film"].get("branches", [[]] * (v + 1))[v]]
    own = [f"pw_{r['side']}" for r in pw_sides(model) if j in (r.get("branches") or [[]] * (v + 1))[v]]
    factor = (["pv"] if film_scaled(model) else []) + own + [f"pg_{n}" for n in moved]
    return ("*".join(factor), moved[0] if moved else "") if factor else None


def film_scaled(model: MacroModel) -> bool:
    """The compressible film's branches follow the viscosity ratio pv (temp declared; damper r_j times
    pv, corner over pv: netgen.model.process, r_j ~ mu_eff, the gas spring ~ the pressure)."""
    return declared(model, "temp") and bool(model.process["temp"].get("viscosity"))
