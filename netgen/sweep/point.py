"""A sweep's process point (process.tscale, escale, temp, etch, dg_<set>) both ways: on the shared
[process] build as instance parameters (at_point: the model's numbers at the point, for the loop's
design and analysis, while the netlists take the point on the model's instance line), and as the
reference, a rebuild of the structure file at the point without [process] (rebuilt). The laws are
netgen.model.process's; nothing here derives physics, it only evaluates them or edits the file."""

from __future__ import annotations

import dataclasses
import math
import re
from collections import defaultdict
from math import comb
from typing import Any

import numpy as np

from ..core.errors import SweepError
from ..fit.capacitance import CapacitanceFit
from ..fit.polynomial import Polynomial
from ..model import MacroModel
from ..model.etch_state import ETCH, TSCALE, Axis, cross_weights, state_polynomial, weighted_polynomial
from ..model.process import GAP_SIDES, KELVIN, coordinate_values, energy_factor, etched, film_at, ratio_value, scaled
from ..model.process_loads import acceleration_at
from ..structure import Structure, parse_structure
from ..structure.process_table import BEAM_KINDS, PLATE_KINDS
from ..structure.schema import Process
from .tomltext import to_toml

# the process parameters a sweep moves (process.<name>), each with its unit: dg_<set> per plate set
RATIOS = ("tscale", "escale")
NAMES = (*RATIOS, "temp", "etch")
GAP = re.compile(r"dg_([A-Za-z_][A-Za-z0-9_]*)")
UNITS = {"tscale": "ratio", "escale": "ratio", "temp": "degC", "etch": "m"}


def known(name: str) -> bool:
    """`name` (after process.) is a parameter a sweep moves: NAMES or dg_<set>."""
    return name in NAMES or GAP.fullmatch(name) is not None


def unit(name: str) -> str:
    """The unit of a process parameter's values: ratio, degC or m (dg_<set>: m)."""
    return UNITS.get(name, "m")


def gap_set(name: str) -> str | None:
    """The electrode set of dg_<set>, else None."""
    m = GAP.fullmatch(name)
    return m.group(1) if m else None


# ----------------------------------------------------------------------------- instance parameters


def at_point(model: MacroModel, point: dict[str, float]) -> MacroModel:
    """A MacroModel's copy at a process point, for the loop design and analysis of a run whose netlist
    takes the point as instance parameters: each coordinate's mass, stiffness and damping from the
    laws (netgen.model.process.coordinate_values, the arithmetic the emitters render, the squeeze film
    at the gap sets' offsets too) and its frequency from them; a compressible film's branches
    likewise (netgen.model.process.film_at); the a_in participation times tscale and its etch ratio
    (as the emitters scale the port: netgen.model.process_loads.acceleration_at); the fitted strain
    energy times its law pu (netgen.model.process.energy_factor, as the emitters scale its forces);
    the thermal noise at the point's temperature; each gap set's capacitance terms reading xs_z - sign dg / L_z (shifted: the
    polynomials re-expanded, exact); a comb's state factor as its fit's factor (etched_fits, thickness_fits);
    the plate terms' clamps at the nominal model's rest terms, as the forms clamp (MacroModel.term_rest)."""
    law = model.process
    tscale, escale = point.get("tscale", 1.0), point.get("escale", 1.0)
    temp, etch = point.get("temp"), point.get("etch", 0.0)
    dg = {s: x for n, x in point.items() if (s := gap_set(n))}  # the squeeze film follows its gap too
    coords = []
    for v, c in enumerate(model.coordinates):
        mass, stiffness, damping = coordinate_values(law, v, tscale, escale, temp, etch, dg)
        freq = math.sqrt(stiffness / mass) / (2 * math.pi) if stiffness > 0 else 0.0
        film = film_at(law, v, c.film, temp, dg)
        coords.append(
            dataclasses.replace(c, mass=mass, stiffness=stiffness, damping=damping, frequency_hz=freq, film=film)
        )
    keep = {"term_rest": model.term_rest()} if model.contact else {}  # the forms clamp at the nominal P(0)
    out = dataclasses.replace(
        model,
        coordinates=coords,
        acceleration=acceleration_at(model, tscale, etch),
        capacitances=shifted_fits(model, point),
        contact=model.contact | keep,
    )
    if model.nonlinear and law.get("strain_energy"):
        pu = energy_factor(law, tscale, escale, temp, etch)
        energy = model.nonlinear["energy_J"]
        out.nonlinear = {**model.nonlinear, "energy_J": {**energy, "coeffs": [pu * c for c in energy["coeffs"]]}}
    if temp is not None and "damping" in model.report:
        out.report = {**model.report, "damping": {**model.report["damping"], "temperature_K": temp + KELVIN}}
    return out


