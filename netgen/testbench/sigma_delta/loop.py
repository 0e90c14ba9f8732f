"""The sigma-delta loop's design, derived from the MacroModel and the loop description
(netgen.testbench.sigma_delta.loopfile): the channels (any of the model's coordinates), per
electrode the sense weights and feedback pattern (from the signs of dC_i/dq at rest, or given),
the feedback forces of every bit pattern, voltages, charge-amplifier capacitors, each channel's
loop filter (FILTERS), the clock timing and the dither; and the loop's inputs (DC and tone on
the force ports or a_in). Every back end (netgen.testbench.sigma_delta.ngspice, .vacask, .osdi)
renders the same Design. Why a model cannot close the loop (a channel no electrode senses or
drives, feedback that cannot balance the input) is a LoopError naming the file and key.
"""

from __future__ import annotations

import functools
import itertools
from dataclasses import dataclass, field, fields, replace

import numpy as np
from scipy import integrate, optimize

from ...core.constants import G
from ...core.options import Record, of_role
from ...model import MacroModel
from . import kinds
from .balance import (
    ONE_SIDED_FIX,
    Plant,
    check_balance,
    check_sensing,
    check_step,
    coord_index,
    drive_forces,
    feedback_voltage,
    one_sided,
    si_factor,
    step_volts,
    tone_forces,
    volts,
)
from .loopfile import LoopSpec, check_input_tone
from .options import OPTIONS
from .signals import Timing, Tone, duty, selected

FILTERS, FilterKind = kinds.FILTERS, kinds.FilterKind  # the loop-filter registry (kinds.py), by its old name


# per channel (in order; the disk's z, tilt_x, tilt_y take the first three): the dither sits at
# f_s (1/2 - delta), a different delta per channel so that the dithers are uncorrelated
DITHER_DELTA = (0.0218, 0.0274, 0.0331, 0.0388, 0.0445, 0.0502)
# the comparator's stated model (Design.latch_resolution): above its resolution a held level is
# regenerated to within this of 0 or 1 (to 0.5 (1 - tanh(latch_gain / 2)) = 6e-6 at the default gain)
CLEAN_LATCH = 1e-3


