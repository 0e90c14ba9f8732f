"""The sigma-delta loop's design, derived from the MacroModel: electrode groups from the signs of
dC_i/dq at the centre, the feedback pattern and its forces, voltages, charge-amplifier
capacitors, the clock timing and the dither; and the loop's inputs (gravity, a tone). Every back
end (netgen.testbench.sigma_delta.ngspice, .vacask) renders the same Design.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from ...constants import G
from ...model import MacroModel

CHANNELS = ("z", "tilt_x", "tilt_y")


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


# per channel (z, tilt_x, tilt_y): the dither sits at f_s (1/2 - delta), a different delta per
# channel so that the three dithers are uncorrelated
DITHER_DELTA = (0.0218, 0.0274, 0.0331)
# the simulators' relative tolerance: range accepted from the CLI and sweep files
RELTOL_RANGE = (1e-7, 1e-2)
RELTOL_TEXT = "1e-7..1e-2"


@dataclass
class Tone:
    """A sinusoidal generalized force on one coordinate (amplitude in the f_ port unit)."""
    coord: str
    amplitude: float
    freq: float
    unit: str = ""

    @classmethod
    def parse(cls, text: str) -> "Tone":
        """Parse COORD:AMPLITUDE:FREQ, e.g. z:0.02:1e3 (uN on z at 1 kHz)."""
        parts = text.split(":")
        if len(parts) != 3:
            raise ValueError(f"tone {text!r} is not COORD:AMPLITUDE:FREQ (e.g. z:0.02:1000)")
        try:
            return cls(parts[0], float(parts[1]), float(parts[2]))
        except ValueError:
            raise ValueError(f"tone {text!r}: amplitude and frequency must be numbers") from None


@dataclass
class Design:
    """Everything the testbench needs; all derived from the model and the few choices here."""
    ts: float
    vs: float
    vfb: float
    lead: float
    full_scale: float
    electrodes: list[dict]
    channels: list[dict]
    table: list[dict]
    mass: float
    g: float
    gravity_un: float
    duty: float
    sense_force: list[float]
    t: Timing = field(default_factory=Timing)
    cs: float = 1e-12
    reltol: float = 1e-3
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

    @property
    def feedback_basis(self) -> dict:
        """The feedback phase (0 -> 1 over [a, b], 1 until c, 1 -> 0 over [c, d]) as
        k1 T1 - k2 T2 of two delay-free PULSE trapezoids, T1 rising over [0, b], T2 over [0, a],
        both falling over [c, d]: on [0, a] the two ramps cancel (k1 / b = k2 / a), on [a, b]
        the sum rises with slope 1 / (b - a), and k1 - k2 = 1 on [b, c]. Why: the template."""
        t, ts = self.t, self.ts
        a, b = t.fb_on - t.edge / 2, t.fb_on + t.edge / 2
        c, e = t.fb_off - t.edge / 2, t.fb_off + t.edge / 2
        return {"tr1": b * ts, "pw1": (c - b) * ts, "tr2": a * ts, "pw2": (c - a) * ts, "tf": (e - c) * ts,
                "k1": b / (b - a), "k2": a / (b - a)}

    def corners(self) -> list[float]:
        """Period phases of the electrode-phase corners (the breakpoints the ramps need)."""
        t, h = self.t, self.t.edge / 2
        return sorted({t.sense_on - h, t.sense_on + h, t.sense_off - h, t.sense_off + h,
                       t.fb_on - h, t.fb_on + h, t.fb_off - h, t.fb_off + h})

    @property
    def g_latch(self) -> float:
        """Latch-switch conductance: C_s settles `latch_settle` time constants within the clock pulse."""
        return self.latch_settle * self.cs / (self.t.sample * self.ts)

    @property
    def g_switch(self) -> float:
        """Sampling-switch conductance: C_s settles `settle` time constants within a sample pulse."""
        return self.settle * self.cs / (self.t.sample * self.ts)

    def g_reset(self, cf: float) -> float:
        """Reset-switch conductance: C_f discharges `settle` time constants within 10 % of T_s."""
        return self.settle * cf / (0.1 * self.ts)

    def level(self, channel: str) -> float:
        """Mean |fed-back force or torque| of a channel over a period (SI), for normalisation."""
        key = {"z": "fz", "tilt_x": "tx", "tilt_y": "ty"}[channel]
        unit = 1e-6 if channel == "z" else 1e-9
        return float(np.mean([abs(r[key]) for r in self.table])) * unit * self.duty


def coord_index(model: MacroModel, name: str) -> int:
    """Index of a coordinate, or a clear error."""
    names = [c.name for c in model.coordinates]
    if name not in names:
        raise ValueError(f"model {model.name} has no coordinate {name!r} (has {names}); "
                         "the sigma-delta loop needs z, tilt_x and tilt_y")
    return names.index(name)


def window(p: np.ndarray, a: float, b: float, t: Timing) -> np.ndarray:
    """The template's smooth clock window W(a, b) at period phase p."""
    w = t.edge / 8
    return 0.5 * (np.tanh((p - a) / w) - np.tanh((p - b) / w))


def duty(t: Timing, a: float | None = None, b: float | None = None) -> float:
    """Mean of the squared PULSE phase (linear edges of t.edge centred on a and b) over a period
    (feedback phase by default)."""
    a, b = (t.fb_on if a is None else a), (t.fb_off if b is None else b)
    return (b - a - t.edge) + 2 * t.edge / 3


