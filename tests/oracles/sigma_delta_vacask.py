"""The sigma-delta loop of tests/testbench/test_sigma_delta_vacask.py (the reference disk at
T_s = 1 us, its run lengths and channels), shared with bench/vacask_options.py: one run of the loop
in a given simulator (run), and the independent integration of the mechanics driven by the bits a run
produced (replay: scipy solve_ivp of M q'' + D q' + K q = F_el(q, V) + F_ext with the Python model's
forces, for the electrode voltages the bench applies). The test module's docstring gives the checks
and tolerances."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from netgen.model import MacroModel
from netgen.testbench import sigma_delta as sd
from netgen.testbench.sigma_delta import loop as sd_loop

ROOT = Path(__file__).resolve().parents[2]

CHANNELS = ("z", "tilt_x", "tilt_y")  # the levitated disk's default channels (loop.channel_names)

LIB = ROOT / "netlists" / "levitated_disk.lib"
TS = 1e-6
CYCLES, SKIP = 512, 64  # VACASK: ~10 s; long enough for a momentum balance within 1 %
REPLAY = 48  # clocks of the independent integration (~10 s)


def run(model, out, simulator, cycles, skip):
    """sigma_delta.run of the loop on LIB in `simulator` (cycles periods, skip settling), with its wall time."""
    start = time.perf_counter()
    s = sd.run(model, LIB, out, sd.RunRequest(TS, cycles, progress=False, plots=False, skip=skip, simulator=simulator))
    return s | {"wall": time.perf_counter() - start}


def _phase(t: float, on: float, off: float, edge: float, ts: float) -> float:
    """The bench's trapezoidal clock phase (linear edges of `edge` centred on on/off), 0..1."""
    p = t / ts - np.floor(t / ts)
    return float(np.clip((p - on + edge / 2) / edge, 0, 1) - np.clip((p - off + edge / 2) / edge, 0, 1))


def replay(model: MacroModel, d: sd.Design, clock: dict, cycles: int, velocities: bool = False):
    """Coordinates (port units) at the per-clock sample times from solve_ivp of the mechanics driven
    by the electrode voltages the bench applies for the recorded bits: V_s in the sense phase, V_fb
    on the electrodes netgen.testbench.sigma_delta.loop.selected() picks in the feedback phase, gravity on z.
    With velocities, (coordinates, their velocities in port units per second)."""
    t = d.t
    n = model.ncoords
    sel = [sd_loop.selected(d.electrodes, tuple(int(clock[f"bits_{c}"][k]) for c in CHANNELS)) for k in range(cycles)]
    mass = np.array([c.mass for c in model.coordinates])
    stiff = np.array([c.stiffness for c in model.coordinates])
    damp = np.array([c.damping for c in model.coordinates])
    scale = model.scales
    f_ext = np.zeros(n)
    f_ext[0] = -d.mass * 9.81  # gravity on z (the design's default input)

    def rhs(time_, y):
        k = min(int(time_ / d.ts), cycles - 1)
        v = (
            d.vs * _phase(time_, t.sense_on, t.sense_off, t.edge, d.ts)
            + d.vfb * _phase(time_, t.fb_on, t.fb_off, t.edge, d.ts) * sel[k]
        )
        f = model.electrostatic_force(y[:n] / scale, v)[0] + f_ext
        return np.concatenate([y[n:], (f - damp * y[n:] - stiff * y[:n]) / mass])

    # integrate between the corners of the voltage waveform (smooth inside each piece)
    corners = [
        (k + f) * d.ts
        for k in range(cycles)
        for f in (
            t.sense_on - t.edge / 2,
            t.sense_on + t.edge / 2,
            t.sense_off - t.edge / 2,
            t.sense_off + t.edge / 2,
            t.fb_on - t.edge / 2,
            t.fb_on + t.edge / 2,
            t.fb_off - t.edge / 2,
            t.fb_off + t.edge / 2,
        )
    ]
    corners = np.unique(np.clip([0.0, *corners, cycles * d.ts], 0.0, cycles * d.ts))
    at = clock["time"][:cycles]
    y, out = np.zeros(2 * n), np.zeros((cycles, 2 * n))
    for a, b in zip(corners[:-1], corners[1:]):
        inside = np.nonzero((at > a) & (at <= b))[0]
        sol = solve_ivp(rhs, (a, b), y, method="DOP853", rtol=1e-9, atol=1e-30, dense_output=True)
        for i in inside:
            out[i] = sol.sol(at[i])
        y = sol.y[:, -1]
    units = np.array([c.port_units[1] for c in model.coordinates])
    return (out[:, :n] / units, out[:, n:] / units) if velocities else out[:, :n] / units


