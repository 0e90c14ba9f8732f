"""What every emitter shares: number and polynomial text, node names, the model time scale and
force scaling, the header tables, the contact stops and the nonlinear restoring forces, all read
from the MacroModel (no physics here)."""

from __future__ import annotations

import math

import numpy as np

from ..core.text import comment_text, is_identifier
from ..fit.polynomial import Polynomial
from ..model import MacroModel


def num(value: float) -> str:
    """Deterministic, round-trip-safe number text for netlists."""
    if not math.isfinite(value):
        raise ValueError(f"non-finite value {value} cannot be emitted")
    return repr(float(value))


def poly_expr(poly: Polynomial, names: list[str], drop: float = 0.0, access: str = "v({})") -> str:
    """Polynomial as explicit products of node voltages, `access` formatting each (ngspice's ^ is |x|^y)."""
    terms = []
    for e, c in zip(poly.exponents, poly.coeffs):
        if c == 0.0 or abs(c) < drop:
            continue
        factors = [access.format(names[v]) for v in range(len(names)) for _ in range(int(e[v]))]
        terms.append("*".join([num(c)] + factors))
    if not terms:
        return "0"
    return " + ".join(terms).replace("+ -", "- ")


def time_scale(model: MacroModel) -> float:
    """Model time scale w_s (rad/s): the geometric mean of the modal frequencies, else 1e6."""
    freqs = [c.frequency_hz for c in model.coordinates if c.frequency_hz > 0]
    f = math.exp(float(np.mean(np.log(freqs)))) if freqs else 1e6 / (2 * math.pi)
    return 2 * math.pi * f


def force_gain(c, ws: float) -> float:
    """Scaled velocity rate per newton (or N*m) of generalized force on coordinate c:
    d u / d tau = F / (m L w_s^2), the factor every force term of its velocity integrator carries."""
    return 1.0 / (c.mass * c.scale * ws * ws)


def node(electrode: str, k: int) -> str:
    """Name of the node carrying term k of an electrode's capacitance polynomial(s)."""
    return f"p_{electrode}_{k + 1}"


def dv2_node(electrode: str) -> str:
    """Node carrying (V_electrode - V_plate)^2, shared by the force terms of one electrode."""
    return f"dv2_{electrode}"


def y_node(electrode: str, k: int) -> str:
    """Node carrying (V_e - V_plate)^2 / P_k^2: the force terms are linear in it."""
    return f"y_{electrode}_{k + 1}"


def g_node(electrode: str, k: int) -> str:
    """Node carrying 1/P_eff of plate term k (the term's capacitance over c_ref)."""
    return f"g_{electrode}_{k + 1}"


def c_node(electrode: str) -> str:
    """Node carrying (C_i(q) - C_i(0)) / c_ref = sum_k g_k - sum_k 1/P_k(0)."""
    return f"c_{electrode}"


def unit_load(n: str) -> str:
    """The 1 ohm to ground that makes node n the sum of the currents fed into it, noiseless (noisy=0): its
    thermal noise is no physics of the device, and .noise would report it (through the forces under bias)."""
    return f"R{n} {n} 0 1 noisy=0"


def rest_capacitance(f, ncoords: int) -> float:
    """C_i(0) / c_ref = sum_k 1/P_k(0) of a plate fit (at rest no term is clamped)."""
    zero = np.zeros((1, ncoords))
    return float(sum(1.0 / poly(zero)[0] for poly in f.polys))


INPUT_KINDS = ("force_in", "acceleration_in", "rate_in")  # the mechanical input ports' kinds (MacroModel.ports)
# every mechanical input (f_<q>, a_in, a_x, w_z, ...) is tied to ground inside the model by this conductance
# (noiseless: a VCCS in ngspice, a plain contribution in Verilog-A), so an unused, open input reads
# 0 instead of leaving the matrix singular; an input driven through a source resistance R_s reads
# low by R_s * PORT_TIE (1e-6 for 1 Mohm), one driven by an ideal source not at all
PORT_TIE = 1e-12


def input_ties(model: MacroModel) -> list[str]:
    """The mechanical input ports that carry the PORT_TIE to ground, in port order."""
    return [p["name"] for p in model.ports() if p["kind"] in INPUT_KINDS]


def si(value: float, unit: str) -> str:
    return f"{value:.6g} {unit}".strip()


