"""KiCad's form of a model (--format kicad): a symbol library <name>.kicad_sym (KiCad 6+
s-expression format, version 20211014) with one symbol whose pins are the `.subckt` ports in the
card's order (pin number k = port k, pin name = port name; electrodes and the conductor on the
left, mechanical ports on the right) and whose simulation fields point at the subcircuit of
<name>.lib: KiCad 7+'s Sim.Device / Sim.Library / Sim.Name / Sim.Pins and KiCad 6's
Spice_Primitive / Spice_Model / Spice_Lib_File / Spice_Node_Sequence. Only the MacroModel's port
list is read (no physics here); every name is an identifier (common.check_names), so no text from
input files reaches the file but as those names."""

from __future__ import annotations

from ..core.templating import render
from ..model import MacroModel
from .common import check_names

PITCH = 2.54  # mm, KiCad's pin grid
PIN = 2.54  # pin length
CHAR = 0.9  # mm per character of a pin name at 1.27 mm text, for the body width
ELECTRICAL = ("electrode", "conductor")
TYPE = {"electrode": "passive", "conductor": "passive", "displacement_out": "output"}  # else "input"


def mm(value: float) -> str:
    """A coordinate in mm as KiCad writes it (at most 4 decimals, no trailing zeros)."""
    v = round(value, 4)
    return f"{v:.4f}".rstrip("0").rstrip(".") if v else "0"


def pins(model: MacroModel) -> tuple[list[dict], float, float]:
    """The pins in port order (number, name, type, end point, angle: 0 points right into the
    body from the left side, 180 from the right), the body's half width and its half height."""
    ports = model.ports()
    left = [p for p in ports if p["kind"] in ELECTRICAL]
    rows = max(len(left), len(ports) - len(left))
    half_w = PITCH * round((2 + CHAR * max(len(p["name"]) for p in ports)) / PITCH)
    half_h = PITCH * (rows + 1) / 2
    seen = {-1: 0, 1: 0}
    out = []
    for number, p in enumerate(ports, start=1):
        side = -1 if p["kind"] in ELECTRICAL else 1
        y = half_h - PITCH * (1 + seen[side])
        seen[side] += 1
        out.append(
            {
                "number": number,
                "name": p["name"],
                "type": TYPE.get(p["kind"], "input"),
                "x": mm(side * (half_w + PIN)),
                "y": mm(y),
                "angle": 0 if side < 0 else 180,
            }
        )
    return out, half_w, half_h


def fields(model: MacroModel) -> list[tuple[str, str]]:
    """The simulation fields (both KiCad generations) after Reference, Value, Footprint, Datasheet."""
    ports = model.ports()
    return [
        ("Sim.Device", "SUBCKT"),
        ("Sim.Library", f"{model.name}.lib"),
        ("Sim.Name", model.name),
        ("Sim.Pins", " ".join(f"{k}={p['name']}" for k, p in enumerate(ports, start=1))),
        ("Spice_Primitive", "X"),
        ("Spice_Model", model.name),
        ("Spice_Lib_File", f"{model.name}.lib"),
        ("Spice_Node_Sequence", " ".join(str(k) for k in range(1, len(ports) + 1))),
        ("Spice_Netlist_Enabled", "Y"),
    ]


def symbol_library(model: MacroModel) -> str:
    """The <name>.kicad_sym text."""
    check_names(model)
    ps, half_w, half_h = pins(model)
    return render(
        "kicad/symbol.kicad_sym.j2",
        model=model.name,
        pins=ps,
        fields=[{"id": 4 + i, "key": k, "value": v} for i, (k, v) in enumerate(fields(model))],
        left=mm(-half_w),
        right=mm(half_w),
        top=mm(half_h),
        bottom=mm(-half_h),
        label_y=mm(half_h + 1.27),
        value_y=mm(-half_h - 1.27),
    )
