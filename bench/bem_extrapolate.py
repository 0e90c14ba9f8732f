"""The reference disk's analytic-vs-BEM differences extrapolated to the reference g/R = 3/473,
from the runs of bench/bem_reference_disk.py (their --json files): per electrode the relative
differences (analytic - BEM) / BEM of C, dC/dz and dC/dtilt_x, and every electrode-electrode
coupling; with the uncertainty from alternative fit forms; and the cost scaling of the solves
(elements, seconds, memory against g/R), with the smallest g/R that fits a memory and time budget.

    .venv/bin/python bench/bem_extrapolate.py RUN.json [RUN.json ...] [--json out.json]

Fit forms. Both extractors tend to eps A / g as g -> 0, so a relative difference vanishes there;
the edge fringe per unit length is eps (a + b ln(L/g)) (netgen.electrostatics.parallel_plate),
so the fringe's share of C is (g/R)(alpha + beta ln(R/g)) to first order. But the slots (10 um)
are fixed while the gap shrinks: slot/gap runs from 0.2 (g/R = 0.1) to 1.4 (0.015) and is 3.3 at
the reference, so the per-edge coefficients drift along the way and no single form is exact. Four
forms through the smallest computed gaps, each zero at g = 0:
  power  y = c x^p             (the two smallest gaps: the local slope)
  xlog2  y = x (alpha + beta ln(1/x))   (through the two smallest; the fringe error per unit
         edge length, y/x, linear in ln g: it may change sign, the others cannot)
  xlog   the same, least squares through the three smallest
  quad   y = alpha x + gamma x^2        (least squares, the three smallest)
The value is their median, the uncertainty half their spread plus the smallest gap's BEM error
estimate (for a derivative also its own: level_error). Couplings (F) tend to a constant (the sheets' back-side field does not see the plate):
  lin    c0 + c1 x (two smallest), quad c0 + c1 x + c2 x^2 (three smallest), xlog c0 + c1 x ln(1/x)
  (two smallest); median and half-spread again, clipped at 0.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

TARGET = 3.0 / 473.0


def load(paths: list[Path]) -> list[dict]:
    """One result per g/R (the last file's wins), sorted by g/R, smallest first."""
    by_gap = {}
    for p in paths:
        for r in json.loads(p.read_text()):
            by_gap[round(r["g_over_R"], 9)] = r
    return [by_gap[k] for k in sorted(by_gap)]


def rel(a, b) -> np.ndarray:
    """(a - b) / b elementwise, nan where b vanishes (a derivative zero by symmetry)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    keep = np.abs(b) > 1e-3 * np.abs(b).max()
    return np.where(keep, a / np.where(keep, b, 1.0) - 1.0, np.nan)


def forms_difference(x: np.ndarray, y: np.ndarray, target: float) -> dict[str, float]:
    """The three zero-at-origin forms evaluated at target (x ascending)."""
    out = {}
    if len(x) >= 2 and y[0] * y[1] > 0:
        p = math.log(y[1] / y[0]) / math.log(x[1] / x[0])
        out["power"] = float(y[0] * (target / x[0]) ** p)
    at = np.array([target, target * math.log(1 / target)])
    a2 = np.column_stack([x[:2], x[:2] * np.log(1 / x[:2])])
    out["xlog2"] = float(at @ np.linalg.solve(a2, y[:2]))
    k = min(3, len(x))
    xs, ys = x[:k], y[:k]
    a = np.column_stack([xs, xs * np.log(1 / xs)])
    out["xlog"] = float(at @ np.linalg.lstsq(a, ys, rcond=None)[0])
    a = np.column_stack([xs, xs**2])
    out["quad"] = float(np.array([target, target**2]) @ np.linalg.lstsq(a, ys, rcond=None)[0])
    return out


def forms_coupling(x: np.ndarray, y: np.ndarray, target: float) -> dict[str, float]:
    """The coupling forms (a constant at g = 0) evaluated at target."""
    out = {"lin": float(np.polyval(np.polyfit(x[:2], y[:2], 1), target))}
    if len(x) >= 3:
        out["quad"] = float(np.polyval(np.polyfit(x[:3], y[:3], 2), target))
    u = x[:2] * np.log(1 / x[:2])
    out["xlog"] = float(np.polyval(np.polyfit(u, y[:2], 1), target * math.log(1 / target)))
    return out


def summarise(values: dict[str, float], err: float = 0.0, floor: float | None = None) -> dict:
    """Median of the forms, half their spread plus err, each form's value."""
    v = np.array(list(values.values()))
    mid = float(np.median(v))
    if floor is not None:
        mid = max(mid, floor)
    return {"value": mid, "uncertainty": float(0.5 * (v.max() - v.min()) + err), "forms": values}


def level_error(r: dict, q: str) -> np.ndarray:
    """Per electrode, the estimated relative error of a two-level BEM derivative: the finest
    level's distance from the extrapolation, |coarsest / extrapolated - 1| / 2 (Richardson with
    order 2 and levels sqrt(2) apart puts the finest level halfway); 0 where not recorded."""
    coarse = (r.get("dC_bem_coarsest_level") or {}).get(q)
    if coarse is None:
        return np.zeros(len(r["names"]))
    a, c = np.asarray(r["dC_bem"][q], float), np.asarray(coarse, float)
    return 0.5 * np.abs(np.divide(c, a, out=np.ones_like(a), where=a != 0.0) - 1.0)


def differences(results: list[dict]) -> dict:
    """Per electrode and quantity (C, dz, tilt_x): the relative difference at each gap and extrapolated."""
    x = np.array([r["g_over_R"] for r in results])
    names = results[0]["names"]
    err = results[0]["error_bem"]
    level = {q: level_error(results[0], q) for q in results[0].get("dC_bem", {})}
    out = {}
    for q in ("C", "z", "tilt_x"):
        series = []
        for r in results:
            if q == "C":
                series.append(rel(r["C_pp"], r["C_bem"]))
            elif q in r["dC_bem"]:
                series.append(rel(r["dC_pp"][q], r["dC_bem"][q]))
        if len(series) < 2:
            continue
        ys = np.array(series)
        xq = x[: len(ys)] if q == "C" else np.array([r["g_over_R"] for r in results if q in r["dC_bem"]])
        out[q] = {}
        for i, n in enumerate(names):
            y = ys[:, i]
            if not np.isfinite(y).all():
                continue
            out[q][n] = {
                "at": dict(zip(map(float, xq), map(float, y))),
                **summarise(forms_difference(xq, y, TARGET), err + (level[q][i] if q in level else 0.0)),
            }
    return out


def couplings(results: list[dict]) -> dict:
    """Every electrode pair's coupling (F) at each gap (runs that stored the Maxwell matrix) and extrapolated."""
    runs = [r for r in results if r.get("maxwell") is not None]
    x = np.array([r["g_over_R"] for r in runs])
    names = runs[0]["names"]
    mats = np.array([-np.asarray(r["maxwell"])[1:, 1:] for r in runs])
    out = {}
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            y = 0.5 * (mats[:, i, j] + mats[:, j, i])
            out[f"{names[i]}-{names[j]}"] = {
                "at": dict(zip(map(float, x), map(float, y))),
                **summarise(forms_coupling(x, y, TARGET), floor=0.0),
            }
    return out


def ring_table(diff: dict) -> list[str]:
    """Mean over the sectors of each ring and side of the extrapolated differences."""
    lines = [f"(analytic - BEM) / BEM, mean over a ring's sectors; extrapolated to g/R = {TARGET:.4f}:"]
    for q, per in diff.items():
        for side in ("top", "bot"):
            for ring in ("r1", "r2"):
                rows = [v for n, v in per.items() if n.startswith(f"{side}_{ring}")]
                if not rows:
                    continue
                gaps = sorted(rows[0]["at"])
                pts = "  ".join(f"{100 * np.mean([r['at'][g] for r in rows]):+6.2f} %@{g:g}" for g in gaps)
                val = np.mean([r["value"] for r in rows])
                unc = np.mean([r["uncertainty"] for r in rows])
                forms = ", ".join(f"{k} {100 * np.mean([r['forms'][k] for r in rows]):+.2f}" for k in rows[0]["forms"])
                lines.append(f"  {q:6s} {side}_{ring}: {pts}  ->  {100 * val:+.2f} +- {100 * unc:.2f} %  ({forms})")
    return lines


def coupling_table(cpl: dict, results: list[dict]) -> list[str]:
    """The couplings of each kind (one representative pair) in fF and over C of its first electrode."""
    names = results[0]["names"]
    kinds = {
        "adjacent, inner ring": "top_r1s1-top_r1s2",
        "adjacent, outer ring": "top_r2s1-top_r2s2",
        "inner-outer, same sector": "top_r1s1-top_r2s1",
        "inner-outer, next sector": "top_r1s1-top_r2s2",
        "opposite, inner ring": "top_r1s1-top_r1s3",
        "opposite, outer ring": "top_r2s1-top_r2s3",
        "top-bottom, outer sector": "top_r2s1-bot_r2s1",
    }
    c_small = {g: np.asarray(r["C_bem"]) for g, r in ((r["g_over_R"], r) for r in results)}
    lines = ["couplings (fF; % of the first electrode's plate capacitance C_bem at that gap):"]
    for label, pair in kinds.items():
        if pair not in cpl:
            continue
        v = cpl[pair]
        i = names.index(pair.split("-")[0])
        pts = "  ".join(f"{1e15 * c:7.3f} ({100 * c / c_small[g][i]:5.2f} %)@{g:g}" for g, c in sorted(v["at"].items()))
        lines.append(f"  {label:26s} {pts}  ->  {1e15 * v['value']:.3f} +- {1e15 * v['uncertainty']:.3f} fF")
    return lines


def cost(results: list[dict], memory_gb: float, seconds: float) -> list[str]:
    """Elements (counted on the meshes: bem_reference_disk.elements), seconds (a power law in N
    through the measured solves) and memory (netgen.electrostatics.bem.BYTES_PER_ENTRY per matrix
    entry of the finest level; measured 8.9-10.1) against g/R, and the smallest g/R whose solve
    (both levels) fits memory_gb and `seconds`."""
    import bem_reference_disk as ref  # the script beside this one

    from netgen.electrostatics.bem import BYTES_PER_ENTRY

    rows = []
    for r in results:  # a derivative solve where there is one (the first solve pays the JIT)
        solves = sorted(
            (s for s in r.get("all_solves", []) if len(s["levels"]) > 1),  # both levels
            key=lambda s: s["what"] == "q=0",
        )
        if solves:
            lv = solves[0]["levels"]
            rows.append((r["g_over_R"], lv[-1]["elements"], sum(v["assembly_s"] + v["solve_s"] for v in lv)))
    if len(rows) < 2:
        return ["cost: needs the derivative solves of two gaps (their first solve pays the JIT)"]
    g, n_fine, t = map(np.array, zip(*rows))
    pt = np.polyfit(np.log(n_fine), np.log(t), 1)
    lines = [
        f"cost: solve time (both levels) ~ N^{pt[0]:.2f} over the finest level's N "
        f"(from {len(rows)} solves: "
        + ", ".join(f"{gi:g}: {ni} el {ti:.0f} s" for gi, ni, ti in zip(g, n_fine, t))
        + ")"
    ]
    settings = ref.settings_for()
    grid = sorted({0.015, 0.0125, 0.012, 0.0115, 0.011, 0.0105, 0.01, 0.009, TARGET})
    fits = []
    for x in reversed(grid):
        n = ref.elements(x, settings)[-1]
        mem, tt = BYTES_PER_ENTRY * n * n / 1e9, float(np.exp(np.polyval(pt, np.log(n))))
        ok = mem <= memory_gb and tt <= seconds
        fits.append((x, ok))
        lines.append(
            f"  g/R = {x:.4f}: {n} elements (finest level), {mem:.1f} GB, {tt:.0f} s per solve on this "
            f"machine's share{'' if ok else '  (over the budget)'}"
        )
    best = min((x for x, ok in fits if ok), default=None)
    lines.insert(
        1,
        f"  smallest g/R within {memory_gb:g} GB and {seconds:g} s per solve: "
        + (f"{best:.4f}" if best else "none of " + ", ".join(f"{x:.4f}" for x in grid)),
    )
    return lines


def main() -> None:
    """Read the runs, print the tables, write the JSON."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path)
    ap.add_argument("--json", type=Path)
    ap.add_argument("--memory-gb", type=float, default=16.0)
    ap.add_argument("--seconds", type=float, default=3600.0)
    a = ap.parse_args()
    results = load(a.runs)
    diff, cpl = differences(results), couplings(results)
    for line in ring_table(diff) + coupling_table(cpl, results) + cost(results, a.memory_gb, a.seconds):
        print(line)
    if a.json:
        a.json.write_text(
            json.dumps(
                {
                    "target_g_over_R": TARGET,
                    "gaps": [r["g_over_R"] for r in results],
                    "names": results[0]["names"],
                    "differences": diff,
                    "couplings": cpl,
                    "bem_error_smallest_gap": results[0]["error_bem"],
                },
                indent=1,
            )
        )


if __name__ == "__main__":
    main()
