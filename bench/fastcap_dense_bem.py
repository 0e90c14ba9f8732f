"""The multipole extractor (netgen.electrostatics.fastcap) against the dense BEM
(netgen.electrostatics.bem) on the reference disk's layout scaled to R = 100 um
(tests/oracles/small_disk.reference_layout: 2 rings x 4 quadrants above a thin disk), per
electrode: C, dC/dz and dC/dtilt_x, each solver with its own error bar (docs/fastcap.md,
'Against the dense BEM, per electrode').

    .venv/bin/python bench/fastcap_dense_bem.py --gap-over-r 0.05 --solver fastcap --element-to-gap 2 --levels 3 --json fc.json
    .venv/bin/python bench/fastcap_dense_bem.py --gap-over-r 0.05 --solver bem --edge-to-gap 0.5 --element-to-gap 2 --levels 2 --no-centre --json bem.json
    .venv/bin/python bench/fastcap_dense_bem.py --compare fc.json bem.json   # the markdown table of two runs
    ... --only 1+ 1-        # solve and store only these (level, q); one process each, then rerun without

--solver bem-graded triangulates the BEM's plate face through the corners of FastCap's face
(graded towards the electrode outlines; bem_mesh.plate_face grades a disk towards its rim only).
Diagnostics printed beside the values: each electrode's meshed area against the slot-trimmed
sector's, and C with the lost area's parallel-plate charge added back.

Every mesh level is solved on its own at q = 0 and at +-(dz, dtilt_x) (central differences, one
step along both, split by the y-mirror: bem_reference_disk.separate), and stored as it finishes
(--store): a rerun recomputes only what is missing. Each quantity (C and both derivatives) is
Richardson-extrapolated over the last two levels at order 2 (with three levels the order observed
from the last three is printed beside it); its bar is the Richardson correction, plus for FastCap
the change of the coarse level from --order to --check-order (the multipole error, and the
multipole tree's jumps between the displaced solves).

Step: s = 1 % of the gap along z and s g / R in tilt (the rim moves by s g). For C ~ 1/(g - z)
the central difference is high by s^2 = 1e-4 of dC/dz, the same for both solvers (it cancels in
their comparison); the solver noise it amplifies is 1/s = 100 (z) and R / (s r) (tilt, r the
electrode's mean radius: 200..400) times the noise of C: rounding in the dense solve (1e-13),
FastCap's GMRES (--iter-tol 1e-6 here, not the extractor's 1e-4, which would allow 1e-2 of a derivative)
and its multipole tree, which the order change bounds.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import resource
import sys
import time
from pathlib import Path

import numpy as np
from bem_reference_disk import mirrors, separate
from scipy.spatial import Delaunay
from support import small_disk

from netgen.core.constants import EPS0
from netgen.electrostatics import bem, fastcap
from netgen.electrostatics.bem_mesh import Surface
from netgen.electrostatics.fastcap_mesh import disk_face

R = 100e-6
ASPECT = 4.0  # the graded plate's longest panel side over its radial side (fastcap_mesh.ASPECT)
STORE = Path.home() / ".cache" / "netgen" / "fastcap_dense_bem"


def basis(x, y):
    """Rigid z and tilt_x (w = z + theta y)."""
    x, y = np.broadcast_arrays(np.atleast_1d(np.asarray(x, float)), np.atleast_1d(np.asarray(y, float)))
    return np.stack([np.ones_like(x), y], axis=1)


def prepared(solver: str, gap: float, edge: float, element: float, levels: int, order: int, iter_tol: float):
    """The prepared extractor of one solver (bem: `levels` mesh levels meshed; order unused)."""
    plate, els = small_disk.reference_layout(gap, R)
    if solver.startswith("bem"):
        st = bem.BemSettings(edge_to_gap=edge, element_to_gap=element, max_levels=levels, memory_budget=8e9)
        return bem.BemExtractor(eps=EPS0, settings=st).prepare(els, plate, basis), els
    st = fastcap.FastcapSettings(
        edge_to_gap=edge, element_to_gap=element, levels=levels, expansion_order=order, iter_tol=iter_tol
    )
    return fastcap.FastcapExtractor(settings=st).prepare(els, plate, basis), els


def graded_plate(p, els, level: int) -> tuple[Surface, np.ndarray]:
    """The BEM's plate face triangulated through the corners of the multipole extractor's panels
    (fastcap_mesh.disk_face at the BEM's sizes: graded towards the rim and towards every electrode
    radius and slot side in projection; scipy's Delaunay of the corner points, a conforming mesh),
    and the basis at its vertices. bem_mesh.plate_face grades a disk towards its rim only."""
    sizes = p.settings.sizes(p.gap, level, p.plate_size)
    face = disk_face(R, [e.shape for e in els], sizes, aspect=ASPECT)
    xy = np.unique(np.round(face.corners[:, :, :2].reshape(-1, 2) / (1e-9 * R)), axis=0) * (1e-9 * R)
    tri = Delaunay(xy).simplices
    c = xy[tri]
    u, w = c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]
    area = 0.5 * np.abs(u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0])
    tri = tri[area > 1e-12 * area.max()]
    v = np.column_stack([xy, np.zeros(len(xy))])
    return Surface(v, tri), basis(xy[:, 0], xy[:, 1])


def solve(p, solver: str, q: np.ndarray, level: int, order: int, iter_tol: float, els=()) -> tuple[np.ndarray, dict]:
    """Maxwell matrix of one level at q (bem: quadrature by the element-to-gap rule; bem-graded:
    the plate face of graded_plate; fastcap: multipole `order`)."""
    if solver.startswith("bem"):
        st = p.settings
        qo = bem.quadrature_order(st.sizes(p.gap, 0, p.plate_size).h_max / p.gap)
        surfaces = p.surfaces(q, level)
        if solver == "bem-graded":
            plate, phi = graded_plate(p, els, level)
            surfaces = [plate.moved(phi @ q), *surfaces[1:]]
        return bem.solve_surfaces(surfaces, EPS0, qo, st.singular_order, st.memory_budget)
    return fastcap.solve_panels(p.panels(q, level), 1.0, order, iter_tol)


def stored(store: Path, key: dict, make) -> tuple[np.ndarray, dict]:
    """make() once per key (an .npz in store)."""
    h = hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:16]
    f = store / f"{h}.npz"
    if f.exists():
        d = np.load(f, allow_pickle=False)
        return d["C"], json.loads(str(d["record"]))
    C, rec = make()
    rec = {**rec, "peak_rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6}
    tmp = f.with_suffix(".partial.npz")
    np.savez(tmp, C=C, record=json.dumps(rec), key=json.dumps(key))
    tmp.replace(f)
    return C, rec


def sector_area(shape, n: int = 200001) -> float:
    """Area of an annular sector trimmed by its slot (two lines slot / 2 from its radial edges), by quadrature."""
    r = np.linspace(shape.r_in, shape.r_out, n)
    w = r * (shape.theta_end - shape.theta_start) - 2.0 * r * np.arcsin(np.minimum(1.0, 0.5 * shape.slot / r))
    return float(np.trapezoid(np.maximum(w, 0.0), r))


def mesh_areas(p, solver: str, level: int) -> np.ndarray:
    """Each electrode's meshed area on one level (flat chords and panels lose area at the arcs)."""
    if solver.startswith("bem"):
        return np.array([s.areas().sum() for s in p.surfaces(np.zeros(2), level)[1:]])
    return np.array([c.areas().sum() for c in p.panels(np.zeros(2), level)[1:]])


def quantities(cs: dict, mirror: list[int], steps: dict) -> dict:
    """C, dC/dz, dC/dtilt_x per electrode from the Maxwell matrices at 0, +d, -d."""
    c = {k: -v[0, 1:] for k, v in cs.items()}
    d = separate(0.5 * (c["+"] - c["-"]), mirror, steps)
    mean = 0.5 * (c["+"] + c["-"])  # C(0) + s^2 g^2 C''/2: 1e-4 of C high for C ~ 1/(g - z)
    return {"C": c.get("0", mean), "C_pm": mean, "dz": d["z"], "dtilt": d["tilt_x"]}


def richardson(values: list[np.ndarray], ratio: float) -> dict:
    """Order-2 Richardson of the last two levels, its correction (the bar), the observed order."""
    fine, coarse = values[-1], values[-2]
    best = fine + (fine - coarse) / (ratio**2 - 1.0)
    out = {"best": best, "bar": np.abs(best - fine), "fine": fine}
    if len(values) >= 3:
        with np.errstate(divide="ignore", invalid="ignore"):
            r = (values[-2] - values[-3]) / (fine - coarse)
            observed = np.where(r > 1.0, np.log(np.abs(r)) / math.log(ratio), np.nan)
            # the observed order where bem.extrapolate would trust it (0.5 .. 4), else 2
            p = np.where((observed >= 0.5) & (observed <= 4.0), observed, 2.0)
            out["observed_order"] = observed
            out["best_observed"] = fine + (fine - coarse) / (ratio**p - 1.0)
            # its bar: its own correction, and at least the distance to the order-2 estimate
            out["bar_observed"] = np.maximum(np.abs(out["best_observed"] - fine), np.abs(out["best_observed"] - best))
    return out


def run(a) -> dict:
    """Every level at 0 and +-d (and FastCap's check order on level 0), the extrapolated quantities."""
    gap = a.gap_over_r * R
    p, els = prepared(a.solver, gap, a.edge_to_gap, a.element_to_gap, a.levels, a.order, a.iter_tol)
    steps = {"z": a.step * gap, "tilt_x": a.step * gap / R}
    d = np.array([steps["z"], steps["tilt_x"]])
    qs = {"+": d, "-": -d} if a.no_centre else {"+": d, "-": -d, "0": np.zeros(2)}
    mirror = mirrors(els)
    a.store.mkdir(parents=True, exist_ok=True)
    base = {
        "solver": a.solver,
        "gap": gap,
        "edge": a.edge_to_gap,
        "element": a.element_to_gap,
        "tol": a.iter_tol if a.solver == "fastcap" else None,
        **({"aspect": a.aspect} if a.aspect != 4.0 else {}),
        # the BEM's meshes since bem_mesh made them dihedral (a new key: the stored asymmetric solves stay apart)
        **({"mesh": "dihedral"} if a.solver.startswith("bem") else {}),
    }
    per_level, records = [], []
    runs = [(k, a.order) for k in range(a.levels)]
    if a.solver == "fastcap":
        runs.append((0, a.check_order))
    for level, order in runs:
        cs = {}
        for name, q in qs.items():
            if a.only and f"{level}{name}" not in a.only:
                continue
            key = {**base, "level": level, "order": order if a.solver == "fastcap" else None, "q": q.tolist()}
            t0 = time.perf_counter()
            cs[name], rec = stored(
                a.store, key, lambda q=q, level=level, order=order: solve(p, a.solver, q, level, order, a.iter_tol, els)
            )
            records.append({"level": level, "order": order, "q": name, **rec})
            print(
                f"{time.strftime('%H:%M:%S')} {a.solver} g/R {a.gap_over_r} level {level} "
                f"{'order ' + str(order) if a.solver == 'fastcap' else ''} q{name}: "
                f"{rec.get('panels', rec.get('elements'))} unknowns, {time.perf_counter() - t0:.0f} s "
                f"(stored record {rec.get('seconds', rec.get('assembly_s', 0) + rec.get('solve_s', 0)):.0f} s), "
                f"peak {rec['peak_rss_gb']:.2f} GB",
                file=sys.stderr,
                flush=True,
            )
        if a.only:
            continue
        per_level.append(quantities(cs, mirror, steps))
    if a.only:
        return {}
    ratio = math.sqrt(2.0)
    exact = np.array([sector_area(e.shape) for e in els])
    for k, lv in enumerate(per_level[: a.levels]):
        lv["area_deficit"] = mesh_areas(p, a.solver, k) / exact - 1.0
        # the parallel-plate charge of the area the chords lose: a diagnostic of how much of a
        # level's change is the electrodes' outline, not the field
        lv["C_area"] = lv["C"] - EPS0 * exact * lv["area_deficit"] / gap
    out = {
        "args": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(a).items()},
        "names": [e.name for e in els],
    }
    out["records"] = records
    mesh = per_level[: a.levels]
    out["centre"] = not a.no_centre
    for qn in ("C", "C_pm", "dz", "dtilt", "area_deficit", "C_area"):
        r = richardson([lv[qn] for lv in mesh], ratio)
        if a.solver == "fastcap" and qn not in ("area_deficit", "C_area"):
            r["order_change"] = np.abs(per_level[-1][qn] - mesh[0][qn])
            r["bar"] = r["bar"] + r["order_change"]
            if "bar_observed" in r:
                r["bar_observed"] = r["bar_observed"] + r["order_change"]
        r["levels"] = [lv[qn] for lv in mesh]
        out[qn] = {k: np.asarray(v).tolist() for k, v in r.items()}
    return out