def shifted_fits(model: MacroModel, point: dict[str, float]) -> list:
    """The capacitance fits with each gap set's z moved by -sign dg / L_z (the model's gap sets,
    netgen.model.process.gap_sets); the others as they are."""
    names = [c.name for c in model.coordinates]
    fits = list(model.capacitances)
    for g in model.process.get("gaps", []):
        dg = point.get(f"dg_{g['set']}", 0.0)
        if not dg:
            continue
        z = names.index("z")
        delta = -g["sign"] * dg / model.coordinates[z].scale
        for i, f in enumerate(fits):
            if f.electrode in g["electrodes"]:
                polys = tuple(shift(p, z, delta) for p in f.polys)
                fits[i] = dataclasses.replace(f, polys=polys)
    etch, tscale = point.get("etch", 0.0), point.get("tscale", 1.0)
    return cross_fits(model, thickness_fits(model, etched_fits(model, fits, etch), tscale), tscale, etch)


def cross_fits(model: MacroModel, fits: list, tscale: float, etch: float) -> list:
    """The fits times their etch law's cross factor 1 + (tscale - 1) (u Q1(xs) + u^2 Q2(xs)) where the
    model has one (netgen.model.etch_state.cross_laws: tscale and etch together), as their fit's factor."""
    laws = {r["electrode"]: r for r in (model.process.get("etch") or {}).get("capacitance", []) if "cross" in r}
    if tscale == 1.0 or not etch or not laws:
        return fits
    for i, f in enumerate(fits):
        if f.electrode in laws:
            factor = weighted_polynomial(laws[f.electrode]["cross"], *cross_weights(tscale, etch))
            fits[i] = dataclasses.replace(f, factor=factor if f.factor is None else f.factor.times(factor))
    return fits


def thickness_fits(model: MacroModel, fits: list, tscale: float) -> list:
    """The fits at tscale: each electrode with a tscale law (comb fingers ~ t, netgen.model.process.
    thickness_capacitance) times its ratio, as the emitters render pc_<electrode>, and a comb's state
    factor 1 + u P1(xs) + u^2 P2(xs), u = tscale - 1 (netgen.model.etch_state) as its fit's factor."""
    laws = {r["electrode"]: r for r in (model.process.get("tscale") or {}).get("capacitance_laws", [])}
    if tscale == 1.0 or not laws:
        return fits
    for i, f in enumerate(fits):
        law = laws.get(f.electrode)
        if law is not None:
            f = dataclasses.replace(f, c_ref=f.c_ref * float(np.dot(law["ratio"], [1, tscale, tscale**2, tscale**3])))
            fits[i] = with_state(f, law, tscale, TSCALE)
    return fits


def with_state(f: CapacitanceFit, law: dict, value: float, axis: Axis) -> CapacitanceFit:
    """The fit times its law's state factor at the `axis` parameter's value (netgen.model.etch_state.
    state_polynomial, read at the unshifted state as every form reads it); as it was without one."""
    if "state" not in law:
        return f
    factor = state_polynomial(law["state"], value, axis)
    return dataclasses.replace(f, factor=factor if f.factor is None else f.factor.times(factor))


