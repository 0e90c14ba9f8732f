"""The build report <name>_report.html: one self-contained page (no external resources, figures
inline as SVG or base64 PNG) a designer opens instead of the JSON, the PNGs and a netlist header.

Everything on it is read from the MacroModel (the layout drawn to scale from `model.layout`,
netgen.geometry.layout.drawing) and from the figures the build wrote; no physics here. Every
number shown also sits, at full precision, in the `data-value` attribute of its table cell, so a
reader (tests/test_report.py) can check the page against the JSON. Text from input files is
HTML-escaped by the template (`|e`)."""

from __future__ import annotations

import base64
import math
from pathlib import Path

from ..core.files import write_atomic
from ..core.templating import render
from ..model import MacroModel

SIDE_COLOURS = {"above": "#c0392b", "below": "#2471a3", "in_plane": "#1e8449"}
FILES = {  # what each emitted file is, by its ending (the figures: netgen.build.figure_names)
    ".lib": "ngspice .subckt (behavioural sources)",
    "_xspice.lib": "ngspice .subckt with the compiled netgen_es code model",
    "_osdi.lib": "ngspice .subckt instantiating the compiled Verilog-A module",
    ".va": "Verilog-A module",
    ".osdi": "compiled Verilog-A module (openvaf-r)",
    ".json": "the model (MacroModel JSON): every number on this page",
    ".sym": "Xschem symbol",
    "_tb.sch": "Xschem example testbench",
    ".kicad_sym": "KiCad symbol library",
    "_fit_errors.png": "figure: capacitance fit errors",
    "_modes.png": "figure: mode shapes",
    "_small_angle.png": "figure: small-angle kinematics error",
    "_calibration.json": "electrostatic calibration report",
    "_calibration.png": "figure: electrostatic calibration",
}
LABEL_SHIFT = {"above": -0.6, "below": 1.2}  # font heights: labels of stacked electrodes apart
SUFFIXES = sorted(FILES, key=len, reverse=True)  # the longest ending that matches names a file


def cell(value: float, fmt: str = ".6g") -> dict:
    """A numeric table cell: the shown text and the exact value."""
    return {"text": format(value, fmt), "value": repr(float(value))}


def describe(model: MacroModel, name: str) -> str:
    """What an emitted file is (from its ending after the model name)."""
    rest = name[len(model.name) :] if name.startswith(model.name) else name
    return next((FILES[s] for s in SUFFIXES if rest == s), "")


def layout_svg(model: MacroModel, width: float = 640.0) -> dict | None:
    """The conductor outline and the electrodes' overlap pieces as SVG paths in um (y up), with
    the viewBox, a scale bar of a round length and each electrode's label at its pieces' centre."""
    lay = model.layout
    if not lay:
        return None
    um = 1e6
    xs = lay["conductor"][0] + [v for e in lay["electrodes"] for p in e["pieces"] for v in p[0]]
    ys = lay["conductor"][1] + [v for e in lay["electrodes"] for p in e["pieces"] for v in p[1]]
    x0, x1, y0, y1 = min(xs) * um, max(xs) * um, min(ys) * um, max(ys) * um
    span = max(x1 - x0, y1 - y0)
    pad = 0.08 * span

    def path(line: list[list[float]]) -> str:
        return " ".join(f"{'M' if k == 0 else 'L'}{x * um:.4g},{-y * um:.4g}" for k, (x, y) in enumerate(zip(*line)))

    electrodes = []
    for e in lay["electrodes"]:
        px = [v for p in e["pieces"] for v in p[0]]
        py = [v for p in e["pieces"] for v in p[1]]
        electrodes.append(
            {
                "name": e["name"],
                "colour": SIDE_COLOURS.get(e["side"], "#7d3c98"),
                "paths": [path(p) for p in e["pieces"]],
                "x": f"{um * sum(px) / max(len(px), 1):.4g}",
                "y": f"{-um * sum(py) / max(len(py), 1) + LABEL_SHIFT.get(e['side'], 0.0) * span / 45:.4g}",
                "dash": f"{span / 100:.3g}" if e["side"] == "below" else "none",
            }
        )
    bar = 10 ** math.floor(math.log10(span / 3))
    return {
        "box": f"{x0 - pad:.4g} {-y1 - pad:.4g} {x1 - x0 + 2 * pad:.4g} {y1 - y0 + 2 * pad:.4g}",
        "height": round(width * (y1 - y0 + 2 * pad) / (x1 - x0 + 2 * pad)),
        "width": round(width),
        "conductor": path(lay["conductor"]),
        "electrodes": electrodes,
        "stroke": f"{span / 400:.3g}",
        "font": f"{span / 45:.3g}",
        "bar": {"x": f"{x0:.4g}", "y": f"{-y0 + pad / 2:.4g}", "length": f"{bar:g}", "text": f"{bar:g} um"},
        "sides": SIDE_COLOURS,
    }


