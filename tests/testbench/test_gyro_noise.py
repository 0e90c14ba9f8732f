"""`netgen gyro`'s rate noise floor against the numpy reference of the same loop equations
(tests/oracles/gyro_reference.py: the sense mode a resonator discretised exactly at the loop's
clock, the loop filter and quantiser as netgen.testbench.sigma_delta.loop.design made them, the
drive an ideal sinusoid at its amplitude): both bitstreams demodulated and read the same way
(gyro_reference.inband_density), at zero rate, with the quadrature k_xy X_d on.

Tolerance (derived): the reading is a mean of K Hann-periodogram bins, S_hat / S ~ chi2_nu / nu
with nu = 2 K / (1 + 2 (4/9 + 1/36)) (the Hann bins' correlation); the ratio of the circuit's and
the reference's readings is then F(nu_c, nu_r) distributed, and the test takes its two-sided 1e-3
quantiles. A 6144-period ngspice run read over the 4 kHz either side of the drive gives nu_c = 21:
the quantiles are -5.7 dB and +3.9 dB (the 2 x 65536-period reference: nu_r = 469); measured
-1.55 dB. Not all of the noise is Gaussian: two reference runs of 131072 periods at drive phases
0 and 90 degrees read 2 dB apart over 4 kHz (chi-square: +-0.6 dB), so the measured value keeps
4 dB from either quantile. The 3 dB statement needs nu_c near 60 (F(58, 469): -3.2 dB, +2.6 dB):
bench/gyroscope.py --noise-reference reads 32768 periods over 500 Hz to 4 kHz, where the loop's
notch at the sense resonance shapes the noise (docs/gyroscope.md: -0.58 dB over 2 kHz). About
40 s of CPU (100 s on the loaded 2-core machine)."""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

from netgen.build import build_model
from netgen.emit.ngspice import subcircuit
from netgen.structure import load_structure
from netgen.testbench.gyro.run import GyroRequest, run, sense_design
from netgen.testbench.sigma_delta import filters
from netgen.testbench.sigma_delta.loopfile import read_structure_loop
from tests.fixtures import ROOT
from tests.oracles import gyro_reference as reference

EXAMPLE = ROOT / "examples" / "gyroscope_z.toml"
K_XY = 5e-3  # N/m, the file's k_xy
X_D = 4e-6
CYCLES, REFERENCE_CYCLES, BAND_HZ = 6144, 65536, 4000.0
QUANTILE = 1e-3


def test_rate_noise_floor_matches_the_reference_loop(tmp_path):
    """The in-band bit PSD near the drive of a 6144-period ngspice run over that of the reference
    loop (two runs of 65536 periods, drive phases 0 and pi/2): inside the F(nu_c, nu_r) 1e-3
    quantiles (module docstring)."""
    model = build_model(load_structure(EXAMPLE))
    spec = read_structure_loop(EXAMPLE)
    lib = tmp_path / "g.lib"
    lib.write_text(subcircuit(model))
    s = run(model, lib, tmp_path / "run", spec, GyroRequest(cycles=CYCLES, progress=False, plots=False))
    z = np.load(tmp_path / "run" / "bitstreams.npz")
    keep = slice(CYCLES // 8, None)  # run.SKIP: the loop's start
    drive_w = 2 * math.pi * s["runs"][0]["drive_hz"]
    got, nu_c = reference.inband_density(z["time_0"][keep], z["bits_y_0"][keep], s["ts"], drive_w, BAND_HZ)

    d = sense_design(model, spec, GyroRequest())
    mech, ch = filters.mechanics_of(model, d, "y"), d.channels[0]
    cx = next(c for c in model.coordinates if c.name == "x")
    w = math.sqrt(cx.stiffness / cx.mass)
    want, nu_r = [], 0.0
    for phase in (0.0, math.pi / 2):
        r = reference.simulate(
            mech,
            filters.Filter.from_dict(ch["filter"]),
            REFERENCE_CYCLES,
            w,
            X_D,
            k_xy=K_XY,
            dc=filters.dc_acceleration(model, d, "y"),
            dither=ch["dither_v"],
            dither_step=ch["dither_step"],
            phase=phase,
        )
        k = slice(REFERENCE_CYCLES // 8, None)
        sr, nu = reference.inband_density(r["t"][k], r["v"][k], d.ts, w, BAND_HZ)
        want.append(sr)
        nu_r += nu
    ratio = got / float(np.mean(want))
    low, high = stats.f.ppf([QUANTILE / 2, 1 - QUANTILE / 2], nu_c, nu_r)
    per_rate = 2 * mech.mass * X_D * w / ch["full_scale_force_si"]
    print(
        f"rate noise: circuit {math.degrees(math.sqrt(2 * got) / per_rate):.4g}, reference "
        f"{math.degrees(math.sqrt(2 * np.mean(want)) / per_rate):.4g} deg/s/rtHz over +-{BAND_HZ:g} Hz; "
        f"ratio {10 * math.log10(ratio):+.2f} dB in [{10 * math.log10(low):+.2f}, {10 * math.log10(high):+.2f}] dB "
        f"(nu {nu_c:.1f}, {nu_r:.1f})"
    )
    assert low <= ratio <= high
