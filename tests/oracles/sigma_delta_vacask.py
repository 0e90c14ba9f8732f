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
    model: MacroModel,
    d: sd.Design,
    clock: dict,
    ref: np.ndarray,
    vel: np.ndarray,
    gain: float,
    first: float,
    orders1: int = 1,
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
    - corners: the first `orders1` steps after each breakpoint (Design.corners, every period; ngspice
      one, VACASK two) are backward Euler, each shrinking the oscillation about the equilibrium by
      (omega h_b)^2 / 2; h_b is at most `first` of a ramp (ngspice: 0.1 of the gap to the next
      breakpoint and of the step before, the ramp on either side of a corner; VACASK: its ramp step
      bound), so |dx(t)| <= orders1 n_corners / T_s (omega h_b)^2 / 2 int_0^t A_F(s) ds;
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
            corners = orders1 * len(d.corners()) / d.ts * (w * h_b) ** 2 / 2 * reach.max() / peak
        accel = (force[:, i] - c.stiffness * q[:, i] - c.damping * v[:, i]) / c.mass
        interp = h**2 / 8 * np.abs(accel).max() / peak
        out[c.name] = {"gain": gain, "drift": float(drift), "corners": float(corners), "interp": float(interp)}
    return out


def impulse_bound(
    model: MacroModel,
    d: sd.Design,
    clock: dict,
    ref: np.ndarray,
    gain: float,
    sense_gain: float | None = None,
    first: float = 0.1,
    orders1: int = 1,
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """z's error per period, as the second difference of |simulated - replayed| at the samples
    t_n (mid-feedback), and the terms of its derived bound (arrays over n = 1 .. len(ref) - 2, m).

    For x'' = a(t) the second difference is exact: x_n+1 - 2 x_n + x_n-1 = int a(t) L_n(t) dt, L_n
    the hat (T_s - |t - t_n|)+, so an impulse error dJ inside a pulse moves it by at most
    |dJ| / m max L_n over the pulse, and nothing outside (t_n-1, t_n+1) counts: the error is not
    amplified by the free mass's double integration, as the samples themselves are. Terms:
    - gain: each feedback and sense impulse of the electrostatic force on z (the plateau force of the
      period's pattern, resp. the net pull of every electrode at V_s, at the replayed position)
      integrated within `gain` (`sense_gain`, default `gain`) of itself; max L_n is T_s over the
      sample's own feedback pulse, the
      half-width w over its neighbours', T_s minus the gap to the sample over the sense phases of
      periods n and n + 1;
    - position: the trapezoidal rule on x' = v over a ramp of tau (steps <= tau between its corner
      breakpoints) leaves sum h^3 / 12 |F'| / m <= |F| tau^2 / (6 m) (V^2 quadratic, |F'| <= 2 |F| / tau),
      and each backward-Euler step after either corner (`orders1` of them, each <= `first` tau:
      ngspice one, NGSPICE_FIRST; VACASK two, its ramp step bound) h^2 |F| / (2 m) more; a position
      offset made inside (t_n-1, t_n+1) enters the second difference once: four feedback and four
      sense ramps;
    - interp: each sample is interpolated linearly between time points <= tmax T_s apart, off by
      h^2 / 8 |x''| (x'' the plateau's acceleration, gravity included): 1 + 2 + 1 of that;
    - coupling: the error's own force, sum_c max |dF_z / dq_c| max |e_c| over the window times
      int L_n = T_s^2 (slopes by central differences at 1e-3 of each scale over the feedback
      patterns and the sense voltages; e_c the run's largest error on c at the samples, which for
      the modes, swinging several times a period, stands for the error's amplitude: the term is
      about 1e-3 of the bound on the runs measured)."""
    n, ts = len(ref), d.ts
    units = np.array([c.port_units[1] for c in model.coordinates])
    q = ref * units
    sim = np.stack([np.asarray(clock[f"x_{c.name}"][:n]) for c in model.coordinates], axis=1) * units
    e = sim - q
    second = np.abs(e[2:, 0] - 2 * e[1:-1, 0] + e[:-2, 0])
    volts = np.array(
        [d.vfb * sd_loop.selected(d.electrodes, tuple(int(clock[f"bits_{c}"][k]) for c in d.names)) for k in range(n)]
    )
    f_fb = np.abs(model.electrostatic_force(q / model.scales, volts)[:, 0])
    f_s = np.abs(model.electrostatic_force(q / model.scales, np.full((n, len(d.electrodes)), d.vs))[:, 0])
    t, mass = d.t, model.coordinates[0].mass
    sample = (t.fb_on + t.fb_off) / 2
    w = (t.fb_off - t.fb_on + t.fb_ramp) / 2
    j_fb = f_fb * d.duty * ts
    j_s = f_s * sd.duty(t, t.sense_on, t.sense_off) * ts
    own_sense = 1 - (sample - t.sense_off - t.edge / 2)  # max L_n / T_s over period n's sense phase
    next_sense = 1 - (1 + t.sense_on - t.edge / 2 - sample)  # over period n + 1's
    mid = slice(1, n - 1)
    sense_gain = gain if sense_gain is None else sense_gain
    gain_term = (
        ts
        / mass
        * (
            gain * (j_fb[mid] + w * (j_fb[:-2] + j_fb[2:]))
            + sense_gain * (max(own_sense, 0.0) * j_s[mid] + max(next_sense, 0.0) * j_s[2:])
        )
    )
    near_fb = np.maximum(np.maximum(f_fb[:-2], f_fb[1:-1]), f_fb[2:])
    near_s = np.maximum(np.maximum(f_s[:-2], f_s[1:-1]), f_s[2:])
    tau, tau_fb = t.edge * ts, max(t.fb_ramp, t.edge) * ts
    ramp = (1 / 6 + 2 * orders1 * first**2 / 2) / mass  # the trapezoidal ramp, the steps after its corners
    position = 4 * near_fb * tau_fb**2 * ramp + 4 * near_s * tau**2 * ramp
    accel = np.abs(model.electrostatic_force(q / model.scales, volts)[:, 0] - d.mass * 9.81) / mass
    interp = 4 * (d.tmax * ts) ** 2 / 8 * np.maximum(np.maximum(accel[:-2], accel[1:-1]), accel[2:])
    slopes = _slopes(model, volts, d.vs)
    reach = np.abs(e).max(axis=0)
    coupling = np.full(n - 2, float(slopes @ reach) * ts**2 / mass)
    return second, {"gain": gain_term, "position": position, "interp": interp, "coupling": coupling}


def _slopes(model: MacroModel, volts: np.ndarray, vs: float) -> np.ndarray:
    """max |dF_z / dq_c| (SI) over the feedback patterns in `volts` and the sense voltages, per c."""
    patterns = np.unique(np.vstack([volts, np.full((1, volts.shape[1]), vs)]), axis=0)
    out = np.zeros(model.ncoords)
    for i, c in enumerate(model.coordinates):
        step = np.zeros((1, model.ncoords))
        step[0, i] = 1e-3
        for v in patterns:
            f = model.electrostatic_force(np.concatenate([step, -step]), np.array([v, v]))[:, 0]
            out[i] = max(out[i], abs(f[0] - f[1]) / (2e-3 * c.scale))
    return out
