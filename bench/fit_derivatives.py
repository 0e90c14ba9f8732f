"""How well do models of one structure (e.g. the grid design's and an adaptive one's) follow the
extractor in the quantities a sigma-delta loop's dynamics depend on: C, dC/dq and d2C/dq dq' at
rest per electrode, the loop-weighted electrostatic stiffness 1/2 sum_i V_i^2 d2C_i/dq dq' of
every feedback bit pattern and of the sense phase, and C and dC/dq along a loop run's trajectory:

    .venv/bin/python bench/fit_derivatives.py examples/levitated_disk.toml \\
        netlists/levitated_disk.json out/adaptive/levitated_disk.json [--run SD_DIR] [--rows z,tilt_x]

The reference is the structure's own extractor (netgen.electrostatics: its analytic gradient,
second derivatives by central differences of it, two steps, Richardson-extrapolated); the models'
second derivatives come the same way from MacroModel.capacitance_gradient. Every error is printed
relative to the electrode's C at rest (per electrode) or to the pattern's diagonal stiffness (loop
rows). --run: a `netgen sigma-delta` output folder whose bitstreams.npz positions are the trajectory.
Measured on the disk: CHANGELOG (the adaptive model's tilt_x floor).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

from netgen.electrostatics import extractor
from netgen.geometry.layout import electrodes, plate_outline
from netgen.mechanics import mechanics
from netgen.model import MacroModel
from netgen.structure import load_structure
from netgen.testbench.sigma_delta.loop import design
from netgen.testbench.sigma_delta.signals import selected

STEP = 1e-3  # scaled step of the second derivatives' central differences (and half of it)

Gradient = Callable[[np.ndarray], np.ndarray]  # scaled x (npts, n) -> dC/dx (npts, nel, n)


def hessian(grad: Gradient, n: int) -> np.ndarray:
    """d2C_i/dx_u dx_v at rest (nel, n, n), central differences of the gradient, Richardson."""

    def diff(u: int, h: float) -> np.ndarray:
        e = np.zeros((1, n))
        e[0, u] = h
        return (grad(e)[0] - grad(-e)[0]) / (2.0 * h)

    return np.stack([(4.0 * diff(u, STEP / 2) - diff(u, STEP)) / 3.0 for u in range(n)], axis=1)


def per_electrode(
    names: list[str], cnames: list[str], c0: np.ndarray, ref: dict, models: dict, rows: list[int]
) -> None:
    """Per electrode: the extractor's values and each model's errors, relative to C(0)."""
    pairs = [(u, u) for u in rows] + [(u, v) for u in rows for v in rows if u < v]
    heads = ["C", *(f"dC/d{cnames[u]}" for u in rows), *(f"d2C/d{cnames[u]}d{cnames[v]}" for u, v in pairs)]
    print("\nper electrode, relative to C(0): extractor value, then each model's error")
    print(f"{'electrode':10} {'model':10} " + " ".join(f"{h:>14}" for h in heads))

    def values(c: np.ndarray, g: np.ndarray, h: np.ndarray, i: int) -> list[float]:
        return [c[i], *(g[i, u] for u in rows), *(h[i, u, v] for u, v in pairs)]

    for i, e in enumerate(names):
        r = values(*ref, i)
        print(f"{e:10} {'extractor':10} " + " ".join(f"{v / c0[i]:14.4e}" for v in r))
        for k, m in models.items():
            print(f"{'':10} {k:10} " + " ".join(f"{(a - b) / c0[i]:+14.1e}" for a, b in zip(values(*m, i), r)))


def loop_stiffness(grid: MacroModel, cnames: list[str], ref: np.ndarray, models: dict, rows: list[int]) -> None:
    """0.5 sum_i V_i^2 d2C_i/dx_u dx_v per bit pattern and the sense phase, models against the extractor."""
    d = design(grid, 1e-6)
    phases = [(r["bits"], d.vfb * selected(d.electrodes, r["pattern"])) for r in d.table]
    phases.append(("sense", np.full(len(d.electrodes), d.vs)))
    for u in rows:
        print(
            f"\nstiffness row {cnames[u]} (scaled coordinates): model error / |K_ext[{cnames[u]},{cnames[u]}]| "
            f"per column {', '.join(cnames)}"
        )
        for bits, v in phases:
            k_ext = 0.5 * np.einsum("i,iuv->uv", v**2, ref)
            unit = abs(k_ext[u, u]) or 1.0
            line = f"{bits:6} K_ext[{cnames[u]},{cnames[u]}] {k_ext[u, u]:+.3e}"
            for k, h in models.items():
                err = 0.5 * np.einsum("i,iuv->uv", v**2, h)[u] - k_ext[u]
                line += f" | {k}: " + " ".join(f"{e / unit:+.1e}" for e in err)
            print(line)


def trajectory(run: Path, cnames: list[str], scales: np.ndarray, prepared, c0: np.ndarray, models: dict) -> None:
    """Largest error of C and dC/dx (relative to C(0)) over the positions of a loop run."""
    b = np.load(run / "bitstreams.npz")
    x = np.stack([b[f"x_{n}"] for n in cnames], axis=1)
    print(
        f"\ntrajectory of {run} ({len(x)} periods): x from {np.array2string(x.min(0), precision=2)} "
        f"to {np.array2string(x.max(0), precision=2)}"
    )
    ce = prepared.capacitance(x * scales) / c0
    ge = prepared.gradient(x * scales) * scales[None, None, :] / c0[None, :, None]
    for k, m in models.items():
        c = m.capacitance(x) / c0
        g = m.capacitance_gradient(x) * scales[None, None, :] / c0[None, :, None]
        print(
            f"{k:10} C max rel error {np.abs(c / ce - 1).max():.1e}; dC/dx max error / C(0) per coordinate "
            + " ".join(f"{cn} {e:.1e}" for cn, e in zip(cnames, np.abs(g - ge).max(axis=(0, 1))))
        )


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("structure", type=Path)
    p.add_argument("models", type=Path, nargs="+", help="model .json files (the first designs the loop)")
    p.add_argument("--run", type=Path, help="a netgen sigma-delta output folder: its trajectory")
    p.add_argument("--rows", default="z,tilt_x", help="coordinates whose derivatives and stiffness rows to print")
    args = p.parse_args()
    s = load_structure(args.structure)
    m = mechanics(s)
    plate, shapes = plate_outline(s), electrodes(s)
    prepared = extractor(s, plate).prepare(shapes, plate, m.basis)
    loaded = {f"{k}_{path.parent.name}": MacroModel.load_json(path) for k, path in enumerate(args.models)}
    first = next(iter(loaded.values()))
    scales, cnames, n = first.scales, [c.name for c in first.coordinates], first.ncoords
    rows = [cnames.index(r) for r in args.rows.split(",")]
    ext_grad: Gradient = lambda x: prepared.gradient(x * scales) * scales[None, None, :]  # noqa: E731
    zero = np.zeros((1, n))
    ref = (prepared.capacitance(zero)[0], ext_grad(zero)[0], hessian(ext_grad, n))
    models = {}
    for k, mm in loaded.items():
        if not np.allclose(mm.scales, scales):
            raise SystemExit(f"{k}: other coordinate scales than the first model's: not the same structure")
        grad: Gradient = lambda x, mm=mm: mm.capacitance_gradient(x) * scales[None, None, :]  # noqa: E731
        models[k] = (mm.capacitance(zero)[0], grad(zero)[0], hessian(grad, n))
    c0 = ref[0]
    per_electrode([e.name for e in shapes], cnames, c0, ref, models, rows)
    loop_stiffness(first, cnames, ref[2], {k: v[2] for k, v in models.items()}, rows)
    if args.run:
        trajectory(args.run, cnames, scales, prepared, c0, loaded)
    return 0


if __name__ == "__main__":
    sys.exit(main())
