"""The calibrated extractor against BEM on a disk between sector electrodes: writes a structure
(the reference disk's radius and thickness, `--rings` rings of four sectors per side at `--gap`,
rigid coordinates), builds it with extractor = "calibrated" and `--points` BEM solves (needs the
BEM extractor: pip install -e '.[bem]'), and prints per electrode the analytic and calibrated
errors of C and of its central differences against BEM, the fitted fringes and the couplings
over C(0), with the wall time:

    .venv/bin/python bench/calibrate_bem.py OUT [--gap 20um] [--points 7] [--rings 1] [--slot 20um]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from support import ROOT

from netgen.cli.commands import main as netgen
from netgen.electrostatics.calibration import pairs

# the reduced disk of examples/calibrated_disk.toml (tests/electrostatics/test_calibration.py
# shares it): its geometry without the [electrostatics] table, then gap, slot and rings set here
EXAMPLE = ROOT / "examples" / "calibrated_disk.toml"
RINGS = {1: '[["20 um", "473 um"]]', 2: '[["20 um", "230 um"], ["240 um", "473 um"]]'}
# a central difference of the field solution below this fraction of the largest along its
# coordinate vanishes by symmetry: its error is printed against C(0), not relative to itself
VANISHING = 1e-3


def structure(gap: str, slot: str, rings: int, points: int) -> str:
    """The example's reduced disk at `gap`, `slot`, `rings` rings per side, calibrated at `points` BEM solves."""
    text = EXAMPLE.read_text().split("[electrostatics]")[0]
    for old, new in (
        ('gap = "3 um"', f'gap = "{gap}"'),
        ('slot = "10 um"', f'slot = "{slot}"'),
        ('rings = [["20 um", "473 um"]]', f"rings = {RINGS[rings]}"),
    ):
        if old not in text:
            raise SystemExit(f"{EXAMPLE}: no line {old!r} to replace")
        text = text.replace(old, new)
    return text + f'[fit]\nholdout = 50\n[electrostatics]\nextractor = "calibrated"\ncalibration_points = {points}\n'


def derivative_errors(r: dict, name: str, label: str) -> dict[str, str]:
    """Per coordinate the worst error of the central differences of C of `label` ("analytic" or
    "calibrated"): relative where the field solution's difference is finite, and as a fraction
    of C(0) where it vanishes by symmetry (a relative error of a near-zero value says nothing)."""
    row, coords = r["electrodes"][name], r["coordinates"]
    c = np.asarray(row["c_field_F"])
    q = np.asarray(r["points_si"])
    out = {}
    for v, rel in row[f"{label}_dc_rel_error"].items():
        v = int(v)
        ks = [(k, j) for vv, k, j, _ in pairs(q) if vv == v]
        dc = np.array([c[k] - c[j] for k, j in ks])
        largest = max(
            abs(np.asarray(x["c_field_F"])[k] - np.asarray(x["c_field_F"])[j])
            for x in r["electrodes"].values()
            for k, j in ks
        )
        kept = [d for d in dc if abs(d) > 1e-6 * abs(c[0])]  # the differences comparison() kept
        if all(abs(d) < VANISHING * largest for d in kept):
            err = max(abs(e * d) for e, d in zip(rel, kept)) / c[0]
            out[coords[v]] = f"{100 * err:.3f} % of C(0) (vanishes by symmetry)"
        else:
            out[coords[v]] = f"{100 * max(abs(e) for e in rel):.2f} %"
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out", type=Path)
    p.add_argument("--gap", default="20 um")
    p.add_argument("--slot", default="20 um")
    p.add_argument("--points", type=int, default=7)
    p.add_argument("--rings", type=int, choices=(1, 2), default=1)
    a = p.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "bem_disk.toml").write_text(structure(a.gap, a.slot, a.rings, a.points))
    start = time.perf_counter()
    code = netgen(["build", str(a.out / "bem_disk.toml"), "-o", str(a.out / "model"), "--format", "all", "-q"])
    print(f"build exit {code}, {time.perf_counter() - start:.0f} s")
    if code:
        raise SystemExit(code)
    r = json.loads((a.out / "model" / "calibrated_disk_calibration.json").read_text())
    print(f"{r['source']}; BEM estimated errors {[f'{e:.1e}' for e in r['field_solution_rel_errors']]}")
    for name, s in r["summary"].items():
        f = next(x for x in r["calibration"]["fringe"] if x["electrode"] == name)
        before, after = derivative_errors(r, name, "analytic"), derivative_errors(r, name, "calibrated")
        dc = ", ".join(f"{c} {before[c]} -> {after[c]}" for c in before)
        cc = ", ".join(f"{k} {100 * v:.1f} %" for k, v in r["electrodes"][name]["coupling_over_c0"].items())
        print(
            f"{name}: C {100 * s['analytic_c_max_abs_rel_error']:.2f} -> {100 * s['calibrated_c_max_abs_rel_error']:.3f} %; "
            f"dC {dc}; a {f['a']:.4f} b {f['b']:.4f}; couplings/C(0): {cc}"
        )


if __name__ == "__main__":
    main()
