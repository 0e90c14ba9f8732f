"""netgen_sdloop, the sigma-delta testbench's compiled loop (netgen/testbench/sigma_delta/netgen_sdloop,
its own code-model library), against the loop's definition in numpy: samples at the exact
instants, bits, drives, initial state and AC gain, and its own PULSE phases against the PULSE
definition."""

from __future__ import annotations

import numpy as np
import pytest

from netgen.sim import codemodel
from netgen.sim.ngspice import run_ngspice
from netgen.testbench.sigma_delta.ngspice import LOOP_LIBRARY


@pytest.fixture(scope="module")
def cold_build():
    """The loop's library for the installed ngspice (built once, under the cache's lock)."""
    return codemodel.build(LOOP_LIBRARY, progress=lambda m: None)


# netgen_sdloop: two channels, three electrodes, two phase inputs
TS, T_SAMPLE, T_LATCH, LEAD, START = 1e-6, 0.34, 0.42, 0.8, 5
CA = [(1.0, 37e3, 0.0, 0.0), (0.5, 91e3, 0.3, 0.1)]  # amplitude, frequency, phase, offset
DITHER = [(0.05, 2.9), (0.02, 1.7)]  # amplitude, phase step per period
SEL = [[1, 0], [-1, 1], [0, 0]]  # e0: b0 = 1; e1: b0 = 0 and b1 = 1; e2: never (sense only)
LEADS = [0.8, 0.55]  # per channel (the leads vector), for the second case
INIT = {"cur0": [0.3, -0.2], "prev0": [0.1, 0.4], "b0": [1, 0]}


