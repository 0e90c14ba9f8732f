"""The reference disk (examples/levitated_disk.toml: R = 473 um, 10 um thick, 2 x 8 sector
electrodes, 10 um slots) at enlarged gaps: the analytic extractor (parallel plate over the
local gap + edge fringe, netgen.electrostatics.parallel_plate) against the BEM extractor
(netgen.electrostatics.bem) for each plate-electrode capacitance and its z and tilt
derivatives; the adjacent-sector couplings against the earlier 5-15 % (docs/bem.md); the trend of the
differences extrapolated to the reference g/R = 3/473 = 0.0063.

    .venv/bin/python bench/bem_reference_disk.py                    # g/R = 0.05 and 0.02
    .venv/bin/python bench/bem_reference_disk.py --gaps 0.05 --json out.json

    .venv/bin/python bench/bem_reference_disk.py --gaps 0.015 --combined --coordinates 2 --json r.json

Derivatives: central differences of BEM solves on the same meshes (a step closing 1 % of the
gap); --forward halves the cost (one-sided, about 1 % high for 1/g-like capacitances); --combined
takes dC/dz and dC/dtilt_x from one forward solve along both, split by the y-mirror symmetry. The
analytic extractor is differenced over the same step, so the one-sided bias cancels in the
comparison. Each solve prints its mesh sizes, quadrature order, time and peak memory on stderr and
is stored as it finishes (--store, default ~/.cache/netgen/bem_reference_disk): a rerun or an
interrupted run recomputes only what is missing. bench/bem_extrapolate.py (which imports this
script, not the reverse) extrapolates several --json files to the reference gap.
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
from support import ROOT

from netgen.core.constants import EPS0
from netgen.electrostatics import EXTRACTORS, bem
from netgen.geometry.layout import electrodes, plate_outline
from netgen.mechanics import mechanics
from netgen.structure.parse import parse_structure

REFERENCE = ROOT / "examples" / "levitated_disk.toml"
RIGID = ("z", "tilt_x", "tilt_y")
STORE = Path.home() / ".cache" / "netgen" / "bem_reference_disk"


class SolveStore:
    """Each BEM solve of the bench stored as it finishes (one .npz per solve, keyed by g/R, the
    displacement, the quadrature order and the settings), so an interrupted run loses at most the
    solve under way and a rerun or a later extrapolation reads the stored ones."""

    def __init__(self, folder: Path | None):
        """folder None: store nothing."""
        self.folder = folder
        if folder is not None:
            folder.mkdir(parents=True, exist_ok=True)

    def path(self, gr: float, what: str, order: int | None, settings: bem.BemSettings) -> Path:
        """The file of one solve."""
        given = {
            k: v for k, v in asdict(settings).items() if v is not None
        }  # a field added later as None keeps the key
        key = hashlib.sha256(json.dumps([given, order], sort_keys=True).encode()).hexdigest()[:12]
        return self.folder / f"gR{gr:g}_{what}_{key}.npz"

    def solve(self, pb, gr: float, what: str, dq: np.ndarray, order: int | None = None) -> bem.MaxwellMatrix:
        """pb.maxwell(dq, order), from the store when it holds it."""
        if self.folder is None:
            return pb.maxwell(dq, order)
        f = self.path(gr, what, order, pb.settings)
        if f.exists():
            d = np.load(f, allow_pickle=False)
            if np.array_equal(d["q"], dq):
                return bem.MaxwellMatrix(
                    tuple(str(n) for n in d["names"]),
                    d["matrix"],
                    d["coarse"],
                    float(d["error"]),
                    json.loads(str(d["settings"])),
                )
        m = pb.maxwell(dq, order)
        return self.keep(f, dq, m)

    def solve_levelwise(self, pb, gr: float, what: str, dq: np.ndarray, order: int) -> bem.MaxwellMatrix:
        """pb.maxwell(dq, order) on two levels, each level stored as it finishes (an interrupted
        run keeps its coarse level): the same extrapolation as netgen.electrostatics.bem.converged
        with two levels."""
        f = None if self.folder is None else self.path(gr, what, order, pb.settings)
        if f is not None and f.exists():
            return self.solve(pb, gr, what, dq, order)
        t0 = time.perf_counter()
        lv = [self.solve_level(pb, gr, what, dq, order, k) for k in range(2)]
        best, p = bem.extrapolate([m.matrix for m in lv], pb.settings.refinement, pb.settings.richardson_order)
        err = (
            bem.relative_change(best, lv[1].matrix)
            if p is not None
            else bem.relative_change(lv[1].matrix, lv[0].matrix)
        )
        record = {
            "gap": pb.gap,
            "solves": [m.settings["solves"][0] for m in lv],
            "richardson_order": p,
            "seconds": time.perf_counter() - t0,
            "levelwise": True,
        }
        return bem.MaxwellMatrix(pb.names, best, lv[0].matrix, err, record)

    def solve_level(self, pb, gr: float, what: str, dq: np.ndarray, order: int, level: int) -> bem.MaxwellMatrix:
        """One solve on mesh level `level` only (matrix = coarse = that level, error nan), stored."""
        f = None if self.folder is None else self.path(gr, what + f"_level{level}", order, pb.settings)
        if f is not None and f.exists():
            d = np.load(f, allow_pickle=False)
            if np.array_equal(d["q"], dq):
                return bem.MaxwellMatrix(
                    tuple(str(n) for n in d["names"]),
                    d["matrix"],
                    d["coarse"],
                    float(d["error"]),
                    json.loads(str(d["settings"])),
                )
        t0 = time.perf_counter()
        s = pb.settings
        C, cost = bem.solve_surfaces(pb.surfaces(dq, level), pb.eps, order, s.singular_order, s.memory_budget)
        m = bem.MaxwellMatrix(pb.names, C, C, math.nan, {"solves": [cost], "seconds": time.perf_counter() - t0})
        return m if f is None else self.keep(f, dq, m)

    def keep(self, f: Path, dq: np.ndarray, m: bem.MaxwellMatrix) -> bem.MaxwellMatrix:
        """Write one solve to its file (through a .partial file, so a kill leaves no torn one)."""
        tmp = f.with_suffix(".partial.npz")
        np.savez(
            tmp,
            q=dq,
            names=np.array(m.names),
            matrix=m.matrix,
            coarse=m.coarse,
            error=m.error,
            settings=json.dumps(m.settings),
        )
        tmp.replace(f)
        return m


def structure(gap_over_r: float):
    """The reference structure with both gaps set to gap_over_r * R."""
    text = REFERENCE.read_text()
    gap_um = gap_over_r * 473.0
    return parse_structure(text.replace('gap = "3 um"', f'gap = "{gap_um:.6g} um"'), str(REFERENCE))


def settings_for(element_to_gap: float = 4.0, edge_to_gap: float = 0.5, budget_gb: float = 12.0) -> bem.BemSettings:
    """The bench's BEM settings: two mesh levels, 5 % tolerance (the differences it measures are
    several times its error estimate), the memory budget in GB."""
    return bem.BemSettings(
        element_to_gap=element_to_gap,
        edge_to_gap=edge_to_gap,
        max_levels=2,
        tolerance=0.05,
        memory_budget=budget_gb * 1e9,
    )


def elements(gap_over_r: float, settings: bem.BemSettings) -> list[int]:
    """Elements of each mesh level at g/R (meshing only, seconds): the cost projection counts
    them rather than extrapolating, since the plate-size cap on the element size
    (BemSettings.element_to_size) flattens the count at wide gaps."""
    s = structure(gap_over_r)
    m = mechanics(s)
    plate, shapes = plate_outline(s), electrodes(s)
    pb = bem.BemExtractor(eps=EPS0, thickness=s.conductor.thickness, settings=settings).prepare(shapes, plate, m.basis)
    q0 = np.zeros(len(m.names))
    return [sum(len(x.triangles) for x in pb.surfaces(q0, k)) for k in range(settings.max_levels)]


def adjacent_pairs(shapes) -> list[tuple[int, int]]:
    """Index pairs of neighbouring sectors: same side and ring, next sector."""
    out = []
    for i, a in enumerate(shapes):
        for j, b in enumerate(shapes):
            if j <= i or a.side != b.side or a.shape.r_in != b.shape.r_in:
                continue
            if math.isclose(
                a.shape.theta_end % (2 * math.pi), b.shape.theta_start % (2 * math.pi), abs_tol=1e-9
            ) or math.isclose(b.shape.theta_end % (2 * math.pi), a.shape.theta_start % (2 * math.pi), abs_tol=1e-9):
                out.append((i, j))
    return out


def mirrors(shapes) -> list[int]:
    """Index of each electrode's mirror image under y -> -y (same side and ring, angles negated)."""

    def key(e, sign):
        a, b = (e.shape.theta_start, e.shape.theta_end) if sign > 0 else (-e.shape.theta_end, -e.shape.theta_start)
        c = 0.5 * (a + b)
        return e.side, round(e.shape.r_in, 12), round(math.cos(c), 9) + 0.0, round(math.sin(c), 9) + 0.0

    where = {key(e, 1): i for i, e in enumerate(shapes)}
    return [where[key(e, -1)] for e in shapes]


