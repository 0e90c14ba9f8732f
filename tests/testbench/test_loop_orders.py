"""Higher-order loop filters from a [loop] table (kinds.FILTERS "cifb"/"crfb", designed inside
loop.design from the channel's mechanics, filters.mechanics_of) on the z accelerometer
(examples/accelerometer_z.toml): the mechanics the design sees against the parallel-plate
formulas, the readout trim, the bad keys (exit 2 naming the file and the key), and a 4th-order loop in the compiled ngspice loop against
the numpy reference loop bit for bit over its first periods. Long runs: bench/sigma_delta_orders.py."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from netgen.build import build_model
from netgen.cli import commands as cli
from netgen.core.constants import EPS0, G
from netgen.structure import load_structure
from netgen.testbench import sigma_delta as sd
from netgen.testbench.sigma_delta import filters, loopfile
from netgen.testbench.sigma_delta.loop import duty
from tests.oracles import sigma_delta_reference as reference
from tests.oracles.loop_orders import CIFB4, EXAMPLE, GAP, K_SPRING, MASS, SIDE, TS, momentum_defect
from tests.testbench.test_sigma_delta_vacask import NGSPICE_GAIN


@pytest.fixture(scope="module")
def model():
    """The accelerometer's MacroModel (parallel plates, no fringe: the formulas below hold)."""
    return build_model(load_structure(EXAMPLE), progress=False)


def spec_of(tmp_path, text: str) -> loopfile.LoopSpec:
    """A loop file's LoopSpec."""
    p = tmp_path / "loop.toml"
    p.write_text(text, encoding="utf-8")
    return loopfile.read_loop_file(p)


def test_the_mechanics_the_design_sees_follow_the_parallel_plate(model, tmp_path):
    """filters.mechanics_of on the accelerometer's Design: the mass, the spring plus the
    electrostatic spring -eps A V^2 / g^3 of one plate at V_fb over the feedback duty and of both
    at V_s over the sense duty, the force eps A V_fb^2 / (2 g^2), the readout V_s 2 eps A / g^2 / C_f
    per metre, no rest offset (symmetric plates), and gravity as the DC input."""
    d = sd.design(model, TS, spec=spec_of(tmp_path, CIFB4))
    m = filters.mechanics_of(model, d, "z")
    ea = EPS0 * SIDE**2
    t = d.t
    k_el = -ea * d.vfb**2 / GAP**3 * d.duty - 2 * ea * d.vs**2 / GAP**3 * duty(t, t.sense_on, t.sense_off)
    assert m.mass == pytest.approx(MASS, rel=1e-12, abs=0)
    assert m.stiffness == pytest.approx(K_SPRING + k_el, rel=2e-3, abs=1e-4)
    assert m.force == pytest.approx(ea * d.vfb**2 / (2 * GAP**2), rel=1e-6, abs=0)
    assert m.gain == pytest.approx(d.vs * 2 * ea / GAP**2 / d.channels[0]["cf"], rel=1e-6)
    assert abs(m.offset) < 1e-9 and d.channels[0]["filter"]["x0"] == pytest.approx(m.offset)
    assert filters.dc_acceleration(model, d, "z") == pytest.approx(-G, rel=1e-6)


@pytest.mark.parametrize("kind", ["cifb", "crfb"])
def test_a_loop_table_selects_a_designed_filter(model, tmp_path, kind):
    """[loop.filter] kind/order/osr/h_inf reaches filters.design: the channel's filter is the
    order's state-space loop (order - 2 states), no dither, the NTF of the table's H_inf, and its
    linearised NTF (the loop as realised with the accelerometer's mechanics) peaks at H_inf
    within 5 % and has DC zeros (|NTF| at f_s/1000 below -60 dB at order 4)."""
    d = sd.design(
        model,
        TS,
        spec=spec_of(tmp_path, CIFB4.replace('"cifb"', f'"{kind}"').replace("osr = 64", "osr = 64\nh_inf = 1.5")),
    )
    ch = d.channels[0]
    f = filters.Filter.from_dict(ch["filter"])
    assert (f.kind, f.order, f.states, ch["dither_v"]) == (kind, 4, 2, 0.0)
    assert ch["filter"]["osr"] == 64 and ch["filter"]["h_inf"] == 1.5
    mech = filters.mechanics_of(model, d, "z")
    w = np.linspace(1e-3, np.pi, 2000)
    ntf = np.abs(filters.realised_ntf(mech, f, np.exp(1j * w)))
    assert ntf.max() == pytest.approx(1.5, rel=0.05)
    assert 20 * np.log10(abs(filters.realised_ntf(mech, f, np.exp(2j * np.pi * 1e-3))[0])) < -60


