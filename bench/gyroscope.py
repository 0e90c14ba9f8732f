"""The closed-loop gyroscope (`netgen gyro`, netgen.testbench.gyro) on examples/gyroscope_z.toml:
a rate sweep of long runs, printing the figures: scale factor over the design's 2 m X_d w_d / F_fb,
nonlinearity over the sweep, zero-rate output (the rate read at Omega = 0: quadrature leaking into
the rate channel), quadrature force against k_xy X_d, and rate noise density. Each rate is one
ngspice run of --cycles periods (2^16 periods of 1 us with the compiled loop: about 20 min of CPU
each on a loaded machine; tests/testbench/test_gyro.py runs 2048).

With --noise-reference: one run at zero rate instead, its rate noise density near the drive read
as tests/oracles/gyro_reference.py reads it (demodulated, 1 Hz to BAND) against the numpy reference
of the same sense loop (four runs of 8 x --cycles periods at drive phases 0 to 270 degrees, read
over pieces of the circuit's record), with the reading's 1e-3 prediction interval from the pieces'
spread (gyro_reference.prediction_interval). The suite's test of this floor was moved here: at the
6144 periods a test can afford, the interval is +-6.7 dB.

With --brownian: the Brownian variant (gyro_reference.brownian_variant: Q_y = 10, thermal force
on, a fourth-order CIFB sense loop) at zero rate: the bits' PSD over the drive +-band against the
closed form 4 k_B T b_y / F_fb^2 and against the reference loop with the same thermal force (two
runs of 4 x --cycles periods), the rate noise density against sqrt(4 k_B T b_y) / (2 m X_d w_d),
and brownian.png (tests/testbench/test_gyro_noise.py runs 8192 periods over +-4 kHz).

    .venv/bin/python bench/gyroscope.py [--cycles 65536] [--points 9] [--span 0.5] [--simulator ngspice-xspice] [-o DIR]
    .venv/bin/python bench/gyroscope.py --simulator vacask --points 3   (2^16 periods: about 2 min of CPU per rate)

--simulator takes every gyro back end (netgen.testbench.gyro.options.SIMULATORS): the drive loop is a
B-source in ngspice and ngspice-xspice, the Verilog-A block drive.va in vacask and ngspice-osdi
(ngspice 45 or later: NETGEN_NGSPICE=~/.cache/netgen/ngspice-46/bin/ngspice).
    .venv/bin/python bench/gyroscope.py --noise-reference --cycles 32768
    .venv/bin/python bench/gyroscope.py --brownian --cycles 16384 [--simulator ngspice] [-o DIR]

With --dof: no circuit; the reference loop of the Brownian variant over --runs runs of 9 x --cycles
periods, each cut into pieces of the test's record (7/8 of --cycles): the band reading's mean over
the closed form, the reading without the thermal force, their difference (the loop's band
transfer), and the readings' spread as chi-square degrees of freedom against the Hann bin count,
which is why tests/testbench/test_gyro_noise.py bounds a reading by the reference's own spread.
    .venv/bin/python bench/gyroscope.py --dof --cycles 8192 --runs 16
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from scipy import signal, stats
from support import ROOT
from support import gyro_reference as reference
from tqdm import tqdm

from netgen.build import build_model
from netgen.emit.ngspice import subcircuit
from netgen.structure import load_structure
from netgen.testbench.gyro.options import SIMULATORS
from netgen.testbench.gyro.run import GyroRequest, run, sense_design
from netgen.testbench.sigma_delta.loopfile import read_structure_loop

EXAMPLE = ROOT / "examples" / "gyroscope_z.toml"
BANDS_HZ = (500.0, 1000.0, 2000.0, 4000.0)
BROWNIAN_BANDS_HZ = (2000.0, 4000.0)
TEMPERATURE = 300.0  # K, the structure's [damping] temperature (its default)


def zero_rate_run(model, spec, out: Path, cycles: int, simulator: str):
    """One zero-rate gyro run of `model` in `out`: its bitstreams, the settled slice (after the first
    eighth) and the drive's angular frequency."""
    lib = out / "g.lib"
    lib.write_text(subcircuit(model))
    s = run(model, lib, out, spec, GyroRequest(cycles=cycles, simulator=simulator, progress=False, plots=False))
    return np.load(out / "bitstreams.npz"), slice(cycles // 8, None), 2 * math.pi * s["runs"][0]["drive_hz"]


def noise_reference(model, out: Path, cycles: int, simulator: str) -> None:
    """The zero-rate run's rate noise density against the reference loop's, per band: the reference
    read over pieces of the circuit's record in four runs of 8 x cycles periods (drive phases 0 to
    270 degrees), the circuit's reading against their 1e-3 prediction interval
    (gyro_reference.prediction_interval; the F quantiles of the Hann bin counts beside it)."""
    spec = read_structure_loop(EXAMPLE)
    z, keep, drive_w = zero_rate_run(model, spec, out, cycles, simulator)
    d = sense_design(model, spec, GyroRequest())
    refs = [reference.simulate_design(model, d, 8 * cycles, phase) for phase in np.arange(4) * math.pi / 2]
    per_rate, piece = refs[0]["per_rate"], cycles - keep.start
    deg = lambda sd: math.degrees(math.sqrt(2 * sd) / per_rate)  # noqa: E731
    db = lambda x: 10 * math.log10(x)  # noqa: E731
    print(
        f"{cycles} periods at zero rate, reference 4 x {8 * cycles} in pieces of {piece}; rate noise density (deg/s/rtHz):"
    )
    for band in BANDS_HZ:
        got, nu_c = reference.inband_density(z["time_0"][keep], z["bits_y_0"][keep], d.ts, drive_w, band)
        reads = [reference.segment_readings(r, cycles, piece, reference.inband_density, d.ts, band) for r in refs]
        low, high = reference.prediction_interval(reads, 1e-3)
        want = float(np.exp(np.mean(np.log(reads))))
        f_lo, f_hi = stats.f.ppf([5e-4, 1 - 5e-4], nu_c, nu_c * np.size(reads))
        print(
            f"  1 Hz..{band:5.0f} Hz: circuit {deg(got):.4g}, reference {deg(want):.4g}, ratio {db(got / want):+.2f} dB "
            f"(prediction interval {db(low / want):+.2f}, {db(high / want):+.2f} dB; the Hann count's F quantiles "
            f"{db(f_lo):+.2f}, {db(f_hi):+.2f} dB)"
        )


def brownian(out: Path, cycles: int, simulator: str) -> None:
    """The Brownian variant's zero-rate run: its noise floor against the closed form and the reference."""
    path = out / "brownian.toml"
    path.write_text(reference.brownian_variant(EXAMPLE.read_text()))
    model = build_model(load_structure(path), progress=False)
    spec = read_structure_loop(path)
    z, keep, drive_w = zero_rate_run(model, spec, out, cycles, simulator)
    cy = next(c for c in model.coordinates if c.name == "y")
    thermal = 4 * reference.K_B * TEMPERATURE * math.sqrt(cy.stiffness * cy.mass) / reference.BROWNIAN_Q_Y
    d = sense_design(model, spec, GyroRequest())
    refs = [reference.simulate_design(model, d, 4 * cycles, force_noise=thermal, seed=n) for n in (1, 2)]
    closed = thermal / refs[0]["full_scale_force"] ** 2
    per_rate, w = refs[0]["per_rate"], refs[0]["drive_w"]
    one_sideband = math.sqrt(thermal) / (2 * cy.mass * reference.X_D * w)
    db = lambda x: 10 * math.log10(x)  # noqa: E731
    print(
        f"{cycles} periods ({simulator}), Q_y = {reference.BROWNIAN_Q_Y:g}, 4 k_B T b_y = {thermal:.4g} N^2/Hz; "
        f"sqrt(4 k_B T b_y) / (2 m X_d w_d) = {math.degrees(one_sideband):.4g} deg/s/rtHz"
    )
    for band in BROWNIAN_BANDS_HZ:
        got, nu_c = reference.band_density(z["time_0"][keep], z["bits_y_0"][keep], d.ts, drive_w, band)
        rk = slice(len(refs[0]["v"]) // 8, None)
        reads = [reference.band_density(r["t"][rk], r["v"][rk], d.ts, w, band) for r in refs]
        want, nu_r = float(np.mean([r[0] for r in reads])), sum(r[1] for r in reads)
        c_lo, c_hi = stats.chi2.ppf([5e-4, 1 - 5e-4], nu_c) / nu_c
        f_lo, f_hi = stats.f.ppf([5e-4, 1 - 5e-4], nu_c, nu_r)
        rate = math.sqrt(2 * got) / per_rate
        print(
            f"  drive +-{band:4.0f} Hz: rate noise {math.degrees(rate):.4g} deg/s/rtHz, "
            f"{20 * math.log10(rate / one_sideband):+.2f} dB over the one-sideband form; bits' PSD over "
            f"4 k_B T b_y / F_fb^2 {db(got / closed):+.2f} dB (chi2 1e-3 quantiles {db(c_lo):+.2f}, {db(c_hi):+.2f}; "
            f"nu {nu_c:.0f}), over the reference with the thermal force {db(got / want):+.2f} dB "
            f"(F quantiles {db(f_lo):+.2f}, {db(f_hi):+.2f}; nu_r {nu_r:.0f})"
        )
    rk = slice(len(refs[0]["v"]) // 8, None)
    runs = [
        (z["time_0"][keep], z["bits_y_0"][keep], drive_w, simulator),
        (refs[0]["t"][rk], refs[0]["v"][rk], w, "reference loop"),
    ]
    plot_brownian(runs, d.ts, closed, out / "brownian.png")
    print(f"results in {out}")


def dof(out: Path, cycles: int, runs: int) -> None:
    """The Brownian variant's band reading over `cycles`-period records of the reference loop: the
    mean against 4 k_B T b_y / F_fb^2, the reading without the thermal force, and the spread as
    chi-square degrees of freedom (2 mean^2 / variance) against the Hann bin count's."""
    path = out / "brownian.toml"
    path.write_text(reference.brownian_variant(EXAMPLE.read_text()))
    model = build_model(load_structure(path), progress=False)
    spec = read_structure_loop(path)
    cy = next(c for c in model.coordinates if c.name == "y")
    thermal = 4 * reference.K_B * TEMPERATURE * math.sqrt(cy.stiffness * cy.mass) / reference.BROWNIAN_Q_Y
    d = sense_design(model, spec, GyroRequest())
    piece, skip = cycles - cycles // 8, cycles  # the first --cycles periods of each run are its start
    band = BROWNIAN_BANDS_HZ[-1]
    reads, quiet = [], []
    for seed in tqdm(range(runs), desc="reference runs", file=sys.stderr, leave=False):
        r = reference.simulate_design(model, d, 9 * cycles, force_noise=thermal, seed=100 + seed)
        reads.append(reference.segment_readings(r, skip, piece, reference.band_density, d.ts, band))
    q = reference.simulate_design(model, d, 9 * cycles)
    quiet = reference.segment_readings(q, skip, piece, reference.band_density, d.ts, band)
    x, closed = np.ravel(reads), thermal / r["full_scale_force"] ** 2
    nu_hann = reference.band_density(
        r["t"][skip : skip + piece], r["v"][skip : skip + piece], d.ts, r["drive_w"], band
    )[1]
    lo, hi = reference.prediction_interval(reads, 1e-3)
    m = float(np.exp(np.mean(np.log(x))))
    print(
        f"{len(x)} pieces of {piece} periods, drive +-{band:g} Hz: mean / S_B {x.mean() / closed:.4f} "
        f"(+-{x.std(ddof=1) / math.sqrt(len(x)) / closed:.4f}), without the thermal force {np.mean(quiet) / closed:.4f}, "
        f"band transfer {(x.mean() - np.mean(quiet)) / closed:.4f}; degrees of freedom {2 * x.mean() ** 2 / x.var(ddof=1):.1f} "
        f"(Hann count {nu_hann:.1f}); 1e-3 prediction interval {10 * math.log10(lo / m):+.2f} / {10 * math.log10(hi / m):+.2f} dB"
    )


def plot_brownian(runs: list[tuple], ts: float, closed: float, path: Path) -> None:
    """Welch PSDs near the drive of each (t, bits, drive_w, label), its drive tones taken out, and
    the closed form's level."""
    fig, ax = plt.subplots(figsize=(7, 4))
    for t, bits, w, label in runs:
        basis = np.column_stack([np.cos(w * t), np.sin(w * t), np.ones_like(t)])
        rest = bits.astype(float) - basis @ np.linalg.lstsq(basis, bits.astype(float), rcond=None)[0]
        f, p = signal.welch(rest, fs=1.0 / ts, nperseg=min(4096, len(rest)))
        near = np.abs(f - w / (2 * math.pi)) <= 8000.0
        ax.semilogy((f[near] - w / (2 * math.pi)) / 1e3, p[near], label=label)
    ax.axhline(closed, color="k", ls="--", label="4 k_B T b_y / F_fb^2")
    ax.set_xlabel("frequency - drive (kHz)")
    ax.set_ylabel("bits' PSD (1/Hz)")
    ax.set_title("gyroscope_z, Brownian variant: sense bits near the drive")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=65536)
    ap.add_argument("--points", type=int, default=9, help="rates (odd: one at 0)")
    ap.add_argument("--span", type=float, default=0.5, help="the sweep's extent, a fraction of the full-scale rate")
    ap.add_argument("--simulator", default="ngspice-xspice", choices=SIMULATORS)
    ap.add_argument("-o", "--output", default=None)
    ap.add_argument("--noise-reference", action="store_true", help="the noise floor against the reference loop")
    ap.add_argument("--brownian", action="store_true", help="the Brownian variant's floor against 4 k_B T b_y")
    ap.add_argument("--dof", action="store_true", help="the reference's Brownian readings: spread and band transfer")
    ap.add_argument("--runs", type=int, default=16, help="--dof: reference runs of 9 x --cycles periods")
    a = ap.parse_args()
    if a.dof:
        out = Path(a.output or tempfile.mkdtemp(prefix="gyroscope-dof-"))
        out.mkdir(parents=True, exist_ok=True)
        return dof(out, a.cycles, a.runs)
    if a.brownian:
        out = Path(a.output or tempfile.mkdtemp(prefix="gyroscope-brownian-"))
        out.mkdir(parents=True, exist_ok=True)
        return brownian(out, a.cycles, a.simulator)
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
            f"quadrature force / k_xy X_d - 1 {r['quadrature_force_n'] / (reference.K_XY * r['drive_amplitude_m']) - 1:+.2e}  "
            f"noise {r['rate_noise_deg_s_rthz']:.3g} deg/s/rtHz  "
            f"drive {r['drive_hz']:.4f} Hz at {r['drive_amplitude_m'] / reference.X_D - 1:+.2e} of X_d"
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
