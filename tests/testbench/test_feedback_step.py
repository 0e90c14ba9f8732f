"""The feedback step (signals.Timing.fb_edge = 0; netgen_sdloop's fb_level): the designed loop
filters' default, which removed the compiled loop's flat in-band floor. A ramped feedback phase's
V^2 force is integrated by ngspice with an error that depends on its time steps inside the ramps,
and those change from period to period (bench/sigma_delta_impulse.py: 8.6e-5 of one bit's impulse
rms on the z accelerometer, white, the -138 dB/Hz floor of the 4th-order loop); a step at the
instance's own breakpoints is integrated exactly (backward Euler over a constant force). Here: the
impulse the mass gets in every period against the MacroModel's force along the circuit's own
trajectory, the defaults, and the back ends that cannot render a step."""

from __future__ import annotations

import re

import numpy as np
import pytest

from netgen.build import build_model
from netgen.cli import commands as cli
from netgen.structure import load_structure
from netgen.testbench import sigma_delta as sd
from netgen.testbench.sigma_delta import filters, loopfile, ngspice
from netgen.testbench.sigma_delta.signals import duty, selected
from tests.fixtures import ROOT

TS = 1e-6
EXAMPLE = ROOT / "examples" / "accelerometer_z.toml"
CIFB4 = (
    '[loop]\nchannels = ["z"]\n[loop.filter]\nkind = "cifb"\norder = 4\nosr = 64\n[loop.input]\nacceleration = 9.81\n'
)
PERIODS = 300
WINDOW = (0.47, 0.97)  # sense off .. reset off: only the feedback, the spring and gravity act


@pytest.fixture(scope="module")
def model():
    """The z accelerometer's MacroModel."""
    return build_model(load_structure(EXAMPLE), progress=False)


def loop_file(tmp_path, text: str):
    """A loop file with `text`, and its path."""
    p = tmp_path / "loop.toml"
    p.write_text(text, encoding="utf-8")
    return p


def window_impulse(model, d, t: np.ndarray, xs: np.ndarray, bit: int, n: int, on: bool = True) -> float:
    """The velocity change (m/s) over WINDOW of period n from the MacroModel's electrostatic force
    with the feedback pattern of `bit` on (fb_on, fb_off], its spring and gravity, along the
    circuit's own position xs (q / L) at the times t; the force integrated piece by piece
    (exact at the steps)."""
    i = d.channels[0]["coord"]
    c = model.coordinates[i]
    volts = d.vfb * selected(d.electrodes, (bit,)) * (1.0 if on else 0.0)
    total = 0.0
    for lo, hi, v in (
        (WINDOW[0], d.t.fb_on, 0.0 * volts),
        (d.t.fb_on, d.t.fb_off, volts),
        (d.t.fb_off, WINDOW[1], 0.0 * volts),
    ):
        grid = (n + np.linspace(lo, hi, 41)) * d.ts
        q = np.zeros((len(grid), model.ncoords))
        q[:, i] = np.interp(grid, t, xs)
        f = model.electrostatic_force(q, np.tile(v, (len(grid), 1)))[:, i] - c.stiffness * q[:, i] * c.scale
        f -= model.acceleration[i] * d.inputs["a_in"]
        total += np.trapezoid(f, grid)
    return total / c.mass