def _loop_reference(periods: int, leads: list[float] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The loop's definition, period by period, with ca sampled at its exact instants: samples,
    bits and the lead-filter-plus-dither decision variable y (lead per channel: `leads`)."""
    lead = np.array(leads) if leads else LEAD
    cur, prev = np.array(INIT["cur0"], float), np.array(INIT["prev0"], float)
    curs, bits, ys = [], [], []
    for k in range(periods):
        t = (k + T_SAMPLE) * TS
        prev, cur = cur, np.array([a * np.sin(2 * np.pi * f * t + p) + o for a, f, p, o in CA])
        y = lead * prev - cur + np.array([a * np.sin(s * (k + START)) for a, s in DITHER])
        curs.append(cur)
        ys.append(y)
        bits.append((y > 0).astype(float))
    return np.array(curs), np.array(bits), np.array(ys)


def _sdloop_netlist(
    cm, analysis: str, pulses: list[tuple] | None = None, leads: list[float] | None = None, extra: str = ""
) -> str:
    """The instance with the phases as inputs from DC sources, or (pulses given) from its own
    PULSE(v1 v2 td tr tf pw per) waveforms; `leads`: a lead coefficient per channel; `extra`:
    more .model parameters."""
    vec = lambda xs: "[" + " ".join(str(x) for x in xs) + "]"  # noqa: E731
    ph_pulse = vec(float(v) for p in pulses for v in p) if pulses else "[0]"
    lead = f"leads={vec(leads)}" if leads else f"lead={LEAD}"
    card = (
        f".model lp netgen_sdloop (ts={TS} t_sample={T_SAMPLE} t_latch={T_LATCH} {lead} start={START} "
        f"sel={vec(v for row in SEL for v in row)} ph_sense=[0.5 0] ph_fb=[0 2] ph_pulse={ph_pulse} "
        f"dither_amp={vec(a for a, _ in DITHER)} dither_step={vec(s for _, s in DITHER)} "
        + " ".join(f"{k}={vec(v)}" for k, v in INIT.items())
        + " flt_n=[0 0] flt_a=[0] flt_bx=[0] flt_bv=[0] flt_c=[0] flt_d=[0 0] u0=[0]"
        + (f" {extra}" if extra else "")
        + ")"
    )  # lead channels
    sources = [f"Vca{i} ca{i} 0 SIN({o} {a} {f} 0 0 {np.degrees(p)})" for i, (a, f, p, o) in enumerate(CA)]
    return "\n".join(
        [
            "netgen_sdloop: two channels, three electrodes",
            *sources,
            "Vphs phs 0 DC 1",
            "Vphf phf 0 DC 1 AC 1",
            f"A1 [ca0 ca1] {'NULL' if pulses else '[phs phf]'} [d0 d1 d2] [b0 b1] [cur0 cur1] [prev0 prev1] NULL lp",
            card,
            ".control",
            *codemodel.control_lines(cm),
            ".endc",
            analysis,
            ".end",
            "",
        ]
    )


@pytest.mark.parametrize("leads", [None, LEADS], ids=["lead", "leads"])
def test_sdloop_samples_filters_quantizes_and_drives(cold_build, tmp_path, leads):
    """Over 200 periods the code model's samples equal ca at the exact sample instants (within the
    linear interpolation between time points, 1e-4 of the amplitude), its latched bits equal the
    sign of lead*prev - cur + dither of that reference, prev holds the sample before, the drives
    are ph_sense.ph + selection(bits) * ph_fb.ph, and the state starts from cur0/prev0/b0."""
    periods = 200
    plot = run_ngspice(
        _sdloop_netlist(cold_build, f".tran {TS / 50} {periods * TS} 0 {TS / 20}", leads=leads), tmp_path
    )[0]
    t = np.asarray(plot["time"])
    at = (np.arange(periods) + 0.7) * TS  # after the latch of each period
    cur, bits, y = _loop_reference(periods, leads)
    got = {k: np.array([np.interp(at, t, plot[f"v({k}{i})"]) for i in range(2)]).T for k in ("cur", "prev", "b")}
    assert np.abs(got["cur"] - cur).max() < 1e-4
    assert np.abs(got["prev"][1:] - cur[:-1]).max() < 1e-4
    assert got["prev"][0] == pytest.approx(INIT["cur0"])  # the first sample shifts cur0 into prev
    clear = np.abs(y) > 1e-3  # decisions the interpolation cannot flip
    assert clear.mean() > 0.95 and 0.2 < bits.mean() < 0.8
    assert np.array_equal(got["b"][clear], bits[clear])
    before = np.interp(0.2 * TS, t, plot["v(b0)"]), np.interp(0.2 * TS, t, plot["v(b1)"])
    assert before == tuple(float(b) for b in INIT["b0"])  # the latch holds b0 until the first clock
    b = got["b"]
    drives = np.array([np.interp(at, t, plot[f"v(d{e})"]) for e in range(3)]).T
    expect = 0.5 + 2 * np.array([b[:, 0], (1 - b[:, 0]) * b[:, 1], np.zeros(periods)]).T
    assert np.abs(drives - expect).max() < 1e-9


def test_sdloop_ac_gain_is_the_selected_drive(cold_build, tmp_path):
    """At the initial state (b0 = [1, 0]: electrode 0 selected, 1 not, 2 in no pattern)
    d drv / d phf = ph_fb = 2 on the selected electrode and 0 on the others."""
    plot = run_ngspice(_sdloop_netlist(cold_build, ".ac lin 1 1k 1k"), tmp_path)[0]
    assert [plot[f"v(d{e})"][0].real for e in range(3)] == pytest.approx([2.0, 0.0, 0.0], abs=1e-12)


def _pulse(t: np.ndarray, v1, v2, td, tr, tf, pw, per) -> np.ndarray:
    """PULSE as the ngspice manual defines it (linear ramps, periodic after td)."""
    x = np.mod(t - td, per)
    x = np.where(t < td, -1.0, x)
    return np.select(
        [x <= 0, x < tr, x <= tr + pw, x < tr + pw + tf],
        [v1, v1 + (v2 - v1) * x / tr, v2, v2 + (v1 - v2) * (x - tr - pw) / tf],
        v1,
    )


def test_sdloop_drives_from_its_own_pulse_phases(cold_build, tmp_path):
    """Without ph inputs the instance evaluates the phases from ph_pulse: the drives follow
    ph_sense.PULSE + selection * ph_fb.PULSE at every time point (the selection is constant here:
    b0 = [1, 0] until the first latch at 0.42 us, so the run stops before it)."""
    pulses = [(0, 1, 0.05e-6, 0.02e-6, 0.03e-6, 0.1e-6, 0.25e-6), (0, 2, 0.0, 0.04e-6, 0.01e-6, 0.05e-6, 0.2e-6)]
    plot = run_ngspice(_sdloop_netlist(cold_build, ".tran 1e-9 0.4e-6 0 5e-9", pulses), tmp_path)[0]
    t = np.asarray(plot["time"])
    sense, fb = (_pulse(t, *p) for p in pulses)
    expect = [0.5 * sense + 2 * fb, 0.5 * sense + 0 * fb, 0.5 * sense + 0 * fb]  # s = [1, 0, 0]
    for e in range(3):
        assert np.abs(np.asarray(plot[f"v(d{e})"]) - expect[e]).max() < 1e-12
    assert fb.max() == 2 and sense.max() == 1  # the ramps were covered


FB_LEVEL, FB_ON, FB_OFF = 1.5, 0.5, 0.94


def test_sdloop_feedback_step_is_a_step_at_its_own_breakpoints(cold_build, tmp_path):
    """With fb_level the drives add fb_level x selection on (fb_on, fb_off] of every period, a
    step: at every time point the drive is the definition's (the selection from the numpy loop's
    bits, latched at 0.42 T_s), and ngspice put a time point on each step instant and on the one
    1e-3 T_s after it (the instance's own breakpoints: backward-Euler steps there, so a force that
    is constant between them is integrated exactly; netgen_sdloop/cfunc.mod)."""
    pulses = [(0, 1, 0.05e-6, 0.02e-6, 0.03e-6, 0.1e-6, 1e-6), (0, 0, 0.0, 0.04e-6, 0.01e-6, 0.05e-6, 1e-6)]
    periods = 3
    net = _sdloop_netlist(
        cold_build,
        f".tran 1e-9 {periods * TS} 0 5e-8",
        pulses,
        extra=f"fb_level={FB_LEVEL} fb_on={FB_ON} fb_off={FB_OFF}",
    )
    plot = run_ngspice(net, tmp_path)[0]
    t = np.asarray(plot["time"])
    _, bits, _ = _loop_reference(periods)
    phase = t / TS - np.floor(t / TS)
    last = np.floor(t / TS - T_LATCH).astype(int)  # the latch that set the bits at t
    b = np.where(last[:, None] < 0, np.array(INIT["b0"], float)[None, :], bits[np.clip(last, 0, None)])
    on = ((phase > FB_ON + 1e-6) & (phase <= FB_OFF + 1e-6)).astype(float)
    sel = [b[:, 0], (1 - b[:, 0]) * b[:, 1], 0 * b[:, 0]]
    sense = _pulse(t, *pulses[0])
    away = np.abs(t / TS - np.round(t / TS - T_LATCH) - T_LATCH) > 1e-3  # not at a latch instant
    for e in range(3):
        expect = 0.5 * sense + sel[e] * FB_LEVEL * on
        assert np.abs(np.asarray(plot[f"v(d{e})"]) - expect)[away].max() < 1e-12, e
    for k in range(periods):
        for at in (FB_ON, FB_ON + 1e-3, FB_OFF, FB_OFF + 1e-3):
            assert np.abs(t - (k + at) * TS).min() < 1e-9 * TS, (k, at)
    assert on.any() and any(sel[0] * on)  # a step was on in the run


def test_sdloop_ramp_steps_cross_each_edge_in_equal_steps(cold_build, tmp_path):
    """With ramp_steps = N ngspice's time points on every edge of the drives (an interval between
    the PULSE corners where the sense or the feedback phase changes, from the PULSE definition) are
    the N + 1 equally spaced points from corner to corner, in each of three periods, and no others
    (the circuit has no charge whose truncation error could ask for more; tmax 50 ns is 2.5 to 7.5
    edge lengths, so without the grid an edge gets fewer points). The instance sets the corners as
    breakpoints too (the netlist has no PULSE source). Tolerance 1e-15 s: a breakpoint is reached as
    the last time plus the difference, exact to the double round-off of times below 3 us (1e-21 s
    per step)."""
    n = 5
    sense, fb = (0, 1, 0.05e-6, 0.02e-6, 0.03e-6, 0.2e-6, TS), (0, 2, 0.5e-6, 0.04e-6, 0.02e-6, 0.3e-6, TS)
    edges = [(0.05e-6, 0.07e-6), (0.27e-6, 0.30e-6), (0.5e-6, 0.54e-6), (0.84e-6, 0.86e-6)]
    netlist = _sdloop_netlist(cold_build, ".tran 1e-9 3e-6 0 50e-9", [sense, fb], extra=f"ramp_steps={n}")
    t = np.asarray(run_ngspice(netlist, tmp_path)[0]["time"]).real
    for k in range(3):
        for a, b in edges:
            a, b = a + k * TS, b + k * TS
            inside = t[(t > a - 1e-15) & (t < b + 1e-15)]
            assert inside == pytest.approx(a + (b - a) * np.arange(n + 1) / n, abs=1e-15, rel=0)