def warnings(model: MacroModel) -> list[str]:
    """Every warning the model carries: a missed fit tolerance, the validity box, rotations whose
    small-angle error passes its limit, a narrowed sampling range."""
    out = [model.fit_warning()] if model.fit_warning() else []
    out.append(model.to_dict()["validity"]["warning"])
    small = model.report.get("small_angle") or {}
    out += [
        f"small-angle kinematics: {r['coordinate']} passes {small['limit']:.1%} displacement error before touching "
        f"(at {small['threshold_rad'] * 1e3:.3g} mrad; touching at {r['touching_rad'] * 1e3:.3g} mrad)"
        for r in small.get("rotations", [])
        if r["exceeds_0p1_percent"]
    ]
    if "range_narrowed_from" in model.sampling:
        out.append(
            f"[sampling] range narrowed to {model.sampling['range']:g} from {model.sampling['range_narrowed_from']:g} "
            "(the default box reached an electrode)"
        )
    return out


def rows(model: MacroModel) -> dict:
    """The tables: coordinates, electrodes, dielectric layers, fits, contact, damping."""
    coords = [
        {
            "name": c.name,
            "kind": c.kind,
            "label": c.label,
            "unit": c.unit,
            "xunit": c.port_units[0],
            "funit": c.port_units[2],
            "cells": [cell(c.scale), cell(c.mass), cell(c.stiffness), cell(c.damping), cell(c.frequency_hz)],
        }
        for c in model.coordinates
    ]
    electrodes = [
        {"name": e.name, "group": e.group, "side": e.side, "cells": [cell(e.gap), cell(e.area)]}
        for e in model.electrodes
    ]
    fits = [
        {
            "name": f.electrode,
            "terms": len(f.polys),
            "cells": [cell(f.c_ref), cell(f.max_rel_error, ".3e"), cell(f.rms_rel_error, ".3e")],
        }
        for f in model.capacitances
    ]
    contact = {k: cell(v) for k, v in model.contact.items() if isinstance(v, float)}
    damping = model.report.get("damping", {})
    layers = [  # netgen.build.dielectric_layers; none without the structure keys
        {
            "set": d["set"],
            "cells": [cell(d[k]) for k in ("thickness_m", "relative_permittivity", "effective_gap_m", "stop_gap_m")],
        }
        for d in model.report.get("electrostatics", {}).get("dielectric_layers", [])
    ]
    return {
        "coords": coords,
        "electrodes": electrodes,
        "fits": fits,
        "contact": contact,
        "damping": damping,
        "layers": layers,
    }


def page(model: MacroModel, files: list[str], figures: dict[str, bytes]) -> str:
    """The report's HTML text: `files` the names the build wrote, `figures` PNG name -> bytes."""
    pngs = {k: base64.b64encode(v).decode("ascii") for k, v in figures.items()}
    return render(
        "report/model.html.j2",
        m=model,
        layout=layout_svg(model),
        warnings=warnings(model),
        files=[{"name": f, "what": describe(model, f)} for f in files],
        ports=model.ports(),
        pngs=pngs,
        pull_in=model.report.get("pull_in"),
        **rows(model),
    )


def write(model: MacroModel, folder: Path, written: list[Path]) -> Path:
    """Write <name>_report.html into `folder` beside the files `written` (their PNGs inline)."""
    figures = {p.name: p.read_bytes() for p in written if p.suffix == ".png"}
    path = folder / f"{model.name}_report.html"
    write_atomic(path, page(model, [p.name for p in written] + [path.name], figures))
    return path
