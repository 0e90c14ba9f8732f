"""The z accelerometer in force feedback (examples/accelerometer_z.toml: a 500 x 500 x 20 um proof
mass between electrodes 2 um above and below, gravity through a_in), second-order loop: the
design against the parallel-plate formulas, the loop in the compiled ngspice loop and in VACASK
(blocks.va's general driver sd_driver4), a tone through a_in at the level the scale factor
predicts, and the DC scale-factor fit. Long runs: bench/sigma_delta_accelerometer.py."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from netgen.build import build_model
from netgen.core.constants import EPS0, G
from netgen.emit import write_outputs
from netgen.structure import load_structure
from netgen.testbench import sigma_delta as sd
from netgen.testbench.sigma_delta import analysis, loopfile
from tests.fixtures import ROOT
from tests.testbench.test_sigma_delta_vacask import NGSPICE_GAIN, balance_bound, vacask_gain

TS = 1e-6
SIDE, GAP, RHO, THICK = 500e-6, 2e-6, 2330.0, 20e-6
MASS = SIDE * SIDE * THICK * RHO


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The accelerometer's model and .lib (about 2 s), and its [loop] table."""
    path = ROOT / "examples" / "accelerometer_z.toml"
    model = build_model(load_structure(path), progress=False)
    out = tmp_path_factory.mktemp("acc")
    write_outputs(model, out, "all")
    return model, out / f"{model.name}.lib", sd.read_structure_loop(path)


def test_design_follows_the_parallel_plate(built):
    """Top +1, bottom -1; bit +1 energises the top plate: F = eps A V^2 / (2 g^2) up, bit -1 the
    bottom one down; V_fb so that gravity needs a mean bit of 0.5 (to 1 mV), C_f so that 1 % of
    the gap reads 1 V with the sense voltage on both plates (dC/dz = eps A / g^2 each)."""
    model, _, loop = built
    d = sd.design(model, TS, spec=loop)
    assert d.names == ["z"] and model.coordinates[0].mass == pytest.approx(MASS, rel=1e-12, abs=0)
    assert {e["name"]: (e["w"], e["sel"]) for e in d.electrodes} == {"top": ([1], [1]), "bottom": ([-1], [-1])}
    per_v2 = EPS0 * SIDE**2 / (2 * GAP**2)
    rows = {r["bits"]: r["f"]["z"] * 1e-6 for r in d.table}
    assert rows["+"] == pytest.approx(per_v2 * d.vfb**2, rel=1e-6, abs=0) and rows["-"] == pytest.approx(
        -rows["+"], rel=1e-6, abs=0
    )
    assert d.vfb == pytest.approx(np.sqrt(MASS * G / (0.5 * d.duty * per_v2)), abs=6e-4)
    assert d.inputs == {"a_in": 9.81} and d.balance["dc_force_n"] == pytest.approx(-MASS * G, rel=1e-9, abs=0)
    touch = model.coordinates[0].scale
    assert d.channels[0]["cf"] == pytest.approx(d.vs * 2 * EPS0 * SIDE**2 / GAP**2 * touch * 0.01, rel=1e-3, abs=0)


def test_explicit_electrodes_give_the_derived_design(built):
    """[loop.channels.z] sense/feedback written out as the signs of dC/dz: the same design."""
    model, _, loop = built
    spec = replace(loop, channels=(loopfile.ChannelSpec("z", {"top": 1, "bottom": -1}, {"top": 1, "bottom": -1}),))
    a, b = sd.design(model, TS, spec=loop), sd.design(model, TS, spec=spec)
    assert a.electrodes == b.electrodes and a.vfb == b.vfb and a.channels[0]["cf"] == b.channels[0]["cf"]


@pytest.fixture(scope="module")
def runs(built, tmp_path_factory):
    """512 periods in the compiled ngspice loop and in VACASK."""
    model, lib, loop = built
    return {
        sim: sd.run(
            model,
            lib,
            tmp_path_factory.mktemp(sim),
            sd.RunRequest(TS, 512, progress=False, plots=False, simulator=sim, loop=loop, skip=64),
        )
        for sim in ("ngspice-xspice", "vacask")
    }