@dataclass
class Design:
    """Everything the testbench needs; all derived from the model and the loop description.
    channels: per channel name, coordinate index `coord`, sensitivity, C_f, dither, `filter`
    (FILTERS), full-scale force; electrodes: per electrode the sense weights `w` and the
    feedback pattern `sel` (one entry per channel); table: the generalized forces of every bit
    pattern; inputs: DC value per input port (port units); balance: the DC force balance of the
    channel whose input needs the largest mean bit."""

    ts: float
    vs: float
    vfb: float
    lead: float | None
    full_scale: float
    electrodes: list[dict]
    channels: list[dict]
    table: list[dict]
    inputs: dict[str, float]
    balance: dict
    duty: float
    sense_force: list[float]
    t: Timing = field(default_factory=Timing)
    cs: float = 1e-12
    reltol: float = 1e-3
    # ngspice's absolute tolerances (None: its defaults, abstol 1e-12 A and vntol 1e-6 V, which are
    # near the loop's own signals: the charge amplifier's node moves by ~1e-5 V per period). The
    # FMU loop's reference runs set 1e-20 and 1e-14 with reltol 1e-6 (docs/fmu.md); the ngspice
    # templates only, not VACASK
    abstol: float | None = None
    vntol: float | None = None
    # the compiled loop (netgen_sdloop's ramp_steps): ngspice crosses every drive edge in this many
    # equal steps (0: its own step control, whose steps inside an edge miss the edge's V^2 impulse by
    # up to 2e-3 of the feedback impulse, changing from period to period; docs/fmu.md)
    ramp_steps: int = 0
    tmax: float = 0.05
    # (the compiled loop, netgen_sdloop, needs no time point inside a window; there tmax is set by
    # the plate modes: at 0.1 T_s the (3,0) modes drift 3 % of their peak from an independent
    # integration in 48 periods, at 0.2 T_s 8 %; 66-68 points per period instead of 77)
    settle: float = 5.0
    # comparator tanh width: a decision with |y| inside it applies a partial feedback force while the
    # bitstream records +-1; at 1e-6 V that happened in ~22 of 65536 periods and set a flat in-band
    # floor near -99 dB/Hz (an exact-sign model of the loop gives -134); 1e-9 V brings it back
    vcmp: float = 1e-9
    # z damping at DC, B(0) (N*s/m, dashpot plus film branches): its impulse enters the force balance
    damping: float = 0.0
    # comparator dither: a sine near f_s/2 added to the lead-filter output, amplitude `dither` x the
    # channel's one-period feedback displacement a_fb T_s^2 (in readout volts), held constant within
    # each period (its value at the period start: a dither that moved during the latch window left
    # 275 of 28672 latches up to 0.45 off 0/1 in a VACASK run, i.e. partial forces). Without it the z
    # loop, whose DC input (gravity) sits at a rational bit density (3/4 ones), locks into idle
    # patterns near f_s/4 and its in-band shaping depends erratically on the operating point
    # (exact-kinematics model, bench/sigma_delta_ideal_loop.py: 32-42 dB/decade over
    # f_s/640..f_s/64 for bit means 0.42-0.54; 39-41 with this dither). Deterministic (same run,
    # same bits) and out of band: sampled once per period it sits at f_s (1/2 - delta).
    dither: float = 0.2

    # latch: settles only latch_settle time constants (to e^-2 = 13 %; the electrode drive's bit()
    # restores 0.87 to a full 1), so its time constant (0.03 T_s) exceeds half of every ngspice
    # step (maxstep 0.05 T_s) and the trapezoidal rule cannot ring on it. At settle = 5 (0.012 T_s)
    # it rang: held levels up to 0.53 off 0/1 in 16 % of the periods, i.e. partial feedback forces
    # while the bitstream recorded +-1 (measured in a 160-period window of a 2300-period run).
    latch_settle: float = 2.0
    # regeneration (blocks.va's sd_quantizer): while the latch clock is low, positive feedback
    # I(b) += g_regen (1 - clk) (V(b) - f(V(b))), f(v) = (1 + tanh(latch_gain (v - 1/2))) / 2, the
    # cross-coupled pair of a real latch: stable at 0 and 1 (within 2 e^-latch_gain), unstable at
    # 1/2 with growth rate (latch_gain / 2 - 1) / tau_r, tau_r = C_s / g_regen = latch_regen T_s,
    # at least half of tmax so that the trapezoidal rule cannot ring on it (at 0.01 T_s held levels
    # overshot the rail by 1.8e-3 in ngspice at the feedback phase's start).
    # Without it the held level kept e^-2 of the previous one (the track above) and ngspice's time
    # steps over the latch window up to 0.31 (bench/sigma_delta_latch.py): partial forces.
    latch_gain: float = 12.0
    latch_regen: float = 0.025

    @property
    def feedback_basis(self) -> dict:
        """The feedback phase (0 -> 1 over [a, b], 1 until c, 1 -> 0 over [c, d]) as
        k1 T1 - k2 T2 of two delay-free PULSE trapezoids, T1 rising over [0, b], T2 over [0, a],
        both falling over [c, d]: on [0, a] the two ramps cancel (k1 / b = k2 / a), on [a, b]
        the sum rises with slope 1 / (b - a), and k1 - k2 = 1 on [b, c]. Why: the template.
        A feedback step (Timing.fb_ramp 0, the compiled loop's fb_level) has k1 = k2 = 0: T1 and
        T2 then only give ngspice breakpoints at the step instants (corners at 0, fb_on, fb_off, 1)."""
        t, ts = self.t, self.ts
        if t.fb_ramp == 0:
            on, off = t.fb_on * ts, (t.fb_off - t.fb_on) * ts
            return {"tr1": on, "pw1": off, "tr2": on, "pw2": off, "tf": (1.0 - t.fb_off) * ts, "k1": 0.0, "k2": 0.0}
        a, b = t.fb_on - t.fb_ramp / 2, t.fb_on + t.fb_ramp / 2
        c, e = t.fb_off - t.fb_ramp / 2, t.fb_off + t.fb_ramp / 2
        return {
            "tr1": b * ts,
            "pw1": (c - b) * ts,
            "tr2": a * ts,
            "pw2": (c - a) * ts,
            "tf": (e - c) * ts,
            "k1": b / (b - a),
            "k2": a / (b - a),
        }

    def corners(self) -> list[float]:
        """Period phases of the electrode-phase corners (the breakpoints the ramps need)."""
        t, h, hf = self.t, self.t.edge / 2, self.t.fb_ramp / 2
        return sorted(
            {
                t.sense_on - h,
                t.sense_on + h,
                t.sense_off - h,
                t.sense_off + h,
                t.fb_on - hf,
                t.fb_on + hf,
                t.fb_off - hf,
                t.fb_off + hf,
            }
        )

    @property
    def g_latch(self) -> float:
        """Latch-switch conductance: C_s settles `latch_settle` time constants within the clock pulse."""
        return self.latch_settle * self.cs / (self.t.sample * self.ts)

    @property
    def g_regen(self) -> float:
        """Latch regeneration conductance: C_s / (latch_regen T_s)."""
        return self.cs / (self.latch_regen * self.ts)

    @property
    def latch_resolution(self) -> float:
        """The comparator's resolution (V): the smallest |y + dither| that the latch holds within
        CLEAN_LATCH of 0 or 1 where per_clock() reads it, whatever it held before (latch_resolution())."""
        t = self.t
        return latch_resolution(
            self.vcmp, self.latch_settle, self.latch_gain, self.latch_regen, t, 0.5 * (t.fb_on + t.fb_off)
        )

    @property
    def g_switch(self) -> float:
        """Sampling-switch conductance: C_s settles `settle` time constants within a sample pulse."""
        return self.settle * self.cs / (self.t.sample * self.ts)

    def g_reset(self, cf: float) -> float:
        """Reset-switch conductance: C_f discharges `settle` time constants within 10 % of T_s."""
        return self.settle * cf / (0.1 * self.ts)

    @property
    def names(self) -> list[str]:
        """The channel names (coordinates) in order."""
        return [c["name"] for c in self.channels]

    @property
    def gravity_un(self) -> float:
        """The DC force on f_z in uN (the disk's gravity), 0 if none."""
        return self.inputs.get("f_z", 0.0)

    @property
    def mass(self) -> float:
        """Mass (or inertia) of the balanced channel's coordinate."""
        return self.balance["mass"]

    def channel(self, name: str) -> dict:
        """The channel entry of a coordinate."""
        return next(c for c in self.channels if c["name"] == name)

    def level(self, channel: str) -> float:
        """Mean |fed-back force or torque| of a channel over a period (SI), for normalisation."""
        ch = self.channel(channel)
        return float(np.mean([abs(r["f"][channel]) for r in self.table])) * ch["force_unit_si"] * self.duty


