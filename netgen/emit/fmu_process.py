"""The process instance parameters of the FMU (netgen.emit.fmu): tscale, escale, temp, etch and
dg_<set> as FMI parameters (start = nominal, min/max = the valid range the model's process record
states) and the C data by which the runtime applies them: the law coefficients of
netgen.model.process, read from MacroModel.process exactly as netgen.emit.process renders them
into the .lib and the .va (mass, stiffness and damping ratios pm, pk, pd per coordinate, the a_in
gain times tscale, each capacitance term's z shifted by -sign dg / L_z, each stop's penetration
by -dg / gap; with etch declared the laws' etch ratios with their torsion knots (KNOTS,
netgen.model.etch_knots), each electrode's capacitance ratio pc (a cubic in etch / 1 um,
netgen.emit.process.capacitance_ratios) scaling its C, a comb's terms read at the state shifted by
shift / L per metre of etch (etch_columns) and its stops' penetrations by a . shift / L etch
(etch_offsets)). No physics here: every number comes from the model; the runtime
(templates/fmu/runtime.c.j2, process_apply) evaluates the same polynomials."""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from ..model import MacroModel
from ..model.process import ETCH_UNIT, LAW_KEYS
from ..model.process_film import set_side
from . import etch_state, process
from .common import num, stop_constants

PAIRS = ("xx", "yy", "zz", "xy", "xz", "yz")  # the runtime's order of the centrifugal products
# the runtime's inertial tables: (C name, kind, keys in order)
TABLES = (
    ("PAX", "participation", ("a_x",)),
    ("PAY", "participation", ("a_y",)),
    ("GYRO", "gyroscopic", tuple("xyz")),
    ("CENT", "centrifugal", PAIRS),
    ("CENTF", "centrifugal_force", PAIRS),
)
IDENTITY = [1.0, 0.0, 0.0, 0.0]
UNITLESS = ""  # FMI: a Real without a unit attribute (a ratio)
NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


def rows(model: MacroModel) -> list[dict]:
    """The declared parameters as FMI parameter rows: name, unit, start (nominal), min, max (the
    model's stated valid range, unwidened) and description; [] without [process]."""
    if not process.enabled(model):
        return []
    p, out = model.process, []
    text = {
        "tscale": (p["tscale"]["range"], UNITLESS, "device-layer thickness / nominal"),
        "escale": (p["escale"]["range"], UNITLESS, "Young's modulus / nominal"),
        "temp": (p["temp"]["range_C"], "degC", "die temperature in degC (modulus temperature coefficient)"),
        "etch": (
            (p.get("etch") or {}).get("range_m", [0.0, 0.0]),
            "m",
            "lateral over-etch per edge in m (beam widths w - 2 etch)",
        ),
    }
    for name, default in process.params(model, gaps=False):
        (lo, hi), unit, what = text[name]
        out.append(row(name, unit, float(default), lo, hi, what))
    for g in p["gaps"]:
        m = g["max_m"]
        out.append(row(f"dg_{g['set']}", "m", 0.0, -m, m, f"gap increase of electrode set {g['set']} in m"))
    return out


def row(name: str, unit: str, start: float, lo: float, hi: float, what: str) -> dict:
    """One parameter row; the name must be a C/FMI identifier (the set names are validated ones).
    The range's ends are rounded to 12 digits: a dg range of sampling range x gap / 4 carries the
    gap scale's round-off (2.999999999999775e-07 for 0.3 um), which would refuse the corner a user
    writes (3e-07); 12 digits move an end by < 5e-13 relative, far below any law's stated error."""
    if not NAME.match(name):
        raise ValueError(f"process parameter name {name!r} is not an identifier")
    lo, hi = float(f"{lo:.12g}"), float(f"{hi:.12g}")
    return {
        "name": name,
        "unit": unit,
        "start": num(start),
        "min": num(lo),
        "max": num(hi),
        "description": f"process: {what}, valid {lo:.6g}..{hi:.6g} (netgen.model.process)",
    }


