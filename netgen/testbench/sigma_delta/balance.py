"""The feedback's balance and size in the sigma-delta loop's design
(netgen.testbench.sigma_delta.loop.design): coordinate lookup and port units, the force each
channel's bit pushes with, the feedback voltage an input needs, the mean bit it needs and the
one-period step; each refusal a LoopError naming the loop description's key."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...model import MacroModel
from .loopfile import LoopSpec
from .signals import Timing, Tone, duty


def coord_index(model: MacroModel, name: str) -> int:
    """Index of a coordinate, or a clear error."""
    names = [c.name for c in model.coordinates]
    if name not in names:
        raise ValueError(f"model {model.name} has no coordinate {name!r} (has {names})")
    return names.index(name)


def si_factor(model: MacroModel, index: int) -> tuple[float, float]:
    """(SI per f_ port unit, port units per SI) of a coordinate's force port: (1e-6, 1e6) for uN.
    The second is rounded to an integer where it is one (1/1e-9 is not 1e9 in floating point)."""
    f = model.coordinates[index].port_units[3]
    inv = 1.0 / f
    return f, float(round(inv)) if abs(inv - round(inv)) < 1e-6 * inv else inv


def tone_forces(model: MacroModel, tone: Tone | None) -> np.ndarray:
    """Amplitude of the tone's generalized force per coordinate (SI)."""
    out = np.zeros(model.ncoords)
    if tone is None:
        return out
    if tone.coord == "a_in":
        return np.abs(np.array(model.acceleration or [0.0] * model.ncoords)) * abs(tone.amplitude)
    if tone.coord in model.inertial.participation:  # a_x, a_y (netgen.model.inertial)
        return np.abs(np.array(model.inertial.participation[tone.coord])) * abs(tone.amplitude)
    i = coord_index(model, tone.coord)
    out[i] = abs(tone.amplitude) * si_factor(model, i)[0]
    return out


MAX_VFB = 1e4  # V: the derived feedback voltage's limit (a [loop] feedback_voltage's range)
MAX_BIT_MEAN = 0.95  # |mean bit| an input may need (DC + tone peak): beyond it the loop overloads
ONE_SIDED_FIX = (
    "add an electrode on the other side (force feedback pulls both ways: "
    "examples/accelerometer_z.toml), or give an input the feedback can balance"
)


def one_sided(fp: float, fm: float) -> str:
    """Why a channel's feedback is one-sided, in words."""
    return (
        f"its feedback is one-sided (the electrodes only push towards {'-' if fp <= 0 else '+'}q: "
        f"{fp:.3g} N with the bit 1, {fm:.3g} N with 0)"
    )


def drive_forces(model: MacroModel, spec: LoopSpec, table: list[dict], names: list[str]) -> list[tuple[float, float]]:
    """(f+, f-) per channel, SI: its mean feedback force over the patterns with its bit +1 / -1;
    a channel whose bit does not push towards +q (f+ <= f-) is a LoopError."""
    out = []
    for j, n in enumerate(names):
        unit = si_factor(model, coord_index(model, n))[0]
        fp = float(np.mean([r["f"][n] for r in table if r["pattern"][j] > 0])) * unit
        fm = float(np.mean([r["f"][n] for r in table if r["pattern"][j] < 0])) * unit
        if not fp - fm > 1e-9 * max(abs(fp), abs(fm), 1e-300):
            where = f"loop.channels.{n}.feedback" if feedback_given(spec, n) else "loop.channels"
            why = (
                "no electrode drives it"
                if max(abs(fp), abs(fm)) == 0
                else "its feedback pushes towards -q when its bit is 1"
                if fp < fm
                else "its bit does not change its force"
            )
            raise spec.fail(
                where,
                f"channel {n}: {why} (feedback force {fp:.3g} N with the bit 1, {fm:.3g} N with 0, at 1 V)",
                "close the loop on a coordinate the electrodes can push both ways, or "
                f"give [loop.channels.{n}] feedback = {{electrode = +1 or -1}} that does",
            )
        out.append((fp, fm))
    return out


def feedback_given(spec: LoopSpec, name: str) -> bool:
    """Did the loop description give this channel's feedback pattern?"""
    return any(c.name == name and c.feedback for c in spec.channels or ())


def check_sensing(
    model: MacroModel, spec: LoopSpec, electrodes: list[dict], names: list[str], grad: np.ndarray
) -> None:
    """A channel whose readout sum_i w_i dC_i/dq (grad: the scaled_gradient) is not positive is a LoopError."""
    for j, n in enumerate(names):
        s = float(sum(e["w"][j] * grad[i, coord_index(model, n)] for i, e in enumerate(electrodes)))
        peak = float(np.abs(grad).max(initial=0.0))
        if not s > 1e-9 * peak:
            given = any(c.name == n and c.sense for c in spec.channels or ())
            why = "no electrode senses it" if abs(s) <= 1e-9 * peak else "its sense weights read -q"
            raise spec.fail(
                f"loop.channels.{n}.sense" if given else "loop.channels",
                f"channel {n}: {why} (sum_i w_i dC_i/dq = {s:.3g} F per touch amplitude)",
                "close the loop on a coordinate the electrodes sense, or give sense weights with the sign of dC/dq",
            )


