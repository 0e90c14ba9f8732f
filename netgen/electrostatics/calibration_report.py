"""The calibration report beside a build's netlists: the analytic extractor (uncalibrated and
calibrated) against the field solution per electrode and coordinate direction, and the
couplings with their spread (netgen.electrostatics.calibrated.CalibratedExtractor.report)."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import numpy as np

from ..core.files import write_atomic
from ..core.plots import plt, save


def summary(report: dict) -> dict:
    """Per electrode the worst |relative error| of C over the points and of its central difference
    per coordinate, uncalibrated and calibrated (what the figure shows)."""
    coords = report["coordinates"]
    out = {}
    for name, row in report["electrodes"].items():
        entry = {}
        for label in ("analytic", "calibrated"):
            entry[f"{label}_c_max_abs_rel_error"] = float(np.max(np.abs(row[f"{label}_c_rel_error"])))
            entry[f"{label}_dc_max_abs_rel_error"] = {
                coords[int(v)]: float(np.max(np.abs(e))) for v, e in row[f"{label}_dc_rel_error"].items()
            }
        out[name] = entry
    return out


def write(report: dict, json_path: Path, png_path: Path | None) -> list[Path]:
    """The report JSON (with its summary), and the PNG when png_path is given; returns the paths."""
    doc = report | {"summary": summary(report)}
    write_atomic(json_path, json.dumps(doc, indent=1, allow_nan=False) + "\n")
    return [json_path] + ([figure(doc, png_path)] if png_path is not None else [])


def figure(doc: dict, path: Path) -> Path:
    """Bars per electrode: |relative error| of C (left) and of dC along each coordinate (right),
    uncalibrated and calibrated; the couplings over C_i(0) (bottom)."""
    names, s = list(doc["electrodes"]), doc["summary"]
    x = np.arange(len(names))
    fig, axes = plt.subplots(3, 1, figsize=(max(6.0, 0.45 * len(names) + 2), 8.5))
    for k, label in enumerate(("analytic", "calibrated")):
        axes[0].bar(x + (k - 0.5) * 0.4, [100 * s[n][f"{label}_c_max_abs_rel_error"] for n in names], 0.4, label=label)
    axes[0].set_yscale("symlog", linthresh=1e-3)
    axes[0].set_ylabel("max |C - C_field| / C_field (%)")
    axes[0].legend(fontsize=8)
    coords = sorted({c for n in names for c in s[n]["analytic_dc_max_abs_rel_error"]})
    width = 0.8 / max(1, 2 * len(coords))
    for j, c in enumerate(coords):
        for k, label in enumerate(("analytic", "calibrated")):
            vals = [100 * s[n][f"{label}_dc_max_abs_rel_error"].get(c, np.nan) for n in names]
            axes[1].bar(
                x - 0.4 + (2 * j + k + 0.5) * width, vals, width, label=f"{c} {label}", hatch="" if k == 0 else "//"
            )
    axes[1].set_ylabel("max |dC - dC_field| / |dC_field| (%)")
    axes[1].set_yscale("symlog", linthresh=1e-3)
    axes[1].legend(fontsize=6, ncol=max(1, len(coords)))
    for i, n in enumerate(names):
        ratios = doc["electrodes"][n]["coupling_over_c0"]
        axes[2].scatter([i] * len(ratios), [100 * r for r in ratios.values()], s=12, color="k")
    axes[2].set_ylabel("C_ij / C_i(0) (%)")
    for ax in axes:
        ax.set_xticks(x, names, rotation=60, fontsize=7)
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle(textwrap.fill(f"calibration against {doc['source']}", 90), fontsize=8)
    fig.tight_layout()
    return save(fig, path)