def arrays(model: MacroModel, vr: dict[str, int], array) -> tuple[list[dict], dict[str, Any], list[str]]:
    """The runtime's process data (`array` builds one C array), its #defines and the parameters'
    names, from the model's process record and the value references `vr` (name -> vr)."""
    names = [r["name"] for r in rows(model)]
    law = model.process.get("coordinates", []) if process.enabled(model) else []
    ident = [1.0, 0.0, 0.0, 0.0]
    knots = process.knots(model) if law else []
    coeffs, etch, nominal = [], [], []
    for v, c in enumerate(model.coordinates):
        cl: dict[str, Any] = law[v] if law else {k: [0.0] * 4 for k in LAW_KEYS}
        coeffs += [cl[k] for k in LAW_KEYS]
        ratio = cl.get("etch", {}) if process.declared(model, "etch") else {}
        etch += [ratio.get(k, ident + [0.0] * 3 * len(knots)) for k in LAW_KEYS]
        nominal += [c.mass, c.stiffness, c.damping]
    p = model.process if law else {}
    visc = ((p.get("temp") or {}).get("viscosity") or {}).get("coeffs", [])
    shifts = process.gap_shifts(model)
    elec = [shifts.get(e.name) for e in model.electrodes]
    stops = model.contact.get("points", []) if stop_constants(model) else []
    stop_sets = [shifts.get(pt["electrode"]) for pt in stops]
    rngs = {r["name"]: r for r in rows(model)}
    ratios, etch_stops = process.capacitance_ratios(model), process.etch_offsets(model)
    thick = process.thickness_ratios(model)
    data = [
        array("int", "PROC_VR", [vr[n] for n in names]),
        array("double", "PROC_MIN", [float(rngs[n]["min"]) for n in names]),
        array("double", "PROC_MAX", [float(rngs[n]["max"]) for n in names]),
        array("double", "LAW", coeffs),
        array("double", "ETCH_LAW", etch),
        array("double", "LAW_NOM", nominal),
        array("double", "VISC", visc),
        array("double", "ENERGY_LAW", energy_law(model)),
        array("int", "ELEC_DG", [vr[f"dg_{s[0]}"] if s else -1 for s in elec]),
        array("double", "ELEC_SHIFT", [s[1] if s else 0.0 for s in elec]),
        array("int", "STOP_DG", [vr[f"dg_{s[0]}"] if s else -1 for s in stop_sets]),
        array("double", "STOP_INV_GAP", [1.0 / pt["gap"] for pt in stops]),
        array("double", "PC_LAW", [padded(ratios.get(e.name, ident), knots) for e in model.electrodes]),
        array("double", "PC_TLAW", [thick.get(e.name, ident) for e in model.electrodes]),
        array("double", "ELEC_ETCH", etch_shifts(model)),
        array("double", "STOP_ETCH", [etch_stops.get(j, 0.0) for j in range(len(stops))]),
    ]
    data += load_arrays(model, array) + film_arrays(model, vr, array)
    data += [array("double", "KNOTS", knots)] if knots else []  # the etch laws' torsion knots (etch / 1 um)

    def ref(name: str) -> int:
        return vr[name] if name in names else -1

    defines = {
        "NP": len(names),
        "NVISC": len(visc),
        "IZ": next((i for i, c in enumerate(model.coordinates) if c.name == "z"), -1),
        "VR_TSCALE": ref("tscale"),
        "VR_ESCALE": ref("escale"),
        "VR_TEMP": ref("temp"),
        "VR_ETCH": ref("etch"),
        "ACTIVE_PM": int(process.active(model, "pm")),
        "ACTIVE_PK": int(process.active(model, "pk")),
        "ACTIVE_PD": int(process.active(model, "pd")),
        "T0_C": f"({num(p.get('temperature_C', 0.0))})",  # parenthesized: a negative value in any expression
        "MODULUS_TC": f"({num(p.get('modulus_tc_per_K', 0.0))})",
        "INV_ETCH_UNIT": f"({num(1.0 / ETCH_UNIT)})",
        "NFILM": len(process.film_sets(model)),
        "NPW": len(process.pw_sides(model)),
    }
    if knots:  # only then: the runtime's text without knots is unchanged
        defines["NKNOT"] = len(knots)
    state = state_arrays(model, array)
    if state:  # likewise: the combs' etch state factors (netgen.emit.etch_state)
        data += state
        defines["NSTATE"] = len(state[0]["data"].split(", "))
        defines["STATE_U"] = state_u(model)
    return data, defines, names