def table(x: dict) -> str:
    """One run's quantities per electrode: value, bar, fine level, observed order."""
    lines = []
    for qn, unit in (("C", 1e15), ("dz", 1e9), ("dtilt", 1e12), ("C_area", 1e15)):
        q = x[qn]
        lines.append(
            {"C": "C (fF)", "dz": "dC/dz (fF/um)", "dtilt": "dC/dtilt_x (fF/mrad)"}.get(
                qn, "C + eps0 (sector area - meshed area) / g (fF), a diagnostic"
            )
        )
        for i, n in enumerate(x["names"]):
            b = q["best"][i]
            rel = q["bar"][i] / abs(b) if b else math.nan
            obs = q.get("observed_order", [math.nan] * len(x["names"]))[i]
            lvl = " ".join(f"{v[i] * unit:.5g}" for v in q["levels"])
            lines.append(f"  {n}: {b * unit:.6g} +- {100 * rel:.3f} %  levels {lvl}  observed order {obs:.2f}")
    q = x["area_deficit"]
    lines.append("meshed area / sector area - 1 (%): levels, order-2 extrapolation")
    for i, n in enumerate(x["names"]):
        lines.append(f"  {n}: {' '.join(f'{100 * v[i]:+.3f}' for v in q['levels'])} -> {100 * q['best'][i]:+.3f}")
    return "\n".join(lines)


