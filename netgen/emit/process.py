"""The process instance parameters (tscale, escale, temp, dg_<set>) as netlist text: the laws of
netgen.model.process (MacroModel.process) rendered as parameter expressions, shared by the
dialects (the expressions use only + - * / and parentheses: valid in ngspice .param and Verilog-A).
No physics here: every number comes from the model."""

from __future__ import annotations

from ..model import MacroModel
from .common import num

KELVIN = 273.15


def enabled(model: MacroModel) -> bool:
    """The model carries process laws for its coordinates."""
    return bool(model.process.get("coordinates"))


def params(model: MacroModel, gaps: bool = True) -> list[tuple[str, str]]:
    """(name, default) of the instance parameters (the dg_<set> only with `gaps`); [] without laws."""
    if not enabled(model):
        return []
    p = model.process
    out = [("tscale", "1"), ("escale", "1"), ("temp", f"{p['temperature_C']:.6g}")]
    return out + ([(f"dg_{g['set']}", "0") for g in p["gaps"]] if gaps else [])


def poly(coeffs: list[float], x: str) -> str:
    """c0 + c1 x + c2 x^2 + c3 x^3 as products (no power operator: the dialects differ)."""
    terms = [f"{num(c)}" + "".join(f"*{x}" for _ in range(k)) for k, c in enumerate(coeffs) if c != 0.0]
    return "(" + (" + ".join(terms) if terms else "0") + ")"


def factors(model: MacroModel) -> list[tuple[str, str]]:
    """(name, expression) of the derived parameters: per coordinate q the ratios pm_q, pk_q, pd_q of
    its mass, stiffness and damping to the model's values, and pt_q = pd_q T / T0 (the thermal noise
    PSD's factor); the modulus factor pe and the film viscosity ratio pv first."""
    if not enabled(model):
        return []
    p = model.process
    out = [("pe", f"escale*(1 + {num(p['modulus_tc_per_K'])}*(temp - {num(p['temperature_C'])}))")]
    visc = p["temp"].get("viscosity") or {}
    u = f"((temp - {num(p['temperature_C'])})/100)"
    out.append(("pv", poly(visc["coeffs"], u) if visc else "1"))
    t0 = p["temperature_C"] + KELVIN
    for c, law in zip(model.coordinates, p["coordinates"]):
        out.append((f"pm_{c.name}", f"{poly(law['mass'], 'tscale')}/{num(c.mass)}"))
        if c.stiffness:
            stiff = join([f"pe*{poly(law['a'], 'tscale')}", poly(law["b"], "tscale")], [law["a"], law["b"]])
            out.append((f"pk_{c.name}", f"{stiff}/{num(c.stiffness)}"))
        if c.damping:
            damp = join(
                [poly(law["d_rest"], "tscale"), f"pv*{poly(law['d_film'], 'tscale')}"], [law["d_rest"], law["d_film"]]
            )
            damp = f"{damp}/{num(c.damping)}"
            out.append((f"pd_{c.name}", damp))
            out.append((f"pt_{c.name}", f"pd_{c.name}*(temp + {num(KELVIN)})/{num(t0)}"))
    return out


def join(parts: list[str], coeffs: list[list[float]]) -> str:
    """The sum of the parts whose polynomial is not identically zero, in parentheses."""
    kept = [p for p, c in zip(parts, coeffs) if any(c)]
    return "(" + (" + ".join(kept) if kept else "0") + ")"


def factor(model: MacroModel, kind: str, name: str, value: str) -> str:
    """ngspice text of `value` times coordinate `name`'s process ratio `kind` (pm, pk, pd, pt) or tscale,
    in braces; `value` unchanged without process laws."""
    if not enabled(model):
        return value
    return "{" + (f"tscale*{value}" if kind == "tscale" else f"{kind}_{name}*{value}") + "}"


def gap_shifts(model: MacroModel) -> dict[str, tuple[str, float]]:
    """electrode -> (shifted state node, xs_z offset per metre of dg): the set's capacitance terms read
    xs_z - sign dg / L_z (netgen.model.process)."""
    if not enabled(model):
        return {}
    scale = {c.name: c.scale for c in model.coordinates}.get("z")
    out = {}
    for g in model.process["gaps"]:
        for e in g["electrodes"]:
            out[e] = (f"xg_{g['set']}", -g["sign"] / scale)
    return out


def electrode_state(model: MacroModel, electrode: str, state: list[str]) -> list[str]:
    """The state names the plate terms of `electrode` read: xs_z replaced by its set's shifted node."""
    shift = gap_shifts(model).get(electrode)
    if shift is None:
        return state
    return [shift[0] if s == "xs_z" else s for s in state]


def gap_networks(model: MacroModel) -> list[str]:
    """ngspice lines of the shifted nodes xg_<set> = xs_z - sign dg_<set> / L_z (1 ohm, a VCCS, a
    parameter current source: linear, nothing to differentiate)."""
    if not enabled(model):
        return []
    scale = {c.name: c.scale for c in model.coordinates}.get("z")
    lines = []
    for g in model.process["gaps"]:
        n = f"xg_{g['set']}"
        lines += [
            f"R{n} {n} 0 1",
            f"G{n} 0 {n} xs_z 0 1",
            f"I{n} 0 {n} {{{num(-g['sign'] / scale)}*dg_{g['set']}}}",
        ]
    return lines


def header_text(model: MacroModel, gaps: bool = True) -> str:
    """The header's statement of each process parameter: meaning, valid range and error (without
    `gaps`, why this form has no dg_<set>)."""
    p = model.process
    if not enabled(model):
        return f"Process parameters: none ({p['refused']})." if p.get("refused") else ""
    t = p["tscale"]
    parts = [
        f"Process parameters (netgen/model/process.py): tscale = device-layer thickness / nominal, valid "
        f"{t['range'][0]:g}..{t['range'][1]:g}, mass, stiffness and damping laws within "
        f"{t['max_rel_error']:.1e}"
        + (f" (capacitance: {t['capacitance']})" if "refused" not in t else f" (WARNING: {t['refused']})")
        + f"; escale = Young's modulus / nominal, valid {p['escale']['range'][0]:g}..{p['escale']['range'][1]:g} "
        f"(given springs and residual stress do not scale); temp = die temperature in degC (default "
        f"{p['temperature_C']:.6g}), valid {p['temp']['range_C'][0]:g}..{p['temp']['range_C'][1]:g}: modulus "
        f"{p['modulus_tc_per_K'] * 1e6:.4g} ppm/K, thermal noise k_B T"
    ]
    visc = p["temp"].get("viscosity")
    if visc:
        parts.append(f", squeeze film by {visc['law']} within {visc['max_rel_error']:.1e}")
    if p["temp"].get("film_branches"):
        parts.append(f" ({p['temp']['film_branches']})")
    if p["gaps"] and not gaps:
        parts.append("; no gap offsets in this form (the code model reads xs_z: use the B-source .lib)")
    for g in p["gaps"] if gaps else []:
        parts.append(
            f"; dg_{g['set']} (m) = gap increase of electrode set {g['set']}, exact as a shift of z, "
            f"valid |dg| <= {g['max_m']:.3g} (the fit's box moves by dg)"
        )
    if p.get("gaps_refused"):
        parts.append(f"; no gap offsets ({p['gaps_refused']})")
    parts.append(". Damping given as Q, zeta or Rayleigh keeps its N*s/m under escale and temp.")
    return "".join(parts)
