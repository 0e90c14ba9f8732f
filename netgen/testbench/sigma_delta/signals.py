"""The loop's clock timing (Timing, fractions of T_s) and its sinusoidal input (Tone), with the
feedback phase's duty (duty) and the feedback selection per bit pattern (selected): plain
values that the loop description (netgen.testbench.sigma_delta.loopfile) reads and the Design
(netgen.testbench.sigma_delta.loop) carries to every back end."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...core.options import number


@dataclass(frozen=True)
class Timing:
    """Event times within one period, as fractions of T_s (see the template header).

    Chosen for few ngspice time points (bench/sigma_delta.py counts them): the three electrode ramps (sense
    on, sense off, feedback on/off) are PULSE edges whose 8 corners are breakpoints at least
    2 % of T_s apart (each corner costs ngspice ~8 time points: it restarts the step at 1/10 of
    the previous one); the reset switches inside the gaps where every electrode is static and the
    charge amplifier is near 0 (sense off -> feedback on, feedback off -> next sense on), so it
    is a smooth window without breakpoints. The samplers and the latch sit in the sense phase."""

    edge: float = 0.02
    sense_on: float = 0.01
    prev: float = 0.20
    cur: float = 0.28
    sample: float = 0.06
    clk: float = 0.36
    sense_off: float = 0.46
    fb_on: float = 0.50
    fb_off: float = 0.94
    rst_on: float = 0.48
    rst_off: float = -0.04
    # the feedback phase's own edge width (None: `edge`); 0 is a voltage step at fb_on and fb_off,
    # which only the compiled loop (netgen_sdloop) renders: there the proof mass gets the same
    # impulse in every period, while a ramp's V^2 force is integrated with an error that depends on
    # ngspice's time steps inside the ramp (a flat in-band floor near -138 dB/Hz on the z
    # accelerometer; docs/sigma-delta.md, "The feedback step"). The designed loop filters default to 0.
    fb_edge: float | None = None

    @property
    def fb_ramp(self) -> float:
        """The width of the feedback phase's voltage edges (fraction of T_s; 0: a step)."""
        return self.edge if self.fb_edge is None else self.fb_edge


@dataclass
class Tone:
    """A sinusoidal input: a generalized force on coordinate `coord` (amplitude in its f_ port
    unit), or with coord "a_in" (or "a_x", "a_y") the frame acceleration (m/s^2) through that port."""

    coord: str
    amplitude: float
    freq: float
    unit: str = ""

    @classmethod
    def parse(cls, text: str) -> Tone:
        """Parse COORD:AMPLITUDE:FREQ, e.g. z:0.02:1e3 (uN on z at 1 kHz) or a_in:2:1e3 (m/s^2)."""
        parts = text.split(":")
        if len(parts) != 3:
            raise ValueError(f"tone {text!r} is not COORD:AMPLITUDE:FREQ (e.g. z:0.02:1000 or a_in:2:1000)")
        amplitude, freq = number(parts[1]), number(parts[2])  # strictly: no underscores, inf or nan
        if amplitude is None or freq is None:
            raise ValueError(f"tone {text!r}: amplitude and frequency must be numbers")
        return cls(parts[0], amplitude, freq)


def duty(t: Timing, a: float | None = None, b: float | None = None) -> float:
    """Mean of the squared PULSE phase (linear edges of t.edge centred on a and b) over a period
    (the feedback phase by default, with its edges t.fb_ramp)."""
    edge = t.fb_ramp if a is None else t.edge
    a, b = (t.fb_on if a is None else a), (t.fb_off if b is None else b)
    return (b - a - edge) + 2 * edge / 3


def selected(electrodes: list[dict], bits: tuple[int, ...]) -> np.ndarray:
    """0/1 per electrode: energised for the bit pattern (one +-1 per channel): every channel's bit
    equals the electrode's feedback entry where that is non-zero (all zero: never fed back)."""
    return np.array(
        [float(any(e["sel"]) and all(s == 0 or s == b for s, b in zip(e["sel"], bits))) for e in electrodes]
    )