def compare(fc: dict, bm: dict, observed: bool = False) -> str:
    """A markdown table: per electrode and quantity FastCap, BEM (each +- its bar in %), FastCap / BEM - 1
    and the sum of both bars (C from the mean of the +-d solves when either run skipped q = 0).
    observed: each run's estimate at its observed order where it has three levels (best_observed)."""
    c = "C" if fc.get("centre", True) and bm.get("centre", True) else "C_pm"

    def est(x: dict, qn: str, i: int) -> tuple[float, float]:
        q = x[qn]
        if observed and "best_observed" in q:
            return q["best_observed"][i], q["bar_observed"][i]
        return q["best"][i], q["bar"][i]

    units = {c: (1e15, "fF"), "dz": (1e9, "fF/um"), "dtilt": (1e12, "fF/mrad")}
    head = "| electrode |" + "".join(
        f" {q} FastCap ({u}) | {q} BEM | dev | bars |"
        for q, (_, u) in zip(("C", "dC/dz", "dC/dtilt_x"), units.values())
    )
    lines = [head, "|" + " --- |" * 13]
    for i, n in enumerate(fc["names"]):
        row = f"| {n} |"
        for qn, (unit, _) in units.items():
            (f, bf), (b, bb) = est(fc, qn, i), est(bm, qn, i)
            if abs(b) < 1e-6 * max(abs(v) for v in bm[qn]["best"]):
                row += " 0 | 0 | (symmetry) | |"
                continue
            ef, eb = bf / abs(f), bb / abs(b)
            row += (
                f" {f * unit:.5g} ({100 * ef:.2f} %) | {b * unit:.5g} ({100 * eb:.2f} %) |"
                f" {100 * (f / b - 1):+.3f} % | {100 * (ef + eb):.2f} % |"
            )
        lines.append(row)
    return "\n".join(lines)


