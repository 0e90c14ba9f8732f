"""Xschem's forms of a model (--format xschem): a symbol <name>.sym with one pin per `.subckt`
port in the card's order (electrodes and the conductor on the left, mechanical ports on the right,
units in the pin labels) that instantiates the subcircuit of <name>.lib, and an example testbench
<name>_tb.sch driving it as examples/levitated_disk_tb.cir does. Only the MacroModel's ports, names
and masses are read (no physics here); every name is an identifier (common.check_names), so no
text from input files reaches the files but as those names.

The files use Xschem's file format 1.2 (doc/xschem_man/developer_info.html of Xschem) with both
the `G` and the `K` global property, so Xschem 2.8.1 (Debian 12) and 3.x read the same symbol;
`type=primitive` makes the netlister write the instance line only (the .lib holds the .subckt).
"""

from __future__ import annotations

from ..core.templating import render
from ..model import MacroModel
from .common import check_names

PITCH = 20  # pin spacing, Xschem's default grid
STUB = 20  # pin line length outside the body
CHAR = 7  # width of one label character at text size 0.2 (Xschem units), for the body width
GRAVITY = 9.81  # m/s^2: the testbench's load (a_in = 9.81 is gravity: MacroModel.to_dict)
PER_ROW = 8  # sources per row in the testbench
ELECTRICAL = ("electrode", "conductor")
DIRECTION = {"electrode": "inout", "conductor": "inout", "displacement_out": "out"}  # else "in"


def snap(value: float) -> int:
    """Up to the next multiple of 10 (Xschem's snap)."""
    return int(-(-value // 10) * 10)


def pins(model: MacroModel) -> list[dict]:
    """Every port in the .subckt card's order with its side (-1 left, +1 right), pin end point
    (x, y), direction and label 'name [unit]'."""
    ports = model.ports()
    width = snap(10 + CHAR * max(len(f"{p['name']} [{p['unit']}]") for p in ports))
    rows = {-1: 0, 1: 0}
    out = []
    for number, p in enumerate(ports, start=1):
        side = -1 if p["kind"] in ELECTRICAL else 1
        rows[side] += 1
        out.append(
            {
                "name": p["name"],
                "number": number,
                "side": side,
                "x": side * (width + STUB),
                "edge": side * width,
                "y": rows[side] * PITCH,
                "dir": DIRECTION.get(p["kind"], "in"),
                "label": f"{p['name']} [{p['unit']}]",
                "kind": p["kind"],
            }
        )
    return out


def symbol(model: MacroModel) -> str:
    """The <name>.sym text."""
    check_names(model)
    ps = pins(model)
    width = abs(ps[0]["edge"])
    bottom = (max(sum(p["side"] == s for p in ps) for s in (-1, 1)) + 1) * PITCH
    return render("xschem/symbol.sym.j2", model=model.name, pins=ps, width=width, bottom=bottom)


def drives(model: MacroModel) -> list[tuple[str, float]]:
    """The testbench's source on every input port (examples/levitated_disk_tb.cir): electrodes and
    conductor at 0 V, gravity on a_in (9.81 m/s^2) when the model has it, else on f_z as -m g in
    the port's unit when z is a translation, every other f_ port at 0 (an f_ port must be driven)."""
    ports = model.ports()
    names = {p["name"] for p in ports}
    gravity: dict[str, float] = {}
    z = next((c for c in model.coordinates if c.name == "z" and c.unit == "m"), None)
    if "a_in" in names:
        gravity["a_in"] = GRAVITY
    elif z is not None:
        _, _, _, per_volt = z.port_units
        gravity["f_z"] = float(f"{-z.mass * GRAVITY / per_volt:.6g}")
    return [(p["name"], gravity.get(p["name"], 0.0)) for p in ports if p["kind"] != "displacement_out"]


def measured(model: MacroModel) -> str:
    """The displacement port the testbench measures at 20 us: x_z if there is one, else the first."""
    outs = [p["name"] for p in model.ports() if p["kind"] == "displacement_out"]
    return "x_z" if "x_z" in outs else outs[0]


def testbench(model: MacroModel) -> str:
    """The <name>_tb.sch text: the symbol with a labelled wire on every pin, a source per input in
    rows below it, and a code block with the .include of <name>.lib, the transient and a .meas."""
    check_names(model)
    ps = pins(model)
    bottom = (max(sum(p["side"] == s for p in ps) for s in (-1, 1)) + 2) * PITCH
    sources = [
        {
            "port": port,
            "value": f"{value:.6g}",
            "x": (k % PER_ROW) * 120 - 420,
            "y": bottom + 100 + (k // PER_ROW) * 160,
        }
        for k, (port, value) in enumerate(drives(model))
    ]
    return render(
        "xschem/tb.sch.j2",
        model=model.name,
        pins=ps,
        sources=sources,
        measured=measured(model),
        code_x=abs(ps[0]["x"]) + 200,
    )


def outputs(model: MacroModel, cpu: str = "") -> dict[str, str | bytes]:
    """Beside the symbol: the example testbench (`cpu`, the compile target of emit.Outputs, unused:
    nothing is compiled)."""
    return {"_tb.sch": testbench(model)}
