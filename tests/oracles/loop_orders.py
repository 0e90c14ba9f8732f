"""The loop-orders comparison's device and loop (tests/testbench/test_loop_orders.py, shared with
bench/loop_orders_spring.py): accelerometer_z's square plate on its spring, in a 4th-order CIFB loop."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from netgen.testbench import sigma_delta as sd
from netgen.testbench.sigma_delta import loop as sd_loop

ROOT = Path(__file__).resolve().parents[2]

TS = 1e-6
SIDE, GAP, RHO, THICK, K_SPRING = 500e-6, 2e-6, 2330.0, 20e-6, 0.3
MASS = SIDE * SIDE * THICK * RHO
EXAMPLE = ROOT / "examples" / "accelerometer_z.toml"
CIFB4 = (
    '[loop]\nchannels = ["z"]\n[loop.filter]\nkind = "cifb"\norder = 4\nosr = 64\n[loop.input]\nacceleration = 9.81\n'
)


def second_difference(x: np.ndarray) -> np.ndarray:
    """x_n+1 - 2 x_n + x_n-1 for n = 1 .. len(x) - 2: for x'' = a, int a(t) (T_s - |t - t_n|)+ dt."""
    return x[2:] - 2 * x[1:-1] + x[:-2]


def impulse_bound(model, d, mech, a_in: float, bits: np.ndarray, z_ref: np.ndarray, err: np.ndarray, gain: float):
    """The derived bound on the second difference of z's error (the circuit's samples against the
    reference's, m) per period n = 1 .. len(bits) - 2, as terms (arrays, m). The error obeys
    e'' = [F(x_c) - F(x_r)] / m + [F(x_r) - F_ref(x_r)] / m + the circuit's integration error, F the
    model's electrostatic force plus the spring (the circuit) and F_ref the reference's bit x force x
    pulse minus its mean stiffness (filters.mechanics_of), and the second difference integrates e''
    against the hat (T_s - |t - t_n|)+ (max T_s, integral T_s^2), so nothing is amplified:
    - gain: every feedback and sense impulse within `gain` of itself (ngspice's LTE limit,
      NGSPICE_GAIN of tests/testbench/test_sigma_delta_vacask.py), weighted by the hat's largest
      value over it: T_s (the sample's own pulse), the half-width w (its neighbours'), T_s minus the
      gap to the sample (the sense phases of periods n and n + 1);
    - model: the reference's linear force against the model's, max |F(x, V) - F_ref(x, V)| over the
      phases (feedback for either bit, sense at V_s, off; V^2 scales a ramp's force between off and
      on) and |x| <= R, R the reference's largest sample plus T_s^2 / 8 of its largest acceleration
      (a curve's departure from its chord), times T_s^2 / m;
    - coupling: the error's own force, max |dF/dx| (the spring's K included) times the largest |e|
      over (t_n-1, t_n+1), T_s^2 / m;
    - interp: each circuit sample is interpolated linearly between time points <= tmax T_s apart,
      off by (tmax T_s)^2 / 8 max |x''|, 1 + 2 + 1 of that;
    - position: the backward-Euler step after each breakpoint (<= 0.1 of the step before, itself
      <= tmax T_s: ngspice's dctran.c) moves x by h^2 |F| / (2 m) where the feedback steps (the
      feedback ends of periods n - 1 and n, the starts of n and n + 1), the trapezoidal rule over a
      sense ramp tau by |F_s| tau^2 / (6 m) (four ramps);
    - drift: the trapezoidal rule's stiffness error (omega h)^2 / 6 at h = tmax T_s on the spring
      force max |K_eff| R, omega^2 = max |K_eff| / m."""
    ts, t, m = d.ts, d.t, mech.mass
    k_mech = model.coordinates[0].stiffness
    k_mean = mech.stiffness - k_mech  # the reference's mean electrostatic spring
    scale = model.coordinates[0].scale
    v_bit = {b: d.vfb * sd_loop.selected(d.electrodes, (b,)) for b in (-1, 1)}
    v_s = np.full(len(d.electrodes), d.vs)

    def force(x: np.ndarray, v: np.ndarray) -> np.ndarray:
        return model.electrostatic_force((x / scale)[:, None], np.broadcast_to(v, (len(x), len(v))))[:, 0]

    r0 = np.abs(z_ref).max()
    grid0 = np.linspace(-2 * r0, 2 * r0, 81)
    a_max = (max(np.abs(force(grid0, v)).max() for v in v_bit.values()) + m * abs(a_in)) / m
    a_max += (k_mech + abs(k_mean)) * 2 * r0 / m
    reach = r0 + ts**2 / 8 * a_max
    assert reach < 2 * r0  # a_max holds on [-R, R]
    grid = np.linspace(-reach, reach, 81)
    f_fb = {b: force(grid, v) for b, v in v_bit.items()}
    f_s = force(grid, v_s)
    model_err = max(
        *(np.abs(f_fb[b] - b * mech.force + k_mean * grid).max() for b in (-1, 1)),
        np.abs(f_s + k_mean * grid).max(),
        np.abs(k_mean * grid).max(),
    )
    step = 1e-3 * reach
    slope = max(
        np.abs((force(grid + step, v) - force(grid - step, v)) / (2 * step) - k_mech).max()
        for v in (*v_bit.values(), v_s, 0 * v_s)
    )
    sense_duty = sd.duty(t, t.sense_on, t.sense_off)
    j_fb = np.array([np.abs(f_fb[int(b)]).max() for b in bits]) * d.duty * ts
    j_s = np.abs(f_s).max() * sense_duty * ts
    at = (t.fb_on + t.fb_off) / 2
    w = (t.fb_off - t.fb_on + t.fb_ramp) / 2
    own_sense = max(1 - (at - t.sense_off - t.edge / 2), 0.0)
    next_sense = max(1 - (1 + t.sense_on - t.edge / 2 - at), 0.0)
    mid = slice(1, len(bits) - 1)
    gain_term = gain * ts / m * (j_fb[mid] + w * (j_fb[:-2] + j_fb[2:]) + (own_sense + next_sense) * j_s)
    h = d.tmax * ts
    f_max = max(np.abs(f).max() for f in f_fb.values())
    position = (
        4 * (0.1 * h) ** 2 * f_max / (2 * m) + 4 * np.abs(f_s).max() * (t.edge * ts) ** 2 * (1 / 6 + 0.01 / 2) / m
    )
    k_eff = k_mech + max(abs(k_mean), slope)
    drift = (np.sqrt(k_eff / m) * h) ** 2 / 6 * k_eff * reach * ts**2 / m
    n = len(bits) - 2
    model_term = np.full(n, model_err * ts**2 / m)
    near = np.maximum(np.maximum(np.abs(err[:-2]), np.abs(err[1:-1])), np.abs(err[2:]))
    # |e| between samples: the samples' largest plus a chord's departure, T_s / 4 of int |e''| over
    # the interval, <= (gain + 2 model) / 4 and the coupling's own share (1 - slope T_s^2 / (2 m))
    local = (near + (gain_term + 2 * model_term) / 4) / (1 - slope * ts**2 / (2 * m))
    return {
        "gain": gain_term,
        "model": model_term,
        "coupling": slope * local * ts**2 / m,
        "interp": np.full(n, 4 * h**2 / 8 * a_max),
        "position": np.full(n, position),
        "drift": np.full(n, drift),
    }