def separate(dc: np.ndarray, mirror: list[int], steps: dict) -> dict:
    """dC/dz and dC/dtilt_x from one forward step along both (dc = C(q0 + dz + dtilt) - C(q0)):
    z keeps the y-mirror symmetry and tilt_x (w = theta y) reverses it, so the mirror pair's mean
    is the z part and half its difference the tilt part (exactly zero for a sector on the x axis)."""
    dc = np.asarray(dc, dtype=float)
    m = dc[mirror]
    return {"z": 0.5 * (dc + m) / steps["z"], "tilt_x": 0.5 * (dc - m) / steps["tilt_x"]}


def run_gap(
    gap_over_r: float,
    settings: bem.BemSettings,
    forward: bool,
    coords: int = 3,
    store: SolveStore | None = None,
    combined: bool = False,
) -> dict:
    """Analytic and BEM capacitances and rigid-coordinate derivatives at one g/R."""
    s = structure(gap_over_r)
    m = mechanics(s)
    plate, shapes = plate_outline(s), electrodes(s)
    pp = EXTRACTORS["parallel_plate"](s, plate).prepare(shapes, plate, m.basis)
    ext = bem.BemExtractor(
        eps=EPS0 * s.electrostatics.relative_permittivity, thickness=s.conductor.thickness, settings=settings
    )
    pb = ext.prepare(shapes, plate, m.basis)
    nc = len(m.names)
    q0 = np.zeros(nc)
    t0 = time.perf_counter()
    store = store or SolveStore(None)
    centre = store.solve(pb, gap_over_r, "q0", q0)
    log(gap_over_r, "q=0", centre)
    c_pp = pp.capacitance(q0)
    for i, e in enumerate(shapes):  # the capacitances at once (derivatives take longer)
        print(
            f"  {e.name:10s} C_bem {centre.plate_electrode[i] * 1e15:9.3f} fF  pp-bem "
            f"{pct(c_pp[i], centre.plate_electrode[i])} %",
            file=sys.stderr,
            flush=True,
        )
    order = centre.settings["solves"][0]["order"]  # the same rule for the differences
    amp = np.abs(pb.geometry.probe.phi).max(axis=0)
    steps = {name: 0.01 * pb.gap / amp[m.names.index(name)] for name in RIGID[:coords]}
    grads_bem, grads_pp, exact_pp = {}, {}, {}
    coarse_grads = None
    for name in RIGID[:coords]:
        exact_pp[name] = pp.gradient(q0)[:, m.names.index(name)]
    if combined:  # one forward solve along z and tilt_x at once
        dq = np.zeros(nc)
        for name in ("z", "tilt_x"):
            dq[m.names.index(name)] = steps[name]
        mirror = mirrors(shapes)
        plus = store.solve_levelwise(pb, gap_over_r, "+z+tilt_x", dq, order)
        log(gap_over_r, "+z+tilt_x", plus)
        grads_bem.update(separate(plus.plate_electrode - centre.plate_electrode, mirror, steps))
        # the same step on the coarsest level alone: bem_extrapolate.level_error's estimate
        coarse_grads = separate(-plus.coarse[0, 1:] + centre.coarse[0, 1:], mirror, steps)
        grads_pp.update(separate(pp.capacitance(dq) - c_pp, mirror, steps))
    for name in [] if combined else RIGID[:coords]:
        v = m.names.index(name)
        dq = np.zeros(nc)
        dq[v] = steps[name]
        plus = store.solve(pb, gap_over_r, f"+{name}", dq, order)
        log(gap_over_r, f"+{name}", plus)
        if forward:
            grads_bem[name] = (plus.plate_electrode - centre.plate_electrode) / steps[name]
            grads_pp[name] = (pp.capacitance(dq) - c_pp) / steps[name]
        else:
            minus = store.solve(pb, gap_over_r, f"-{name}", -dq, order)
            log(gap_over_r, f"-{name}", minus)
            grads_bem[name] = (plus.plate_electrode - minus.plate_electrode) / (2 * steps[name])
            grads_pp[name] = (pp.capacitance(dq) - pp.capacitance(-dq)) / (2 * steps[name])
    pairs = adjacent_pairs(shapes)
    cpl = [centre.coupling[i, j] / centre.plate_electrode[i] for i, j in pairs]
    return {
        "g_over_R": gap_over_r,
        "gap_m": pb.gap,
        "names": [e.name for e in shapes],
        "C_pp": pp.capacitance(q0).tolist(),
        "C_bem": centre.plate_electrode.tolist(),
        "error_bem": centre.error,
        "dC_pp": {k: v.tolist() for k, v in grads_pp.items()},
        "dC_pp_exact": {k: v.tolist() for k, v in exact_pp.items()},
        "steps": steps,
        "maxwell": centre.matrix.tolist(),
        "C_pp_plus": None if not combined else pp.capacitance(dq).tolist(),
        "dC_bem": {k: v.tolist() for k, v in grads_bem.items()},
        "adjacent_coupling_ratio": cpl,
        "pairs": pairs,
        "symmetry": asymmetry(centre.matrix),
        "dC_bem_coarsest_level": None if not coarse_grads else {k: v.tolist() for k, v in coarse_grads.items()},
        "derivatives": "combined forward (z + tilt_x in one solve, split by the y-mirror)"
        if combined
        else "forward"
        if forward
        else "central",
        "seconds": time.perf_counter() - t0,
        "solve": {k: v for k, v in centre.settings.items() if k != "solves"},
        "solves": centre.settings["solves"],
        "all_solves": [x for x in SOLVES if x["g_over_R"] == gap_over_r],
    }


