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


def phase_forces(model, d, reach: float) -> dict:
    """Per electrode phase of the period (feedback for bit -1 and +1, sense at V_s, off): the model's
    z force at rest F0, its slope k at rest, its largest |F| and the largest departure from
    F0 + k x over |x| <= reach (N, N/m)."""
    scale = model.coordinates[0].scale
    grid = np.linspace(-reach, reach, 81)
    volts = {b: d.vfb * sd_loop.selected(d.electrodes, (b,)) for b in (-1, 1)}
    volts["sense"] = np.full(len(d.electrodes), d.vs)
    out = {"off": {"f0": 0.0, "k": 0.0, "max": 0.0, "nonlinear": 0.0}}
    for name, v in volts.items():
        f = model.electrostatic_force((grid / scale)[:, None], np.broadcast_to(v, (len(grid), len(v))))[:, 0]
        step = 1e-3 * reach
        ends = model.electrostatic_force(np.array([[step], [-step]]) / scale, np.array([v, v]))[:, 0]
        f0, k = float(f[len(grid) // 2]), float((ends[0] - ends[1]) / (2 * step))
        out[name] = {
            "f0": f0,
            "k": k,
            "max": float(np.abs(f).max()),
            "nonlinear": float(np.abs(f - f0 - k * grid).max()),
        }
    return out


def phase_at(d, p: float, bit: int) -> str:
    """The electrode phase at period phase p of a period with feedback bit `bit` (the sense phase
    from sense_on to sense_off, its ramps centred there; the feedback a step on fb_on..fb_off)."""
    t = d.t
    if t.sense_on <= p <= t.sense_off:
        return "sense"
    return bit if t.fb_on <= p <= t.fb_off else "off"


def momentum_defect(model, d, a_in: float, bits: np.ndarray, x: np.ndarray, gain: float):
    """Each period's momentum balance on z in the circuit's own samples x (m, mid-feedback): the
    second difference x_n+1 - 2 x_n + x_n-1 less the integral of the forces the model applies at
    the circuit's positions against the hat (T_s - |t - t_n|)+ over m, for n = 1 .. len(x) - 2, and
    the terms of its derived bound (arrays, m). For x'' = a the second difference is exactly that
    integral of a, so what is left is what the forces' linear form per phase (F0 + k x, the
    feedback a step, the sense phase full from sense_on to sense_off) and the circuit's integration
    leave; nothing accumulates from period to period. Terms:
    - gain: every feedback and sense impulse within `gain` of itself (ngspice's LTE limit,
      NGSPICE_GAIN of tests/testbench/test_sigma_delta_vacask.py), weighted by the hat's largest
      value over it: T_s (the sample's own pulse), the half-width w (its neighbours'), T_s less the
      gap to the sample (the sense phases of periods n and n + 1);
    - nonlinear: the model's force off F0 + k x over |x| <= R (R the samples' largest |x| plus a
      chord's departure T_s^2 / 8 max |x''|), times int hat = T_s^2, over m;
    - ramps: the sense ramps (tau, centred on the corners) against the full phase: int |(t / tau)^2 -
      step| = tau / 4 each, four in the window, times the largest sense force and T_s, over m;
    - chord: the positions between samples taken as the chord, off by T_s^2 / 8 max |x''| plus the
      samples' own interpolation, times max |k - K| T_s^2 / m;
    - interp: each sample interpolated linearly between time points <= tmax T_s apart,
      (tmax T_s)^2 / 8 max |x''|, 1 + 2 + 1 of that;
    - position: the backward-Euler step after each breakpoint (<= 0.1 of the step before, itself
      <= tmax T_s: ngspice's dctran.c) moves x by h^2 |F| / (2 m) where the feedback steps (four in
      the window), and over a sense ramp the trapezoidal rule and the two backward-Euler steps at its
      corners (<= 0.1 tau) |F_s| tau^2 (1 / 6 + 0.01) / m (four ramps);
    - drift: the trapezoidal rule's stiffness error (omega h)^2 / 6 at h = tmax T_s on the spring
      force max |k - K| R, omega^2 = max |k - K| / m, times T_s^2 / m.
    The z damping is zero on this device (asserted)."""
    c, t, ts = model.coordinates[0], d.t, d.ts
    assert c.damping == 0.0 and float(c.admittance(0.0).real) == 0.0
    m, k_mech = c.mass, c.stiffness
    r0 = np.abs(x).max()
    force = phase_forces(model, d, 2 * r0)
    a_max = (max(f["max"] for f in force.values()) + m * abs(a_in) + k_mech * 2 * r0) / m
    h = d.tmax * ts
    chord = ts**2 / 8 * a_max
    reach = r0 + chord
    assert reach < 2 * r0  # a_max holds on [-R, R]
    force = phase_forces(model, d, reach)
    at = (t.fb_on + t.fb_off) / 2
    edges = sorted({0.0, t.sense_on, t.sense_off, t.fb_on, t.fb_off, 1.0})
    nodes, weights = np.polynomial.legendre.leggauss(2)  # exact on the quadratic chord x hat
    n = len(x)
    defect = np.empty(n - 2)
    for i in range(1, n - 1):
        lo, hi = i - 1 + at, i + 1 + at  # in periods
        cuts = sorted({lo, hi, i + at, *(p + k for k in (i - 1, i, i + 1) for p in edges if lo < p + k < hi)})
        total = 0.0
        for a, b in zip(cuts[:-1], cuts[1:]):
            mid = (a + b) / 2
            period = int(np.floor(mid))
            f = force[phase_at(d, mid - period, int(bits[period]))]
            tq = mid + (b - a) / 2 * nodes
            xq = np.interp(tq, np.arange(n) + at, x)
            hat = 1 - np.abs(tq - (i + at))
            acc = (f["f0"] + (f["k"] - k_mech) * xq) / m + a_in
            total += (b - a) / 2 * float(np.dot(weights, acc * hat))
        defect[i - 1] = x[i + 1] - 2 * x[i] + x[i - 1] - total * ts**2
    j = {b: force[b]["max"] * d.duty * ts for b in (-1, 1)}
    j_fb = np.array([j[int(b)] for b in bits])
    j_s = force["sense"]["max"] * sd.duty(t, t.sense_on, t.sense_off) * ts
    w = (t.fb_off - t.fb_on + t.fb_ramp) / 2
    own_sense = max(1 - (at - t.sense_off - t.edge / 2), 0.0)
    next_sense = max(1 - (1 + t.sense_on - t.edge / 2 - at), 0.0)
    mid = slice(1, n - 1)
    gain_term = gain * ts / m * (j_fb[mid] + w * (j_fb[:-2] + j_fb[2:]) + (own_sense + next_sense) * j_s)
    tau = t.edge * ts
    stiff = max(abs(f["k"] - k_mech) for f in force.values())
    f_max = max(force[b]["max"] for b in (-1, 1))
    terms = {
        "gain": gain_term,
        "nonlinear": max(f["nonlinear"] for f in force.values()) * ts**2 / m,
        "ramps": 4 * tau / 4 * force["sense"]["max"] * ts / m,
        "chord": stiff * (chord + h**2 / 8 * a_max) * ts**2 / m,
        "interp": 4 * h**2 / 8 * a_max,
        "position": 4 * (0.1 * h) ** 2 * f_max / (2 * m) + 4 * force["sense"]["max"] * tau**2 * (1 / 6 + 0.01) / m,
        "drift": (np.sqrt(stiff / m) * h) ** 2 / 6 * stiff * reach * ts**2 / m,
    }
    return defect, {k: np.broadcast_to(v, (n - 2,)) for k, v in terms.items()}