def etched_fits(model: MacroModel, fits: list, etch: float) -> list:
    """The fits at the etch bias (netgen.model.process.capacitance_at's arithmetic, as the emitters
    render it): each electrode with an etch law read at x + shift etch / L_q and times its ratio (a
    beam's knotted one too), and a comb's or an overhanging tip's state factor, 1 + u P1(xs) + u^2
    P2(xs) in u = etch / 1 um or (k - u)+ (netgen.model.etch_state), as its fit's factor."""
    laws = {r["electrode"]: r for r in (model.process.get("etch") or {}).get("capacitance", [])}
    if not etch or not laws:
        return fits
    names = [c.name for c in model.coordinates]
    for i, f in enumerate(fits):
        law = laws.get(f.electrode)
        if law is None:
            continue
        polys = f.polys
        for q, k in law.get("shift", {}).items():
            v = names.index(q)
            polys = tuple(shift(p, v, k * etch / model.coordinates[v].scale) for p in polys)
        knots = tuple(model.process["etch"].get("knots", []))  # a beam's edge knots (netgen.model.etch_knots)
        moved = dataclasses.replace(f, polys=polys, c_ref=f.c_ref * ratio_value(law["ratio"], etch, knots))
        fits[i] = with_state(moved, law, etch, ETCH)
    return fits


def shift(p: Polynomial, v: int, delta: float) -> Polynomial:
    """P(x + delta e_v) as a polynomial (binomial expansion of each monomial's x_v power: exact)."""
    terms: dict[tuple, float] = defaultdict(float)
    for e, c in zip(p.exponents, p.coeffs):
        k = int(e[v])
        for j in range(k + 1):
            ex = list(int(x) for x in e)
            ex[v] = j
            terms[tuple(ex)] += float(c) * comb(k, j) * delta ** (k - j)
    keys = sorted(terms)
    return Polynomial(np.array(keys, dtype=p.exponents.dtype), np.array([terms[k] for k in keys]))


# ----------------------------------------------------------------------------- the reference: rebuilds


def rebuilt_structure(s: Structure, point: dict[str, float]) -> Structure:
    """The structure at the process point, by the same edits the laws were fitted on: thickness and
    modulus scaled (netgen.model.process.scaled), the modulus also by its temperature coefficient
    ([process] modulus_tc, else its default), the gas and noise at temp, the flexures etched
    (netgen.model.process.etched), each dg_<set> added to that set's gap."""
    p = s.process or Process()
    t0_c = (s.damping.temperature if s.damping else 300.0) - KELVIN
    temp = point.get("temp", t0_c)
    escale = point.get("escale", 1.0) * (1.0 + p.modulus_tc * (temp - t0_c))
    out = scaled(s, point.get("tscale", 1.0), escale)
    if point.get("etch"):
        out = etched(out, point["etch"])
    if "temp" in point and out.damping is not None:
        out = dataclasses.replace(out, damping=dataclasses.replace(out.damping, temperature=temp + KELVIN))
    sets = []
    for e in out.electrode_sets:
        dg = point.get(f"dg_{e.name}", 0.0)
        sets.append(dataclasses.replace(e, gap=e.gap + dg) if dg else e)
    return dataclasses.replace(out, electrode_sets=tuple(sets))


def rebuild_doc(doc: dict, s: Structure, point: dict[str, float], where: tuple[str, str]) -> dict:
    """The structure file's document at the process point, without [process]: the keys
    rebuilt_structure changes, written as SI numbers; checked by parsing it back (a change the file
    cannot say is refused: SweepError at `where` = (sweep file, key))."""
    target = rebuilt_structure(s, point)
    out = {k: v for k, v in doc.items() if k != "process"}
    out["conductor"] = dict(out["conductor"])
    for _ in range(2):  # a second pass writes what a parsed default derived from the first (spacing ~ width)
        now = parse_structure(to_toml(out), s.source).conductor
        write_changes(out["conductor"], now, target.conductor)
    if "temp" in point and target.damping is not None:
        out["damping"] = dict(out["damping"], temperature=target.damping.temperature)
    electrodes = [dict(e) for e in out.get("electrodes", [])]
    for e in electrodes:
        dg = point.get(f"dg_{e.get('name')}", 0.0)
        if dg:
            e["gap"] = next(x.gap for x in target.electrode_sets if x.name == e["name"])
        if "etch" in point:  # a rectangle drawn as "the whole conductor" stays as drawn while the outline recedes
            keep = next((x for x in target.electrode_sets if x.name == e.get("name") and hasattr(x, "x0")), None)
            if keep is not None:
                e.setdefault("x", [keep.x0, keep.x1])
                e.setdefault("y", [keep.y0, keep.y1])
    if electrodes:
        out["electrodes"] = electrodes
    back = parse_structure(to_toml(out), s.source)
    same = back.conductor == target.conductor and back.electrode_sets == target.electrode_sets
    if not same or back.damping != (target.damping if "temp" in point else s.damping):
        raise SweepError(
            where[0],
            where[1],
            f"the structure file cannot be written at the process point {point} (a changed value has no key of its own)",
            'sweep it with process = "parameters", or give the changed keys explicitly as structure.<table>.<key>',
        )
    return out