def test_the_compiled_loop_gives_the_mass_the_models_impulse_in_every_period(model, tmp_path):
    """A 4th-order cifb loop under gravity in ngspice-xspice, 300 periods from rest: in every
    period the proof mass's velocity change over the feedback phase (the model's velocity node,
    u = (dq/dt) / (L w_s), w_s = 1 / C_x from the .lib: a plain number, where C_u carries the
    mass's process ratio of a [process] model) equals the MacroModel's force with the
    period's feedback pattern, its spring and gravity integrated along the circuit's own
    trajectory, both the scale error (the same in every period) and what changes from period to
    period (rms) within a derived share of one bit's impulse. The feedback step and gravity are
    constant over ngspice's steps and integrated exactly; only the position-dependent forces, the
    spring k q and the feedback's electrostatic spring k_el q (k_el = (k - k_eff) / duty from the
    mechanics the design sees), carry integration error, which ngspice's truncation-error control
    holds to trtol x reltol = 7 x 1e-3 of what it integrates. Their impulse over the window is at
    most P = (|k| + |k_el|) max|q| window / (one bit's impulse x m) (1.3e-3 here), so the bound is
    7e-3 P (9e-6 here; the ramped feedback's rms was 8.6e-5, bench/sigma_delta_impulse.py). This
    machine: scale -5.55e-6, rms 1.72e-9, both unchanged (and the same 23405 steps) when V_fb is
    changed by +-1e-12 and +-3e-12 relative: no CPU's rounding moves them."""
    d = sd.design(model, TS, spec=loopfile.read_loop_file(loop_file(tmp_path, CIFB4)))
    assert d.t.fb_ramp == 0 and model.coordinates[0].admittance(0.0).real == 0.0
    lib, control = ngspice.xspice_library(model, tmp_path, ngspice.code_models(False))
    nodes = ["x1.u_z", "x1.xs_z"]
    net = ngspice.testbench(
        model,
        d,
        lib.resolve(),
        PERIODS,
        "sigma_delta.raw",
        None,
        ngspice.Settings("xspice", control, chunks=1),
        ngspice.Segment(states=nodes),
    )
    plot = ngspice.simulate(net, tmp_path, d.ts * PERIODS, False)
    t, u, xs, b = (np.asarray(plot[k]) for k in ("time", "v(x1.u_z)", "v(x1.xs_z)", "v(b_z)"))
    w_s = 1.0 / float(re.search(r"^Cx_z xs_z 0 (\S+)", lib.read_text(), re.M).group(1))
    scale = model.coordinates[0].scale * w_s  # m/s per unit u
    bit_impulse = filters.mechanics_of(model, d, "z").force * duty(d.t) * d.ts / model.coordinates[0].mass
    errors, bits = [], []
    for n in range(2, PERIODS - 1):
        bit = 1 if np.interp((n + 0.72) * d.ts, t, b) > 0.5 else -1
        du = np.interp((n + WINDOW[1]) * d.ts, t, u) - np.interp((n + WINDOW[0]) * d.ts, t, u)
        errors.append((du * scale - window_impulse(model, d, t, xs, bit, n)) / bit_impulse)
        bits.append(bit)
    errors, bits = np.array(errors), np.array(bits)
    assert np.abs(np.asarray(xs)).max() < 0.01 and len(set(bits)) == 2  # held near rest, both bits
    gain = np.mean(errors * bits)  # a scale error, the same every period: no noise
    spread = np.std(errors - gain * bits)  # what changes from period to period
    c, mech = model.coordinates[0], filters.mechanics_of(model, d, "z")
    k_el = (c.stiffness - mech.stiffness) / duty(d.t)
    share = (abs(c.stiffness) + abs(k_el)) * np.abs(xs).max() * c.scale * (WINDOW[1] - WINDOW[0]) * d.ts
    bound = 7 * d.reltol * share / (bit_impulse * c.mass)
    assert abs(gain) < bound and spread < bound, (gain, spread, bound)


def test_the_designed_filters_default_to_the_step_and_lead2_keeps_its_ramps(model, tmp_path):
    """cifb: Timing.fb_edge 0, the reference's force pulse one piece over [fb_on, fb_off], duty
    fb_off - fb_on and two step corners; the example's lead2 loop, and cifb where the back end has
    no step: the 0.02 T_s ramps of the paper's bench; [loop.timing] fb_edge chooses either."""
    d = sd.design(model, TS, spec=loopfile.read_loop_file(loop_file(tmp_path, CIFB4)))
    t = d.t
    assert t.fb_ramp == 0 and filters.mechanics_of(model, d, "z").pulse == ((t.fb_on, t.fb_off, 1.0),)
    assert duty(t) == pytest.approx(t.fb_off - t.fb_on) and {t.fb_on, t.fb_off} <= set(d.corners())
    lead = sd.design(model, TS, spec=sd.read_structure_loop(EXAMPLE))
    assert lead.t.fb_ramp == 0.02 == lead.t.edge and lead.t.fb_edge is None
    ramp = sd.design(
        model, TS, spec=loopfile.read_loop_file(loop_file(tmp_path, CIFB4 + "[loop.timing]\nfb_edge = 0.02\n"))
    )
    assert ramp.t.fb_ramp == 0.02 and len(filters.mechanics_of(model, ramp, "z").pulse) == 2 * filters.RAMP_PIECES + 1
    # a back end without the step (runner.STEP_BACKENDS) keeps a designed filter on the ramps
    assert sd.design(model, TS, spec=loopfile.read_loop_file(loop_file(tmp_path, CIFB4)), step=False).t.fb_ramp == 0.02


@pytest.mark.parametrize(
    "sim,text,key",
    [
        ("ngspice", '[loop]\nchannels = ["z"]\n[loop.timing]\nfb_edge = 0\n', "loop.timing.fb_edge"),
        ("ngspice-xspice", '[loop]\nchannels = ["z"]\n[loop.timing]\nfb_edge = 0.2\n', "loop.timing.fb_edge"),
    ],
)
def test_a_feedback_step_where_it_cannot_run_exits_2(sim, text, key, tmp_path, capsys):
    """A step on the behavioural ngspice loop, or an edge wider than 0.1 T_s: exit 2 naming the
    file and loop.timing.fb_edge, no traceback."""
    code = cli.main(
        [
            "sigma-delta",
            str(EXAMPLE),
            "--loop",
            str(loop_file(tmp_path, text)),
            "--simulator",
            sim,
            "--cycles",
            "64",
            "-o",
            str(tmp_path / "sd"),
            "-q",
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err and key in err and "loop.toml" in err, err
