"""The closed-loop gyroscope (`netgen gyro`, netgen.testbench.gyro) on examples/gyroscope_z.toml:
a rate sweep of long runs, printing the figures: scale factor over the design's 2 m X_d w_d / F_fb,
nonlinearity over the sweep, zero-rate output (the rate read at Omega = 0: quadrature leaking into
the rate channel), quadrature force against k_xy X_d, and rate noise density. Each rate is one
ngspice run of --cycles periods (2^16 periods of 1 us with the compiled loop: about 20 min of CPU
each on a loaded machine; tests/testbench/test_gyro.py runs 2048).

    .venv/bin/python bench/gyroscope.py [--cycles 65536] [--points 9] [--span 0.5] [--simulator ngspice-xspice] [-o DIR]
"""

from __future__ import annotations

import argparse
import math
import tempfile
from pathlib import Path

from support import ROOT

from netgen.build import build_model
from netgen.emit.ngspice import subcircuit
from netgen.structure import load_structure
from netgen.testbench.gyro.run import GyroRequest, run
from netgen.testbench.sigma_delta.loopfile import read_structure_loop

EXAMPLE = ROOT / "examples" / "gyroscope_z.toml"
K_XY = 5e-3  # N/m, the file's k_xy


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=65536)
    ap.add_argument("--points", type=int, default=9, help="rates (odd: one at 0)")
    ap.add_argument("--span", type=float, default=0.5, help="the sweep's extent, a fraction of the full-scale rate")
    ap.add_argument("--simulator", default="ngspice-xspice")
    ap.add_argument("-o", "--output", default=None)
    a = ap.parse_args()
    model = build_model(load_structure(EXAMPLE), progress=False)
    out = Path(a.output or tempfile.mkdtemp(prefix="gyroscope-"))
    out.mkdir(parents=True, exist_ok=True)
    lib = out / "g.lib"
    lib.write_text(subcircuit(model))
    req = GyroRequest(cycles=a.cycles, rate_points=a.points, rate_span=a.span, simulator=a.simulator, progress=False)
    s = run(model, lib, out, read_structure_loop(EXAMPLE), req)
    deg = math.pi / 180
    print(
        f"full scale {s['full_scale_rate_deg_s']:.5g} deg/s (F_fb {s['feedback_force_n']:.5g} N), {a.cycles} periods per rate"
    )
    for r in s["runs"]:
        print(
            f"  applied {r['rate_applied_rad_s'] / deg:+10.3f} deg/s  read {r['rate_rad_s'] / deg:+10.3f}  "
            f"quadrature force / k_xy X_d - 1 {r['quadrature_force_n'] / (K_XY * r['drive_amplitude_m']) - 1:+.2e}  "
            f"noise {r['rate_noise_deg_s_rthz']:.3g} deg/s/rtHz"
        )
    sw = s["sweep"]
    zero = [r for r in s["runs"] if r["rate_applied_rad_s"] == 0.0]
    print(f"scale factor / design - 1: {sw['slope'] - 1:+.2e}")
    print(f"nonlinearity over +-{a.span:g} full scale: {sw['nonlinearity_of_full_scale']:.2e}")
    if zero:
        print(
            f"zero-rate output: {zero[0]['rate_rad_s'] / deg:+.4f} deg/s (quadrature {zero[0]['quadrature_rad_s'] / deg:.2f} deg/s)"
        )
    print(f"results in {out}")


if __name__ == "__main__":
    main()