def padded(ratio: list[float], knots: list[float]) -> list[float]:
    """An etch ratio in the knotted law's length 4 + 3 per knot (the runtime's etch_ratio reads PC_LAW
    with that stride where there are knots; a plain cubic's knot columns are 0)."""
    return list(ratio) + [0.0] * (4 + 3 * len(knots) - len(ratio)) if knots else list(ratio)


def state_u(model: MacroModel) -> str:
    """The C text of the etch state factors' u: etch / 1 um, or (k - u)+ for a cantilever's overhanging
    tip (a law marked "below" k, netgen.model.etch_state); the runtime has one u for all the factors."""
    below = {law.get("below") for fs in etch_state.state_laws(model).values() for k, law in fs if k == "etch"}
    below = below or {None}  # no etch factor: STATE_U unread (the tscale and cross factors' weights are t's)
    if len(below) > 1:
        raise ValueError("the FMU renders one state-factor variable; these laws differ in it")
    k = below.pop()
    return "u" if k is None else f"(u < {num(k)} ? {num(k)} - u : 0.0)"


def state_arrays(model: MacroModel, array) -> list[dict]:
    """The combs' state factors (netgen.model.etch_state: 1 + w1 P1(xs) + w2 P2(xs) of each kind,
    netgen.emit.etch_state.KINDS) as monomials: owner (index in model.capacitances) STATE_ELEC, kind
    STATE_KIND (0 etch: u, u^2; 1 tscale: tscale - 1 and its square; 2 their cross factor: (tscale - 1)
    u, (tscale - 1) u^2), exponents STATE_EXP, P1's and P2's coefficients STATE_C1, STATE_C2; [] without
    any. The runtime multiplies an electrode's factors."""
    laws = etch_state.state_laws(model)
    rows = [
        (i, etch_state.KINDS.index(k), e, a, b)
        for i, f in enumerate(model.capacitances)
        for k, law in laws.get(f.electrode, [])
        for e, a, b in zip(law["exponents"], *law["coeffs"])
    ]
    if not rows:
        return []
    return [
        array("int", "STATE_ELEC", [r[0] for r in rows]),
        array("int", "STATE_KIND", [r[1] for r in rows]),
        array("int", "STATE_EXP", [x for r in rows for x in r[2]]),
        array("double", "STATE_C1", [r[3] for r in rows]),
        array("double", "STATE_C2", [r[4] for r in rows]),
    ]


def film_arrays(model: MacroModel, vr: dict[str, int], array) -> list[dict]:
    """The gap sets' squeeze-film laws (netgen.emit.process_film.film_factors): per film set its dg's value
    reference FILM_VR, gap FILM_GAP, Veijola's 9.638 Kn^1.159 FILM_A, per coordinate its share
    FILM_SHARE and, for a perforated film (FILM_FIT 1), its cubics in dg / 1 um FILM_POLY; PATH_LAW = (sealed, S, T0 K) of the mean free path's temperature ratio (S = 0: none);
    per compressible-film branch the film set whose gap moves it FILM_SET (-1: none)."""
    sets, n, sides = process.film_sets(model), model.ncoords, process.pw_sides(model)
    wanted = (sets or sides) and process.declared(model, "temp")
    visc = (model.process.get("temp") or {}).get("viscosity") or {} if wanted else {}
    path = [float(visc.get("cavity") == "sealed"), visc["sutherland_K"], visc["t0_K"]] if visc else [0.0, 0.0, 1.0]
    index = {r["side"]: k for k, r in enumerate(sides)}
    return side_arrays(model, sets, sides, array) + [
        array("int", "FILM_PW", [index.get(set_side(g), -1) for g in sets]),
        array("int", "FILM_VR", [vr[f"dg_{g['set']}"] for g in sets]),
        array("double", "FILM_GAP", [g["film"]["gap_m"] for g in sets]),
        array("double", "FILM_A", [g["film"]["rarefaction"] for g in sets]),
        array("double", "FILM_SHARE", [g["film"]["share"] for g in sets]),
        array("int", "FILM_FIT", [int("fit" in g["film"]) for g in sets]),  # 1: a perforated film's cubics
        array("double", "FILM_POLY", [(g["film"].get("fit") or {}).get("coeffs", [IDENTITY] * n) for g in sets]),
        array("double", "PATH_LAW", path),
        array(
            "int",
            "FILM_SET",
            [branch_set(sets, v, j) for v, c in enumerate(model.coordinates) for j in range(len(c.film))],
        ),
    ]


