"""The sigma-delta loop with the mechanics in the model's FMU (netgen.emit.fmu) and the
discrete-time part in numpy: the same Design, instants, drives and decisions as the compiled
ngspice loop (netgen_sdloop, rendered by netgen.testbench.sigma_delta.ngspice.loop_card), the
analog between clock edges stepped by the FMU's co-simulation.

Per period n (fractions of T_s): the electrode drives are piecewise linear between the corners of
the three phase PULSEs (sense phs, feedback basis fb1, fb2; loop_card's ph_pulse, evaluated as
ngspice evaluates PULSE), plus the feedback step fb_level on (fb_on, fb_off] when the design has
one; each piece is one doStep with the drives' slopes as input derivatives, so the FMU integrates
the same drive ngspice does. At t_sample the charge amplifier reads cur = sum_e w_e Q_e / C_f (the
FMU's electrode charges: the ideal integrator of the ngspice testbench, reset while every
electrode is at 0 V, so its output is the charge itself), prev is the cur before; at t_latch
b = [lead prev - cur + dither_amp sin(dither_step n) > 0] (lead2 channels; the state-space filters
of netgen.testbench.sigma_delta.filters are not mirrored here: refused). The drive of electrode e
is sense V_s phs + s_e(b) (feedback), s_e(b) the product over channels of b or 1 - b as sel asks.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from ...core.errors import LoopError
from ...model import MacroModel
from ...sim import fmu
from .loop import Design
from .ngspice import loop_card


def pulse(p: tuple[float, ...], t: float) -> float:
    """ngspice's PULSE(v1 v2 td tr tf pw per) at time t (netgen_sdloop's sd_pulse)."""
    v1, v2, td, tr, tf, pw, per = p
    t -= td
    if per > 0.0 and t > per:
        t -= per * math.floor(t / per)
    if t <= 0.0 or t >= tr + pw + tf:
        return v1
    if tr <= t <= tr + pw:
        return v2
    if 0.0 < t < tr:
        return v1 + (v2 - v1) * t / tr
    return v2 + (v1 - v2) * (t - tr - pw) / tf


@dataclass
class Loop:
    """The loop's numbers from the Design (loop_card's parameters), per channel and electrode."""

    ts: float
    t_sample: float
    t_latch: float
    leads: list[float]
    sel: np.ndarray  # (electrodes, channels): +1 on when the bit is 1, -1 when 0, 0 not fed back
    ph_sense: list[float]
    ph_fb: list[float]
    pulses: list[tuple[float, ...]]
    fb_level: float
    fb_on: float
    fb_off: float
    dither_amp: np.ndarray
    dither_step: np.ndarray
    weights: np.ndarray  # (channels, electrodes): the charge amplifiers' sense weights over C_f
    electrodes: list[str]
    channels: list[str]
    t_record: float  # where the coordinates are recorded: mid feedback phase (analysis.per_clock)

    @classmethod
    def of(cls, d: Design) -> Loop:
        """The compiled loop's parameters of this design (loop_card at period 0, from rest)."""
        bad = [c["name"] for c in d.channels if c["filter"].get("kind") != "lead2"]
        if bad:
            raise LoopError(
                "(loop)",
                "loop.filter",
                f"channel {bad[0]} has a designed state-space filter; the FMU loop mirrors lead2 only",
                'use kind = "lead2", or run the designed filter with --simulator ngspice-xspice',
            )
        p = loop_card(d, 0, {})["params"]
        nc = len(d.channels)
        w = np.array([[e["w"][k] for e in d.electrodes] for k in range(nc)], dtype=float)
        return cls(
            ts=p["ts"],
            t_sample=p["t_sample"],
            t_latch=p["t_latch"],
            leads=list(p.get("leads") or [p["lead"]] * nc),
            sel=np.array(p["sel"], dtype=int).reshape(len(d.electrodes), nc),
            ph_sense=p["ph_sense"],
            ph_fb=p["ph_fb"],
            pulses=[tuple(p["ph_pulse"][7 * j : 7 * j + 7]) for j in range(len(p["ph_pulse"]) // 7)],
            fb_level=p.get("fb_level", 0.0),
            fb_on=p.get("fb_on", 0.0),
            fb_off=p.get("fb_off", 0.0),
            dither_amp=np.array(p["dither_amp"]),
            dither_step=np.array(p["dither_step"]),
            weights=w / np.array([c["cf"] for c in d.channels])[:, None],
            electrodes=[e["name"] for e in d.electrodes],
            channels=[c["name"] for c in d.channels],
            t_record=0.5 * (d.t.fb_on + d.t.fb_off),
        )

    def corners(self) -> list[float]:
        """The period's instants (fractions of T_s) where a drive bends or the loop acts, 0 and 1 included."""
        out = {0.0, 1.0, self.t_sample, self.t_latch, self.t_record}
        for _v1, _v2, td, tr, tf, pw, per in self.pulses:
            for t in (td, td + tr, td + tr + pw, td + tr + pw + tf):
                out.add((t % per) / self.ts if per else t / self.ts)
        if self.fb_level:
            out |= {self.fb_on, self.fb_off}
        return sorted(f for f in out if 0.0 <= f <= 1.0)

    def phases(self, t: float) -> tuple[float, float]:
        """The sense and the feedback drive levels at time t (s), the feedback step included."""
        ph = [pulse(p, t) for p in self.pulses]
        sense = sum(a * v for a, v in zip(self.ph_sense, ph))
        fb = sum(a * v for a, v in zip(self.ph_fb, ph))
        frac = t / self.ts - math.floor(t / self.ts)
        if self.fb_level and self.fb_on < frac <= self.fb_off:
            fb += self.fb_level
        return sense, fb

    def selection(self, bits: np.ndarray) -> np.ndarray:
        """Per electrode s_e(b): the product over channels of b (sel +1) or 1 - b (sel -1); 0 unfed."""
        g = np.where(self.sel > 0, bits[None, :], np.where(self.sel < 0, 1.0 - bits[None, :], 1.0)).prod(axis=1)
        return np.where(np.any(self.sel != 0, axis=1), g, 0.0)


def segments(lp: Loop) -> list[tuple[float, float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """The period's pieces (a, b fractions of T_s) with the sense and feedback drives at both ends
    of each (the drives are linear inside; the feedback step's level of the piece added to both):
    the same in every period, the PULSEs being periodic."""
    out = []
    for a, b in itertools.pairwise(lp.corners()):
        ta, tb = a * lp.ts, b * lp.ts
        step = lp.phases(0.5 * (ta + tb))[1] - linear_fb(lp, ta, tb, 0.5)
        sense_a, sense_b = lp.phases(ta)[0], lp.phases(tb)[0]
        fb_a, fb_b = linear_fb(lp, ta, tb, 0.0) + step, linear_fb(lp, ta, tb, 1.0) + step
        out.append((a, b, np.array(sense_a), np.array(sense_b), np.array(fb_a), np.array(fb_b)))
    return out


def run(model: MacroModel, d: Design, cycles: int, tolerance: float = 1e-9) -> dict[str, np.ndarray]:
    """The loop for `cycles` periods from rest with the design's DC inputs (d.inputs: a_in, f_<q>);
    returns the per-period arrays the ngspice back ends give (netgen.testbench.sigma_delta.analysis:
    bits_<ch> +-1, latch_<ch> 0/1, x_<q> in port units mid feedback phase, time) and cur_<ch>."""
    lp = Loop.of(d)
    inst = fmu.Instance(fmu.built(model), tolerance=tolerance)
    inst.set({k: v * scale(model, k) for k, v in d.inputs.items()})
    inst.start()
    ne, nc = len(lp.electrodes), len(lp.channels)
    step = inst.stepper(
        [f"V_{e}" for e in lp.electrodes],
        [f"Q_{e}" for e in lp.electrodes] + [f"x_{c.name}" for c in model.coordinates],
    )
    # per bit pattern and piece: the drives at the start and their slopes (sel(b) chooses the feedback)
    patterns = list(itertools.product((0.0, 1.0), repeat=nc))
    table = {}
    for bits in patterns:
        sel = lp.selection(np.array(bits))
        table[bits] = [
            (b, list(sa + sel * fa), list((sb + sel * fb - sa - sel * fa) / ((b - a) * lp.ts)), (b - a) * lp.ts)
            for a, b, sa, sb, fa, fb in segments(lp)
        ]
    bits, cur, prev = (0.0,) * nc, np.zeros(nc), np.zeros(nc)
    out_bits = np.zeros((cycles, nc), dtype=np.int8)
    out_cur = np.zeros((cycles, nc))
    out_x = np.zeros((cycles, model.ncoords))
    per_unit = np.array([c.port_units[1] for c in model.coordinates])
    leads = np.array(lp.leads)
    pieces = range(len(table[bits]))
    for n in range(cycles):
        for k in pieces:  # the pattern changes at the latch, inside the period
            b, v, dv, h = table[bits][k]
            got = step(v, dv, h)
            if b == lp.t_sample:
                prev, cur = cur, lp.weights @ got[:ne]
            elif b == lp.t_latch:
                y = leads * prev - cur + lp.dither_amp * np.sin(lp.dither_step * n)
                bits = tuple(float(x) for x in y > 0.0)
            elif b == lp.t_record:
                out_x[n] = got[ne:] / per_unit
        out_bits[n] = [1 if x else -1 for x in bits]
        out_cur[n] = cur
    inst.close()
    t = (np.arange(cycles) + lp.t_record) * lp.ts
    res: dict[str, np.ndarray] = {f"bits_{c}": out_bits[:, k] for k, c in enumerate(lp.channels)}
    res |= {f"latch_{c}": (out_bits[:, k] > 0).astype(float) for k, c in enumerate(lp.channels)}
    res |= {f"cur_{c}": out_cur[:, k] for k, c in enumerate(lp.channels)}
    res |= {f"x_{c.name}": out_x[:, v] for v, c in enumerate(model.coordinates)}
    return res | {"time": t}


def linear_fb(lp: Loop, ta: float, tb: float, where: float) -> float:
    """The PULSE part of the feedback drive on [ta, tb] (linear there) at the fraction `where`
    (0: ta, 1: tb, between: interpolated), without the step."""
    pa = sum(a * pulse(p, ta) for a, p in zip(lp.ph_fb, lp.pulses))
    pb = sum(a * pulse(p, tb) for a, p in zip(lp.ph_fb, lp.pulses))
    return pa + where * (pb - pa)


def scale(model: MacroModel, port: str) -> float:
    """SI per unit of a loop input port's value: 1 for a_in (m/s^2), the force unit for f_<q>."""
    c = next((c for c in model.coordinates if f"f_{c.name}" == port), None)
    return c.port_units[3] if c else 1.0