MAX_STEP = 0.01  # one period's feedback displacement a_fb T_s^2 / touch amplitude (the disk: 1.5e-5)


def check_step(model: MacroModel, spec: LoopSpec, table: list[dict], names: list[str], ts: float) -> None:
    """One period of feedback must move each channel's coordinate by less than MAX_STEP of its
    touching amplitude (the loop holds it within 2 %: analysis.levitation); else a LoopError."""
    for n in names:
        step = step_volts(model, table, n, ts, 1.0)
        if step > MAX_STEP:
            raise spec.fail(
                "loop.feedback_voltage" if spec.settings.feedback_voltage else "loop.input",
                f"channel {n}: one period of feedback moves it {step:.3g} of its touching amplitude "
                f"(at most {MAX_STEP}: the loop could not hold it near rest)",
                "lower the input or the feedback voltage, or shorten --ts",
            )


def volts(v: float) -> float:
    """A voltage rounded for the netlist: to 1 mV (the disk's 2.12 V), 4 digits below 1 V."""
    return round(v, 3) if v >= 1.0 else float(f"{v:.4g}")


def feedback_voltage(spec: LoopSpec, force: float, per_v2: float) -> float:
    """V_fb from the input the feedback must carry at the design's mean bit (force: SI)."""
    if not force > 0:
        raise spec.fail(
            "loop.feedback_voltage",
            "the loop has no input to size the feedback from (no DC input or tone on its channels)",
            'give feedback_voltage = "5 V" in [loop], or an input',
        )
    v = volts(float(np.sqrt(force / per_v2)))
    if v > MAX_VFB:
        raise spec.fail(
            "loop.input",
            f"the input needs a feedback voltage of {v:.4g} V (more than {MAX_VFB:g} V)",
            "lower the input, or give a device with more electrode area or smaller gaps",
        )
    return v


@dataclass(frozen=True)
class Plant:
    """What the loop closes around, as loop.design derives it before sizing the feedback: the model
    and its loop description, the channels (`names`, coordinate indices `idx`), the scaled_gradient
    `grad`, per electrode the weights (`electrodes`), per channel the (f+, f-) feedback force at 1 V
    (`drive`, SI) and mean |force| per V^2 (`per_v2`, SI), the DC inputs (`inputs`, port units;
    `dc_si`, SI per coordinate)."""

    model: MacroModel
    spec: LoopSpec
    names: list[str]
    idx: list[int]
    grad: np.ndarray
    electrodes: list[dict]
    drive: list[tuple[float, float]]
    per_v2: list[float]
    inputs: dict[str, float]
    dc_si: np.ndarray


def check_balance(
    p: Plant, sense: np.ndarray, tone: Tone | None, vfb: float, t: Timing, refuse: bool = True
) -> list[float]:
    """The mean bit each channel needs for its DC input (with the sense phase's force), and a
    LoopError when DC + tone peak need more than MAX_BIT_MEAN of the feedback's range."""
    model, spec, drive, dc_si = p.model, p.spec, p.drive, p.dc_si
    sduty, fduty, amp = duty(t, t.sense_on, t.sense_off), duty(t), tone_forces(model, tone)
    out = []
    for j, n in enumerate(p.names):
        i = coord_index(model, n)
        fp, fm = drive[j][0] * vfb**2, drive[j][1] * vfb**2
        need = -(dc_si[i] + sense[i] * sduty) / fduty
        bit = 2 * (need - fm) / (fp - fm) - 1
        swing = 2 * amp[i] / fduty / (fp - fm)
        if refuse and abs(bit) + swing > MAX_BIT_MEAN:
            v = vfb * np.sqrt((abs(bit) + swing) / (0.9 * MAX_BIT_MEAN))  # the forces go as V^2
            where = "loop.feedback_voltage" if spec.settings.feedback_voltage else "loop.input"
            if (fp <= 0 and need > 0) or (fm >= 0 and need < 0):
                raise spec.fail(
                    where,
                    f"channel {n}: the feedback cannot balance the input at any voltage: "
                    f"{one_sided(fp, fm)}, and the input needs a force towards "
                    f"{'+' if need > 0 else '-'}q ({need * fduty:.4g} N)",
                    ONE_SIDED_FIX,
                )
            raise spec.fail(
                where,
                f"channel {n}: the feedback cannot balance the input: it needs a mean bit of "
                f"{bit:+.3f}" + (f" +- {swing:.3f} (tone)" if swing else "") + f" at V_fb = {vfb:g} V "
                f"(at most +-{MAX_BIT_MEAN}; full-scale force {0.5 * (fp - fm) * fduty:.4g} N, DC input "
                f"{-dc_si[i]:.4g} N)",
                f"raise feedback_voltage to about {v:.3g} V or more, or lower the input",
            )
        out.append(float(bit))
    return out


def step_volts(model: MacroModel, table: list[dict], channel: str, ts: float, full_scale: float) -> float:
    """The channel's one-period feedback displacement a_fb T_s^2 (a_fb: mean |fed-back force or
    torque| while on, over the mass or inertia) in readout volts (1 V = full_scale x touch)."""
    i = coord_index(model, channel)
    c = model.coordinates[i]
    force = float(np.mean([abs(r["f"][channel]) for r in table])) * si_factor(model, i)[0]
    return force / c.mass * ts**2 / (c.scale * full_scale)