def channel_names(model: MacroModel, spec: LoopSpec, grad: np.ndarray | None = None) -> list[str]:
    """The loop's channels: as given, else the model's rigid-body coordinates that the electrodes
    can push both ways (dC_i/dq of both signs: the disk's z, tilt_x, tilt_y; the z accelerometer's
    z; the xyz proof mass's x and y), else the rigid ones some electrode senses (design() then says
    why their feedback is one-sided), else the first coordinate (a beam's m1). `grad`: the
    model's scaled_gradient, if the caller has it."""
    names = [c.name for c in model.coordinates]
    if spec.channels is not None:
        for k, ch in enumerate(spec.channels):
            if ch.name not in names:
                where = "loop.channels" + (f".{ch.name}" if ch.sense or ch.feedback or ch.filter else f"[{k}]")
                raise spec.fail(
                    where,
                    f"model {model.name} has no coordinate {ch.name!r}",
                    f"{did_you_mean(ch.name, names)}choose among {', '.join(names)}",
                )
        return [ch.name for ch in spec.channels]
    grad = scaled_gradient(model) if grad is None else grad
    peak = np.abs(grad).max(initial=0.0)
    rigid = [
        k
        for k, c in enumerate(model.coordinates)
        if c.kind != "mode" and np.abs(grad[:, k]).max(initial=0.0) > 1e-9 * peak
    ]
    both = [k for k in rigid if grad[:, k].max() > 1e-6 * np.abs(grad[:, k]).max() < -grad[:, k].min()]
    return [names[k] for k in (both or rigid)][:4] or names[:1]


def did_you_mean(value: str, choices: list[str]) -> str:
    """'did you mean X? ' (netgen.core.files.did_you_mean)."""
    from ...core.files import did_you_mean as near

    return near(value, choices)


