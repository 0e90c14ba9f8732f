"""The run's report.html: one self-contained page of a sigma-delta run (netgen.emit.report is
the build's): held or not, the per-channel in-band figures and latch quality, the force balance,
the coordinates' range, the loop's design, the thermal floor, and the spectra and coordinate
figures inline (base64 PNG). Everything is read from the run's summary (the summary.json it
writes); every number also sits at full precision in its cell's `data-value` attribute."""

from __future__ import annotations

import base64
from pathlib import Path

from ...core.files import write_atomic
from ...core.templating import render

FIGURES = ("spectra.png", "coordinates.png")


def scalar(value: object) -> bool:
    return value is None or isinstance(value, (bool, int, float, str))


def cell(value: object) -> dict:
    """A table cell: shown text, and the exact value of a number (None for other values)."""
    if isinstance(value, float):
        return {"text": f"{value:.6g}", "value": repr(value)}
    if isinstance(value, int) and not isinstance(value, bool):
        return {"text": str(value), "value": str(value)}
    return {"text": "-" if value is None else str(value), "value": None}


def tree(value: object) -> object:
    """A nested entry for the template: dicts and lists of dicts as tables, other lists as text."""
    if isinstance(value, dict):
        return {"rows": [(str(k), tree(v)) for k, v in value.items()]}
    if isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
        return {"rows": [(str(k), tree(v)) for k, v in enumerate(value)]}
    if isinstance(value, list):
        return cell(", ".join(f"{v:.6g}" if isinstance(v, float) else str(v) for v in value))
    return cell(value)


def channel_table(summary: dict) -> dict:
    """One row per channel, one column per scalar entry any channel has (in first-seen order)."""
    channels = summary.get("channels", {})
    keys: list[str] = []
    for entries in channels.values():
        keys += [k for k, v in entries.items() if scalar(v) and k not in keys]
    rows = [(name, [cell(entries.get(k)) for k in keys]) for name, entries in channels.items()]
    return {"keys": keys, "rows": rows}


def page(summary: dict, figures: dict[str, bytes]) -> str:
    """The report's HTML text from the run's summary and its PNG figures (name -> bytes)."""
    design = summary.get("design", {})
    return render(
        "sigma_delta/report.html.j2",
        s=summary,
        held=summary.get("levitation", {}),
        channels=channel_table(summary),
        balance=tree(summary.get("gravity_balance", {})),
        coordinates=tree(summary.get("coordinates", {})),
        loop=tree({k: design[k] for k in design if k != "table"}),
        thermal=tree(summary.get("thermal_noise", {})),
        run=tree({k: v for k, v in summary.items() if scalar(v)}),
        pngs={k: base64.b64encode(v).decode("ascii") for k, v in figures.items()},
    )


def write(out: Path, summary: dict) -> Path:
    """Write report.html into the run folder `out` (its figures inline, those it has)."""
    figures = {n: (out / n).read_bytes() for n in FIGURES if (out / n).exists()}
    path = out / "report.html"
    write_atomic(path, page(summary, figures))
    return path