@pytest.mark.parametrize("sim", ["ngspice-xspice", "vacask"])
def test_the_loop_holds_the_mass_and_carries_gravity(runs, built, sim):
    """Within 1 % of the gap at every clock; momentum balance on z: the bits' mean force against
    m g within the sum of the terms of tests/testbench/test_sigma_delta_vacask.balance_bound (the
    simulator's bound on its feedback impulse gain, the forces at the mass's offset, the end
    velocities; was 1 %); mean bit 0.5 (the design's density) within 0.02."""
    model, _, loop = built
    s = runs[sim]
    x = s["clock"]["x_z"] * 1e-6
    assert s["levitation"]["held"] and np.abs(x).max() < 0.01 * GAP
    d = sd.design(model, TS, spec=loop)
    terms = balance_bound(model, d, s["clock"], 64, NGSPICE_GAIN if sim.startswith("ngspice") else vacask_gain(d))
    ratio = s["gravity_balance"]["ratio"]
    print(f"F / m g - 1 = {ratio - 1:.2e}; bound " + ", ".join(f"{k} {v:.2e}" for k, v in terms.items()))
    assert abs(ratio - 1) < sum(terms.values())
    assert s["channels"]["z"]["bit_mean"] == pytest.approx(0.5, abs=0.02)


def test_vacask_and_ngspice_agree(runs):
    """Same loop, two simulators: bit means within 0.02, mean positions within 20 % of the
    larger excursion."""
    a, b = runs["ngspice-xspice"], runs["vacask"]
    assert a["channels"]["z"]["bit_mean"] == pytest.approx(b["channels"]["z"]["bit_mean"], abs=0.02)
    za, zb = a["coordinates"]["z"], b["coordinates"]["z"]
    span = max(abs(za["min"]), abs(za["max"]), abs(zb["min"]), abs(zb["max"]))
    assert abs(za["mean"] - zb["mean"]) < 0.2 * span


def test_a_tone_through_a_in_appears_at_the_scale_factor(built, tmp_path):
    """A 2 m/s^2 tone at 1953 Hz on a_in: in band the loop's signal transfer is ~1, so the
    bitstream carries B = m A / F_fs (F_fs: the full-scale force, bit +-1) within 1 % (a sine
    fit at the tone's frequency); the SQNR is its power B^2/2 over the in-band noise."""
    model, lib, loop = built
    tone = sd.Tone("a_in", 2.0, 1e6 / 512)
    s = sd.run(
        model,
        lib,
        tmp_path,
        sd.RunRequest(TS, 4096, tone, progress=False, plots=False, simulator="ngspice-xspice", loop=loop, skip=512),
    )
    d = sd.design(model, TS, spec=loop)
    b = MASS * 2.0 / d.channels[0]["full_scale_force_si"]
    ch = s["channels"]["z"]
    assert ch["tone_amplitude_bits"] == pytest.approx(b, rel=0.01)
    assert ch["sqnr_db"] == pytest.approx(10 * np.log10(b * b / 2) - ch["residual_inband_noise_db"], abs=0.1)
    assert ch["sqnr_db"] > 20


def test_scale_factor_fit():
    """analysis.scale_factor on hand-made data: slope 0.1 per m/s^2, offset 0.02, one point 0.003
    off the line: 0.3 % of the bit range over a full scale of 10 m/s^2 (a bit mean of 1)."""
    x = np.linspace(-8, 8, 9)
    y = 0.1 * x + 0.02
    y[4] += 0.003
    fit = analysis.scale_factor(x, y, full_scale=10.0)
    assert fit["scale_factor"] == pytest.approx(0.1, rel=1e-3) and fit["offset"] == pytest.approx(
        0.02 + 0.003 / 9, rel=1e-6
    )
    resid = 0.003 - 0.003 / 9
    assert fit["max_nonlinearity_pct_fs"] == pytest.approx(resid / 0.1 / 10 * 100, rel=1e-6)


def test_a_tone_above_the_band_has_no_snr():
    """A flat PSD of 1e-8 /Hz: a tone at 20 kHz (above f_s / 2 / 64 = 7.8 kHz) gets a note and no
    tone level or SNR; a line of 1e-4 /Hz in one bin at 3.9 kHz gives its power over the flat
    in-band noise: the 7 bins within 3 of the tone are its power (the line and 6 flat bins), the
    rest of the band the noise."""
    f = np.linspace(0, 5e5, 1025)
    p = np.full_like(f, 1e-8)
    far = analysis.band_metrics(f, p, TS, 64, 2e4)
    assert "snr_db" not in far and "tone_level_db" not in far and "20000" in far["tone_note"]
    k = int(np.argmin(np.abs(f - 3906.25)))
    p[k] = 1e-4
    near = analysis.band_metrics(f, p, TS, 64, f[k])
    band = int(np.sum((f > 0) & (f <= 7812.5)))
    assert near["snr_db"] == pytest.approx(10 * np.log10((1e-4 + 6e-8) / (1e-8 * (band - 7))), abs=1e-9)