def write_changes(table: dict, now: Any, target: Any) -> None:
    """Set in the TOML table every float field of the dataclass `target` that differs from `now`
    (nested dataclasses, e.g. the flexure, as nested tables)."""
    for f in dataclasses.fields(target):
        a, b = getattr(now, f.name), getattr(target, f.name)
        if a == b:
            continue
        if dataclasses.is_dataclass(b) and isinstance(table.get(f.name), dict):
            sub = dict(table[f.name])
            write_changes(sub, a, b)
            table[f.name] = sub
        elif isinstance(b, float):
            table[f.name] = b


# ----------------------------------------------------------------------------- checks


def problem(s: Structure, name: str, value: float, rebuild: bool) -> tuple[str, str] | None:
    """Why the structure cannot take process.<name> = value on this path, and the fix; None if it can.
    The parameters path needs the parameter declared in [process] and the value in its valid
    range (dg_<set>: within the bound the model will state, range x L_z / 4 <= range x gap / 4);
    the rebuild needs what it edits (a flexure to etch, the set, no squeeze film's viscosity at temp)."""
    p = s.process
    other = 'or write [sweep] process = "rebuild"' if not rebuild else ""
    declared = "dg" if gap_set(name) else name
    if not rebuild and (p is None or not p.wants(declared)):
        return (
            f"process.{name}: the structure does not declare {declared} in its [process] table",
            f'add [process] parameters = ["{declared}"] to the structure, {other}'.rstrip(", "),
        )
    gset = gap_set(name)
    if gset is not None:
        plates = {e.name: e for e in s.electrode_sets if getattr(e, "side", None) in GAP_SIDES}
        if gset not in plates:
            return (
                f"process.{name}: {gset!r} is not an electrode set above or below the conductor",
                f"use dg_<set> with a set of {', '.join(f'dg_{n}' for n in plates) or '(none)'}",
            )
        bound = s.sampling.range * min(e.gap for e in plates.values()) / 4
        if not rebuild and abs(value) > bound:
            return (
                f"process.{name} = {value:g} m is outside the gap offsets' valid range |dg| <= {bound:.3g} m "
                "([sampling] range x the gap / 4: the fit's box moves by dg)",
                f"keep |dg| <= {bound:.3g} m, widen [sampling] range, {other}".rstrip(", "),
            )
        if value <= -plates[gset].gap:
            return (f"process.{name} = {value:g} m closes the gap of {gset}", "give dg > -gap")
        return None
    if not rebuild:
        lo, hi = getattr(p, f"{name}_range")
        if not lo <= value <= hi:
            return (
                f"process.{name} = {value:g} is outside the structure's {name}_range [{lo:g}, {hi:g}]",
                f"keep the values inside {name}_range, widen it in [process], {other}".rstrip(", "),
            )
    beam = getattr(s.conductor, "kind", "") in BEAM_KINDS + PLATE_KINDS  # no flexure: the body itself etches
    if rebuild and name == "etch" and getattr(s.conductor, "flexure", None) is None and not beam:
        return ("process.etch: the structure has no flexure beams to etch", "sweep the widths as structure.<key>")
    t0 = s.damping.temperature - KELVIN if s.damping else 26.85
    if rebuild and name == "temp" and s.damping and s.damping.squeeze_film and value != t0:
        return (
            "process.temp: a rebuild cannot move the squeeze film's gas viscosity with the temperature (the "
            "damping stage takes the gas at its tabulated viscosity): the rebuilt model would be wrong",
            'sweep temp with process = "parameters" (the viscosity law of [process]), or without the film',
        )
    return None


def gap_bound(model: MacroModel, name: str) -> float | None:
    """The model's stated bound |dg| <= max_m of dg_<set> (None: not a gap offset of this model)."""
    gset = gap_set(name)
    return next((g["max_m"] for g in model.process.get("gaps", []) if g["set"] == gset), None)
