"""`netgen gyro`'s Brownian rate noise floor against the numpy reference of the same loop equations
(tests/oracles/gyro_reference.py: the sense mode a resonator discretised exactly at the loop's
clock, the loop filter and quantiser as netgen.testbench.sigma_delta.loop.design made them, the
drive an ideal sinusoid at its amplitude, the same thermal force), both bitstreams read the same
way (gyro_reference.band_density), at zero rate, with the quadrature k_xy X_d on. The
quantisation-only floor's comparison is bench/gyroscope.py --noise-reference: at the 6144 periods
a test can afford, the drive phase moves that floor so much that its interval is +-6.7 dB.

Tolerance (derived): the circuit's one reading against the readings of the reference over pieces
of the same length (gyro_reference.segment_readings): it must lie in their two-sided 1e-3
prediction interval (gyro_reference.prediction_interval, Student's t on the logarithms). The
reference's own spread is the yardstick because the bits are not Gaussian noise: their band power
fluctuates together across bins, so a Hann bin count overstates the degrees of freedom about
twofold (the Brownian variant: 29 measured, 60 counted; bench/gyroscope.py --dof), and an F or
chi-square bound from that count fails on some draws. ngspice seeds TRNOISE from its process id
and the loop is chaotic under another CPU's rounding, so every run is a new draw; the interval is
what makes the check hold on any machine."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from netgen.build import build_model
from netgen.emit import xspice
from netgen.emit.ngspice import subcircuit
from netgen.structure import load_structure
from netgen.testbench.gyro.run import GyroRequest, run, sense_design
from netgen.testbench.sigma_delta.loopfile import read_structure_loop
from tests.fixtures import ROOT
from tests.oracles import gyro_reference as reference

EXAMPLE = ROOT / "examples" / "gyroscope_z.toml"
REFERENCE_CYCLES = 65536
REFERENCE_RUNS = 4  # seeds of the reference, each run cut into pieces of the circuit's length
QUANTILE = 1e-3
# the Brownian check (test_brownian_rate_noise_floor): periods, the band either side of the drive
BROWNIAN_CYCLES, BROWNIAN_BAND_HZ = 8192, 4000.0
# the span of the loop's |STF|^2 across the drive +-4 kHz (test_brownian_rate_noise_floor's docstring)
TRANSFER_RANGE = (0.8, 1.43)
TEMPERATURE = 300.0  # K, the structure's [damping] temperature (its default)


@pytest.mark.slow
def test_brownian_rate_noise_floor(tmp_path):
    """With the thermal force on, the rate noise floor is the sense damping's Brownian limit.

    The design: examples/gyroscope_z.toml with the sense damped to Q_y = 10, [damping] noise = true and
    a fourth-order CIFB sense loop (gyro_reference.brownian_variant, which says why). The closed
    form: the thermal force's one-sided PSD 4 k_B T b_y, b_y = m w_y / Q_y (the model's y mass and
    stiffness, the file's Q_y), over the feedback force squared is the bits' PSD near the drive,
    S_B = 4 k_B T b_y / F_fb^2; in rate units sqrt(2 S_B) / (2 m X_d w_d / F_fb) =
    sqrt(2) sqrt(4 k_B T b_y) / (2 m X_d w_d) (the phase-sensitive demodulation folds both
    sidebands of the force noise into the rate channel: +3.01 dB over the one-sideband form
    sqrt(4 k_B T b_y) / (2 m X_d w_d)).

    Read: the bits of an 8192-period ngspice run (compiled loop, zero rate, the first eighth left
    out), their PSD over the drive +-4 kHz (gyro_reference.band_density: both sidebands).
    Tolerances (derived):
    - against the reference loop with the same thermal force (gyro_reference.simulate_design,
      force_noise = 4 k_B T b_y, four seeds of 65536 periods cut into 7168-period pieces): the 1e-3
      prediction interval of the pieces' readings (module docstring), about -3.7 / +3.7 dB. Checked:
      over eight such sets of four seeds, 1.1e-3 of 1000 independent 8192-period reference runs fell
      outside (nominal 1e-3). Measured +0.57 dB and -1.29 dB in two runs;
    - the reference against the closed form: its band transfer, the pieces' mean reading less the
      reading without the thermal force (S_Q, 0.06 S_B), over S_B, is the band average of the
      loop's |STF|^2 (1.14: it rises from 0.8 to 1.43 of S_B across the drive +-4 kHz, 0.964 at
      the drive for a Coriolis tone; bench/gyroscope.py --dof). It must lie in TRANSFER_RANGE, that
      span: a force or F_fb off by a factor 2 in power lands at 0.57 or 2.3.
    The circuit carries the closed form through the reference: its TRNOISE amplitude is checked
    against sqrt(2 k_B T b_y / dt) above, and its floor against the reference loop's.
    ngspice 39 seeds TRNOISE from its process id: the run is statistical, hence the interval.
    About 5 min on the loaded 2-core machine."""
    path = tmp_path / "brownian.toml"
    path.write_text(reference.brownian_variant(EXAMPLE.read_text()))
    model = build_model(load_structure(path))
    spec = read_structure_loop(path)
    lib = tmp_path / "g.lib"
    lib.write_text(subcircuit(model))
    cy = next(c for c in model.coordinates if c.name == "y")
    b_y = math.sqrt(cy.stiffness * cy.mass) / reference.BROWNIAN_Q_Y
    thermal = 4 * reference.K_B * TEMPERATURE * b_y  # N^2/Hz
    for text in (lib.read_text(), xspice.subcircuit(model)):  # both ngspice paths: rms sqrt(2 k_B T b_y / dt)
        rms = re.search(r"^Vn_y .*TRNOISE\(\{noise\*([0-9.eE+-]+)/sqrt\(noise_dt\)\}", text, re.M)
        assert rms and float(rms.group(1)) * cy.port_units[3] == pytest.approx(math.sqrt(thermal / 2), rel=1e-12, abs=0)
    s = run(model, lib, tmp_path / "run", spec, GyroRequest(cycles=BROWNIAN_CYCLES, progress=False, plots=False))
    z = np.load(tmp_path / "run" / "bitstreams.npz")
    keep = slice(BROWNIAN_CYCLES // 8, None)
    drive_w = 2 * math.pi * s["runs"][0]["drive_hz"]
    got, nu_c = reference.band_density(z["time_0"][keep], z["bits_y_0"][keep], s["ts"], drive_w, BROWNIAN_BAND_HZ)

    d = sense_design(model, spec, GyroRequest())
    piece, skip = BROWNIAN_CYCLES - keep.start, REFERENCE_CYCLES // 8
    reads, quiet = [], []
    for seed in range(1, REFERENCE_RUNS + 1):
        r = reference.simulate_design(model, d, REFERENCE_CYCLES, force_noise=thermal, seed=seed)
        reads.append(reference.segment_readings(r, skip, piece, reference.band_density, d.ts, BROWNIAN_BAND_HZ))
    r0 = reference.simulate_design(model, d, REFERENCE_CYCLES)
    quiet = reference.segment_readings(r0, skip, piece, reference.band_density, d.ts, BROWNIAN_BAND_HZ)
    low, high = reference.prediction_interval(reads, QUANTILE)
    want = float(np.exp(np.mean(np.log(reads))))
    closed = thermal / r["full_scale_force"] ** 2
    floor = float(np.mean(quiet))
    transfer = (float(np.mean(reads)) - floor) / closed

    db = lambda x: 10 * math.log10(x)  # noqa: E731
    per_rate, m, w = r["per_rate"], cy.mass, r["drive_w"]
    print(
        f"Brownian: circuit {math.degrees(math.sqrt(2 * got) / per_rate):.4g} deg/s/rtHz over +-{BROWNIAN_BAND_HZ:g} Hz; "
        f"reference with the thermal force {db(got / want):+.2f} dB in [{db(low / want):+.2f}, {db(high / want):+.2f}] "
        f"({np.size(reads)} pieces; Hann count nu {nu_c:.0f}); closed form 4 k_B T b_y / F_fb^2 {db(got / closed):+.2f} dB "
        f"(band transfer {transfer:.3f}, quantisation {floor / closed:.3f} S_B); over sqrt(4 k_B T b_y) / (2 m X_d w_d) = "
        f"{math.degrees(math.sqrt(thermal) / (2 * m * reference.X_D * w)):.4g} deg/s/rtHz: "
        f"{20 * math.log10(math.sqrt(2 * got) / per_rate / (math.sqrt(thermal) / (2 * m * reference.X_D * w))):+.2f} dB"
    )
    assert low <= got <= high
    assert TRANSFER_RANGE[0] <= transfer <= TRANSFER_RANGE[1]
