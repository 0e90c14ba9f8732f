"""The process instance parameters (tscale, escale, temp, etch, dg_<set>) as netlist text: the laws of
netgen.model.process (MacroModel.process) rendered as parameter expressions, shared by the
dialects (the expressions use only + - * / and parentheses: valid in ngspice .param and Verilog-A).
No physics here: every number comes from the model."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..model import MacroModel
from ..model.process_loads import IDENTITY
from .common import noise_kelvin, num, unit_load
from .process_base import declared as declared  # re-exported: the emitters ask netgen.emit.process
from .process_base import enabled as enabled
from .process_base import poly as poly
from .process_etch import etch_columns as etch_columns
from .process_etch import etch_header
from .process_etch import etch_networks as etch_networks
from .process_etch import etch_ratio as etch_ratio
from .process_etch import etch_states as etch_states
from .process_etch import knot_params as knot_params
from .process_etch import knots as knots
from .process_etch import stop_shift as stop_shift
from .process_film import VEIJOLA_POWER as VEIJOLA_POWER
from .process_film import branch_law as branch_law
from .process_film import film_factors, film_share, film_text, joint_error, sides_text
from .process_film import film_pg as film_pg
from .process_film import film_scaled as film_scaled
from .process_film import film_sets as film_sets
from .process_film import pw_sides as pw_sides
from .process_film import side_factors as side_factors

KELVIN = 273.15


# the derived ratios each parameter moves (netgen.emit.process.factors): pm mass, pk stiffness,
# pd damping, pt the noise PSD
MOVES = {
    "pm": ("tscale", "etch"),
    "pk": ("tscale", "escale", "temp", "etch"),
    "pd": ("tscale", "temp", "etch"),
    "pt": ("tscale", "temp", "etch"),
}


def active(model: MacroModel, kind: str) -> bool:
    """Some declared parameter moves the ratio `kind` (MOVES; tscale itself for the inertial gain; a
    gap set's squeeze film the damping, film_sets)."""
    film = kind in ("pd", "pt") and bool(film_sets(model))
    return film or any(declared(model, n) for n in MOVES.get(kind, (kind,)))


def params(model: MacroModel, gaps: bool = True) -> list[tuple[str, str]]:
    """(name, default) of the declared instance parameters (the dg_<set> only with `gaps`); [] without
    laws."""
    if not enabled(model):
        return []
    p = model.process
    out = [(n, "1") for n in ("tscale", "escale") if declared(model, n)]
    out += [("temp", f"{p['temperature_C']:.6g}")] if declared(model, "temp") else []
    out += [("etch", "0")] if declared(model, "etch") else []
    return out + ([(f"dg_{g['set']}", "0") for g in p["gaps"]] if gaps else [])


def factors(model: MacroModel) -> list[tuple[str, str]]:
    """(name, expression) of the derived parameters: per coordinate q the ratios pm_q, pk_q, pd_q of
    its mass, stiffness and damping to the model's values, and pt_q = pd_q T / T0 (the thermal noise
    PSD's factor), each only where a declared parameter moves it (active); the modulus factor pe and
    the film viscosity ratio pv first. An undeclared tscale is 1, an undeclared temp the nominal."""
    if not enabled(model):
        return []
    p = model.process
    tscale = "tscale" if declared(model, "tscale") else "1"
    temp = "temp" if declared(model, "temp") else num(p["temperature_C"])
    escale = "escale*" if declared(model, "escale") else ""
    out = []
    if active(model, "pk"):
        out.append(("pe", f"{escale}(1 + {num(p['modulus_tc_per_K'])}*({temp} - {num(p['temperature_C'])}))"))
    visc = p["temp"].get("viscosity") or {}
    if active(model, "pd"):
        out.append(("pv", poly(visc["coeffs"], f"(({temp} - {num(p['temperature_C'])})/100)") if visc else "1"))
    out += film_factors(model, temp)
    if energy_moved(model):  # the strain energy's law (netgen.model.process.energy_law)
        u = p["strain_energy"]
        pu = join([f"pe*{poly(u['a'], tscale)}", poly(u["b"], tscale)], [u["a"], u["b"]])
        etch = u.get("etch") if declared(model, "etch") else None
        out.append(("pu", f"{pu}*{poly(etch, '(1e6*etch)')}" if etch and etch != IDENTITY else pu))
    t0 = p["temperature_C"] + KELVIN
    out += knot_params(model)  # before pc_<electrode>: a beam's ratio reads its edge knots' ek_<j>
    out += [(f"pc_{e}", pc_text(model, e)) for e in capacitance_ratios(model)]
    for v, (c, law) in enumerate(zip(model.coordinates, p["coordinates"])):
        if active(model, "pm"):
            out.append((f"pm_{c.name}", f"{part(model, law, 'mass', tscale)}/{num(c.mass)}"))
        if c.stiffness and active(model, "pk"):
            stiff = join([f"pe*{part(model, law, 'a', tscale)}", part(model, law, "b", tscale)], [law["a"], law["b"]])
            out.append((f"pk_{c.name}", f"{stiff}/{num(c.stiffness)}"))
        if c.damping and active(model, "pd"):
            damp = join(
                [part(model, law, "d_rest", tscale), f"pv*{part(model, law, 'd_film', tscale)}{film_share(model, v)}"],
                [law["d_rest"], law["d_film"]],
            )
            out.append((f"pd_{c.name}", f"{damp}/{num(c.damping)}"))
            out.append((f"pt_{c.name}", f"pd_{c.name}*({temp} + {num(KELVIN)})/{num(t0)}"))
    return out


def capacitance_ratios(model: MacroModel) -> dict[str, list[float]]:
    """electrode -> its capacitance's etch ratio (a cubic in etch / 1 um, netgen.model.process.
    capacitance_laws; 1 where it has a tscale ratio alone) where etch or tscale moves it; the emitters
    scale the electrode's charge and forces by pc_<electrode> (pc_text). {} otherwise."""
    out = {e: [1.0, 0.0, 0.0, 0.0] for e in thickness_ratios(model)}
    if declared(model, "etch"):
        out |= {r["electrode"]: r["ratio"] for r in model.process["etch"].get("capacitance", [])}
    return out


def thickness_ratios(model: MacroModel) -> dict[str, list[float]]:
    """electrode -> its capacitance's tscale ratio (a cubic in tscale, netgen.model.process.
    thickness_capacitance: comb fingers ~ t) where tscale is declared; {} otherwise."""
    if not declared(model, "tscale"):
        return {}
    return {r["electrode"]: r["ratio"] for r in model.process["tscale"].get("capacitance_laws", [])}


def pc_text(model: MacroModel, electrode: str) -> str:
    """pc_<electrode>'s expression: its etch cubic in 1e6 etch (with a beam's edge knots' truncated
    powers, etch_ratio) times its tscale cubic (either left out where the electrode has none)."""
    etch = capacitance_ratios(model)[electrode]
    thick = thickness_ratios(model).get(electrode)
    parts = [etch_ratio(model, etch)] if declared(model, "etch") else []
    parts += [poly(thick, "tscale")] if thick else []
    return "*".join(parts) or "1"


def charge_scale(model: MacroModel, electrode: str, value: str) -> str:
    """ngspice text of `value` times the electrode's capacitance ratio pc_<electrode>, in braces;
    `value` unchanged without one."""
    return f"{{pc_{electrode}*{value}}}" if electrode in capacitance_ratios(model) else value


def part(model: MacroModel, law: dict, key: str, tscale: str) -> str:
    """One law part's text: its tscale cubic, times its etch ratio (a cubic in etch / 1 um,
    netgen.model.process.etch_laws) where etch is declared and the ratio is not identically 1."""
    text = poly(law[key], tscale)
    ratio = law.get("etch", {}).get(key, [1.0, 0.0, 0.0, 0.0])
    if not declared(model, "etch") or (list(ratio[:4]) == IDENTITY and not any(ratio[4:])):
        return text
    return f"{text}*{etch_ratio(model, ratio)}"


def join(parts: list[str], coeffs: list[list[float]]) -> str:
    """The sum of the parts whose polynomial is not identically zero, in parentheses."""
    kept = [p for p, c in zip(parts, coeffs) if any(c)]
    return "(" + (" + ".join(kept) if kept else "0") + ")"


def factor(model: MacroModel, kind: str, name: str, value: str) -> str:
    """ngspice text of `value` times coordinate `name`'s process ratio `kind` (pm, pk, pd, pt) or tscale,
    in braces; `value` unchanged where no declared parameter moves it."""
    if not active(model, kind):
        return value
    return "{" + (f"tscale*{value}" if kind == "tscale" else f"{kind}_{name}*{value}") + "}"


def gap_shifts(model: MacroModel) -> dict[str, tuple[str, float]]:
    """electrode -> (its set, xs_z offset per metre of dg): the set's capacitance terms read
    xs_z - sign dg / L_z (netgen.model.process)."""
    if not enabled(model):
        return {}
    scale = {c.name: c.scale for c in model.coordinates}.get("z")
    return {e: (g["set"], -g["sign"] / scale) for g in model.process["gaps"] for e in g["electrodes"]}


def read_as_expression(f) -> bool:
    """The fit of one electrode has a term netgen.emit.ngspice renders as an expression of the state
    (target direct, or a plate polynomial of degree > 1), not only linear networks."""
    return f.target == "direct" or any(bool(np.any(p.exponents.sum(axis=1) > 1)) for p in f.polys)


def node_sets(model: MacroModel) -> set[str]:
    """The gap sets whose shifted state is a node xg_<set> (some electrode of the set is read as an
    expression); the others shift their linear networks by a current source (offset_lines): no
    unknown is added to the circuit's matrix (two nodes per set changed KLU's pivoting in ngspice 46
    enough to fail the levitated disk's sigma-delta run, timestep too small at 0.46 us)."""
    shifts = gap_shifts(model)
    return {shifts[f.electrode][0] for f in model.capacitances if f.electrode in shifts and read_as_expression(f)}


def electrode_state(model: MacroModel, electrode: str, state: list[str]) -> list[str]:
    """The state names the plate terms of `electrode` read: xs_z replaced by its set's shifted node
    where the set has one (node_sets), a comb's xs_q by its etch-shifted node (etch_states)."""
    etch = {f"xs_{q}": n for q, n in etch_states(model).get(electrode, {}).items()}
    state = [etch.get(s, s) for s in state]
    shift = gap_shifts(model).get(electrode)
    if shift is None or shift[0] not in node_sets(model):
        return state
    return [f"xg_{shift[0]}" if s == "xs_z" else s for s in state]


def offset_lines(model: MacroModel, electrode: str, name: str, poly, state: list[str]) -> list[str]:
    """The gap offset of an affine network node `name` = sum c_v xs_v (netgen.emit.ngspice.linear_network)
    as one more current source, c_z (-sign / L_z) dg_<set>: a right-hand side only. [] where the
    electrode has no offset, its set reads a shifted node instead, or the node has no z term."""
    shift = gap_shifts(model).get(electrode)
    if shift is None or shift[0] in node_sets(model) or "xs_z" not in state:
        return []
    v = state.index("xs_z")
    c = sum(float(k) for e, k in zip(poly.exponents, poly.coeffs) if e.sum() == 1 and e[v] == 1)
    return [f"I{name}_dg 0 {name} {{{num(c * shift[1])}*dg_{shift[0]}}}"] if c else []


def stop_offsets(model: MacroModel, braces: bool) -> list[str] | None:
    """Per contact stop point the text its penetration p_j = a_j . xs - 1 gains from its electrode's
    gap offset: moving the set away by dg deepens every local gap by dg, so p_j - dg / gap_j (the
    stop follows the electrode; netgen.model.contact); and from a comb's etch shift (etch_columns:
    the stop reads the shifted state as the comb's terms do, so p_j + a_j . shift etch / L: a finger's
    sidewall stop 2 etch later). ngspice text in braces (numparam), Verilog-A plain; None without
    either (the expressions unchanged)."""
    shifts, etch = gap_shifts(model), etch_offsets(model)
    points = model.contact.get("points", [])
    if not (shifts or etch) or not points:
        return None
    out = []
    for j, pt in enumerate(points):
        shift = shifts.get(pt["electrode"])
        terms = [f"-{num(1.0 / pt['gap'])}*dg_{shift[0]}"] if shift else []
        terms += [f"{num(etch[j])}*etch"] if etch.get(j) else []
        sign, text = ("-", terms[0][1:]) if len(terms) == 1 and terms[0][0] == "-" else ("+", " + ".join(terms))
        out.append(f" {sign} {{{text}}}" if text and braces else f" {sign} {text}" if text else "")
    return out


def etch_offsets(model: MacroModel) -> dict[int, float]:
    """Stop point index -> d p_j / d etch = a_j . (shift / L) of a comb's geometric etch shift (stop_shift),
    where not zero (a finger's vertical stop over the substrate has none)."""
    scale = {c.name: c.scale for c in model.coordinates}
    names = [c.name for c in model.coordinates]
    laws = (model.process.get("etch") or {}).get("capacitance", [])
    # a plate's fill shift (netgen.model.etch_fill) is an effective gap: its stops stay at the drawn gap;
    # a comb's fitted effective shift (netgen.model.etch_combs) likewise: its stops follow the geometric one
    shifts = {r["electrode"]: stop_shift(r) for r in laws}
    if not declared(model, "etch"):
        return {}
    out = {}
    for j, pt in enumerate(model.contact.get("points", [])):
        c = sum(pt["a"][names.index(q)] * k / scale[q] for q, k in shifts.get(pt["electrode"], {}).items())
        if c:
            out[j] = c
    return out


def gap_networks(model: MacroModel, every: bool = False) -> list[str]:
    """ngspice lines of the shifted nodes xg_<set> = xs_z - sign dg_<set> / L_z of node_sets (`every`:
    of every gap set, the code model's extra state columns, netgen.emit.xspice) (1 ohm, a VCCS, a
    parameter current source: linear, nothing to differentiate)."""
    if not enabled(model):
        return []
    scale = {c.name: c.scale for c in model.coordinates}.get("z")
    lines = []
    for g in model.process["gaps"]:
        if not every and g["set"] not in node_sets(model):
            continue
        n = f"xg_{g['set']}"
        lines += [
            unit_load(n),
            f"G{n} 0 {n} xs_z 0 1",
            f"I{n} 0 {n} {{{num(-g['sign'] / scale)}*dg_{g['set']}}}",
        ]
    return lines


def thickness_header(t: dict) -> str:
    """The tscale header's capacitance clause: unchanged (plate electrodes), or the electrodes' ratio
    pc_<electrode> in tscale (netgen.model.process.thickness_capacitance), a comb's state factor where
    it has one, and its stated error."""
    laws = t.get("capacitance_laws")
    if laws is None:
        return " (capacitance: unchanged, plate electrodes)"
    err = t["capacitance_max_rel_error"]
    return (
        f"; capacitances of {', '.join(r['electrode'] for r in laws)} times pc_<electrode>, a cubic in tscale"
        + (
            ", the combs' C times a state factor 1 + u P1(xs) + u^2 P2(xs), u = tscale - 1 (netgen.model.etch_state; nodes pr_*)"
            if any("state" in r for r in laws)
            else ""
        )
        + (f" within {err:.1e}" if err else " (exact: eps t / g)")
        + " against the extractor at the re-run thicknesses, rest, 32 fit-box points and the box's corners"
    )


def header_text(model: MacroModel, gaps: bool = True, state: bool = True) -> str:
    """The header's statement of each declared process parameter: meaning, valid range and error
    (without `gaps`, why this form has no dg_<set>; without `state`, that it leaves the combs' etch
    state factor out, netgen.model.etch_state); "" without [process]."""
    if not enabled(model):
        return ""
    p = model.process
    parts = []
    if declared(model, "tscale"):
        t = p["tscale"]
        parts.append(
            f"tscale = device-layer thickness / nominal, valid {t['range'][0]:g}..{t['range'][1]:g}, mass, "
            f"stiffness and damping laws "
            + (f"within {t['max_rel_error']:.1e}" if t["max_rel_error"] else "exact (power laws of t)")
            + thickness_header(t)
        )
    if declared(model, "escale"):
        e = p["escale"]["range"]
        parts.append(
            f"escale = Young's modulus / nominal, valid {e[0]:g}..{e[1]:g} (given springs and residual stress do not scale)"
        )
    if declared(model, "temp"):
        r = p["temp"]["range_C"]
        text = (
            f"temp = die temperature in degC (default {p['temperature_C']:.6g}), valid {r[0]:g}..{r[1]:g}: modulus "
            f"{p['modulus_tc_per_K'] * 1e6:.4g} ppm/K, thermal noise k_B T"
        )
        visc = p["temp"].get("viscosity")
        text += (
            f", squeeze film by Sutherland's law with Veijola's rarefaction within {visc['max_rel_error']:.1e}"
            + sides_text(visc)
            + (", sealed cavity (p ~ T)" if visc.get("cavity") == "sealed" else ", fixed pressure")
            if visc
            else ""
        )
        text += f" ({p['temp']['film_branches']})" if p["temp"].get("film_branches") else ""
        parts.append(text)
    if declared(model, "etch"):
        parts.append(etch_header(p["etch"], knots(model), state))
    if energy_moved(model):
        err = p["strain_energy"]["max_rel_error"]
        parts.append(
            "the fitted strain energy's forces times pu = pe A(tscale) + B(tscale) (A its modulus part)"
            + (" times its etch ratio" if declared(model, "etch") and p["strain_energy"].get("etch") else "")
            + ", "
            + (f"within {err:.1e}" if err else "exact")
        )
    if p["gaps"] and not gaps:
        parts.append("no gap offsets in this form (the code model reads xs_z: use the B-source .lib)")
    for g in p["gaps"] if gaps else []:
        parts.append(
            f"dg_{g['set']} (m) = gap increase of electrode set {g['set']}, exact as a shift of z, "
            f"valid |dg| <= {g['max_m']:.3g} (the fit's box moves by dg); " + film_text(g, joint_error(model, g))
        )
    return (
        "Process parameters (netgen/model/process.py, declared in [process]): "
        + "; ".join(parts)
        + ". Damping given as Q, zeta or Rayleigh keeps its N*s/m under escale and temp."
    )


# relative widening of the Verilog-A `from [lo:hi]` bounds: ngspice's numparam turns a corner value
# passed through the _osdi.lib's .subckt params into a double one ulp off (dg_drive=3e-7 was refused by
# from [-3e-07:3e-07]); 1e-9 is far below any law's stated error
SLACK = 1e-9


def va_params(model: MacroModel) -> list[dict]:
    """The declared parameters as Verilog-A `parameter real` rows: name, default, valid range (lo, hi)
    from the model's process record (widened by SLACK) and the meaning; [] without laws."""
    if not enabled(model):
        return []
    p, out = model.process, []
    ranges = {
        "tscale": (p["tscale"]["range"], "device-layer thickness / nominal, valid {:g}..{:g}"),
        "escale": (p["escale"]["range"], "Young's modulus / nominal, valid {:g}..{:g}"),
        "temp": (p["temp"]["range_C"], "die temperature, degC, valid {:g}..{:g} (thermal noise at temp + 273.15 K)"),
        "etch": ((p.get("etch") or {}).get("range_m", [0.0, 0.0]), "lateral over-etch per edge, m, valid {:g}..{:g}"),
    }
    for name, default in params(model, gaps=False):
        (lo, hi), text = ranges[name]
        text = text.format(lo, hi)
        out.append({"name": name, "default": default, "lo": bound(lo, -1), "hi": bound(hi, 1), "text": text})
    for g in p["gaps"]:
        m = g["max_m"]
        text = f"gap increase of set {g['set']}, m (|dg| <= {m:.6g})"
        out.append({"name": f"dg_{g['set']}", "default": "0", "lo": bound(-m, -1), "hi": bound(m, 1), "text": text})
    return out


def bound(x: float, side: int) -> str:
    """A range end moved outwards (side -1 low, +1 high) by SLACK relative, as Verilog-A text."""
    return f"{x + side * SLACK * abs(x):.10g}"


def noise_temperature(model: MacroModel) -> str:
    """Verilog-A text of the thermal noise's temperature (K): the instance's temp where declared, else
    the model's own (netgen.emit.common.noise_kelvin), never the simulator's $temperature."""
    return f"(temp + {num(KELVIN)})" if declared(model, "temp") else num(noise_kelvin(model))


def va_factor(model: MacroModel, kind: str, name: str, value: str) -> str:
    """Verilog-A text of `value` times coordinate `name`'s process ratio `kind` (as factor)."""
    if not active(model, kind):
        return value
    return f"{'tscale' if kind == 'tscale' else f'{kind}_{name}'} * {value}"


def inertial_scale(model: MacroModel, kind: str, key: str, v: int, w: int | None = None) -> str:
    """The text of the process law of one inertial entry (MacroModel.inertial's `kind`[key][v][w],
    netgen.model.process_loads.inertial_law: (1 - f) tscale + f tscale^3, f its rotary share; with etch
    each part times its etch ratio R1, R3, netgen.model.process_loads); "" where the model has no
    such law (the entry is a constant)."""
    law = model.process.get("inertial") if enabled(model) else None
    if not law:
        return ""

    def entry(table: dict) -> Any:
        x = table[kind][key][v]
        return x if w is None else x[w]

    f = entry(law["t3_fraction"])
    etch = law.get("etch") if declared(model, "etch") else None
    tscale = declared(model, "tscale")
    if not tscale:  # thickness 1: the entry times its own etch ratio (netgen.model.process_loads)
        return product_text([], entry(etch["total"]) if etch else None)
    t1 = product_text(["tscale"], entry(etch["t"]) if etch else None)
    t3 = product_text(["tscale", "tscale", "tscale"], entry(etch["t3"]) if etch else None)
    if f == 0.0:
        return t1
    if f == 1.0:
        return t3
    return f"({num(1.0 - f)}*{t1} + {num(f)}*{t3})"


def product_text(factors: list[str], ratio) -> str:
    """The factors' product times the etch ratio cubic `ratio` (left out where None or 1), "" for 1."""
    if ratio is not None and list(ratio) != IDENTITY:
        factors = factors + [poly(ratio, "(1e6*etch)")]
    return "*".join(factors)


def acceleration_ratio(model: MacroModel, v: int) -> list[float] | None:
    """Coordinate v's a_in load etch ratio (netgen.model.process_loads.acceleration_law) where etch is
    declared and the ratio is not identically 1; else None."""
    if not declared(model, "etch"):
        return None
    law = (model.process["etch"].get("acceleration") or {}).get("ratio")
    return law[v] if law and list(law[v]) != IDENTITY else None


def load_factor(model: MacroModel, v: int, value: str, braces: bool = True) -> str:
    """The a_in gain `value` of coordinate v times its process law: tscale (factor, va_factor) and,
    under etch, the etched body's ratio (acceleration_ratio); ngspice text in braces, else Verilog-A."""
    c = model.coordinates[v]
    ratio = acceleration_ratio(model, v)
    if ratio is None:
        return factor(model, "tscale", c.name, value) if braces else va_factor(model, "tscale", c.name, value)
    law = product_text(["tscale"] if declared(model, "tscale") else [], ratio)
    return f"{{{law}*{value}}}" if braces else f"{law} * {value}"


def scaled_number(value: str, scale: str, braces: bool) -> str:
    """`value` times the law text `scale` (inertial_scale): ngspice text in braces, else plain."""
    if not scale:
        return value
    return f"{{{scale}*{value}}}" if braces else f"{scale}*{value}"


def energy_moved(model: MacroModel) -> bool:
    """The model's strain energy has a process law (netgen.model.process.energy_law): its forces are
    times pu."""
    return enabled(model) and bool(model.process.get("strain_energy"))