def mechanics_bound(
    model: MacroModel, d: sd.Design, clock: dict, ref: np.ndarray, vel: np.ndarray, gain: float, first: float
) -> dict[str, dict[str, float]]:
    """The largest |simulated - replayed| a trapezoidal simulator may leave on each coordinate after
    z, a fraction of the coordinate's peak over the replayed clocks, as three terms:
    - gain: each electrostatic impulse integrated within `gain` of itself (the simulator's bound,
      NGSPICE_GAIN or vacask_gain of tests/testbench/test_sigma_delta_vacask.py); the tilts and
      modes start at rest and only the electrostatic forces drive them, so their response to those
      impulses is the coordinate itself: gain x 1 (ngspice's LTE test, cktterr.c, takes the larger
      of reltol |dq/dt| h and reltol |q|; NGSPICE_GAIN takes the first, while on a step shorter
      than the pulse the velocity exceeds its change and the second allows more: the gain term is
      NGSPICE_GAIN's premise, which the fitted gains on z, 8e-4 to 1.1e-3, stay well within);
    - drift: a trapezoidal step h maps an undamped mode at omega under a force F constant over
      the step as the exact map does, but for its rotation about the equilibrium F / K, slow by
      (omega h)^3 / 12 (amplitude kept): eps = (omega h)^2 / 12 of omega h, with h at most the
      bench's maxstep tmax T_s. So |dx(t)| <= eps omega int_0^t A_F(s) ds, A_F the amplitude about
      the equilibrium, <= A + |F| / K, A = sqrt(x^2 + (v / omega)^2) (0 for the tilts); between
      the samples t_k and t_k+1, A <= A(t_k) + J_k / (m omega), J_k = int |F| <= T_s (duty
      max(|F_k|, |F_k+1|) + sense duty |F_s|) (F_k the feedback plateau's force of the period's
      pattern, F_s the sense phase's), and int |F| / K <= J_k / K;
    - corners: the first step after each breakpoint (Design.corners, every period) is backward
      Euler, which shrinks the oscillation about the equilibrium by (omega h_b)^2 / 2; h_b is at
      most `first` of a ramp (ngspice: 0.1 of the gap to the next breakpoint and of the step
      before, the ramp on either side of a corner), so |dx(t)| <= n_corners / T_s
      (omega h_b)^2 / 2 int_0^t A_F(s) ds;
    - interp: the sample mid-feedback is interpolated linearly between time points at most
      tmax T_s apart, off by at most h^2 / 8 |x''|, x'' = (F_el - K x - D v) / m at the sample
      (the feedback plateau's force, constant over h: the ramps are 0.2 T_s away)."""
    h = d.tmax * d.ts
    units = np.array([c.port_units[1] for c in model.coordinates])
    q, v = ref * units, vel * units
    pattern = [tuple(int(clock[f"bits_{c}"][k]) for c in d.names) for k in range(len(ref))]
    volts = [d.vfb * sd_loop.selected(d.electrodes, p) for p in pattern]
    force = model.electrostatic_force(q / model.scales, np.array(volts))
    sense = np.abs(model.electrostatic_force(q / model.scales, np.full((len(ref), len(d.electrodes)), d.vs)))
    sense_duty = sd.duty(d.t, d.t.sense_on, d.t.sense_off)
    out = {}
    for i, c in enumerate(model.coordinates[1:], start=1):
        peak = np.abs(q[:, i]).max()
        drift = corners = 0.0
        if c.stiffness:
            w = np.sqrt(c.stiffness / c.mass)
            amp = np.hypot(q[:, i], v[:, i] / w)
            f = np.abs(force[:, i])
            first_j = d.ts * (d.duty * f[0] + sense_duty * sense[0, i])  # from rest to the first sample
            j = d.ts * (d.duty * np.maximum(f[:-1], f[1:]) + sense_duty * sense[:-1, i])
            piece = d.ts * (amp[:-1] + j / (c.mass * w)) + j / c.stiffness  # int A_F over each period
            start = (d.t.fb_on + d.t.fb_off) / 2 * d.ts * first_j / (c.mass * w) + first_j / c.stiffness
            reach = start + np.concatenate([[0.0], np.cumsum(piece)])
            drift = (w * h) ** 2 / 12 * w * reach.max() / peak
            h_b = first * max(d.t.edge, d.t.fb_ramp) * d.ts
            corners = len(d.corners()) / d.ts * (w * h_b) ** 2 / 2 * reach.max() / peak
        accel = (force[:, i] - c.stiffness * q[:, i] - c.damping * v[:, i]) / c.mass
        interp = h**2 / 8 * np.abs(accel).max() / peak
        out[c.name] = {"gain": gain, "drift": float(drift), "corners": float(corners), "interp": float(interp)}
    return out