def asymmetry(c: np.ndarray) -> float:
    """max |C - C^T| / max |C|."""
    return float(np.abs(c - c.T).max() / np.abs(c).max())


SOLVES: list[dict] = []  # every solve of the run: g/R, what, mesh levels, seconds (the cost scaling)


def log(gr: float, what: str, m: bem.MaxwellMatrix) -> None:
    """One line per solve on stderr, and its record in SOLVES."""
    SOLVES.append({"g_over_R": gr, "what": what, "levels": m.settings["solves"], "seconds": m.settings.get("seconds")})
    lv = ", ".join(
        f"{s['elements']} el order {s['order']} {s['assembly_s'] + s['solve_s']:.0f} s" for s in m.settings["solves"]
    )
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
    print(
        f"  g/R={gr:g} {what}: est. error {m.error:.2%} ({lv}; peak RSS so far {rss:.2f} GB, "
        f"{time.strftime('%H:%M:%S')})",
        file=sys.stderr,
        flush=True,
    )


def pct(a: float, b: float) -> str:
    """(a/b - 1) in percent."""
    return f"{100 * (a / b - 1):+7.2f}"


def table(r: dict) -> str:
    """The per-electrode table of one g/R."""
    lines = [
        f"g/R = {r['g_over_R']:g} (gap {r['gap_m'] * 1e6:.2f} um), BEM est. error {r['error_bem']:.2%}, "
        f"Maxwell asymmetry {r['symmetry']:.1e}, derivatives {r['derivatives']}, {r['seconds']:.0f} s",
        f"{'electrode':10s} {'C_bem fF':>9s} {'pp-bem %':>8s}"
        + "".join(f" {'d' + k + ' bem':>12s} {'pp-bem %':>8s}" for k in r["dC_bem"]),
    ]
    for i, name in enumerate(r["names"]):
        row = f"{name:10s} {r['C_bem'][i] * 1e15:9.3f} {pct(r['C_pp'][i], r['C_bem'][i]):>8s}"
        for k in r["dC_bem"]:
            b, a = r["dC_bem"][k][i], r["dC_pp"][k][i]
            row += f" {b:12.4e} {pct(a, b) if abs(b) > 1e-3 * max(map(abs, r['dC_bem'][k])) else '     n/a':>8s}"
        lines.append(row)
    c = np.array(r["adjacent_coupling_ratio"])
    lines.append(
        f"adjacent-sector coupling / plate-sector C: {100 * c.min():.1f} .. {100 * c.max():.1f} % (earlier BEM check: 5-15 %)"
    )
    return "\n".join(lines)


