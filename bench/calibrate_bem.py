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

from netgen.cli import main as netgen

STRUCTURE = '''name = "bem_disk"
description = "disk between sector electrodes at an enlarged gap (bench/calibrate_bem.py)"
[conductor]
kind = "free_disk"
radius = "473 um"
thickness = "10 um"
youngs_modulus = "160 GPa"
poisson_ratio = 0.22
density = "2330 kg/m^3"
{electrodes}
[coordinates]
rigid = ["z", "tilt_x", "tilt_y"]
[fit]
holdout = 50
[electrostatics]
extractor = "calibrated"
calibration_points = {points}
'''
ELECTRODES = '''[[electrodes]]
name = "{side}"
side = "{where}"
gap = "{gap}"
rings = {rings}
sectors = 4
sector_start = "-45 deg"
slot = "{slot}"
'''


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out", type=Path)
    p.add_argument("--gap", default="20 um")
    p.add_argument("--slot", default="20 um")
    p.add_argument("--points", type=int, default=7)
    p.add_argument("--rings", type=int, choices=(1, 2), default=1)
    a = p.parse_args()
    rings = '[["20 um", "473 um"]]' if a.rings == 1 else '[["20 um", "230 um"], ["240 um", "473 um"]]'
    els = "".join(ELECTRODES.format(side=s, where=w, gap=a.gap, rings=rings, slot=a.slot)
                  for s, w in (("top", "above"), ("bot", "below")))
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "bem_disk.toml").write_text(STRUCTURE.format(electrodes=els, points=a.points))
    start = time.perf_counter()
    code = netgen(["build", str(a.out / "bem_disk.toml"), "-o", str(a.out / "model"), "--format", "all", "-q"])
    print(f"build exit {code}, {time.perf_counter() - start:.0f} s")
    if code:
        raise SystemExit(code)
    r = json.loads((a.out / "model" / "bem_disk_calibration.json").read_text())
    print(f"{r['source']}; BEM estimated errors {[f'{e:.1e}' for e in r['field_solution_rel_errors']]}")
    for name, s in r["summary"].items():
        f = next(x for x in r["calibration"]["fringe"] if x["electrode"] == name)
        dc = ", ".join(f"{c} {100 * v:.2f}->{100 * s['calibrated_dc_max_abs_rel_error'][c]:.2f} %"
                       for c, v in s["analytic_dc_max_abs_rel_error"].items())
        cc = ", ".join(f"{k} {100 * v:.1f} %" for k, v in r["electrodes"][name]["coupling_over_c0"].items())
        print(f"{name}: C {100 * s['analytic_c_max_abs_rel_error']:.2f} -> {100 * s['calibrated_c_max_abs_rel_error']:.3f} %; "
              f"dC {dc}; a {f['a']:.4f} b {f['b']:.4f}; couplings/C(0): {cc}")


if __name__ == "__main__":
    main()
