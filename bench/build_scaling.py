"""Build cost against the number of coordinates n for each sample design (netgen.electrostatics
.designs): the reference disk's electrodes, the free disk with z, tilt_x, tilt_y and 0..9 modes
(n = 3..12). Per design and n: samples, the time of each stage (mechanics, extractor, fit), the
held-out max error, its electrode and the fit warning (a miss is a row of its own, never
averaged away), and the cost estimate the build prints (netgen.fit.cost) beside the measured time.
Fits the growth exponent b of time ~ n^b for the designs that do not grow exponentially, and
the grid's factor per coordinate from the n it can afford (the rest extrapolated, and marked so).

    .venv/bin/python bench/build_scaling.py -o out/build_scaling [--n 3-12] [--designs grid,sparse,adaptive]
        [--grid-max 8] [--range 0.2]

Writes build_scaling.json, build_scaling.png and prints the table (mechanics are computed once per n).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from support import ROOT

from netgen.build import default_range
from netgen.electrostatics import extractor
from netgen.electrostatics.sampling import coordinate_scales, sample_grid, sample_holdout, sample_points
from netgen.fit import cost
from netgen.fit.adaptive import adaptive_fits
from netgen.fit.capacitance import fit_all
from netgen.geometry.layout import electrodes, plate_outline
from netgen.mechanics import mechanics
from netgen.structure import parse_structure

EXAMPLE = (ROOT / "examples/levitated_disk.toml").read_text()


def structure_text(modes: int, design: str, half_range: float | None) -> str:
    """The reference disk with `modes` elastic modes (by count) and the given [sampling] design;
    half_range None: no `range` key (the build's default, narrowed where the box's corners touch)."""
    text = EXAMPLE.replace('modes = ["2,0c", "2,0s", "3,0c", "3,0s"]', f"modes = {modes}")
    text = text.replace("levels = 3        # 3^7 = 2187 samples, as in the paper", f'design = "{design}"')
    if half_range is None:
        return "\n".join(line for line in text.splitlines() if not line.startswith("range = 0.2")) + "\n"
    return text.replace("range = 0.2       #", f"range = {half_range}       #")


def run_one(s, m, progress: bool = False) -> dict:
    """One design's sampling and fit stages on prepared mechanics; stage times and errors."""
    plate, shapes = plate_outline(s), electrodes(s)
    prepared = extractor(s, plate).prepare(shapes, plate, m.basis)
    scales = coordinate_scales(prepared, m.names, np.array([e.gap for e in shapes]))
    s = default_range(s, prepared, scales, False)
    t0 = time.perf_counter()
    est = cost.estimate(s, prepared, scales, len(shapes))
    t_est = time.perf_counter() - t0
    spent = {"extractor": 0.0, "points": 0}

    def timed(x):
        t = time.perf_counter()
        out = sample_points(prepared, x, scales, False, "probes")
        spent["extractor"] += time.perf_counter() - t
        spent["points"] += len(x)
        return out

    t0 = time.perf_counter()
    grid = sample_grid(s, prepared, scales)
    holdout = sample_holdout(s, prepared, scales)
    t_sample = time.perf_counter() - t0
    t0 = time.perf_counter()
    if s.sampling.design == "adaptive":
        res = adaptive_fits(s, shapes, m.basis, scales, grid, timed, holdout, progress)
        grid, fits, extra = res.samples, res.fits, {"probes": res.probes, "rounds": len(res.rounds)}
    else:
        fits, extra = fit_all(s, shapes, m.basis, scales, grid, holdout), {}
    t_fit = time.perf_counter() - t0 - spent["extractor"]
    worst = max(fits, key=lambda f: f.max_rel_error)
    misses = [f.electrode for f in fits if f.max_rel_error > s.fit.tolerance]
    return {
        "samples": int(len(grid.x)),
        "extractor_s": t_sample + spent["extractor"],
        "fit_s": t_fit,
        "estimate_s": est.extractor_s + est.fit_s,
        "estimate_max_s": est.extractor_s + est.fit_max_s,
        "estimate_calibration_s": t_est,
        "max_rel_error": worst.max_rel_error,
        "worst_electrode": worst.electrode,
        "misses": misses,
        "fit_warning": bool(misses),
        "range": s.sampling.range,
        **extra,
    }


def parse_n(text: str) -> list[int]:
    """'3-12' -> [3, ..., 12]."""
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def growth(rows: list[dict], design: str) -> dict:
    """Least-squares exponent b of total time ~ n^b, and factor g of time ~ g^n, over the rows."""
    r = [x for x in rows if x["design"] == design]
    if len(r) < 3:
        return {}
    n = np.array([x["n"] for x in r], float)
    t = np.array([x["extractor_s"] + x["fit_s"] for x in r])  # the stages the design drives
    b = np.polyfit(np.log(n), np.log(t), 1)[0]
    g = math.exp(np.polyfit(n, np.log(t), 1)[0])
    return {"power_exponent": float(b), "factor_per_coordinate": float(g), "n": [int(v) for v in n]}