def main() -> None:
    """Run the gaps, print the tables and the trend."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--gaps", default="0.05,0.02", help="comma-separated g/R values")
    ap.add_argument("--forward", action="store_true", help="one-sided derivatives (half the solves)")
    ap.add_argument("--element-to-gap", type=float, default=4.0)
    ap.add_argument("--edge-to-gap", type=float, default=0.5)
    ap.add_argument("--budget-gb", type=float, default=12.0)
    ap.add_argument("--coordinates", type=int, default=3, help="derivatives of the first N of z, tilt_x, tilt_y")
    ap.add_argument(
        "--combined",
        action="store_true",
        help="dC/dz and dC/dtilt_x from one forward solve along both (split by the y-mirror symmetry)",
    )
    ap.add_argument("--json", type=Path, help="write the results here")
    ap.add_argument("--store", type=Path, default=STORE, help=f"folder of the stored solves (default {STORE})")
    a = ap.parse_args()
    settings = settings_for(a.element_to_gap, a.edge_to_gap, a.budget_gb)
    results = []
    for gr in (float(g) for g in a.gaps.split(",")):
        results.append(run_gap(gr, settings, a.forward, a.coordinates, SolveStore(a.store), a.combined))
        print(table(results[-1]), flush=True)
        if a.json:
            a.json.write_text(json.dumps(results, indent=1))
    if a.json:
        print(f"trend to the reference gap: .venv/bin/python bench/bem_extrapolate.py {a.json} [more runs' JSON]")


if __name__ == "__main__":
    main()
