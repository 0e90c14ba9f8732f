"""PNG figures of a model next to its netlists: mode shapes over the electrode layout, fit errors."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ..core.plots import plt, save
from .macromodel import MacroModel


def mode_shapes(
    path: Path,
    model: MacroModel,
    basis: Callable[[np.ndarray, np.ndarray], np.ndarray],
    radius: float,
    outlines: Sequence[tuple[np.ndarray, np.ndarray]],
) -> Path:
    """Vertical displacement of every mode coordinate on the disk, electrode outlines on top."""
    modes = [(v, c) for v, c in enumerate(model.coordinates) if c.kind == "mode"]
    n = max(len(modes), 1)
    r, t = np.meshgrid(np.linspace(0, radius * (1 - 1e-7), 60), np.linspace(0, 2 * np.pi, 121))
    x, y = r * np.cos(t), r * np.sin(t)
    w = basis(x.ravel(), y.ravel()).reshape(*x.shape, -1)
    fig, axes = plt.subplots(1, n, figsize=(3.2 * n, 3.4), squeeze=False)
    for ax, (v, c) in zip(axes[0], modes):
        ax.pcolormesh(x * 1e6, y * 1e6, w[..., v], cmap="RdBu_r", vmin=-1, vmax=1, shading="gouraud")
        for ox, oy in outlines:
            ax.plot(ox * 1e6, oy * 1e6, color="k", lw=0.6)
        # parse_math=False: an imported label is text, never mathtext ("$\\x$" would stop the build)
        ax.set_title(f"{c.name} ({c.label})\n{c.frequency_hz / 1e3:.2f} kHz", fontsize=9, parse_math=False)
        ax.set_aspect("equal")
        ax.set_xlabel("x (um)")
    axes[0][0].set_ylabel("y (um)")
    fig.suptitle(f"{model.name}: eigenmodes (peak-normalised), electrode outlines", fontsize=10)
    fig.tight_layout()
    return save(fig, path)


def fit_errors(path: Path, model: MacroModel) -> Path:
    """Held-out max and RMS relative error of every fitted capacitance."""
    names = [f.electrode for f in model.capacitances]
    idx = np.arange(len(names))
    fig, ax = plt.subplots(figsize=(max(6, 0.45 * len(names)), 3.6))
    corners = model.sampling.get("corner_checks", 0)  # the max covers the box's corners too (netgen.build)
    ax.bar(idx - 0.2, [100 * f.max_rel_error for f in model.capacitances], 0.4, label="max (held-out)")
    ax.bar(idx + 0.2, [100 * f.rms_rel_error for f in model.capacitances], 0.4, label="rms (held-out)")
    ax.set_xticks(idx, names, rotation=60, fontsize=8)
    ax.set_ylabel("relative error (%)")
    ax.set_title(
        f"{model.name}: capacitance fit error on {model.sampling['holdout']} random points "
        f"in +-{model.sampling['range']:g} L" + (f"\n(max: and at the box's {corners} corners)" if corners else ""),
        fontsize=10,
    )
    ax.legend(fontsize=8)
    fig.tight_layout()
    return save(fig, path)


def small_angle(path: Path, report: dict) -> Path:
    """The small-angle kinematics' relative displacement error vs angle, with the 0.1 % line and
    each rotation coordinate's sampled and touching amplitudes (netgen.mechanics.kinematics)."""
    t = np.geomspace(1e-5, 0.3, 200)
    err = np.hypot(1 - np.cos(t), t - np.sin(t)) / t
    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    ax.loglog(t * 1e3, err, color="k", lw=1.2, label="displacement error / displacement")
    ax.axhline(report["limit"], color="r", lw=0.8, ls="--", label=f"{report['limit']:.1%}")
    for k, row in enumerate(report["rotations"]):
        color = f"C{k}"
        ax.axvline(row["sampled_rad"] * 1e3, color=color, lw=0.8, ls=":")
        ax.axvline(
            row["touching_rad"] * 1e3, color=color, lw=0.8, label=f"{row['coordinate']}: sampled (dotted), touching"
        )
    ax.set_xlabel("angle (mrad)")
    ax.set_ylabel("relative error")
    ax.set_title(f"small-angle kinematics: 0.1 % beyond {report['threshold_rad'] * 1e3:.3g} mrad", fontsize=9)
    ax.legend(fontsize=7)
    return save(fig, path)