def check_names(model: MacroModel) -> None:
    """Every name an emitter or testbench writes outside comments (model, plate, electrodes,
    coordinates) is an identifier (netgen.core.text.is_identifier): the readers refuse anything else,
    this is the emitters' own guard. Free text (description, source, labels) goes only through
    the templates' `comment` / `comment_text` filters (netgen.core.text.comment_lines, comment_text)."""
    names = [
        model.name,
        model.plate,
        *(e.name for e in model.electrodes),
        *(c.name for c in model.coordinates),
        *(f.electrode for f in model.capacitances),
    ]
    bad = [n for n in names if not is_identifier(n)]
    if bad:
        raise ValueError(
            f"names not usable in a netlist: {', '.join(comment_text(repr(n)) for n in bad)}; "
            "rename the electrodes/coordinates (letters, digits, '_', starting with a letter)"
        )


def check_fits(model: MacroModel) -> None:
    """The forms render each fit's c_ref and polynomials and the process laws from the instance
    parameters: a fit carrying a factor (a process point's copy, netgen.sweep.point.at_point) is
    refused, its factor would be dropped and the point applied twice."""
    bad = [f.electrode for f in model.capacitances if f.factor is not None]
    if bad:
        raise ValueError(
            f"the capacitance fits of {', '.join(bad)} carry a process point's factor (a sweep's model at a "
            "point): emit the nominal model and give the point as instance parameters"
        )


def header_context(model: MacroModel) -> dict:
    """Template context shared by the dialects: header tables, time scale, fit form, ports, couplings."""
    check_names(model)
    check_fits(model)
    coords = []
    for c in model.coordinates:
        xu, _, fu, _ = c.port_units
        mass_unit = "kg" if c.unit == "m" else "kg*m^2"
        stiff_unit = "N/m" if c.unit == "m" else "N*m/rad"
        coords.append(
            {
                "name": c.name,
                "kind": c.kind + (f" {c.label}" if c.label else ""),
                "xunit": xu,
                "funit": fu,
                "scale_text": si(c.scale, c.unit),
                "mass_text": si(c.mass, mass_unit),
                "stiff_text": si(c.stiffness, stiff_unit),
                "freq_text": f"{c.frequency_hz:.6g}" if c.frequency_hz else "-",
            }
        )
    fits = [
        {
            "electrode": f.electrode,
            "c_ref_text": f"{f.c_ref:.6e}",
            "max_text": f"{f.max_rel_error:.3e}",
            "rms_text": f"{f.rms_rel_error:.3e}",
            "terms": len(f.polys),
        }
        for f in model.capacitances
    ]
    fit_form = {
        "plates": "C = c_ref * sum_k 1/P_k(xs): K effective parallel plates",
        "inverse": "C = c_ref / P(xs): fit of 1/C",
        "direct": "C = c_ref * P(xs)",
    }[model.capacitances[0].target]
    degree = max(f.degree for f in model.capacitances)
    couplings = coupling_rows(model)
    ct = model.contact
    contact_text = (
        ""
        if not ct
        else (
            f"Contact: below {ct['knee']:g} of its value at xs = 0 each P_k is clamped smoothly (never under "
            f"{ct['floor']:g}), and {len(ct.get('points', []))} stop points carry a penalty spring "
            f"{ct['stiffness']:.4g} N/m with damping {ct['damping']:.4g} N*s/m, engaged over {ct['smoothing']:g} of the gap"
            " (lone coordinates stop at xs = +-1; see netgen/model/contact.py for the model and its limits)."
        )
    )
    contact_text += layer_text(model)
    tie_text = (
        f"Mechanical inputs are tied to ground inside by {PORT_TIE:g} S (noiseless): an open one reads 0; "
        f"through a source resistance R_s one reads low by R_s * {PORT_TIE:g} (1e-6 for 1 Mohm)."
    )
    return {
        "m": model,
        "ports": model.ports(),
        "coords": coords,
        "kinematics_text": kinematics_text(model),
        "fits": fits,
        "couplings": couplings,
        "coupling_text": coupling_text(model),
        "ws_text": f"{time_scale(model):.6g}",
        "fit_form": fit_form,
        "degree": degree,
        "contact_text": contact_text,
        "ties": input_ties(model),
        "tie": num(PORT_TIE),
        "tie_text": tie_text,
        "fit_warning": model.fit_warning(),
        "damping_text": damping_text(model),
    } | box_texts(model)


def box_texts(model: MacroModel) -> dict:
    """The sampled box in the header: one half-width for every coordinate, or each coordinate's own
    (a [sampling] range table; the JSON's sampling.coordinate_range)."""
    r, per = model.sampling["range"], model.sampling.get("coordinate_range")
    if not per:
        return {"box_text": f"{r * 100} %", "keep_text": f"|xs| below {r}"}
    pct = ", ".join(f"{n} {v * 100:.4g} %" for n, v in per.items())
    each = ", ".join(f"{n} {v:.4g}" for n, v in per.items())
    return {"box_text": f"({pct})", "keep_text": f"each |xs| within its own half-width ({each})"}


