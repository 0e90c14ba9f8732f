"""Loop-filter kinds of the sigma-delta testbench and their design from the mechanics.

Every kind is one per-channel discrete-time state-space filter, updated once per period at the
latch instant (the form the compiled loop netgen_sdloop, the numpy reference
tests/oracles/sigma_delta_reference.py and the netlists evaluate):

    y[n] = c . u[n] + d x[n]            (x: the charge-amplifier sample of period n, volts)
    v[n] = +1 if y[n] + dither > 0 else -1
    u[n+1] = A u[n] + bx x[n] + bv v[n]

"lead2" (the second-order electromechanical loop with lead compensation, y = lead prev - cur) is
the one-state case u = prev. "cifb" and "crfb" are the higher-order electromechanical loops of
order 3-5: the mechanics' two integrations (the proof mass between the bit's force pulse and the
next sample, `Mechanics`) and order - 2 electronic integrators fed by the position, with the bit
fed back into each of them and the position into the first two stages (the second integrator, or the quantizer when there is one integrator). CIFB puts every
electronic integrator at DC (all NTF zeros at DC: 20 x order dB/decade in band); CRFB closes a
pair of them into a resonator that places an optimised in-band NTF zero pair. The coefficients
are designed by matching the loop's impulse response at the sampling instants to the loop filter
L = 1/NTF - 1 of a synthesised NTF (netgen.testbench.sigma_delta.ntf), by least squares over
the first samples (the approach of Dong, Kraft et al. for electromechanical loops; Schreier's
realizeNTF_ct for continuous-time loops); the NTF's zeros are the loop's own poles (the sampled
mechanics' and the electronic integrators'), its poles those of synthesize_ntf for them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import linalg, signal

from . import ntf as ntfs
from .signals import Timing, duty, selected

TOPOLOGIES = ("cifb", "crfb")
ORDERS = (3, 4, 5)
# ramps of the feedback voltage are split into this many constant-force pieces (force ~ V^2:
# each piece carries the exact impulse of its part of the squared ramp)
RAMP_PIECES = 4


@dataclass(frozen=True)
class Mechanics:
    """One channel's mechanics as the loop sees it, SI: q'' = (F - k q - b q')/m + a_in, with
    the feedback force F = force x v x pulse(t) (pulse: (start, end, weight) phases of a period,
    after the sample), read out as x = gain q + offset at the phase `sample` of every period
    (offset: the readout at rest, e.g. unequal electrode capacitances)."""

    mass: float
    stiffness: float
    damping: float
    force: float
    gain: float
    ts: float
    sample: float
    pulse: tuple[tuple[float, float, float], ...]
    offset: float = 0.0

    def continuous(self) -> tuple[np.ndarray, np.ndarray]:
        """(A, B) of the state (q, q') for a force input."""
        a = np.array([[0.0, 1.0], [-self.stiffness / self.mass, -self.damping / self.mass]])
        return a, np.array([0.0, 1.0 / self.mass])

    def period_map(self) -> tuple[np.ndarray, np.ndarray]:
        """(Phi, Gamma): the state at one sample instant to the next, s' = Phi s + Gamma v, exact
        (matrix exponentials of the piecewise-constant force, as in tests/oracles/sigma_delta_reference.py)."""
        a, b = self.continuous()
        return step_map(a, b * self.force, self.ts, self.sample, self.pulse)

    @property
    def full_scale(self) -> float:
        """The input acceleration that a bitstream of all +1 balances (m/s^2 or rad/s^2): the
        pulse's mean force over the period, over the mass (0 dBFS)."""
        return self.force * sum(w * (b - a) for a, b, w in self.pulse) / self.mass

    def output(self) -> np.ndarray:
        """The readout row: x = gain q."""
        return np.array([self.gain, 0.0])


def step_map(
    a: np.ndarray, b: np.ndarray, ts: float, sample: float, pulse: tuple[tuple[float, float, float], ...]
) -> tuple[np.ndarray, np.ndarray]:
    """(Phi, Gamma) of x' = a x + b u(t) from the sample instant to the next one, with u the
    sum of the `pulse` pieces (weight over [start, end] in period phases) times v."""
    n = len(a)
    phi = linalg.expm(a * ts)
    gamma = np.zeros(n)
    for start, end, weight in pulse:
        t0, t1 = (start - sample) * ts, (end - sample) * ts
        if not (0.0 <= t0 < t1 <= ts):
            raise ValueError(f"feedback piece [{start}, {end}] is not within the period after the sample at {sample}")
        m = np.zeros((n + 1, n + 1))
        m[:n, :n], m[:n, n] = a, b * weight
        piece = linalg.expm(m * (t1 - t0))[:n, n]  # the state a constant input leaves at t1
        gamma += linalg.expm(a * (ts - t1)) @ piece
    return phi, gamma


def trapezoid_pulse(
    on: float, off: float, edge: float, pieces: int = RAMP_PIECES
) -> tuple[tuple[float, float, float], ...]:
    """The force pulse of a voltage trapezoid (linear edges of width `edge` centred on `on` and
    `off`): force ~ V^2, so a ramp is `pieces` constant pieces, each with the mean of the squared
    ramp over it (its exact impulse), and the flat top weight 1; edge 0: one piece (a step)."""
    if edge == 0:
        return ((on, off, 1.0),)
    out = []
    h = edge / pieces
    for k in range(pieces):  # mean of s^2 over [k, k+1] / pieces
        w = ((k + 1) ** 3 - k**3) / (3.0 * pieces**2)
        out.append((on - edge / 2 + k * h, on - edge / 2 + (k + 1) * h, w))
    out.append((on + edge / 2, off - edge / 2, 1.0))
    for k in range(pieces):
        w = ((pieces - k) ** 3 - (pieces - k - 1) ** 3) / (3.0 * pieces**2)
        out.append((off - edge / 2 + k * h, off - edge / 2 + (k + 1) * h, w))
    return tuple(out)


@dataclass
class Filter:
    """A loop filter of one channel (module docstring): kind, order, the state-space
    coefficients, and for designed kinds the NTF they realise."""

    kind: str
    order: int
    a: np.ndarray
    bx: np.ndarray
    bv: np.ndarray
    c: np.ndarray
    d: float
    design: dict = field(default_factory=dict)

    @property
    def x0(self) -> float:
        """The readout's rest value trimmed from the filter's input x (V; kinds.design_designed)."""
        return float(self.design.get("x0", 0.0))

    @property
    def states(self) -> int:
        """Number of filter states K."""
        return len(self.c)

    def as_dict(self) -> dict:
        """JSON-able form (summary.json, the netlist header, Design.channels[i]["filter"])."""
        return {
            "kind": self.kind,
            "order": self.order,
            "A": self.a.tolist(),
            "bx": self.bx.tolist(),
            "bv": self.bv.tolist(),
            "c": self.c.tolist(),
            "d": float(self.d),
            **self.design,
        }

    @classmethod
    def from_dict(cls, spec: dict) -> Filter:
        """The filter of a channel's `filter` dict: lead2 ({"kind": "lead2", "lead": L}) or a
        designed kind with its coefficients."""
        if spec.get("kind") == "lead2":
            return lead2(float(spec.get("lead", 0.8)))
        rest = {k: v for k, v in spec.items() if k not in ("kind", "order", "A", "bx", "bv", "c", "d")}
        return cls(
            spec["kind"],
            int(spec["order"]),
            np.array(spec["A"], dtype=float).reshape(len(spec["c"]), -1),
            np.array(spec["bx"], float),
            np.array(spec["bv"], float),
            np.array(spec["c"], float),
            float(spec["d"]),
            rest,
        )


def lead2(lead: float = 0.8) -> Filter:
    """The second-order loop's lead compensator y = lead prev - cur (one state: prev)."""
    return Filter("lead2", 2, np.zeros((1, 1)), np.ones(1), np.zeros(1), np.array([lead]), -1.0, {"lead": lead})


def chain(kind: str, k: int, g: float) -> tuple[np.ndarray, np.ndarray]:
    """(A, M) of k electronic integrators: A the state update, M the mixing of an input injected
    at integrator j into the states' update (column j). CIFB: delaying integrators in cascade,
    u_j' = u_j + u_(j-1) + in_j. CRFB: the last two form a resonator with a non-delaying second
    integrator, u_a' = u_a + u_prev + in_a - g u_b, u_b' = u_b + u_a' + in_b (poles on the unit
    circle at cos w = 1 - g/2)."""
    a, m = np.eye(k), np.eye(k)
    for j in range(1, k):
        a[j, j - 1] = 1.0
    if kind == "crfb" and k >= 2:
        ia, ib = k - 2, k - 1
        a[ia, ib] = -g
        a[ib, :] = a[ib, :] + a[ia, :] - np.eye(k)[ia]  # u_b' = u_b + u_a' (u_a' substituted)
        m[ib, :] += m[ia, :]
    return a, m


def open_loop(mech: Mechanics, f: Filter) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The loop opened at the quantizer, from v[n] to y[n]: state (q, q', u), as (F, G, H) with
    w' = F w + G v, y = H w (strictly causal: the bit moves the mass after the sample)."""
    phi, gamma = mech.period_map()
    k = f.states
    big = np.zeros((2 + k, 2 + k))
    big[:2, :2] = phi
    big[2:, :2] = np.outer(f.bx, mech.output())
    big[2:, 2:] = f.a
    g = np.concatenate([gamma, f.bv])
    h = np.concatenate([f.d * mech.output(), f.c])
    return big, g, h


def loop_impulse(mech: Mechanics, f: Filter, n: int) -> np.ndarray:
    """y[0..n-1] of the open loop for v = impulse at 0 (T(z)'s impulse response)."""
    big, g, h = open_loop(mech, f)
    out, w = np.zeros(n), g.copy()
    for i in range(1, n):
        out[i] = h @ w
        w = big @ w
    return out


def realised_ntf(mech: Mechanics, f: Filter, z: np.ndarray) -> np.ndarray:
    """The linearised NTF of the loop as realised, 1 / (1 - T(z)), T = H (zI - F)^-1 G, at z."""
    big, g, h = open_loop(mech, f)
    eye = np.eye(len(big))
    t = np.array([h @ np.linalg.solve(zz * eye - big, g) for zz in np.atleast_1d(z)])
    return 1.0 / (1.0 - t)


def design(
    mech: Mechanics, order: int, osr: float = 64, h_inf: float = 1.5, topology: str = "cifb", samples: int | None = None
) -> Filter:
    """The electronic integrators' coefficients of an electromechanical loop of `order` (3-5) for
    `mech`: bx (position into the first two integrators), bv = M theta_v (the bit into
    each; with one integrator the position also goes straight to the quantizer, d), fitted by least squares so that the loop's
    impulse response at the first `samples` instants equals -L of the target NTF (zeros: the
    loop's own poles; poles: synthesize_ntf for them with `h_inf`)."""
    if topology not in TOPOLOGIES:
        raise ValueError(f"unknown loop topology {topology!r}; choose one of {', '.join(TOPOLOGIES)}")
    if order not in ORDERS:
        raise ValueError(f"electromechanical loop order must be one of {ORDERS}, not {order}")
    k = order - 2
    zx = ntfs.optimal_zeros(order, fixed_dc=2)
    w = np.pi * float(np.max(np.abs(zx))) / osr if topology == "crfb" and k >= 2 else 0.0
    g = 2.0 - 2.0 * np.cos(w)
    a, m = chain(topology, k, g)
    c = np.eye(k)[k - 1]
    # position into the first integrator and one stage later (the second integrator, or straight to
    # the quantizer when there is one): with the bit into every integrator these span the loop
    # filter's numerator (degree order - 1); the position into one stage only leaves the loop one
    # coefficient short where the mechanics' poles sit at the integrators' (z = 1)
    xin = [m[:, 0].copy()] + ([m[:, 1].copy()] if k >= 2 else [])
    basis = [Filter(topology, order, a, col, np.zeros(k), c, 0.0) for col in xin]
    basis += [Filter(topology, order, a, np.zeros(k), m[:, j].copy(), c, 0.0) for j in range(k)]
    if k == 1:
        basis += [Filter(topology, order, a, np.zeros(k), np.zeros(k), np.zeros(k), 1.0)]
    phi, _ = mech.period_map()
    zeros = ntfs.pair(np.concatenate([np.linalg.eigvals(phi), np.linalg.eigvals(a)]))
    target = ntfs.synthesize_ntf(order, osr, h_inf=h_inf, zeros=zeros)
    n = samples or 4 * order
    num, den = ntfs.loop_filter(target)
    want = -ntfs.impulse(num, den, n)
    cols = np.stack([loop_impulse(mech, b, n) for b in basis], axis=1)
    scale = np.max(np.abs(cols), axis=0)
    theta = np.linalg.lstsq(cols[1:] / scale, want[1:], rcond=None)[0] / scale
    nx = len(xin)
    fit = Filter(
        topology,
        order,
        a,
        np.stack(xin, axis=1) @ theta[:nx],
        m @ theta[nx : nx + k],
        c,
        float(theta[-1]) if k == 1 else 0.0,
        {
            "osr": osr,
            "h_inf": h_inf,
            "resonator_g": g,
            "ntf": {
                "zeros": [[float(q.real), float(q.imag)] for q in target.zeros],
                "poles": [[float(p.real), float(p.imag)] for p in target.poles],
            },
        },
    )
    fit.design["impulse_error"] = float(
        np.max(np.abs(loop_impulse(mech, fit, n)[1:] - want[1:])) / np.max(np.abs(want[1:]))
    )
    return fit


def target_ntf(f: Filter) -> signal.ZerosPolesGain:
    """The NTF a designed filter was fitted to (from its design record)."""
    spec = f.design["ntf"]
    return signal.ZerosPolesGain(
        np.array([complex(*q) for q in spec["zeros"]]), np.array([complex(*p) for p in spec["poles"]]), 1.0, dt=1
    )


def channel_filters(channels: list[dict]) -> list[Filter | None]:
    """The state-space filter of each Design channel whose `filter` is a designed kind (None for
    lead2 or no filter: the compiled loop's lead path)."""
    return [
        Filter.from_dict(ch["filter"]) if ch.get("filter", {}).get("kind", "lead2") != "lead2" else None
        for ch in channels
    ]


def state_nodes(channels: list[dict]) -> list[str]:
    """The compiled loop's filter-state nodes (its u port), u<j>_<channel>, in port order."""
    return [f"u{j}_{ch['name']}" for ch, f in zip(channels, channel_filters(channels)) if f for j in range(f.states)]


def sdloop_params(channels: list[dict], ic: dict[str, float]) -> dict:
    """netgen_sdloop's flt_* and u0 parameters for the channels' filters (the lead-only form,
    flt_n all 0, when none has states); the initial states are popped from `ic` (a segment's
    restart state), else 0."""
    fs = channel_filters(channels)
    if not any(fs):
        zero = [0.0]
        return {
            "flt_n": [0] * len(channels),
            "flt_a": zero,
            "flt_bx": zero,
            "flt_bv": zero,
            "flt_c": zero,
            "flt_d": [0.0] * len(channels),
            "u0": zero,
        }
    cat = lambda get: [float(v) for f in fs if f for v in get(f)]  # noqa: E731
    return {
        "flt_n": [f.states if f else 0 for f in fs],
        "flt_a": cat(lambda f: f.a.ravel()),
        "flt_bx": cat(lambda f: f.bx),
        "flt_bv": cat(lambda f: f.bv),
        "flt_c": cat(lambda f: f.c),
        "flt_d": [float(f.d) if f else 0.0 for f in fs],
        "u0": [ic.pop(n, 0.0) for n in state_nodes(channels)],
        "flt_x0": [f.x0 if f else 0.0 for f in fs],
    }


def mechanics_of(model, d, channel: str) -> Mechanics:
    """A Design channel's mechanics as the loop sees it: the MacroModel's mass, stiffness and
    in-band damping of the coordinate, plus the electrostatic spring of the feedback and sense
    voltages averaged over the period (electrostatic_spring); the fed-back force while on; the
    readout's volts per SI unit and its value at rest, V_s sum_i w_i C_i(0) / C_f; the compiled
    loop's sample instant and the feedback trapezoid of the Design's timing."""
    names = [c.name for c in model.coordinates]
    coord = model.coordinates[names.index(channel)]
    ch = next(c for c in d.channels if c["name"] == channel)
    t = d.t
    rest = model.capacitance(np.zeros(model.ncoords))[0]
    offset = d.vs * sum(e["w"][ch["index"]] * rest[i] for i, e in enumerate(d.electrodes)) / ch["cf"]
    return Mechanics(
        coord.mass,
        coord.stiffness + electrostatic_spring(model, d, names.index(channel)),
        float(coord.admittance(0.0).real),
        d.level(channel) / d.duty,
        ch["sensitivity"] / ch["cf"] / coord.scale,
        d.ts,
        t.cur + t.sample,
        trapezoid_pulse(t.fb_on, t.fb_off, t.fb_ramp),
        float(offset),
    )


def electrostatic_spring(model, d, index: int, h: float = 1e-3) -> float:
    """-dF/dq of the coordinate at the centre (SI, a central difference of the model's
    electrostatic force over +-h of the touching amplitude), averaged over the period: the mean
    over the feedback patterns x the feedback duty plus the sense level's x the sense duty. A
    plate between electrodes gets a negative spring (for the disk's z, -0.27 N/m: a 640 Hz
    instability inside the band that the loop has to hold)."""

    dx = np.zeros(model.ncoords)
    dx[index] = h
    scale = model.coordinates[index].scale

    def spring(volts: np.ndarray) -> float:
        f = model.electrostatic_force(np.stack([dx, -dx]), np.stack([volts, volts]))[:, index]
        return -float(f[0] - f[1]) / (2 * h * scale)

    fb = np.mean([spring(d.vfb * selected(d.electrodes, tuple(r["pattern"]))) for r in d.table])
    sense = spring(np.full(len(d.electrodes), d.vs))
    return float(fb * d.duty + sense * duty(d.t, d.t.sense_on, d.t.sense_off))


def dc_acceleration(model, d, channel: str) -> float:
    """The channel's DC input acceleration in the Design's bench: gravity on z (the -m g on f_z
    of inputs.mechanical_inputs), the sense phase's mean force at the centre, and on z the
    feedback's asymmetry (F_up + F_down) / 2 x the feedback duty (F_up, F_down: the mean z force
    of the patterns with the z bit +1 / -1, d.table; unequal by 0.2 % on the disk, 4e-4 g) — the
    rest, (F_up - F_down) / 2, is Mechanics.force x v."""

    ch = d.channel(channel)  # the balanced channel: the disk's z
    index, j, unit = ch["coord"], ch["index"], ch["force_unit_si"]
    mass = model.coordinates[index].mass
    sense = d.sense_force[index] * duty(d.t, d.t.sense_on, d.t.sense_off) / mass
    if channel != d.balance["channel"]:
        return sense
    up = np.mean([r["f"][channel] for r in d.table if r["pattern"][j] > 0]) * unit
    down = np.mean([r["f"][channel] for r in d.table if r["pattern"][j] < 0]) * unit
    return float(d.balance["dc_force_n"] / mass + sense + 0.5 * (up + down) * d.duty / mass)


def filter_windows(t: Timing) -> dict[str, tuple[float, float]]:
    """The behavioural loop's state-space filter clocks (period phases; ngspice.analog_filters):
    the master window from one edge after the latch window to the middle of the rest of the
    period, the slave window from one edge after it to one edge before the period ends. The
    master computes the next state from the held sample, bit and state; the slave copies it, so
    the state the latch sees changes once per period, after the latch and before the next one
    (the compiled loop's update). blocks.va's sd_statefilter has windows of its own
    (statefilter_params)."""
    on, off = t.clk + t.sample + t.edge, 1.0 - t.edge
    mid = 0.5 * (on + off)
    return {"master": (on, mid - t.edge / 2), "slave": (mid + t.edge / 2, off)}


def statefilter_params(channels: list[dict], d) -> dict[str, str]:
    """Per channel with a designed filter, the instance parameters of blocks.va's sd_statefilter
    (VACASK and OSDI loops): A, bx, bv, c, d of up to 3 states, its clock (master window 0.02 T_s
    after the latch window, slave window at 0.60 T_s, each one sample wide: shorter than the
    behavioural loop's filter_windows) and the sampler switches' C_s and g."""
    out = {}
    for ch, f in zip(channels, channel_filters(channels)):
        if f is None:
            continue
        if f.states > 3:
            raise ValueError(
                f"channel {ch['name']}: blocks.va's sd_statefilter holds 3 states, the filter has {f.states}"
            )
        k, p = f.states, {}
        for i in range(3):
            for j in range(3):
                p[f"a{i + 1}{j + 1}"] = f.a[i, j] if i < k and j < k else 0.0
            for name, vec in (("bx", f.bx), ("bv", f.bv), ("c", f.c)):
                p[f"{name}{i + 1}"] = vec[i] if i < k else 0.0
        t = d.t
        p.update(
            {
                "d": f.d,
                "x0": f.x0,
                "ts": d.ts,
                "w": t.edge / 8,
                "on1": t.clk + t.sample + 0.02,
                "on2": 0.60,
                "width": t.sample,
                "cs": d.cs,
                "g": d.g_switch,
            }
        )
        out[ch["name"]] = " ".join(f"{key}={float(val)!r}" for key, val in p.items())
    return out
