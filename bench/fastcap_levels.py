"""The reference disk (examples/levitated_disk.toml) at its own gap with the multipole extractor on
three or more mesh levels, so that the convergence order is measured rather than assumed: each
ring's C, dC/dz and dC/dtilt_x and the couplings on every level, the observed order from three
successive levels, the Richardson estimate with that order and its error bar, the change from
expansion order 4 to 6 on one level, against the analytic extractor (parallel plate + edge fringe).

    .venv/bin/python bench/fastcap_levels.py --count                       # panels per level, no solve
    nice -n 10 env OMP_NUM_THREADS=1 .venv/bin/python bench/fastcap_levels.py --levels 4 --json out.json
    nice -n 10 env OMP_NUM_THREADS=1 .venv/bin/python bench/fastcap_levels.py --gap-over-r 0.002 --element-to-gap 12.5 --levels 2
    nice -n 10 env OMP_NUM_THREADS=1 /usr/bin/time -v .venv/bin/python bench/fastcap_levels.py --gap-over-r 0.002 --element-to-gap 12.5 --levels 3 --one 1 step 4
    .venv/bin/python bench/fastcap_levels.py --levels 4 --calibration-json direct.json   # from the store

--calibration-json writes the direct solution in bench/bem_extrapolate.py's form (analytic - fastcap
per electrode, every pair's coupling), which bench/bem_calibrated_reference.py turns into the
calibrated reference model.

Levels: sizes edge_to_gap * gap at free edges and element_to_gap * gap inside on level 0, divided
by refinement (sqrt 2) per level. dC/dz and dC/dtilt_x come from one forward step along both (1 %
of the gap), split by the y-mirror symmetry (bem_reference_disk.separate); the analytic extractor
is differenced over the same step, so the one-sided bias cancels in the comparison. FastCap's GMRES
stops at a residual of iter_tol volts at 1 V; a difference over 1 % of the gap would feel 1e-4 of C
as 1 %, so this bench solves to 1e-5 (coaxial disks at d/a = 0.02 give the same C to 1e-6 at 1e-4
and 1e-6: the margin is for the differences). The levels are
solved coarse to fine with the order check after the second, so an interrupted run has a two-level
result with its order check first. The eight sectors of a
ring are equal by symmetry: each ring figure is the mean of the magnitudes over its sectors on both
sides (a forward step closes the gaps on one side and opens them on the other, so the two sides'
one-sided differences differ by about 2 % and their mean is a central difference); the spread
over the sectors of one side is reported beside it, with the analytic extractor's over the same
step. Both are the forward step's curvature, not noise: a sector's one-sided dC/dz is high by
about s (1 + <y^2> / R^2) (s the step in gaps; y^2 averaged over the sector, larger on the y axis,
where the tilt adds to z), so the spread grows with the step and with the ring's radius (the
reference at s = 1 %: inner 0.08 %, outer 0.41 %, the analytic extractor 0.08 / 0.40-0.41 %; at
s = 0.1 % the analytic one is 0.008 / 0.041 %).
Every solve is stored as it
finishes (--store, default ~/.cache/netgen/fastcap_levels; keyed by g/R, settings, level, solve,
order, q and the level's panel count, so a changed mesh is a new solve): an interrupted run
recomputes only the missing solves. Peak RSS and the process CPU time of every solve are printed on stderr; --one
LEVEL WHAT ORDER runs a single solve into the store, so that /usr/bin/time -v measures each solve
in a process of its own, and a later run without --one assembles them.

g/R = 0.002 (docs/fastcap.md): the reference's element_to_gap 4 gives 868k panels on level 2
(21.7 GB); element_to_gap 12.5 keeps the largest panel at the reference's absolute size (4 x its
gap, 0.025 R) and the edge panels at half a gap: 60.7k / 91.5k / 146k / 238k panels on levels
-1 / 0 / 1 / 2 (the plate's face graded towards the electrodes' outlines, fastcap_mesh.disk_face).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import resource
import sys
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
from bem_reference_disk import adjacent_pairs, mirrors, separate, structure

from netgen.electrostatics import EXTRACTORS
from netgen.electrostatics.bem import extrapolate
from netgen.electrostatics.fastcap import FastcapExtractor, FastcapSettings, solve_panels
from netgen.geometry.layout import electrodes, plate_outline
from netgen.mechanics import mechanics

STORE = Path.home() / ".cache" / "netgen" / "fastcap_levels"
BEM_FF = {"adjacent_inner": 1.41, "adjacent_outer": 2.08, "inner_outer_same_sector": 2.83}


def peak_gb() -> float:
    """Peak resident memory of this process so far (GB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e9


def stored_solve(
    folder: Path | None, key: dict, conductors, eps_r: float, order: int, tol: float, stored_only: bool = False
) -> np.ndarray | None:
    """The Maxwell matrix of one FastCap solve, from the store when it holds it (stored_only: None
    when it does not, no solve)."""
    f = None
    if folder is not None:
        folder.mkdir(parents=True, exist_ok=True)
        h = hashlib.sha256(json.dumps(key, sort_keys=True, default=float).encode()).hexdigest()[:16]
        f = folder / f"{h}.npz"
        if f.exists():
            return np.load(f)["matrix"]
    if stored_only:
        return None
    c0, w0 = time.process_time(), time.perf_counter()
    C, rec = solve_panels(conductors, eps_r, order, tol)
    print(
        f"  {key['what']} level {key['level']} order {order}: {rec['panels']} panels, "
        f"{time.perf_counter() - w0:.0f} s wall, {time.process_time() - c0:.0f} s CPU, peak {peak_gb():.2f} GB",
        file=sys.stderr,
        flush=True,
    )
    if f is not None:
        np.savez(f, matrix=C, panels=rec["panels"], seconds=rec["seconds"], cpu=time.process_time() - c0)
    return C


def quantities(centre: np.ndarray, plus: np.ndarray, mirror, steps, pairs) -> dict[str, np.ndarray]:
    """Per-electrode C, dC/dz, dC/dtilt_x (F, F/m, F/rad) and the three coupling kinds (F)."""
    c0, c1 = -centre[0, 1:], -plus[0, 1:]
    g = separate(c1 - c0, mirror, steps)
    coupling = -centre[1:, 1:]
    return {
        "C": c0,
        "dz": g["z"],
        "dtilt": g["tilt_x"],
        **{k: coupling[tuple(np.array(v).T)] for k, v in pairs.items()},
    }


def coupling_pairs(shapes) -> dict[str, list[tuple[int, int]]]:
    """Adjacent sectors of the inner and outer ring, and each inner sector with the outer one of the
    same angles (the 2.83 fF pair of the dense BEM's five-gap extrapolation, docs/bem.md)."""
    inner_r = min(e.shape.r_in for e in shapes)
    adj = adjacent_pairs(shapes)
    same = [
        (i, j)
        for i, a in enumerate(shapes)
        for j, b in enumerate(shapes)
        if a.side == b.side
        and a.shape.r_in == inner_r
        and b.shape.r_in > inner_r
        and math.isclose(a.shape.theta_start, b.shape.theta_start, abs_tol=1e-9)
    ]
    return {
        "adjacent_inner": [(i, j) for i, j in adj if shapes[i].shape.r_in == inner_r],
        "adjacent_outer": [(i, j) for i, j in adj if shapes[i].shape.r_in > inner_r],
        "inner_outer_same_sector": same,
    }


def ring_stats(v: np.ndarray, ring: np.ndarray, skip_zero: bool = False) -> dict:
    """Mean and spread (max - min over the mean) of the magnitudes of v over the ring's entries (the
    electrodes below mirror those above, and the tilt derivative is antisymmetric in y); skip_zero:
    leave out the entries that are zero by symmetry (the tilt derivative of sectors on the x axis)."""
    x = np.abs(v[ring])
    if skip_zero:
        x = x[x > 1e-6 * x.max()]
    m = float(np.mean(x))
    return {"mean": m, "spread": float((x.max() - x.min()) / abs(m))}


def richardson(values: list[float], ratio: float, assumed: float) -> dict:
    """Observed order from the last three levels (if they converge monotonically), the Richardson
    estimate from the last two with it, and the error bar (the correction)."""
    out: dict = {"levels": values}
    p = assumed
    if len(values) >= 3:
        d1, d2 = values[-2] - values[-3], values[-1] - values[-2]
        if d2 != 0 and d1 / d2 > 1.0:
            p = math.log(d1 / d2) / math.log(ratio)
            out["observed_order"] = p
        else:
            out["observed_order"] = None
    if len(values) >= 4:
        d0, d1 = values[-3] - values[-4], values[-2] - values[-3]
        out["observed_order_coarser"] = math.log(d0 / d1) / math.log(ratio) if d1 != 0 and d0 / d1 > 1 else None
    best = values[-1] + (values[-1] - values[-2]) / (ratio**p - 1.0)
    out.update(order_used=p, best=best, correction=abs(best - values[-1]) / abs(best))
    return out


def stored_summary(solve, levels: range, check: int, st: FastcapSettings, rings: dict, analytic: dict, sep) -> dict:
    """What the store holds (--stored-only), for a run cut short: per ring and quantity the levels
    solved, the order-2 Richardson estimate from the last two and its correction, the change at
    check_order on level `check` where both orders are stored, and analytic - fastcap."""
    got: dict[str, list] = {"C": [], "dz": [], "dtilt": []}
    for k in levels:
        centre, step = solve(k, "centre", st.expansion_order), solve(k, "step", st.expansion_order)
        if centre is not None:
            got["C"].append((k, sep(centre, step)))
        if centre is not None and step is not None:
            got["dz"].append((k, got["C"][-1][1]))
            got["dtilt"].append((k, got["C"][-1][1]))
    cc, cs = solve(check, "centre", st.check_order), solve(check, "step", st.check_order)
    base = dict(got["C"]).get(check)
    out: dict = {}
    for ring, sel in rings.items():
        for qn, vals in got.items():
            if not vals:
                continue
            means = [ring_stats(q[qn], sel, qn == "dtilt")["mean"] for _, q in vals]
            r = richardson(means, st.refinement, 2.0) if len(means) >= 2 else {"levels": means, "best": means[-1]}
            entry = {"levels_solved": [k for k, _ in vals], **r}
            if cc is not None and base is not None and (qn == "C" or cs is not None):
                other = sep(cc, cs)
                entry["order_change"] = abs(
                    ring_stats(other[qn], sel, qn == "dtilt")["mean"] / ring_stats(base[qn], sel, qn == "dtilt")["mean"]
                    - 1.0
                )
            entry["analytic_minus_fastcap"] = ring_stats(analytic[qn], sel, qn == "dtilt")["mean"] / r["best"] - 1.0
            out[f"{ring}_{qn}"] = entry
    return out


def run(
    gr: float,
    st: FastcapSettings,
    nlevels: int,
    check_level: int,
    count: bool,
    store: Path | None,
    one: tuple[int, str, int] | None = None,
    first: int = 0,
    stored_only: bool = False,
) -> dict:
    """All levels (centre and step), the order check, and the comparison at g/R = gr; one = (level,
    what, order): that solve alone into the store (a process per solve, so /usr/bin/time -v measures it);
    first: the coarsest level solved (negative: coarser than the settings' sizes, by refinement per level);
    check_level counts from it; stored_only: no solves, what the store holds (stored_summary)."""
    s = structure(gr)
    m = mechanics(s)
    plate, shapes = plate_outline(s), electrodes(s)
    fx = FastcapExtractor(eps_r=s.electrostatics.relative_permittivity, thickness=s.conductor.thickness, settings=st)
    pf = fx.prepare(shapes, plate, m.basis)
    levels = {k: pf.level(plate, m.basis, k) for k in range(min(first, 0), 0)} | dict(enumerate(pf.levels))
    npanels = [len(lv[0]) + sum(len(p) for p in lv[2]) for _, lv in sorted(levels.items())]
    out: dict = {"g_over_r": gr, "panels": npanels, "settings": asdict(st)}
    print(f"g/R {gr}: panels per level {npanels}", file=sys.stderr, flush=True)
    if count:
        return out
    amp = np.abs(pf.geometry.probe.phi).max(axis=0)
    steps = {n: 0.01 * pf.gap / amp[m.names.index(n)] for n in ("z", "tilt_x")}
    dq = np.zeros(pf.ncoords)
    for n in steps:
        dq[m.names.index(n)] = steps[n]
    mirror, pairs = mirrors(shapes), coupling_pairs(shapes)
    base = {"gr": gr, "settings": {k: v for k, v in asdict(st).items() if k not in ("levels", "memory_budget")}}

    def solve(level: int, what: str, order: int) -> np.ndarray:
        plate_p, phi, sheets = levels[level]
        q = dq if what == "step" else np.zeros(pf.ncoords)
        dz = (phi @ q).reshape(len(plate_p), 4)
        key = {
            **base,
            "level": level,
            "what": what,
            "order": order,
            "q": q.tolist(),
            "panels": npanels[level - min(first, 0)],
        }
        return stored_solve(store, key, [plate_p.moved(dz), *sheets], pf.eps_r, order, st.iter_tol, stored_only)

    if one is not None:
        solve(*one)
        out.update(one=list(one), peak_gb=peak_gb(), cpu_s=time.process_time())
        return out
    sides = np.array([e.side for e in shapes])
    inner_r = min(e.shape.r_in for e in shapes)
    rings = {
        "inner": np.array([e.shape.r_in == inner_r for e in shapes]),
        "outer": np.array([e.shape.r_in > inner_r for e in shapes]),
    }
    pp = EXTRACTORS["parallel_plate"](s, plate).prepare(shapes, plate, m.basis)
    q0 = np.zeros(pf.ncoords)
    c_pp = pp.capacitance(q0)
    g_pp = separate(pp.capacitance(dq) - c_pp, mirror, steps)
    analytic = {"C": c_pp, "dz": g_pp["z"], "dtilt": g_pp["tilt_x"]}
    if stored_only:

        def sep(centre, step):
            return quantities(centre, centre if step is None else step, mirror, steps, pairs)

        levels_run = range(first, first + nlevels)
        out["stored"] = stored_summary(solve, levels_run, first + check_level, st, rings, analytic, sep)
        return out
    per_level, couplings, check = [], [], None
    for i, k in enumerate(range(first, first + nlevels)):
        centre = solve(k, "centre", st.expansion_order)
        per_level.append(quantities(centre, solve(k, "step", st.expansion_order), mirror, steps, pairs))
        couplings.append(-centre[1:, 1:])
        if i == max(1, check_level) and check_level >= 0:  # the order check after two levels (-1: none)
            check = quantities(
                solve(first + check_level, "centre", st.check_order),
                solve(first + check_level, "step", st.check_order),
                mirror,
                steps,
                pairs,
            )
    result: dict = {}
    for ring, sel in rings.items():
        for qn in ("C", "dz", "dtilt"):
            vals = [ring_stats(lv[qn], sel, qn == "dtilt") for lv in per_level]
            r = richardson([v["mean"] for v in vals], st.refinement, st.richardson_order)
            order_change = (
                abs(ring_stats(check[qn], sel, qn == "dtilt")["mean"] / vals[check_level]["mean"] - 1.0)
                if check is not None
                else 0.0
            )
            a = ring_stats(analytic[qn], sel, qn == "dtilt")["mean"]
            result[f"{ring}_{qn}"] = {
                **r,
                "spread_finest": max(
                    ring_stats(per_level[-1][qn], sel & (sides == sd), qn == "dtilt")["spread"] for sd in set(sides)
                ),
                "spread_analytic": max(
                    ring_stats(analytic[qn], sel & (sides == sd), qn == "dtilt")["spread"] for sd in set(sides)
                ),
                "order_change": order_change,
                "error": r["correction"] + order_change,
                "analytic_minus_fastcap": a / r["best"] - 1.0,
            }
    for kind in pairs:
        vals = [float(np.mean(lv[kind])) for lv in per_level]
        r = richardson(vals, st.refinement, st.richardson_order)
        oc = abs(float(np.mean(check[kind])) / vals[check_level] - 1.0) if check is not None else 0.0
        result[kind] = {
            **{k: (v * 1e15 if k in ("best",) else v) for k, v in r.items() if k != "levels"},
            "levels_fF": [v * 1e15 for v in vals],
            "order_change": oc,
            "error": r["correction"] + oc,
            "dense_bem_extrapolated_fF": BEM_FF[kind],
        }
    out.update(result=result, peak_gb=peak_gb(), cpu_s=time.process_time())
    out["calibration"] = calibration_block(gr, shapes, result, rings, couplings, st)
    return out


def calibration_block(gr: float, shapes, result: dict, rings: dict, couplings: list, st: FastcapSettings) -> dict:
    """The direct solution in bench/bem_extrapolate.py's form, for bench/bem_calibrated_reference.py:
    per electrode (analytic - fastcap) / fastcap of C, dC/dz, dC/dtilt_x (its ring's Richardson
    estimate), and every electrode pair's coupling (F) Richardson-extrapolated entrywise over the
    last levels (bem.extrapolate: the observed order from three levels)."""
    names = [e.name for e in shapes]
    ring_of = {i: r for r, sel in rings.items() for i in np.flatnonzero(sel)}
    diff = {
        key: {n: {"value": result[f"{ring_of[i]}_{qn}"]["analytic_minus_fastcap"]} for i, n in enumerate(names)}
        for key, qn in (("C", "C"), ("z", "dz"), ("tilt_x", "dtilt"))
    }
    cc, p = extrapolate(couplings[-3:], st.refinement, st.richardson_order)
    pairs = {
        f"{a}-{b}": {"value": float(cc[i, j])}
        for i, a in enumerate(names)
        for j, b in enumerate(names)
        if j > i and cc[i, j] > 0
    }
    return {
        "names": names,
        "gaps": [gr],
        "target_g_over_R": gr,
        "direct": f"FastCap2 at g/R = {gr:.4f} on {len(couplings)} mesh levels (bench/fastcap_levels.py), "
        f"Richardson-extrapolated (couplings at order {p:.2f})",
        "differences": diff,
        "couplings": pairs,
    }


def main() -> None:
    """Parse arguments, run one g/R, print and optionally write JSON."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--gap-over-r", type=float, default=3.0 / 473.0)
    ap.add_argument("--edge-to-gap", type=float, default=0.5)
    ap.add_argument("--element-to-gap", type=float, default=4.0)
    ap.add_argument("--levels", type=int, default=3)
    ap.add_argument(
        "--check-level",
        type=int,
        default=0,
        help="level solved again at --check-order (-1: no check; error = mesh part)",
    )
    ap.add_argument("--order", type=int, default=4)
    ap.add_argument("--check-order", type=int, default=6)
    ap.add_argument(
        "--first-level",
        type=int,
        default=0,
        help="coarsest level solved (-1: one level coarser than --edge-to-gap / --element-to-gap give)",
    )
    ap.add_argument("--iter-tol", type=float, default=1e-5)
    ap.add_argument("--budget-gb", type=float, default=8.0)
    ap.add_argument("--store", default=str(STORE), help="folder of stored solves ('' stores nothing)")
    ap.add_argument("--count", action="store_true", help="count panels only")
    ap.add_argument("--stored-only", action="store_true", help="no solves: summarise what the store holds")
    ap.add_argument(
        "--one",
        nargs=3,
        metavar=("LEVEL", "WHAT", "ORDER"),
        help="one solve into the store and exit (WHAT: centre or step); run under /usr/bin/time -v",
    )
    ap.add_argument("--json")
    ap.add_argument("--calibration-json", help="the direct solution for bench/bem_calibrated_reference.py")
    a = ap.parse_args()
    st = FastcapSettings(
        edge_to_gap=a.edge_to_gap,
        element_to_gap=a.element_to_gap,
        expansion_order=a.order,
        check_order=a.check_order,
        iter_tol=a.iter_tol,
        memory_budget=a.budget_gb * 1e9,
        levels=a.levels,
    )
    one = None
    if a.one:
        if a.one[1] not in ("centre", "step"):
            ap.error(f"--one: WHAT is {a.one[1]!r}; give centre or step")
        one = (int(a.one[0]), a.one[1], int(a.one[2]))
    out = run(
        a.gap_over_r,
        st,
        a.levels,
        a.check_level,
        a.count,
        Path(a.store) if a.store else None,
        one,
        a.first_level,
        a.stored_only,
    )
    print(json.dumps(out, indent=1, default=float))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1, default=float)
    if a.calibration_json and "calibration" in out:
        with open(a.calibration_json, "w") as f:
            json.dump(out["calibration"], f, indent=1, default=float)


if __name__ == "__main__":
    main()
