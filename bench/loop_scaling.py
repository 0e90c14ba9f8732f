"""Cost of the compiled sigma-delta loop against the model's size: coordinates, electrodes and plate
terms. Each model is built by the normal path (`netgen build` of a structure file this script
writes: the reference disk with 0..9 elastic modes, one or two rings, 4 or 8 sectors per side),
then its default loop runs under callgrind (bench/callgrind.py's profile: instructions per Newton
iteration and per period, deterministic) through OSDI in ngspice 46 (osdi loop blocks) and the
XSPICE code models in ngspice 39 (xspice loop), with the floor of each, and through VACASK
(bench/callgrind.py's profile_vacask: the loop of `--simulator vacask`, no floor there).
Above 7 coordinates (5..9 modes) the structure samples the level-2 sparse grid at the default
range (the build's own choice there; the 3^n grid of the reference would take hours).

    NETGEN_NGSPICE=~/.cache/netgen/ngspice-46/bin/ngspice .venv/bin/python bench/loop_scaling.py \
        -o out/loop_scaling [--modes 0,1,2,3,4] [--layouts 2x4] [--cycles 8] [--paths osdi,xspice,vacask]

--modes sets the coordinates (n = 3 + modes, with the reference 2 x 4 layout), --layouts the
electrodes (rings x sectors per side, with no modes; 2 sides). Prints one row per model and path,
the fitted exponents b of instructions per iteration ~ size^b (size: coordinates, electrodes,
plate terms), and writes loop_scaling.json and loop_scaling.png. Rows already in an earlier
loop_scaling.json under -o (same model and path) are reused, so a run can add models or paths.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
from callgrind import profile, profile_vacask
from support import ROOT

from netgen.model import MacroModel
from netgen.sim.ngspice import ngspice_path

EXAMPLE = (ROOT / "examples/levitated_disk.toml").read_text()
RINGS = {1: '[["20 um", "473 um"]]', 2: '[["20 um", "230 um"], ["240 um", "473 um"]]'}
NG39 = "/usr/bin/ngspice"
PATHS = ("osdi", "xspice", "vacask")
SWEEP = {  # the models whose size varies along each key alone
    "coordinates": lambda r: r["layout"] == "2x4",
    "electrodes": lambda r: r["coordinates"] == 3,
    "plate_terms": lambda r: True,
}


def structure(modes: int, rings: int, sectors: int) -> str:
    """The reference disk with the first `modes` elastic modes and `rings` x `sectors` electrodes per side."""
    text = EXAMPLE.replace('modes = ["2,0c", "2,0s", "3,0c", "3,0s"]', f"modes = {modes}")  # the first ones, by count
    if modes > 4:  # n > 7: the build's sparse grid at its default range, not 3^n samples
        text = re.sub(r"\nlevels = 3[^\n]*\nrange = 0.2[^\n]*", '\ndesign = "sparse"', text)
    text = text.replace('rings = [["20 um", "230 um"], ["240 um", "473 um"]]', f"rings = {RINGS[rings]}")
    return text.replace("sectors = 4", f"sectors = {sectors}").replace(
        'name = "levitated_disk"', f'name = "disk_m{modes}_r{rings}s{sectors}"'
    )


def build(text: str, out: Path) -> MacroModel:
    """`netgen build` of the structure text; the model it writes."""
    out.mkdir(parents=True, exist_ok=True)
    toml = out / "structure.toml"
    toml.write_text(text)
    subprocess.run(
        [str(ROOT / ".venv/bin/netgen"), "build", str(toml), "-o", str(out / "model"), "--format", "ngspice", "-q"],
        check=True,
    )
    return MacroModel.load_json(next(p for p in (out / "model").glob("*.json") if "manifest" not in p.name))


def measure(model: MacroModel, path: str, cycles: int, folder: Path) -> dict:
    """Instructions per iteration and per period of the model and its floor through one path."""
    if path == "vacask":
        v = profile_vacask(model, cycles, folder / "vacask")
        return {
            "per_iteration_k": v["instructions"] / v["iterations"] / 1e3,
            "per_period_m": v["instructions"] / cycles / 1e6,
            "iterations_per_period": v["iterations"] / cycles,
            "floor_per_period_m": None,
            "ratio": None,
        }
    variant, ngspice = ("osdi", None) if path == "osdi" else ("xspice", NG39)
    env = os.environ.get("NETGEN_NGSPICE")
    if ngspice:
        os.environ["NETGEN_NGSPICE"] = ngspice
    try:
        runs = {v: profile(model, v, cycles, folder / f"{path}_{v}", path) for v in (variant, "floor")}
    finally:
        if env is None:
            os.environ.pop("NETGEN_NGSPICE", None)
        else:
            os.environ["NETGEN_NGSPICE"] = env
    m, f = runs[variant], runs["floor"]
    return {
        "per_iteration_k": m["instructions"] / m["iterations"] / 1e3,
        "per_period_m": m["instructions"] / cycles / 1e6,
        "iterations_per_period": m["iterations"] / cycles,
        "floor_per_period_m": f["instructions"] / cycles / 1e6,
        "ratio": m["instructions"] / f["instructions"],
    }


def exponent(rows: list[dict], path: str, key: str, what: str = "per_iteration_k") -> float | None:
    """b of instructions per iteration (or `what`: per_period_m) ~ key^b (least squares in logs)
    over the sweep that varies `key` alone (coordinates: the 2 x 4 layout; electrodes: no modes;
    plate terms: every model); None with fewer than 2 distinct sizes."""
    pts = [(r[key], r[path][what]) for r in rows if path in r and SWEEP[key](r)]
    if len({x for x, _ in pts}) < 2:
        return None
    x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    return float(np.polyfit(x, y, 1)[0])


def figure(rows: list[dict], paths: list[str], png: Path) -> None:
    """Instructions per iteration (top) and per period (bottom) against coordinates, electrodes and
    plate terms, per path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 3, figsize=(12, 6.6))
    keys = (("coordinates", "coordinates"), ("electrodes", "electrodes"), ("plate_terms", "plate terms"))
    for row, (what, ylabel) in enumerate(
        (("per_iteration_k", "k instructions per Newton iteration"), ("per_period_m", "M instructions per period"))
    ):
        for ax, (key, label) in zip(axes[row], keys):
            for path in paths:
                pts = sorted((r[key], r[path][what]) for r in rows if path in r and SWEEP[key](r))
                if pts:
                    ax.loglog(*zip(*pts), "o" if key == "plate_terms" else "o-", label=path)
            ax.set_xlabel(label)
            ax.grid(True, which="both", alpha=0.3)
        axes[row][0].set_ylabel(ylabel)
    axes[0][0].legend()
    fig.tight_layout()
    fig.savefig(png, dpi=110)


