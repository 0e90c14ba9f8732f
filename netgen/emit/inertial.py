"""The inertial inputs as emitted terms (shared by the .lib, _xspice.lib and .va emitters): the
frame acceleration ports a_x, a_y (linear: -P a into the velocity node, like a_in) and the rate
ports w_x, w_y, w_z (Coriolis -Omega_k G_k q', centrifugal -Omega_k Omega_l (S_kl q + c_kl):
products of node voltages, one behavioural expression per coordinate). Everything is read from
the MacroModel's Inertial (netgen.model.inertial); the scaling is every force's, 1/(M L w_s^2)."""

from __future__ import annotations

from ..model import MacroModel
from . import process
from .common import force_gain, num


def acceleration_gains(model: MacroModel, ws: float, braces: bool = True) -> list[dict]:
    """Per in-plane acceleration port and coordinate with a non-zero participation P: the gain
    P / (M L w_s^2) from the port (m/s^2) into the velocity node (the force -P a), times P's process
    law where the model has one (netgen.emit.process.inertial_scale; ngspice text in `braces`)."""
    rows = []
    for port, p in model.inertial.participation.items():
        for v, (c, g) in enumerate(zip(model.coordinates, p)):
            if g != 0.0:
                scale = process.inertial_scale(model, "participation", port, v)
                gain = process.scaled_number(num(g * force_gain(c, ws)), scale, braces)
                rows.append({"port": port, "coord": c.name, "gain": gain, "participation": f"{g:.6g}"})
    return rows


def rate_expressions(model: MacroModel, ws: float, access: str = "v({})") -> list[dict]:
    """Per coordinate that a rate input moves: {coord, expr}, the scaled force of the rate ports on
    its velocity node (`access` formats a node voltage: v(n) for ngspice, V(n) for Verilog-A); each
    coefficient times its process law where the model has one (netgen.emit.process.inertial_scale)."""
    inert, coords = model.inertial, model.coordinates
    braces = access == "v({})"

    def law(kind: str, key: str, v: int, w: int | None, g: float) -> str:
        return process.scaled_number(num(g), process.inertial_scale(model, kind, key, v, w), braces) if g else ""

    rows = []
    for v, c in enumerate(coords):
        a = force_gain(c, ws)
        parts = []
        for k, g in inert.gyroscopic.items():  # -Omega_k G q', q' = L w_s u
            lin = [
                (law("gyroscopic", k, v, w, -g[v][w] * cw.scale * ws * a), f"u_{cw.name}")
                for w, cw in enumerate(coords)
            ]
            parts += product([f"w_{k}"], lin, "", access)
        for pair, s in inert.centrifugal.items():  # -Omega_k Omega_l (S q + c), q = L xs
            lin = [
                (law("centrifugal", pair, v, w, -s[v][w] * cw.scale * a), f"xs_{cw.name}")
                for w, cw in enumerate(coords)
            ]
            force = -inert.centrifugal_force.get(pair, [0.0] * len(coords))[v] * a
            const = law("centrifugal_force", pair, v, None, force) if pair in inert.centrifugal_force else ""
            parts += product([f"w_{pair[0]}", f"w_{pair[1]}"], lin, const, access)
        if parts:
            rows.append({"coord": c.name, "expr": " + ".join(parts).replace("+ -", "- ")})
    return rows


def product(rates: list[str], lin: list[tuple[str, str]], const: str, access: str) -> list[str]:
    """The term rates[0]*rates[1]*(sum gain*node + const) as text ("" gains and const: zero), []
    when it is zero."""
    terms = [f"{g}*{access.format(n)}" for g, n in lin if g]
    if const:
        terms.append(const)
    if not terms:
        return []
    factor = "*".join(access.format(r) for r in rates)
    return [f"{factor}*({' + '.join(terms)})".replace("+ -", "- ")]


def header_lines(model: MacroModel) -> list[str]:
    """The header's description of the inertial input ports the model has beyond a_in."""
    lines = []
    if model.inertial.participation:
        ports = ", ".join(model.inertial.participation)
        lines.append(
            f"{ports}: frame acceleration along x / y IN (high impedance), 1 V = 1 m/s^2; each coordinate "
            "feels -P a (P = int rho Phi . e dV, the model JSON's inertial_inputs)."
        )
    if model.inertial.gyroscopic:
        ports = ", ".join(f"w_{k}" for k in model.inertial.gyroscopic)
        lines.append(
            f"{ports}: frame rotation rate about x / y / z IN (high impedance), 1 V = 1 rad/s, taken as slowly "
            "varying (no Euler term); each coordinate feels the Coriolis force -sum_k w_k G_k dq/dt and the "
            "centrifugal force -sum_kl w_k w_l (S_kl q + c_kl) (the model JSON's inertial_inputs)."
        )
    if lines and process.declared(model, "etch") and model.process.get("inertial"):
        law = (
            "X ((1 - f) tscale R1(etch) + f tscale^3 R3(etch)), f its rotary (rho t^3 / 12) share, R1 and R3 "
            "the etched body's ratios of its two parts"
            if process.declared(model, "tscale")
            else "X R(etch), R the etched body's ratio"
        )
        lines.append(
            f"Every P, G, S and c entry above is {law} (cubics in etch / 1 um, the model JSON's "
            "process.inertial: integrals of rho over the etched outline, holes and fingers); escale leaves them."
        )
    elif lines and process.enabled(model) and model.process.get("inertial"):
        lines.append(
            "Under tscale every P, G, S and c entry above is X ((1 - f) tscale + f tscale^3), f its rotary "
            "(rho t^3 / 12) share (the model JSON's process.inertial; exact: integrals of rho over the plate's "
            "thickness); etch and escale leave them (the plate outline is not etched)."
        )
    return lines
