"""The loop's inputs as both back ends render them (netgen.testbench.sigma_delta.ngspice, .vacask):
the DC and tone per input port, the tone's unit, and the header line on the DC inputs."""

from __future__ import annotations

from ...model import MacroModel
from .balance import coord_index
from .loop import Design
from .signals import Tone

ACCEL_INPUTS = ("a_in", "a_x", "a_y")  # frame-acceleration ports a tone can drive (m/s^2)


def mechanical_inputs(model: MacroModel, d: Design, tone: Tone | None) -> list[tuple[str, float, Tone | None]]:
    """(port, DC value, tone or None) per input port of the model: the design's DC inputs (the
    disk: gravity on f_z), the optional tone on its port (f_<q>, or a_in), 0 on the others.
    Both benches format these in their own source syntax."""
    port = None if tone is None else (tone.coord if tone.coord in ACCEL_INPUTS else f"f_{tone.coord}")
    out = [
        (f"f_{c.name}", d.inputs.get(f"f_{c.name}", 0.0), tone if port == f"f_{c.name}" else None)
        for c in model.coordinates
    ]
    driven = {p for p, _, _ in out}
    return out + [
        (p["name"], d.inputs.get(p["name"], 0.0), tone if port == p["name"] else None)
        for p in model.ports()
        if p["kind"].endswith("_in") and p["name"] not in driven
    ]


def tone_unit(model: MacroModel, tone: Tone) -> str:
    """The unit of a tone's amplitude: its f_ port's, or m/s^2 on a_in (a ValueError if the model
    has no such input)."""
    if tone.coord == "a_in":
        if not model.acceleration:
            raise ValueError(f"model {model.name} has no a_in port (structure: [coordinates] acceleration_port = true)")
        return "m/s^2"
    if tone.coord in ACCEL_INPUTS:
        if tone.coord not in model.inertial.participation:
            raise ValueError(f"model {model.name} has no {tone.coord} port (structure: [coordinates] inertial)")
        return "m/s^2"
    return model.coordinates[coord_index(model, tone.coord)].port_units[2]


def input_text(model: MacroModel, d: Design) -> str:
    """One comment line on the DC inputs and the channel they load, for the netlist headers."""
    units = {f"f_{c.name}": c.port_units[2] for c in model.coordinates} | {a: "m/s^2" for a in ACCEL_INPUTS}
    dc = ", ".join(f"{p} = {v:.6g} {units.get(p, '')}" for p, v in d.inputs.items()) or "none"
    b = d.balance
    return (
        f"DC inputs: {dc}; balanced on {b['channel']} by a mean bit of "
        f"{d.channels[b['index']]['bit_mean_needed']:+.4f} (m = {b['mass']:.6g} SI, DC force {b['dc_force_n']:.6g} N)."
    )