def print_row(row: dict, path: str) -> None:
    """One model and path's line of the table (the floor columns blank without a floor)."""
    r = row[path]
    floor = f"{r['floor_per_period_m']:8.2f} {r['ratio']:6.2f}" if r["ratio"] is not None else f"{'-':>8s} {'-':>6s}"
    print(
        f"{row['model']:16s} {row['coordinates']:3d} {row['electrodes']:5d} {row['plate_terms']:6d} {path:7s} "
        f"{r['per_iteration_k']:7.1f} {r['iterations_per_period']:7.1f} {r['per_period_m']:7.2f} {floor}",
        flush=True,
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-o", "--out", required=True, type=Path)
    ap.add_argument("--modes", default="0,1,2,3,4", help="elastic modes of the coordinate sweep (n = 3 + modes)")
    ap.add_argument("--layouts", default="1x4,2x8", help="rings x sectors per side of the electrode sweep (no modes)")
    ap.add_argument("--cycles", type=int, default=8)
    ap.add_argument("--paths", default=",".join(PATHS))
    args = ap.parse_args()
    paths = args.paths.split(",")
    cases = [(int(m), 2, 4) for m in args.modes.split(",") if m]
    cases += [(0, int(r), int(s)) for r, s in (x.split("x") for x in args.layouts.split(",") if x)]
    done = args.out / "loop_scaling.json"
    earlier = {r["model"]: r for r in json.loads(done.read_text())} if done.exists() else {}
    rows = []
    print(f"ngspice 46: {ngspice_path()}; ngspice 39: {NG39}; {args.cycles} periods under callgrind")
    print(
        f"{'model':16s} {'n':>3s} {'elec':>5s} {'terms':>6s} {'path':7s} {'k/iter':>7s} {'it/per':>7s} {'M/per':>7s} {'floor M':>8s} {'ratio':>6s}"
    )
    for modes, rings, sectors in dict.fromkeys(cases):
        name = f"disk_m{modes}_r{rings}s{sectors}"
        row = earlier.get(name, {})
        model = None
        for path in paths:
            if path not in row:
                model = model or build(structure(modes, rings, sectors), args.out / name)
                row |= {
                    "model": name,
                    "layout": f"{rings}x{sectors}",
                    "coordinates": model.ncoords,
                    "electrodes": len(model.electrodes),
                    "plate_terms": sum(len(f.polys) for f in model.capacitances),
                }
                row[path] = measure(model, path, args.cycles, args.out / name)
            print_row(row, path)
        rows.append(row)
        done.write_text(
            json.dumps(rows + [r for n, r in earlier.items() if n not in {x["model"] for x in rows}], indent=1)
        )
    rows += [r for n, r in earlier.items() if n not in {x["model"] for x in rows}]
    shown = [p for p in PATHS if any(p in r for r in rows)]  # this run's and the earlier rows' paths
    for path in shown:
        for what, label in (("per_iteration_k", "per iteration"), ("per_period_m", "per period")):
            fits = {k: exponent(rows, path, k, what) for k in ("coordinates", "electrodes", "plate_terms")}
            print(
                f"{path}: instructions {label} ~ " + ", ".join(f"{k}^{b:.2f}" for k, b in fits.items() if b is not None)
            )
    figure(rows, shown, args.out / "loop_scaling.png")
    print(f"wrote {args.out / 'loop_scaling.json'} and loop_scaling.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
