"""The compiled loop's state-space filter block (netgen_sdloop's flt_* parameters, the
higher-order loops of netgen.testbench.sigma_delta.filters) against the filter's definition in
numpy on the exact-instant samples: a fourth-order channel beside a lead channel in one instance."""

from __future__ import annotations

import numpy as np
import pytest

from netgen.sim import codemodel
from netgen.sim.ngspice import run_ngspice
from netgen.testbench.sigma_delta import filters
from netgen.testbench.sigma_delta.ngspice import LOOP_LIBRARY

from .test_sd_orders import DISK_Z

TS, T_SAMPLE, T_LATCH, LEAD = 1e-6, 0.34, 0.42, 0.8
CA = [(0.02, 37e3, 0.0, 0.001), (0.5, 91e3, 0.3, 0.1)]  # amplitude, frequency, phase, offset


@pytest.fixture(scope="module")
def cold_build():
    """The loop's library for the installed ngspice (built once, under the cache's lock)."""
    return codemodel.build(LOOP_LIBRARY, progress=lambda m: None)


def _netlist(cm, f: filters.Filter, u0: list[float], periods: int) -> str:
    """One instance: channel 0 with the state-space filter f (flt_n = K), channel 1 lead (flt_n 0)."""
    vec = lambda xs: "[" + " ".join(repr(float(x)) for x in xs) + "]"  # noqa: E731
    card = (
        f".model lp netgen_sdloop (ts={TS} t_sample={T_SAMPLE} t_latch={T_LATCH} lead={LEAD} "
        f"sel=[1 0 -1 1] ph_sense=[0.5] ph_fb=[2] ph_pulse=[0 1 0 1e-8 1e-8 1e-7 1e-6] "
        "dither_amp=[0 0] dither_step=[0 0] cur0=[0 0] prev0=[0 0] b0=[0 0] "
        f"flt_n=[{f.states} 0] flt_a={vec(f.a.ravel())} flt_bx={vec(f.bx)} flt_bv={vec(f.bv)} "
        f"flt_c={vec(f.c)} flt_d=[{f.d!r} 0] u0={vec(u0)})"
    )
    sources = [f"Vca{i} ca{i} 0 SIN({o} {a} {fr} 0 0 {np.degrees(p)})" for i, (a, fr, p, o) in enumerate(CA)]
    return "\n".join(
        [
            "netgen_sdloop: a state-space channel and a lead channel",
            *sources,
            f"A1 [ca0 ca1] NULL [d0 d1] [b0 b1] [cur0 cur1] NULL [{' '.join(f'u{i}' for i in range(f.states))}] lp",
            card,
            ".control",
            *codemodel.control_lines(cm),
            ".endc",
            f".tran {TS / 50} {periods * TS} 0 {TS / 20}",
            ".end",
            "",
        ]
    )


def test_state_space_channel_is_the_filter_definition(cold_build, tmp_path):
    """Over 300 periods the filter channel's bits are those of y = c.u + d x, u <- A u + bx x +
    bv v run in numpy on ca at the exact sample instants from u0, bit for bit, and the u port
    carries the states; the lead channel beside it keeps lead prev - cur."""
    periods = 300
    f = filters.design(DISK_Z, 4, 64, 1.5, "cifb")
    u0 = [0.01, -0.02]
    plot = run_ngspice(_netlist(cold_build, f, u0, periods), tmp_path)[0]
    t = np.asarray(plot["time"])
    at = (np.arange(periods) + 0.7) * TS
    got = np.array([np.interp(at, t, plot[f"v(b{i})"]) for i in range(2)]).T
    ts = (np.arange(periods) + T_SAMPLE) * TS
    x = np.array([a * np.sin(2 * np.pi * fr * ts + p) + o for a, fr, p, o in CA]).T
    u, want, ys, us = np.array(u0), [], [], []
    for n in range(periods):
        y = f.c @ u + f.d * x[n, 0]
        v = 1.0 if y > 0 else -1.0
        u = f.a @ u + f.bx * x[n, 0] + f.bv * v
        want.append(v > 0)
        ys.append(y)
        us.append(u)
    assert np.min(np.abs(ys)) > 1e-4 * np.max(np.abs(ys))  # no decision the interpolation could flip
    assert 0.2 < np.mean(want) < 0.8
    assert np.array_equal(got[:, 0] > 0.5, np.array(want))
    states = np.array([np.interp(at, t, plot[f"v(u{i})"]) for i in range(f.states)]).T
    # the u port after each update (the integrators sum the samples' interpolation error, 1e-4 each)
    assert np.abs(states - np.array(us)).max() < 1e-3 * np.abs(us).max()
    assert [plot[f"v(u{i})"][0] for i in range(f.states)] == pytest.approx(u0)
    lead = LEAD * np.concatenate([[0.0], x[:-1, 1]]) - x[:, 1]
    assert np.array_equal(got[:, 1] > 0.5, lead > 0)