def main() -> None:
    """Run one solver at one g/R, or compare two runs' JSON."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--gap-over-r", type=float, default=0.05)
    ap.add_argument("--solver", choices=("fastcap", "bem", "bem-graded"), default="fastcap")
    ap.add_argument("--edge-to-gap", type=float, default=0.25)
    ap.add_argument("--element-to-gap", type=float, default=2.0)
    ap.add_argument("--levels", type=int, default=2)
    ap.add_argument("--order", type=int, default=6, help="FastCap's expansion order")
    ap.add_argument("--check-order", type=int, default=8, help="FastCap's check order (coarse level)")
    ap.add_argument("--iter-tol", type=float, default=1e-6)
    ap.add_argument("--step", type=float, default=0.01, help="the step in units of the gap")
    ap.add_argument(
        "--no-centre", action="store_true", help="skip q = 0: C from the mean of the +-d solves (1e-4 high)"
    )
    ap.add_argument(
        "--aspect", type=float, default=4.0, help="bem-graded: the plate's panel aspect (fastcap_mesh.ASPECT)"
    )
    ap.add_argument(
        "--only", nargs="+", help="solve and store only these, as level and q (0+ 1- 10 ...): one run per process"
    )
    ap.add_argument(
        "--observed", action="store_true", help="--compare: each run at its observed order where it has three levels"
    )
    ap.add_argument("--store", type=Path, default=STORE)
    ap.add_argument("--json", type=Path)
    ap.add_argument("--compare", nargs=2, type=Path, metavar=("FASTCAP_JSON", "BEM_JSON"))
    a = ap.parse_args()
    if a.compare:
        fc, bm = (json.loads(f.read_text()) for f in a.compare)
        print(compare(fc, bm, a.observed))
        return
    global ASPECT
    ASPECT = a.aspect
    out = run(a)
    if a.only:
        return
    print(table(out))
    if a.json:
        a.json.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