def side_arrays(model: MacroModel, sets: list[dict], sides: list[dict], array) -> list[dict]:
    """The sides' own viscosity laws (netgen.emit.process_film.side_factors): PW_A each side's rarefaction and
    PW_LAW the fitted gap's, PW_SHARE per coordinate its share, PW_FILM the film set on that side (-1:
    none, then the side's term is its own), BRANCH_PW per compressible-film branch its side (-1: none)."""
    on = {set_side(g): k for k, g in enumerate(sets)}
    rows = [(v, j) for v, c in enumerate(model.coordinates) for j in range(len(c.film))]
    owner = [
        next((k for k, r in enumerate(sides) if j in (r.get("branches") or [[]] * (v + 1))[v]), -1) for v, j in rows
    ]
    visc = (model.process.get("temp") or {}).get("viscosity") or {} if sides else {}
    return [
        array("double", "PW_LAW", [visc.get("rarefaction", 0.0)]),
        array("double", "PW_A", [r["rarefaction"] for r in sides]),
        array("double", "PW_SHARE", [r["share"] for r in sides]),
        array("int", "PW_FILM", [on.get(r["side"], -1) for r in sides]),
        array("int", "BRANCH_PW", owner),
    ]


def branch_set(sets: list[dict], v: int, j: int) -> int:
    """The index in `sets` of the gap set whose side's compressible film makes coordinate v's branch j
    (netgen.model.process_film.compressible_law), else -1."""
    return next((k for k, g in enumerate(sets) if j in g["film"].get("branches", [[]] * (v + 1))[v]), -1)


def etch_shifts(model: MacroModel) -> list[float]:
    """Per electrode and coordinate the scaled-state offset per metre of etch its capacitance terms
    read (netgen.emit.process.etch_columns: xe_q = xs_q + shift / L_q etch), 0 where none."""
    cols = {n: k for n, _, k in process.etch_columns(model)}
    states = process.etch_states(model)
    return [
        cols[states[e.name][c.name]] if c.name in states.get(e.name, {}) else 0.0
        for e in model.electrodes
        for c in model.coordinates
    ]


def energy_law(model: MacroModel) -> list[float]:
    """The strain energy's law cubics a, b and its etch ratio (netgen.model.process.energy_law: its
    forces times (pe a(tscale) + b(tscale)) R(etch / 1 um)); without one a = 0, b = 1, R = 1."""
    u = model.process.get("strain_energy") if process.energy_moved(model) else None
    if not u:
        return [0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]
    etch = u.get("etch") if process.declared(model, "etch") else None
    return list(u["a"]) + list(u["b"]) + list(etch or [1.0, 0.0, 0.0, 0.0])


def load_arrays(model: MacroModel, array) -> list[dict]:
    """The inertial loads' etch ratios (netgen.model.process_loads), cubics in etch / 1 um, 1 where none:
    AIN_ETCH per coordinate (the a_in load), and per inertial table (TABLES, the runtime's order) <T>_E1
    and <T>_E3 per entry, its t and t^3 parts' ratios (with tscale undeclared both the entry's own:
    the parts then sum to X R(etch))."""
    n = model.ncoords
    ratio = (
        (model.process.get("etch") or {}).get("acceleration", {}).get("ratio")
        if process.declared(model, "etch")
        else None
    )
    out = [array("double", "AIN_ETCH", ratio if ratio and model.acceleration else [IDENTITY] * n)]
    law = (model.process.get("inertial") or {}).get("etch") if process.declared(model, "etch") else None
    parts = ("t", "t3") if process.declared(model, "tscale") else ("total", "total")
    for name, kind, keys in TABLES:
        for suffix, part in zip(("E1", "E3"), parts):
            table = (law or {}).get(part, {}).get(kind, {})
            shape = (n, n) if kind in ("gyroscopic", "centrifugal") else (n,)
            rows = [np.asarray(table[k], dtype=float) if k in table else np.tile(IDENTITY, shape + (1,)) for k in keys]
            out.append(array("double", f"{name}_{suffix}", rows))
    return out
