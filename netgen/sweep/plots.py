"""The sweep's figure: the chosen column against x, one line per combination of the other lists."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..core.plots import plt, save
from ..core.units import UnitError, parse_quantity
from .spec import TESTBENCH, Sweep, kind_of


def _number(v: Any) -> float | None:
    if isinstance(v, bool):
        return float(v)
    if isinstance(v, (int, float)):
        return float(v)
    if isinstance(v, str) and v:
        kind = kind_of(v)
        try:
            return parse_quantity(v, kind)
        except UnitError:
            return None
    return None


def plot(path: Path, rows: list[dict], sweep: Sweep) -> Path | None:
    """PNG of the chosen figure against x: one line per combination of the other swept lists,
    Monte Carlo draws as points; failed runs as crosses on the x axis."""
    others = [p.name for p in sweep.parameters if p.values is not None and p.name != sweep.x]
    mc = any(p.distribution for p in sweep.parameters)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    groups: dict[tuple, list[tuple[float, float]]] = {}
    failed = []
    for r in rows:
        x = _number(r.get(sweep.x))
        if x is None:
            continue
        if r["status"] != "ok" or r.get(sweep.figure) is None:
            failed.append(x)
            continue
        groups.setdefault(tuple(r.get(o) for o in others), []).append((x, float(r[sweep.figure])))
    for g, pts in groups.items():
        pts.sort()
        label = ", ".join(f"{o} = {v}" for o, v in zip(others, g)) or None
        ax.plot(*zip(*pts), "o" if mc else "o-", ms=4, label=label)
    if failed:
        ax.plot(failed, [ax.get_ylim()[0] if groups else 0] * len(failed), "rx", label="failed")
    unit = TESTBENCH.get(sweep.x, ("",))[0]
    ax.set_xlabel(f"{sweep.x}" + (f" ({UNITS_SI.get(unit, '')})" if UNITS_SI.get(unit) else ""))
    ax.set_ylabel(sweep.figure)
    xs = [x for pts in groups.values() for x, _ in pts]
    if xs and min(xs) > 0 and max(xs) >= 10 * min(xs):
        ax.set_xscale("log")
    ax.grid(True, which="both", lw=0.3)
    if any(lbl for lbl in ax.get_legend_handles_labels()[1]):
        ax.legend(fontsize=8)
    ax.set_title(f"{sweep.figure} vs {sweep.x} ({len(rows)} runs, {len(failed)} failed)")
    fig.tight_layout()
    return save(fig, path, dpi=110)


UNITS_SI = {"time": "s", "frequency": "Hz", "length": "m"}