def test_the_readout_trim_removes_a_rest_offset(model, tmp_path):
    """A readout offset x0 trimmed from the filter's input (Filter.x0) gives the loop without the
    offset, bit for bit (x - x0 = gain q in both); untrimmed, the same 4th-order loop's bits differ."""
    d = sd.design(model, TS, spec=spec_of(tmp_path, CIFB4))
    mech = filters.mechanics_of(model, d, "z")
    f = filters.Filter.from_dict(d.channels[0]["filter"])
    inp = reference.Input(filters.dc_acceleration(model, d, "z"))
    clean = reference.simulate(replace(mech, offset=0.0), replace(f, design={**f.design, "x0": 0.0}), 2000, inp)
    offset = replace(mech, offset=0.05)
    trimmed = reference.simulate(offset, replace(f, design={**f.design, "x0": 0.05}), 2000, inp)
    untrimmed = reference.simulate(offset, replace(f, design={**f.design, "x0": 0.0}), 2000, inp)
    assert np.array_equal(trimmed["v"], clean["v"])
    assert not np.array_equal(untrimmed["v"], clean["v"])


BAD = [
    ('kind = "cifb"\norder = 6', "loop.filter.order"),
    ('kind = "cifb"\norder = 2', "loop.filter.order"),
    ('kind = "crfb"\norder = "4"', "loop.filter.order"),
    ('kind = "cifb"\norder = 4.0', "loop.filter.order"),
    ('kind = "cifb"\norder = true', "loop.filter.order"),
    ('kind = "cifb"\nosr = 2', "loop.filter.osr"),
    ('kind = "cifb"\nosr = "64"', "loop.filter.osr"),
    ('kind = "cifb"\nh_inf = 5', "loop.filter.h_inf"),
    ('kind = "cifb"\nh_inf = nan', "loop.filter.h_inf"),
    ('kind = "cifb"\nlead = 0.8', "loop.filter.lead"),
    ('kind = "crfb"\nzeros = [1]', "loop.filter.zeros"),
]