def table(rows: list[dict]) -> str:
    """The rows as a fixed-width table; a design that misses fit.tolerance says so on its row."""
    head = (
        f"{'design':9} {'n':>3} {'range':>5} {'samples':>8} {'mech s':>7} {'extr s':>7} {'fit s':>7} {'est s':>7} "
        f"{'max err':>9} {'worst':>9}  warning"
    )
    lines = [head, "-" * len(head)]
    for r in rows:
        warn = f"MISSES tolerance: {len(r['misses'])} electrode(s)" if r["fit_warning"] else ""
        extra = " (extrapolated)" if r.get("extrapolated") else ""
        err = f"{r['max_rel_error']:9.2e}" if r.get("max_rel_error") is not None else f"{'-':>9}"
        lines.append(
            f"{r['design']:9} {r['n']:3d} {r.get('range', float('nan')):5.3g} {r['samples']:8d} {r['mechanics_s']:7.1f} {r['extractor_s']:7.1f} "
            f"{r['fit_s']:7.1f} {r['estimate_s']:7.1f} {err} {r.get('worst_electrode', '-'):>9}  "
            f"{warn}{extra}"
        )
    return "\n".join(lines)


def figure(rows: list[dict], path: Path) -> None:
    """Time and held-out error against n, one line per design (the grid's extrapolation dashed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    for d in sorted({r["design"] for r in rows}):
        r = [x for x in rows if x["design"] == d and not x.get("extrapolated")]
        n = [x["n"] for x in r]
        (line,) = a.semilogy(n, [x["extractor_s"] + x["fit_s"] for x in r], "o-", label=d)
        b.semilogy(n, [x["max_rel_error"] for x in r], "o-", label=d, color=line.get_color())
        ex = [x for x in rows if x["design"] == d and x.get("extrapolated")]
        if ex:
            a.semilogy(
                [x["n"] for x in ex],
                [x["extractor_s"] + x["fit_s"] for x in ex],
                "x--",
                color=line.get_color(),
                label=f"{d} (extrapolated)",
            )
    tol = rows[0]["tolerance"]
    b.axhline(tol, color="k", ls=":", label="fit.tolerance")
    a.set_xlabel("coordinates n")
    a.set_ylabel("sampling + fit time (s)")
    a.legend(fontsize=8)
    a.grid(alpha=0.3)
    b.set_xlabel("coordinates n")
    b.set_ylabel("held-out max relative error")
    b.legend(fontsize=8)
    b.grid(alpha=0.3)
    fig.suptitle("netgen build cost and accuracy against the number of coordinates (free disk)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("-o", "--output", required=True)
    p.add_argument("--n", default="3-12", help="coordinate counts, e.g. 3-12 (n = 3 + modes)")
    p.add_argument("--designs", default="grid,sparse,adaptive")
    p.add_argument("--grid-max", type=int, default=8, help="largest n the grid is run at (above: extrapolated)")
    p.add_argument(
        "--range",
        default="0.2",
        help="[sampling] range, or 'auto' for none (the build's default: "
        "0.2, narrowed where the box's corners reach an electrode)",
    )
    args = p.parse_args()
    args.range = None if args.range == "auto" else float(args.range)
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    rows: list[dict] = []
    designs = args.designs.split(",")
    for n in parse_n(args.n):
        base = parse_structure(structure_text(n - 3, "sparse", args.range), "bench.toml")
        t0 = time.perf_counter()
        m = mechanics(base)
        t_mech = time.perf_counter() - t0
        for d in designs:
            if d == "grid" and n > args.grid_max:
                continue
            s = parse_structure(structure_text(n - 3, d, args.range), "bench.toml")
            r = {"design": d, "n": n, "mechanics_s": t_mech, "tolerance": s.fit.tolerance} | run_one(s, m)
            rows.append(r)
            print(table([r]).splitlines()[-1], flush=True)
    fits = {d: growth(rows, d) for d in designs}
    g = fits.get("grid", {})
    if g:
        last = max(r["n"] for r in rows if r["design"] == "grid")
        ref = next(r for r in rows if r["design"] == "grid" and r["n"] == last)
        for n in range(last + 1, max(parse_n(args.n)) + 1):
            f = g["factor_per_coordinate"] ** (n - last)
            rows.append(
                {
                    "design": "grid",
                    "n": n,
                    "samples": 3**n,
                    "mechanics_s": float("nan"),
                    "extractor_s": ref["extractor_s"] * f,
                    "fit_s": ref["fit_s"] * f,
                    "estimate_s": float("nan"),
                    "max_rel_error": None,
                    "misses": [],
                    "fit_warning": False,
                    "extrapolated": True,
                    "tolerance": ref["tolerance"],
                }
            )
    rows.sort(key=lambda r: (r["design"], r["n"]))
    print()
    print(table(rows))
    for d, f in fits.items():
        if f:
            print(
                f"{d}: sampling + fit time ~ n^{f['power_exponent']:.2f} "
                f"(or {f['factor_per_coordinate']:.2f}^n) over n = {f['n'][0]}..{f['n'][-1]}"
            )
    (out / "build_scaling.json").write_text(json.dumps({"rows": rows, "growth": fits}, indent=1, default=str))
    figure(rows, out / "build_scaling.png")
    print(f"wrote {out / 'build_scaling.json'} and {out / 'build_scaling.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