def groups(
    model: MacroModel, names: list[str] | None = None, spec: LoopSpec | None = None, grad: np.ndarray | None = None
) -> list[dict]:
    """Per electrode: sense weights `w` and feedback pattern `sel`, one entry per channel. Derived
    from the signs of dC_i/dq at rest (sensing_gradient: round-off counts as 0): the first channel
    reads every electrode with the sign of its dC/dq (the disk's z: top +1, bottom -1); each
    further channel reads the electrodes whose scaled |dC/dq| is largest for it among the further
    channels (the disk's tilts: the sign of
    dC/dtilt of the electrodes that sense that tilt). The feedback pattern is the sign pattern:
    an electrode is energised when every channel's bit equals its weight there. A channel of
    the loop description with explicit `sense` / `feedback` replaces its column. `grad`: the
    model's scaled_gradient, if the caller has it."""
    grad = scaled_gradient(model) if grad is None else grad
    names = names or channel_names(model, spec or LoopSpec(), grad)
    idx = [coord_index(model, n) for n in names]
    grad = sensing_gradient(grad)
    out = []
    for k, e in enumerate(model.electrodes):
        w = [int(np.sign(grad[k, idx[0]]))] + [0] * (len(idx) - 1)
        if len(idx) > 1:
            j = 1 + int(np.argmax([abs(grad[k, i]) for i in idx[1:]]))  # ties: the first (tilt_x)
            w[j] = int(np.sign(grad[k, idx[j]]))
        out.append({"name": e.name, "w": w, "sel": list(w)})
    for j, ch in enumerate((spec.channels or ()) if spec else ()):
        explicit(model, spec, ch, j, out)
    return out


# |dC_i/dq| below this fraction of the largest on coordinate q is round-off (the xyz proof mass's z
# plates in x: 1e-15), not sensing: groups() gives such an electrode weight 0 for q, not a sign
ROUNDOFF = 1e-6


def scaled_gradient(model: MacroModel) -> np.ndarray:
    """dC_i/dq at rest per touch amplitude (electrodes x coordinates): what the loop senses,
    computed once per design() and handed to the steps that read it."""
    return model.capacitance_gradient(np.zeros(model.ncoords))[0] * model.scales[None, :]


def sensing_gradient(grad: np.ndarray) -> np.ndarray:
    """The scaled_gradient `grad` with the entries below ROUNDOFF of their coordinate's largest
    set to 0: the signs groups() derives the weights from."""
    big = np.abs(grad).max(axis=0, initial=0.0)
    return np.where(np.abs(grad) <= ROUNDOFF * big[None, :], 0.0, grad)


def explicit(model: MacroModel, spec: LoopSpec, ch, j: int, out: list[dict]) -> None:
    """Apply a channel's explicit sense weights / feedback pattern (column j) to the electrodes."""
    names = [e.name for e in model.electrodes]
    for key in ("sense", "feedback"):
        given = getattr(ch, key)
        if given is None:
            continue
        for el in given:
            if el not in names:
                raise spec.fail(
                    f"loop.channels.{ch.name}.{key}.{el}",
                    f"model {model.name} has no electrode {el!r}",
                    f"{did_you_mean(el, names)}choose among {', '.join(names)}",
                )
        for e in out:
            e["w" if key == "sense" else "sel"][j] = given.get(e["name"], 0)


def force_table(model: MacroModel, electrodes: list[dict], vfb: float, names: list[str]) -> list[dict]:
    """Generalized forces at rest for each bit pattern: `f` per channel in its f_ port unit (uN,
    nN*m), `all` per coordinate in SI."""
    idx = [coord_index(model, n) for n in names]
    rows = []
    for bits in itertools.product((1, -1), repeat=len(names)):
        f = model.electrostatic_force(np.zeros(model.ncoords), vfb * selected(electrodes, bits))[0]
        rows.append(
            {
                "bits": "".join("+" if b > 0 else "-" for b in bits),
                "pattern": list(bits),
                "f": {n: f[i] * si_factor(model, i)[1] for n, i in zip(names, idx)},
                "all": f.tolist(),
            }
        )
    return rows


