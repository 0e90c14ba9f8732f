"""The closed-loop gyroscope (`netgen gyro`, netgen.testbench.gyro) on examples/gyroscope_z.toml:
a rate sweep of long runs, printing the figures: scale factor over the design's 2 m X_d w_d / F_fb,
nonlinearity over the sweep, zero-rate output (the rate read at Omega = 0: quadrature leaking into
the rate channel), quadrature force against k_xy X_d, and rate noise density. Each rate is one
ngspice run of --cycles periods (2^16 periods of 1 us with the compiled loop: about 20 min of CPU
each on a loaded machine; tests/testbench/test_gyro.py runs 2048).

With --noise-reference: one run at zero rate instead, its rate noise density near the drive read
as tests/oracles/gyro_reference.py reads it (demodulated, 1 Hz to BAND) against the numpy reference
of the same sense loop (two runs of 4 x --cycles periods), with the ratio's F(nu_c, nu_r) 1e-3
quantiles (tests/testbench/test_gyro_noise.py runs 6144 periods over 4 kHz).

    .venv/bin/python bench/gyroscope.py [--cycles 65536] [--points 9] [--span 0.5] [--simulator ngspice-xspice] [-o DIR]
    .venv/bin/python bench/gyroscope.py --noise-reference --cycles 32768
"""

from __future__ import annotations

import argparse
import math
import tempfile
from pathlib import Path

import numpy as np
from scipy import stats
from support import ROOT
from support import gyro_reference as reference

from netgen.build import build_model
from netgen.emit.ngspice import subcircuit
from netgen.structure import load_structure
from netgen.testbench.gyro.run import GyroRequest, run, sense_design
from netgen.testbench.sigma_delta import filters
from netgen.testbench.sigma_delta.loopfile import read_structure_loop

EXAMPLE = ROOT / "examples" / "gyroscope_z.toml"
K_XY = 5e-3  # N/m, the file's k_xy
X_D = 4e-6  # m, the default drive amplitude
BANDS_HZ = (500.0, 1000.0, 2000.0, 4000.0)


def noise_reference(model, out: Path, cycles: int, simulator: str) -> None:
    """The zero-rate run's rate noise density against the reference loop's, per band."""
    spec = read_structure_loop(EXAMPLE)
    lib = out / "g.lib"
    lib.write_text(subcircuit(model))
    s = run(model, lib, out, spec, GyroRequest(cycles=cycles, simulator=simulator, progress=False, plots=False))
    z = np.load(out / "bitstreams.npz")
    keep = slice(cycles // 8, None)
    drive_w = 2 * math.pi * s["runs"][0]["drive_hz"]
    d = sense_design(model, spec, GyroRequest())
    mech, ch = filters.mechanics_of(model, d, "y"), d.channels[0]
    cx = next(c for c in model.coordinates if c.name == "x")
    w = math.sqrt(cx.stiffness / cx.mass)
    refs = [
        reference.simulate(
            mech,
            filters.Filter.from_dict(ch["filter"]),
            4 * cycles,
            w,
            X_D,
            k_xy=K_XY,
            dc=filters.dc_acceleration(model, d, "y"),
            dither=ch["dither_v"],
            dither_step=ch["dither_step"],
            phase=phase,
        )
        for phase in (0.0, math.pi / 2)
    ]
    per_rate = 2 * mech.mass * X_D * w / ch["full_scale_force_si"]
    deg = lambda sd: math.degrees(math.sqrt(2 * sd) / per_rate)  # noqa: E731
    print(f"{cycles} periods at zero rate, reference 2 x {4 * cycles}; rate noise density (deg/s/rtHz):")
    for band in BANDS_HZ:
        got, nu_c = reference.inband_density(z["time_0"][keep], z["bits_y_0"][keep], d.ts, drive_w, band)
        rk = slice(len(refs[0]["v"]) // 8, None)
        reads = [reference.inband_density(r["t"][rk], r["v"][rk], d.ts, w, band) for r in refs]
        want, nu_r = float(np.mean([r[0] for r in reads])), sum(r[1] for r in reads)
        low, high = stats.f.ppf([5e-4, 1 - 5e-4], nu_c, nu_r)
        print(
            f"  1 Hz..{band:5.0f} Hz: circuit {deg(got):.4g}, reference {deg(want):.4g}, ratio "
            f"{10 * math.log10(got / want):+.2f} dB (F 1e-3 quantiles {10 * math.log10(low):+.2f}, "
            f"{10 * math.log10(high):+.2f} dB; nu {nu_c:.0f}, {nu_r:.0f})"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=65536)
    ap.add_argument("--points", type=int, default=9, help="rates (odd: one at 0)")
    ap.add_argument("--span", type=float, default=0.5, help="the sweep's extent, a fraction of the full-scale rate")
    ap.add_argument("--simulator", default="ngspice-xspice")
    ap.add_argument("-o", "--output", default=None)
    ap.add_argument("--noise-reference", action="store_true", help="the noise floor against the reference loop")
    a = ap.parse_args()
    model = build_model(load_structure(EXAMPLE), progress=False)
    out = Path(a.output or tempfile.mkdtemp(prefix="gyroscope-"))
    out.mkdir(parents=True, exist_ok=True)
    if a.noise_reference:
        return noise_reference(model, out, a.cycles, a.simulator)
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