def layer_text(model: MacroModel) -> str:
    """The header's dielectric layers (netgen.build.dielectric_layers), if any: the plate terms
    see the series gap, the stops sit on the layer's surface."""
    layers = model.report.get("electrostatics", {}).get("dielectric_layers", [])
    if not layers:
        return ""
    parts = [
        f"{d['set']} {d['thickness_m'] * 1e6:.4g} um eps_r {d['relative_permittivity']:.4g} "
        f"(effective gap {d['effective_gap_m'] * 1e6:.4g} um, stop at {d['stop_gap_m'] * 1e6:.4g} um)"
        for d in layers
    ]
    return (
        " Dielectric layers on the electrodes (in series with the air gap; the plate stops on the layer): "
        + ", ".join(parts)
        + "."
    )


def damping_text(model: MacroModel) -> str:
    """The header's damping state: a model without [damping] is undamped (Q infinite), which a
    testbench must know (free ringing, a bang-bang loop lets the mass wander)."""
    damped = [c for c in model.coordinates if c.damping > 0 or c.film]
    if not damped:
        return "Damping: none ([damping] not given): every coordinate is undamped, Q infinite."
    parts = []
    for c in damped:
        q = math.sqrt(c.stiffness * c.mass) / c.damping if c.damping > 0 and c.stiffness > 0 else math.inf
        film = f" + {len(c.film)} squeeze-film branch(es)" if c.film else ""
        parts.append(f"{c.name} {c.damping:.4g}{film} (Q {q:.4g})")
    return "Damping (N*s/m or N*m*s/rad, Q at zero bias): " + ", ".join(parts) + "."


def kinematics_text(model: MacroModel) -> str:
    """The header's statement of the rigid-body kinematics and where its small-angle error passes
    0.1 % (the build's report.small_angle: models with in-plane coordinates)."""
    if "small_angle" not in model.report:  # models without in-plane coordinates: as before
        return ""
    text = (
        "Kinematics: small-angle rigid body, at a point (X, Y) of the mid-plane u_x = x - rot_z*Y, "
        "u_y = y + rot_z*X, u_z = z + tilt_x*Y - tilt_y*X (first order in the angles)."
    )
    report = model.report.get("small_angle")
    if report:
        over = [r["coordinate"] for r in report["rotations"] if r["exceeds_0p1_percent"]]
        text += (
            f" Its displacement error passes {report['limit']:.1%} beyond |angle| = "
            f"{report['threshold_rad'] * 1e3:.3g} mrad"
            + (
                f"; within the touching amplitude of {', '.join(over)}"
                if over
                else "; not within any touching amplitude"
            )
            + " (report.small_angle in the model JSON)."
        )
    return text


def coupling_rows(model: MacroModel) -> list[dict]:
    """The constant electrode-electrode capacitors (MacroModel.coupling, upper triangle, non-zero):
    terminals a, b, the netlist value and the header's text (value in fF, and its spread over the
    calibration points when the model records one)."""
    names = [e.name for e in model.electrodes]
    spread = {tuple(r["pair"]): r for r in model.calibration.get("coupling_spread", [])}
    rows, used = [], set()
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            if not model.coupling[i, j]:
                continue
            s = spread.get((names[i], names[j]))
            extra = f" (+-{s['std'] * 1e15:.3g} fF over the calibration points)" if s else ""
            label = f"{names[i]}_{names[j]}"
            label = label if label not in used else f"{label}_{i + 1}_{j + 1}"  # a_b_c: (a_b, c) or (a, b_c)
            used.add(label)
            rows.append(
                {
                    "a": names[i],
                    "b": names[j],
                    "label": label,
                    "value": num(model.coupling[i, j]),
                    "text": f"Cc_{label} = {model.coupling[i, j] * 1e15:.6g} fF{extra}",
                }
            )
    return rows


def coupling_text(model: MacroModel) -> str:
    """Where the couplings and fringe coefficients came from (MacroModel.calibration), one line; "" without."""
    cal = model.calibration
    if not cal:
        return ""
    fringe = f", per-electrode fringe a + b ln(L/g) fitted at {cal['points']} point(s)" if cal.get("fringe") else ""
    return f"Calibration: {cal.get('source', 'given')}{fringe} (the model JSON's calibration entry)."


def noise_kelvin(model: MacroModel) -> float:
    """The model's own temperature (K), the [damping] temperature its damping was computed at: the
    thermal noise's T in every form (fluctuation-dissipation), not the simulator's circuit temperature."""
    return float(model.report.get("damping", {}).get("temperature_K", 300.0))