def dc_forces(model: MacroModel, spec: LoopSpec, g: float) -> tuple[dict[str, float], np.ndarray]:
    """The DC inputs per port (port units) and the DC generalized force per coordinate (SI).
    Default (no [loop.input]): gravity, a_in = g if the model has the port, else -m g on f_z."""
    si = np.zeros(model.ncoords)
    names = [c.name for c in model.coordinates]
    if spec.input.default:
        if model.acceleration:
            si -= np.array(model.acceleration) * g
            return {"a_in": g}, si
        if "z" not in names:
            return {}, si
        iz = names.index("z")
        si[iz] = -model.coordinates[iz].mass * g
        return {"f_z": -model.coordinates[iz].mass * g * si_factor(model, iz)[1]}, si
    for port, value in spec.input.dc.items():
        if port == "a_in":
            if not model.acceleration:
                raise spec.fail(
                    "loop.input.acceleration",
                    f"model {model.name} has no a_in port",
                    "add acceleration_port = true to the structure's [coordinates], or give "
                    "force = {coordinate, dc} instead",
                )
            si -= np.array(model.acceleration) * value
        else:
            i = coord_index_for(model, spec, port[2:], "loop.input.force.coordinate")
            si[i] += value * si_factor(model, i)[0]
    return dict(spec.input.dc), si


def coord_index_for(model: MacroModel, spec: LoopSpec, name: str, where: str) -> int:
    """coord_index with the loop description's error."""
    names = [c.name for c in model.coordinates]
    if name not in names:
        raise spec.fail(
            where,
            f"model {model.name} has no coordinate {name!r}",
            f"{did_you_mean(name, names)}choose among {', '.join(names)}",
        )
    return names.index(name)


def check_timing(spec: LoopSpec, t: Timing) -> None:
    """The period's events in order, each edge inside the period (else LoopError on [loop.timing])."""
    h, hf = t.edge / 2, t.fb_ramp / 2
    order = [
        ("edge", 0 < t.edge <= 0.1),
        ("fb_edge", 0 <= t.fb_ramp <= 0.1),
        ("sense_on", t.sense_on - h >= 0),
        ("prev", t.sense_on < t.prev),
        ("cur", t.prev + t.sample <= t.cur + 1e-12),
        ("clk", t.cur + t.sample <= t.clk + 1e-12),
        ("sample", 0 < t.sample and t.clk + t.sample <= t.sense_off),
        ("sense_off", t.sense_off + h <= t.fb_on - hf),
        ("rst_on", t.sense_off + h <= t.rst_on <= t.fb_on - hf),
        ("fb_off", t.fb_on + hf < t.fb_off - hf and t.fb_off + hf <= 1.0),
        ("rst_off", t.fb_off + hf - 1.0 <= t.rst_off <= t.sense_on - h),
    ]
    for key, ok in order:
        if not ok:
            raise spec.fail(
                f"loop.timing.{key}",
                f"{key} = {getattr(t, key)} breaks the period's order "
                "(sense on < prev < cur < latch < sense off < reset on < feedback on < feedback off, "
                "edges inside the period)",
                f"keep the order of the defaults ({Timing()})",
            )


def channel_filter(spec: LoopSpec, name: str, lead: float | None) -> dict:
    """A channel's loop filter: its own [loop.channels.<q>.filter], else [loop.filter], else lead2;
    lead2's coefficient from the table, else `lead` (--lead), else 0.8."""
    own = next((c.filter for c in spec.channels or () if c.name == name and c.filter), None)
    f = dict(own or spec.filter or {"kind": "lead2", "lead": None})
    if f["kind"] == "lead2":
        f["lead"] = lead if lead is not None else (f["lead"] if f["lead"] is not None else 0.8)
    return f


@functools.lru_cache(maxsize=64)
def latch_resolution(
    vcmp: float, settle: float, gain: float, regen: float, t: Timing, read: float, clean: float = CLEAN_LATCH
) -> float:
    """Smallest |y| (V) that sd_quantizer holds within `clean` of its rail at the period phase
    `read`, starting from the other rail (the worst previous decision): bisection on y of the
    latch's own equation in the period phase p, db/dp = -settle / sample clk(p) (b - q(y))
    - (1 - clk(p)) (b - f(b)) / regen (clk: sd_clocks' tanh window, q: the comparator's tanh of
    y / vcmp, f: the regeneration's tanh of `gain`), integrated to 1e-8. It is the hysteresis of
    the incomplete track (about e^-settle vcmp) plus what regeneration needs; inf when even a
    saturated input does not make it."""
    w = t.edge / 8

    def held(x: float) -> float:
        q = 0.5 + 0.5 * np.tanh(x)

        def rate(p: float, b: np.ndarray) -> np.ndarray:
            clk = 0.5 * (np.tanh((p - t.clk) / w) - np.tanh((p - t.clk - t.sample) / w))
            f = 0.5 + 0.5 * np.tanh(gain * (b - 0.5))
            return -settle / t.sample * clk * (b - q) - (1.0 - clk) * (b - f) / regen

        sol = integrate.solve_ivp(
            rate, (t.clk - 10 * w, read), [0.0], method="LSODA", rtol=1e-8, atol=1e-10, max_step=w
        )
        return float(sol.y[0, -1])

    if held(30.0) < 1.0 - clean:
        return float("inf")
    return float(vcmp * optimize.brentq(lambda x: held(x) - (1.0 - clean), 0.0, 30.0, xtol=1e-6))