def groups(model: MacroModel) -> list[dict]:
    """Per electrode: side (+1 pulls z up), sensed tilt axis and its sign, sense weights."""
    grad = model.capacitance_gradient(np.zeros(model.ncoords))[0]
    iz, ix, iy = (coord_index(model, c) for c in CHANNELS)
    out = []
    for k, e in enumerate(model.electrodes):
        side = int(np.sign(grad[k, iz]))
        axis = "tilt_x" if abs(grad[k, ix]) >= abs(grad[k, iy]) else "tilt_y"
        sign = int(np.sign(grad[k, ix if axis == "tilt_x" else iy]))
        w = [side, sign if axis == "tilt_x" else 0, sign if axis == "tilt_y" else 0]
        bz = "bit(v(b_z))" if side > 0 else "(1-bit(v(b_z)))"
        bt = f"bit(v(b_{axis}))" if sign > 0 else f"(1-bit(v(b_{axis})))"
        out.append({"name": e.name, "side": side, "axis": axis, "sign": sign, "w": w, "select": f"{bz}*{bt}"})
    return out


def selected(electrodes: list[dict], bits: tuple[int, int, int]) -> np.ndarray:
    """0/1 per electrode: energised for the bit pattern (bz, bx, by), each +-1."""
    bz, bx, by = bits
    return np.array([float(e["side"] == bz and e["sign"] == (bx if e["axis"] == "tilt_x" else by))
                     for e in electrodes])


def force_table(model: MacroModel, electrodes: list[dict], vfb: float) -> list[dict]:
    """Generalized forces at the centre for each of the 8 bit patterns (uN, nN*m)."""
    iz, ix, iy = (coord_index(model, c) for c in CHANNELS)
    rows = []
    for bits in itertools.product((1, -1), repeat=3):
        f = model.electrostatic_force(np.zeros(model.ncoords), vfb * selected(electrodes, bits))[0]
        rows.append({"bits": "".join("+" if b > 0 else "-" for b in bits), "pattern": list(bits),
                     "fz": f[iz] * 1e6, "tx": f[ix] * 1e9, "ty": f[iy] * 1e9, "all": f.tolist()})
    return rows


def design(model: MacroModel, ts: float, density: float = 0.5, sense_ratio: float = 0.25,
           lead: float = 0.8, full_scale: float = 0.01, g: float = G, timing: Timing | None = None,
           dither: float = 0.2, reltol: float = 1e-3) -> Design:
    """Loop design from the model: V_fb so that gravity needs a mean z-bit of `density`,
    V_s = sense_ratio * V_fb, C_f so that `full_scale` of the touch amplitude reads 1 V;
    `reltol` is the simulators' relative tolerance (the in-band floors depend on it: bench/compare_simulators.py)."""
    t = timing or Timing()
    iz = coord_index(model, "z")
    electrodes = groups(model)
    unit = force_table(model, electrodes, 1.0)
    fz_per_v2 = float(np.mean([abs(r["fz"]) for r in unit])) * 1e-6
    mass = model.coordinates[iz].mass
    vfb = round(float(np.sqrt(mass * g / (density * duty(t) * fz_per_v2))), 3)
    vs = round(sense_ratio * vfb, 3)
    grad = model.capacitance_gradient(np.zeros(model.ncoords))[0] * model.scales[None, :]
    channels = []
    table = force_table(model, electrodes, vfb)
    for k, name in enumerate(CHANNELS):
        sens = vs * float(sum(e["w"][k] * grad[i, coord_index(model, name)] for i, e in enumerate(electrodes)))
        channels.append({"name": name, "index": k, "sensitivity": sens, "cf": float(f"{sens * full_scale:.4g}"),
                         "dither_v": float(f"{dither * step_volts(model, table, name, ts, full_scale):.4g}"),
                         "dither_step": 2 * np.pi * (0.5 - DITHER_DELTA[k])})
    sense = model.electrostatic_force(np.zeros(model.ncoords), np.full(len(electrodes), vs))[0]
    return Design(ts, vs, vfb, lead, full_scale, electrodes, channels, table,
                  mass, g, -mass * g * 1e6, duty(t), sense.tolist(), t,
                  damping=float(model.coordinates[iz].admittance(0.0).real), dither=dither, reltol=reltol)


def step_volts(model: MacroModel, table: list[dict], channel: str, ts: float, full_scale: float) -> float:
    """The channel's one-period feedback displacement a_fb T_s^2 (a_fb: mean |fed-back force or
    torque| while on, over the mass or inertia) in readout volts (1 V = full_scale x touch)."""
    c = model.coordinates[coord_index(model, channel)]
    key, unit = {"z": ("fz", 1e-6), "tilt_x": ("tx", 1e-9), "tilt_y": ("ty", 1e-9)}[channel]
    force = float(np.mean([abs(r[key]) for r in table])) * unit
    return force / c.mass * ts**2 / (c.scale * full_scale)


def mechanical_inputs(model: MacroModel, d: Design, tone: Tone | None) -> list[tuple[str, float, Tone | None]]:
    """(port, DC value, tone or None) per input port of the model: gravity on f_z, the optional
    tone on its coordinate, 0 on the other force ports and on any other input (e.g. a_in).
    Both benches format these in their own source syntax."""
    out = [(f"f_{c.name}", d.gravity_un if c.name == "z" else 0.0, tone if tone and tone.coord == c.name else None)
           for c in model.coordinates]
    driven = {port for port, _, _ in out}
    return out + [(p["name"], 0.0, None) for p in model.ports()
                  if p["kind"].endswith("_in") and p["name"] not in driven]