@pytest.mark.parametrize("text,key", BAD, ids=[f"{k}-{i}" for i, (_, k) in enumerate(BAD)])
def test_a_bad_filter_table_exits_2_naming_the_file_and_the_key(text, key, tmp_path, capsys):
    """exit 2 before any output, the message names the loop file, the key and a fix."""
    bad = tmp_path / "bad_loop.toml"
    bad.write_text(f"[loop.filter]\n{text}\n", encoding="utf-8")
    out = tmp_path / "sd"
    code = cli.main(["sigma-delta", str(EXAMPLE), "--loop", str(bad), "--cycles", "64", "-o", str(out), "-q"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err and str(bad) in err and key in err and "fix:" in err, err
    assert not out.exists() or not any(out.iterdir())


CIRCUIT_PERIODS = 400
# bit for bit: the 1 % quantile of the first difference between the reference loop and 200 copies
# of it with force, gain, stiffness and input perturbed by eps N(0, 1), eps = 1e-2 (the circuit's
# percent-level mechanics mismatch, below): bench/first_difference.py, 14 (26 at 1e-3, 69 at 1e-6);
# this machine's run parted at 77 (|y| = 2 mV)
MATCH_PERIODS = 14


def test_a_4th_order_loop_in_the_compiled_loop_tracks_the_numpy_loop(model, tmp_path, capsys):
    """`netgen sigma-delta` with [loop.filter] cifb order 4 on ngspice-xspice, 400 periods from
    rest under gravity: its bits equal the numpy reference loop's (the same design, exact
    mechanics, no circuit) in each of the first MATCH_PERIODS periods, both hold the mass, their
    mean bits agree within 0.02, and every period's momentum balance on z holds in the circuit's own
    samples within a derived bound (tests/oracles/loop_orders.momentum_defect): the second
    difference x_n+1 - 2 x_n + x_n-1 equals the model's force at the circuit's positions (its
    linear form per electrode phase) integrated against the hat (T_s - |t - t_n|)+, over m, within
    every impulse off by ngspice's LTE limit NGSPICE_GAIN (7e-3, the premise of
    tests/testbench/test_sigma_delta_vacask.py) weighted by the hat, the force's nonlinearity, the
    sense ramps, the samples' interpolation between time points, the backward-Euler steps at the
    feedback steps and the trapezoidal rule's spring error. Measured 0.17 of that bound (the
    impulses 74 % of it, interpolation 25 %). It replaces the numpy mechanics driven by the
    circuit's bits within 5 % of z's peak (not derived; measured 0.6 %, nearly all a feedback gain
    error of -5.6e-6): z integrates every impulse's error twice, and its response to the feedback
    alone peaks at 1100 times its own peak, so the LTE limit allowed several times z's peak there,
    while each period's balance sees each impulse once and nothing accumulates. A balance with
    every feedback impulse 2 x 7e-3 (3 x 7e-3) strong fails it, 1.02 (1.53) of the bound. The
    circuit is a perturbed copy of the reference at the percent level (and another CPU's rounding
    moves ngspice's steps), so the bit-for-bit span is the low quantile of a perturbed ensemble
    (MATCH_PERIODS). Beyond the first tie the two bitstreams decorrelate in detail (the loop is
    chaotic), not in their statistics (bench/sigma_delta_orders.py)."""
    loop = tmp_path / "loop.toml"
    loop.write_text(CIFB4, encoding="utf-8")
    out = tmp_path / "sd"
    code = cli.main(
        [
            "sigma-delta",
            str(EXAMPLE),
            "--loop",
            str(loop),
            "--simulator",
            "ngspice-xspice",
            "--cycles",
            str(CIRCUIT_PERIODS),
            "-o",
            str(out),
            "-q",
        ]
    )
    assert code == 0, capsys.readouterr().err
    clock = np.load(out / "bitstreams.npz")
    bits = clock["bits_z"].astype(float)
    d = sd.design(model, TS, spec=loopfile.read_loop_file(loop))
    mech = filters.mechanics_of(model, d, "z")
    inp = reference.Input(filters.dc_acceleration(model, d, "z"))
    ref = reference.simulate(mech, filters.Filter.from_dict(d.channels[0]["filter"]), CIRCUIT_PERIODS, inp)
    assert len(bits) == CIRCUIT_PERIODS and reference.stable(ref, 0.01 * GAP)
    assert np.abs(clock["x_z"]).max() * 1e-6 < 0.01 * GAP  # x_z port: 1 V = 1 um
    same = bits == ref["v"]
    assert same[:MATCH_PERIODS].all(), f"first difference at period {int(np.argmin(same))}"
    assert abs(bits.mean() - ref["v"].mean()) < 0.02
    z = clock["x_z"] * 1e-6  # x_z port: 1 V = 1 um
    defect, terms = momentum_defect(model, d, inp.dc, clock["bits_z"].astype(int), z, NGSPICE_GAIN)
    ratio = np.abs(defect) / sum(terms.values())
    print(f"z momentum balance per period: at most {ratio.max():.2f} of the bound (period {int(ratio.argmax()) + 1})")
    assert ratio.max() < 1, f"period {int(ratio.argmax()) + 1}"