class Choices(Record):
    """The design choices a caller (the command line, a sweep) gives over the loop description's
    (None: the description's, else the declared default): one attribute per option of role "design"
    (netgen.testbench.sigma_delta.options); `timing`, a caller's Timing, replaces [loop.timing] whole."""

    declared = of_role(OPTIONS.values(), "design")
    extra = ("timing",)


def design(
    model: MacroModel,
    ts: float,
    choices: Choices | None = None,
    *,
    spec: LoopSpec | None = None,
    tone: Tone | None = None,
    g: float = G,
    balance_check: bool = True,
    step: bool = True,
) -> Design:
    """Loop design from the model and the loop description `spec`: V_fb so that the DC input needs
    a mean bit of `density` on the channel it loads most (the disk: gravity on z), V_s =
    sense_ratio * V_fb, C_f so that `full_scale` of the touch amplitude reads 1 V; `reltol` is
    the simulators' relative tolerance (the in-band floors depend on it: bench/compare_simulators.py).
    The `choices` given win over the description's; `tone` enters the balance check
    (balance_check False: an under-designed loop is built anyway, to test how a lost plate is reported);
    `step`: the back end renders a feedback step (runner.STEP_BACKENDS), which a designed filter then
    gets unless [loop.timing] gives fb_edge (Timing.fb_edge)."""
    spec, choices = spec or LoopSpec(), choices or Choices()
    if tone is None or tone is spec.input.tone:  # a caller's tone replaces the description's
        check_input_tone(spec, ts)
    chosen = choices.over(spec.settings.or_defaults())  # the caller's, else the file's, else the default
    grad = scaled_gradient(model)
    names = channel_names(model, spec, grad)
    t = loop_timing(spec, choices, names, step)
    p = attach(model, spec, names, grad, g)
    vfb, jb = feedback_level(p, tone, chosen.density * duty(t))
    vs = volts(chosen.sense_ratio * vfb)
    sense = model.electrostatic_force(np.zeros(model.ncoords), np.full(len(p.electrodes), vs))[0]
    needed = check_balance(p, sense, tone, vfb, t, balance_check)
    table = force_table(model, p.electrodes, vfb, names)
    check_step(model, spec, table, names, ts)
    balance = balance_of(p, jb)
    d = Design(
        ts, vs, vfb, None, chosen.full_scale, p.electrodes, [], table, p.inputs, balance, duty(t), sense.tolist(), t
    )
    d.damping, d.dither, d.reltol = balance["damping"], chosen.dither, chosen.reltol
    d.ramp_steps = int(chosen.ramp_steps)
    d.channels = [channel_entry(p, d, k, chosen.lead, needed[k]) for k in range(len(names))]
    d.lead = d.channels[0]["filter"].get("lead")
    dither_given = (
        choices.dither is not None or spec.settings.dither is not None
    )  # a designed kind runs without, unless given
    for ch in (c for c in d.channels if FILTERS[c["filter"]["kind"]].design):  # designed kinds (kinds.py)
        ch["filter"] = FILTERS[ch["filter"]["kind"]].design(model, d, ch, ch["filter"])
        ch["dither_v"] = ch["dither_v"] if dither_given else 0.0  # no idle tones to break
    return d