def noise_enabled(model: MacroModel, noise: bool | None) -> bool:
    """Emit thermal noise sources: the explicit option, else the structure's [damping] noise."""
    return model.report.get("damping", {}).get("noise", False) if noise is None else noise


def nonlinear_forces(
    model: MacroModel, state: list[str], access: str = "v({})", gain: list[float] | None = None
) -> list[str]:
    """Per coordinate v, the restoring force -(1/L_v) dU/dxs_v of the model's fitted strain energy
    U(xs) (J) as an explicit polynomial of the states, times gain[v] (default 1: SI force)."""
    poly = model.nonlinear_energy_polynomial()
    if poly is None:
        return []
    out = []
    for v, c in enumerate(model.coordinates):
        d = poly.derivative(v)
        factor = -(1.0 if gain is None else gain[v]) / c.scale
        out.append(poly_expr(Polynomial(d.exponents, d.coeffs * factor), state, access=access))
    return out


def clamp_expr(expr: str, knee: float, floor: float) -> str:
    """P clamped from below (C1 at the knee, never under the floor); the text is valid ngspice and Verilog-A."""
    span = knee - floor
    return f"max({expr}, {num(floor)} + {num(span)}*exp(min({expr} - {num(knee)}, 0)/{num(span)}))"


def slope_expr(p: str, knee: float, floor: float) -> str:
    """dP_eff/dP of the clamp, from the clamped value p."""
    return f"min(1, ({p} - {num(floor)})/{num(knee - floor)})"


def stop_name(j: int) -> tuple[str, str]:
    """Nodes/variables of stop point j: penetration fraction and scaled penalty force."""
    return f"sg_{j + 1}", f"sf_{j + 1}"


def stop_constants(model: MacroModel) -> dict | None:
    """The contact stops' numbers (netgen.model.contact): smoothing delta, damping factor (c/k)/delta^2,
    and per stop point its direction a_j (in xs) and the SI force per unit penalty on each
    coordinate, gain_jv = -k gap^2 delta a_jv / L_v; None without stop points."""
    c = model.contact
    if not c.get("points"):
        return None
    delta = c["smoothing"]
    gains = [
        [
            -c["stiffness"] * pt["gap"] ** 2 * delta * a / model.coordinates[v].scale if a != 0.0 else 0.0
            for v, a in enumerate(pt["a"])
        ]
        for pt in c["points"]
    ]
    return {
        "delta": delta,
        "damp": c["damping"] / c["stiffness"] / delta**2,
        "a": [list(pt["a"]) for pt in c["points"]],
        "gain": gains,
    }


def contact_terms(
    model: MacroModel, access: str = "v({})", var: str = "v({})", offsets: list[str] | None = None
) -> tuple[list[dict], list[list[tuple[str, float]]]]:
    """Stop points as (penetration, penalty) expressions, and per coordinate the (variable, SI force
    per unit) pairs: F_v = sum_j gain_jv * sf_j, sf_j = (pen + (c/k) w dp/dt) / delta. `offsets`: per
    stop point a text appended to its penetration (a gap offset's - dg / gap_j, netgen.emit.process).
    Each point also carries the two parts of f_expr apart (spring, damping: netgen.emit.ngspice.context)."""
    points: list[dict] = []
    per_coord: list[list[tuple[str, float]]] = [[] for _ in model.coordinates]
    k = stop_constants(model)
    if k is None:
        return points, per_coord
    ws, delta = time_scale(model), k["delta"]
    xs = [access.format(f"xs_{c.name}") for c in model.coordinates]
    us = [access.format(f"u_{c.name}") for c in model.coordinates]
    for j, (pt, a_j, gain_j) in enumerate(zip(model.contact["points"], k["a"], k["gain"])):
        g, f = stop_name(j)
        used = [(v, a) for v, a in enumerate(a_j) if a != 0.0]
        gap_expr = " + ".join(f"{num(a)}*{xs[v]}" for v, a in used).replace("+ -", "- ") + " - 1"
        gap_expr += offsets[j] if offsets else ""
        r = f"min(max({var.format(g)}, 0), {num(delta)})"
        rate = " + ".join(f"{num(a * ws)}*{us[v]}" for v, a in used).replace("+ -", "- ")
        spring = f"({r}*{r}*{num(0.5 / delta)} + max({var.format(g)} - {num(delta)}, 0))*{num(1 / delta)}"
        damping = f"{num(k['damp'])}*{r}*({rate})"
        points.append(
            {
                "g": g,
                "g_expr": gap_expr,
                "f": f,
                "f_expr": f"{spring} + {damping}",
                "spring": spring,
                "damping": damping,
                "electrode": pt["electrode"],
            }
        )
        for v, _ in used:
            per_coord[v].append((f, gain_j[v]))
    return points, per_coord