def loop_timing(spec: LoopSpec, choices: Choices, names: list[str], step: bool) -> Timing:
    """The caller's timing, else [loop.timing]'s; a designed (higher-order) filter gets the feedback
    step where the back end renders one (`step`) unless [loop.timing] gives fb_edge (Timing.fb_edge)."""
    given = {f.name for f in fields(Timing)}
    t = choices.timing or Timing(**{k: v for k, v in spec.timing.items() if k in given})
    if (
        step
        and choices.timing is None
        and "fb_edge" not in spec.timing
        and any(FILTERS[channel_filter(spec, n, choices.lead)["kind"]].design for n in names)
    ):
        t = replace(t, fb_edge=0.0)
    check_timing(spec, t)
    return t


def attach(model: MacroModel, spec: LoopSpec, names: list[str], grad: np.ndarray, g: float) -> Plant:
    """The Plant: the channels' electrodes (checked to sense them), their feedback forces at 1 V
    and the DC inputs (gravity `g` by default)."""
    idx = [coord_index(model, n) for n in names]
    electrodes = groups(model, names, spec, grad)
    check_sensing(model, spec, electrodes, names, grad)
    unit = force_table(model, electrodes, 1.0, names)
    drive = drive_forces(model, spec, unit, names)
    inputs, dc_si = dc_forces(model, spec, g)
    per_v2 = [float(np.mean([abs(r["f"][n]) for r in unit])) * si_factor(model, i)[0] for n, i in zip(names, idx)]
    return Plant(model, spec, names, idx, grad, electrodes, drive, per_v2, inputs, dc_si)


def feedback_level(p: Plant, tone: Tone | None, bit_duty: float) -> tuple[float, int]:
    """(V_fb, the channel it is sized on): the given feedback voltage, else the one at which the
    channel the input loads most needs a mean force of `bit_duty` (density x duty) of its per-V^2 one."""
    model, spec, idx = p.model, p.spec, p.idx
    load = [abs(p.dc_si[i]) / v2 for i, v2 in zip(idx, p.per_v2)]
    jb = int(np.argmax(load))
    if not spec.settings.feedback_voltage and not (abs(p.dc_si[idx[jb]]) or tone_forces(model, tone)[idx[jb]]):
        for n, (fp, fm) in zip(p.names, p.drive):  # no input: a one-sided loop has nothing to balance against
            if fp <= 0 or fm >= 0:
                raise spec.fail(
                    "loop.channels",
                    f"channel {n}: {one_sided(fp, fm)} and the loop has no input to balance it against",
                    ONE_SIDED_FIX,
                )
    vfb = spec.settings.feedback_voltage or feedback_voltage(
        spec, abs(p.dc_si[idx[jb]]) or tone_forces(model, tone)[idx[jb]], bit_duty * p.per_v2[jb]
    )
    return vfb, jb


def balance_of(p: Plant, jb: int) -> dict:
    """Design.balance: the DC force balance of channel `jb`."""
    c = p.model.coordinates[p.idx[jb]]
    return {
        "channel": p.names[jb],
        "index": jb,
        "coord": p.idx[jb],
        "mass": c.mass,
        "dc_force_n": float(p.dc_si[p.idx[jb]]),
        "damping": float(c.admittance(0.0).real),
        "stiffness": float(c.stiffness),
        "x_unit_si": c.port_units[1],
    }


def channel_entry(p: Plant, d: Design, k: int, lead: float | None, needed: float) -> dict:
    """Design.channels[k]: readout sensitivity, C_f, dither, loop filter (lead: the caller's) and
    full-scale force of the k-th channel, `needed`: its mean bit (check_balance)."""
    model, name, i = p.model, p.names[k], p.idx[k]
    sens = d.vs * float(sum(e["w"][k] * p.grad[j, i] for j, e in enumerate(p.electrodes)))
    return {
        "name": name,
        "index": k,
        "coord": i,
        "sensitivity": sens,
        "cf": float(f"{sens * d.full_scale:.4g}"),
        "dither_v": float(f"{d.dither * step_volts(model, d.table, name, d.ts, d.full_scale):.4g}"),
        "dither_step": 2 * np.pi * (0.5 - DITHER_DELTA[k]),
        "filter": channel_filter(p.spec, name, lead),
        "force_unit_si": si_factor(model, i)[0],
        "bit_mean_needed": needed,
        "full_scale_force_si": 0.5 * (p.drive[k][0] - p.drive[k][1]) * d.vfb**2 * d.duty,
        "bit_node": {"z": "bz", "tilt_x": "bx", "tilt_y": "by"}.get(name, f"bit_{name}"),
    }
