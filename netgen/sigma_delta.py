"""The paper's sigma-delta levitation loop (section 3, Fig. 3) around an emitted macromodel.

design() derives the loop from the MacroModel (electrode groups from the signs of dC_i/dq at
the centre, feedback pattern, voltages, charge-amplifier capacitors), testbench() renders
templates/sigma_delta_tb.cir.j2, simulate() runs ngspice with progress, and analyse() turns
the bitstreams into Welch spectra normalised to the fed-back force/torque (the paper's
normalisation), noise floors, SNR, notches and peaks.
"""

from __future__ import annotations

import itertools
import json
import math
import re
import shutil
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from scipy import signal

from . import __version__
from .model import MacroModel
from .simulate import SimulationError, diagnose, ngspice_path, read_raw
from .templating import render

CHANNELS = ("z", "tilt_x", "tilt_y")
SIMULATORS = ("ngspice", "ngspice-xspice", "vacask")
# the testbench's sampler/quantizer/driver blocks: behavioural sources, or the netgen_sdloop code model
LOOPS = ("analog", "xspice")
LOOP_OF = {"ngspice": "analog", "ngspice-xspice": "xspice", "vacask": None}
G = 9.81
K_B = 1.380649e-23          # J/K


@dataclass(frozen=True)
class Timing:
    """Event times within one period, as fractions of T_s (see the template header).

    Chosen for few ngspice time points (README "Performance"): the three electrode ramps (sense
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
# ngspice runs go in segments of this much simulated time, restarted at t = 0 (run_segments)
SEGMENT_S = 5e-4
MIN_SEGMENT = 16
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


def _coord_index(model: MacroModel, name: str) -> int:
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
    iz, ix, iy = (_coord_index(model, c) for c in CHANNELS)
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
    iz, ix, iy = (_coord_index(model, c) for c in CHANNELS)
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
    `reltol` is the simulators' relative tolerance (README "Sigma-delta loop": spectra)."""
    t = timing or Timing()
    iz = _coord_index(model, "z")
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
        sens = vs * float(sum(e["w"][k] * grad[i, _coord_index(model, name)] for i, e in enumerate(electrodes)))
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
    c = model.coordinates[_coord_index(model, channel)]
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


def force_sources(model: MacroModel, d: Design, tone: Tone | None, t0: float = 0.0) -> list[dict]:
    """ngspice source text per input port (`mechanical_inputs`); a tone continues from time t0
    (a segment restarted at t = 0) through the SIN phase, in degrees."""
    def sin(dc: float, t: Tone) -> str:
        phase = 360.0 * math.fmod(t.freq * t0, 1.0)
        return f"SIN({dc!r} {t.amplitude!r} {t.freq!r}" + (f" 0 0 {phase!r})" if phase else ")")
    return [{"port": port, "source": sin(dc, t) if t else f"DC {dc!r}"}
            for port, dc, t in mechanical_inputs(model, d, tone)]


def state_nodes(lib: Path, model: MacroModel, d: Design, instance: str = "x1") -> list[str]:
    """The nodes that hold the loop's state (capacitor nodes that no port drives): the model's
    internal ones (position, velocity, film branches; read from the .lib) and the testbench's
    charge amplifiers, samples and latches. A segment restarted from them continues the run."""
    body = Path(lib).read_text().lower().split(f".subckt {model.name.lower()} ", 1)[1].split("\n.ends", 1)[0]
    ports = {p["name"].lower() for p in model.ports()}
    # a capacitor node on a voltage source (the charge nodes qn_i behind their 0 V ammeters) is set
    # by that source, not a state
    driven = {n for line in body.splitlines() if line.startswith("v") for n in line.split()[1:3]}
    inner = sorted({n for line in body.splitlines() if line.startswith("c")
                    for n in line.split()[1:3] if n != "0" and n not in ports and n not in driven})
    bench = [f"{kind}_{c['name']}" for c in d.channels for kind in ("ca", "cur", "prev", "b")]
    return [f"{instance}.{n}" for n in inner] + bench


def testbench(model: MacroModel, d: Design, lib: str | Path, cycles: int, raw: str,
              tone: Tone | None = None, chunks: int = 50, start: int = 0,
              ic: dict[str, float] | None = None, states: list[str] = (), control: list[str] = (),
              loop: str = "analog") -> str:
    """The ngspice netlist of the loop (templates/sigma_delta_tb.cir.j2); for a segment of a
    long run, the periods from `start` on, from the node state `ic`, also saving `states`;
    `control`: extra .control lines (loading the code model); `loop` "analog": the samplers,
    quantizers and drivers as behavioural sources, "xspice": as the compiled netgen_sdloop."""
    if loop not in LOOPS:
        raise ValueError(f"unknown loop {loop!r}; choose one of {', '.join(LOOPS)}")
    ic = dict(ic or {})
    card = loop_card(d, start, ic) if loop == "xspice" else None
    if tone:
        _coord_index(model, tone.coord)
        tone.unit = model.coordinates[_coord_index(model, tone.coord)].port_units[2]
    # only what per_clock() reads: ngspice holds every saved vector in memory (measured 27 kB per
    # period with these 11, 1.8 GB for 2^16 periods; with the 3 lead-filter outputs too, over 2 GB)
    saves = ["time"] + [f"v(b_{c})" for c in CHANNELS] + [f"v(x_{c.name})" for c in model.coordinates]
    saves += [f"v({n})" for n in states]
    stop = d.ts * cycles
    progress = [f"{stop * k / chunks:.6e}" for k in range(1, chunks)]
    return render("sigma_delta_tb.cir.j2", bench="sigma_delta", version=__version__, model=model, d=d,
                  lib=str(lib), cycles=cycles, ports=[p["name"] for p in model.ports()],
                  forces=force_sources(model, d, tone, start * d.ts), tone=tone, saves=saves, raw=raw,
                  progress=progress, selects=selection_nodes(d.electrodes), start=start, ic=ic,
                  control=list(control), sdloop=card, pulses=phase_pulses(d))


def phase_pulses(d: Design) -> dict[str, tuple[float, ...]]:
    """PULSE(v1 v2 td tr tf pw per) of the three electrode-phase sources (seconds): phs, the
    sense phase, and fb1, fb2, the feedback phase's basis (Design.feedback_basis)."""
    t, ts, fb = d.t, d.ts, d.feedback_basis
    return {"phs": (0, 1, ts * (t.sense_on - t.edge / 2), ts * t.edge, ts * t.edge,
                    ts * (t.sense_off - t.sense_on - t.edge), ts),
            "fb1": (0, 1, 0, fb["tr1"], fb["tf"], fb["pw1"], ts),
            "fb2": (0, 1, 0, fb["tr2"], fb["tf"], fb["pw2"], ts)}


def loop_card(d: Design, start: int, ic: dict[str, float]) -> dict:
    """The netgen_sdloop instance of the "xspice" loop: its nodes and .model parameters (the
    same blocks, instants and dither as the analog loop; netgen/xspice/netgen_sdloop). The
    loop's own state (cur, prev, b per channel) is popped from `ic` into its initial values."""
    fb = d.feedback_basis
    names = [c["name"] for c in d.channels]
    init = {kind: [ic.pop(f"{kind}_{n}", 0.0) for n in names] for kind in ("cur", "prev", "b")}
    # an electrode is energised when each channel's bit equals its sense weight there (side for z,
    # tilt sign for its axis; groups(), selected()): the weights are the selection pattern
    params = {"ts": d.ts, "t_sample": d.t.cur + d.t.sample, "t_latch": d.t.clk + d.t.sample, "lead": d.lead,
              "start": float(start), "sel": [w for e in d.electrodes for w in e["w"]],
              "ph_sense": [d.vs, 0.0, 0.0], "ph_fb": [0.0, d.vfb * fb["k1"], -d.vfb * fb["k2"]],
              "ph_pulse": [float(v) for v in itertools.chain(*phase_pulses(d).values())],
              "dither_amp": [c["dither_v"] for c in d.channels],
              "dither_step": [float(c["dither_step"]) for c in d.channels],
              "cur0": init["cur"], "prev0": init["prev"], "b0": init["b"]}
    text = [(k, f"[{' '.join(repr(x) for x in v)}]" if isinstance(v, list) else repr(v)) for k, v in params.items()]
    nodes = [[f"ca_{n}" for n in names], None, [f"drv_{e['name']}" for e in d.electrodes],
             *([f"{kind}_{n}" for n in names] for kind in ("b", "cur", "prev"))]
    return {"params": params, "text": text,
            "instance": " ".join(f"[{' '.join(g)}]" if g else "NULL" for g in nodes)}


def selection_nodes(electrodes: list[dict]) -> dict[str, dict[str, str]]:
    """Per electrode the name of its feedback-selection node, and per node its expression in the
    restored bits bz, bx, by (e.g. sel_zp_tilt_xn = v(bz)*(1-v(bx))): the electrodes share the 8
    products, so the drivers are cheap 3-variable B-sources (README "Performance")."""
    nodes, of = {}, {}
    for e in electrodes:
        name = f"sel_z{'p' if e['side'] > 0 else 'n'}_{e['axis']}{'p' if e['sign'] > 0 else 'n'}"
        bt = "bx" if e["axis"] == "tilt_x" else "by"
        nodes[name] = (("v(bz)" if e["side"] > 0 else "(1-v(bz))") + "*"
                       + (f"v({bt})" if e["sign"] > 0 else f"(1-v({bt}))"))
        of[e["name"]] = name
    return {"nodes": nodes, "of": of}


def simulate(netlist: str, workdir: Path, stop: float, progress: bool = True, timeout: float = 36000.0,
             span: tuple[float, float, float] | None = None):
    """Run ngspice -b on the bench, report simulated/wall time from its progress lines; return the plot.
    span (t0, total, wall0): this run continues a segmented one at t0 of total, wall0 s after its start."""
    workdir.mkdir(parents=True, exist_ok=True)
    cir, raw, log = workdir / "sigma_delta.cir", workdir / "sigma_delta.raw", workdir / "sigma_delta.log"
    cir.write_text(netlist)
    raw.unlink(missing_ok=True)
    start, lines = time.perf_counter(), []
    stdbuf = shutil.which("stdbuf")
    argv = ([stdbuf, "-oL", "-eL"] if stdbuf else []) + [ngspice_path(), "-b", cir.name]
    shown = 0.0
    proc = subprocess.Popen(argv, cwd=workdir, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, stdin=subprocess.DEVNULL)
    for line in proc.stdout:
        lines.append(line)
        m = re.match(r"netgen-progress\s+([0-9.eE+-]+)", line)
        wall = time.perf_counter() - start
        if m and progress and wall - shown > 2.0 and float(m.group(1)) > 0:
            shown = wall
            t0, total, wall0 = span or (0.0, stop, 0.0)
            t, w = t0 + float(m.group(1)), wall0 + wall
            print(f"sigma-delta: simulated {t * 1e3:.3f} / {total * 1e3:.3f} ms, wall {w:.1f} s, "
                  f"eta {w * (total / t - 1):.0f} s", file=sys.stderr, flush=True)
        if time.perf_counter() - start > timeout:
            proc.kill()
            raise SimulationError(f"ngspice exceeded {timeout:.0f} s; reproduce with: ngspice -b {cir}")
    proc.wait()
    text = "".join(lines)
    log.write_text(text)
    # ngspice exits 1 after a paused-and-resumed run; success is a complete raw file (checked by the caller)
    if not raw.exists() or re.search(r"simulation\(s\) aborted|timestep too small", text, re.I):
        raise SimulationError(f"ngspice failed: {diagnose(text) or f'exit code {proc.returncode}'}; "
                              f"log {log}; reproduce with: cd {workdir} && ngspice -b {cir.name}")
    return read_raw(raw)[0]


def per_clock(plot, d: Design, cycles: int, model: MacroModel) -> dict[str, np.ndarray]:
    """Bits (+-1) and coordinates sampled once per period, in the feedback phase."""
    t = np.asarray(plot["time"])
    if t[-1] < 0.999 * cycles * d.ts:
        raise SimulationError(f"ngspice stopped at t = {t[-1]:.4g} s of {cycles * d.ts:.4g} s")
    at = (np.arange(cycles) + 0.5 * (d.t.fb_on + d.t.fb_off)) * d.ts
    out: dict[str, np.ndarray] = {}
    for c in CHANNELS:
        level = np.interp(at, t, plot[f"v(b_{c})"])
        out[f"bits_{c}"] = np.where(level > 0.5, 1, -1).astype(np.int8)
        out[f"latch_{c}"] = level           # the held latch level (ideally 0 or 1): soft decisions
    for c in model.coordinates:
        out[f"x_{c.name}"] = np.interp(at, t, plot[f"v(x_{c.name})"])
    out["time"] = at
    return out


def missed_corners(t: np.ndarray, d: Design, cycles: int) -> dict:
    """Did ngspice put a time point on every electrode-phase corner (its PULSE breakpoints)?
    The periods where one is missing (none expected; a lost breakpoint chain lets the
    trapezoidal electrode currents ring after each ramp, which the readout integrates)."""
    tc = ((np.arange(cycles)[:, None] + np.array(d.corners())[None, :]) * d.ts).ravel()
    tc = tc[(tc > 0) & (tc < t[-1])]                 # t = 0: the start, not a corner
    j = np.clip(np.searchsorted(t, tc), 1, len(t) - 1)
    gap = np.minimum(np.abs(t[j] - tc), np.abs(t[j - 1] - tc))
    # a point within 1e-3 of the ramp time counts as a hit: the kink then falls inside a step at a
    # fraction gap/step of it, and so does the ringing it leaves (ngspice also lands points a few
    # ps short of a corner and keeps its chains: measured, 1.2 ps short at 1 us, chains intact)
    missed = np.unique((tc[gap > 1e-3 * d.ts * d.t.edge] / d.ts).astype(int))
    return {"periods_with_a_missed_corner": int(len(missed)),
            "first_period": int(missed[0]) if len(missed) else None}


def psd(bits: np.ndarray, ts: float, nperseg: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Welch PSD of a +-1 bitstream (Hann, 50 % overlap): the spectrum normalised to the square
    of the fed-back force/torque, one-sided, in 1/Hz."""
    n = nperseg or min(len(bits), max(256, len(bits) // 8))
    return signal.welch(bits.astype(float), fs=1.0 / ts, window="hann", nperseg=n, detrend="constant")


def features(f: np.ndarray, p: np.ndarray, min_db: float = 6.0) -> tuple[list[dict], list[dict]]:
    """Notches and peaks of a PSD: deviations of > min_db from its running median (log f window)."""
    db = 10 * np.log10(p[1:] + 1e-300)
    ff = f[1:]
    width = max(5, len(db) // 40) | 1
    base = signal.medfilt(db, width)
    out = []
    for sign in (-1, 1):
        idx, props = signal.find_peaks(sign * (db - base), height=min_db, distance=width)
        out.append([{"freq_hz": float(ff[i]), "depth_db": float(sign * (db[i] - base[i]))} for i in idx])
    notches = sorted(out[0], key=lambda r: -r["depth_db"])[:10]
    peaks = sorted(out[1], key=lambda r: -r["depth_db"])[:10]
    return notches, peaks


def band_metrics(f: np.ndarray, p: np.ndarray, ts: float, osr: int, tone: Tone | None) -> dict:
    """In-band noise floor (median, dB re F_fb^2/Hz), SNR of the tone, noise-shaping slope."""
    fb = 0.5 / ts / osr
    band = (f > 0) & (f <= fb)
    df = f[1] - f[0]
    mask = band.copy()
    if not band.any():                             # run too short: no PSD bin inside the band
        return {"band_hz": [None, float(fb)], "noise_floor_db_per_hz": None, "inband_noise_db": None,
                "note": "band has no PSD bins: run more cycles"}
    out: dict = {"band_hz": [float(f[band][0]), float(fb)]}
    if tone:
        near = band & (np.abs(f - tone.freq) <= 3 * df)
        mask &= ~near
        sig = float(np.sum(p[near]) * df)
        out["tone_power"] = sig
        out["tone_level_db"] = 10 * np.log10(sig + 1e-300)
    if mask.sum() < 2:                             # run too short to resolve the band
        out.update({"noise_floor_db_per_hz": None, "inband_noise_db": None, "note": "band has < 2 bins"})
        return out
    noise = float(np.sum(p[mask]) * df)
    out["noise_floor_db_per_hz"] = float(10 * np.log10(np.median(p[mask])))
    out["inband_noise_db"] = float(10 * np.log10(noise))
    if tone:
        out["snr_db"] = float(out["tone_level_db"] - out["inband_noise_db"])
    lo, hi = fb / 10, fb
    sel = (f >= lo) & (f <= hi) & mask
    if sel.sum() > 3:
        out["slope_db_per_decade"] = float(np.polyfit(np.log10(f[sel]), 10 * np.log10(p[sel]), 1)[0])
    return out


def analyse(clock: dict, d: Design, tone: Tone | None = None, osr: int = 64, skip: int = 0) -> dict:
    """Summary per channel: spectra features, noise floor, SNR, bit mean and force balance."""
    summary: dict = {"ts": d.ts, "fs_hz": 1 / d.ts, "osr": osr, "cycles": int(len(clock["time"])), "skip": skip,
                     "vfb": d.vfb, "vs": d.vs, "lead": d.lead, "channels": {}, "spectra": {}}
    for c in CHANNELS:
        bits = clock[f"bits_{c}"][skip:]
        f, p = psd(bits, d.ts)
        notches, peaks = features(f, p)
        m = band_metrics(f, p, d.ts, osr, tone)
        summary["channels"][c] = {"bit_mean": float(bits.mean()), "fed_back_level_si": d.level(c),
                                  **m, "notches": notches, "peaks": peaks, **latch_quality(clock, c, skip)}
        summary["spectra"][c] = (f, p)
    summary["gravity_balance"] = gravity_balance(clock, d, skip)
    summary["coordinates"] = {k[2:]: {"mean": float(v[skip:].mean()), "min": float(v[skip:].min()),
                                      "max": float(v[skip:].max())}
                              for k, v in clock.items() if k.startswith("x_")}
    return summary


def latch_quality(clock: dict, channel: str, skip: int = 0) -> dict:
    """How cleanly the latch held its decision: the worst distance of the held level from 0 or 1,
    and the periods where the electrode drive's restoring bit(x) = (1 + tanh(40 (x - 1/2))) / 2
    is more than 1e-3 off 0/1 (distance > 0.41): a partial feedback force while the bitstream
    records +-1. Empty for clocks without latch levels (older bitstream files)."""
    level = clock.get(f"latch_{channel}")
    if level is None:
        return {}
    err = np.minimum(np.abs(level[skip:]), np.abs(level[skip:] - 1.0))
    restored = 0.5 - 0.5 * np.tanh(40.0 * (0.5 - err))          # drive error of bit() at that level
    return {"partial_latches": int(np.sum(restored > 1e-3)), "max_latch_error": float(err.max(initial=0.0))}


def levitation(clock: dict, model: MacroModel, limit: float = 0.02) -> dict:
    """Did the loop hold the plate? The first period where a coordinate leaves `limit` of its
    touching amplitude (the reference loop keeps them within 0.02 % at T_s = 1 us and 0.25 % at
    3.2 us, where the (3,0) modes overload it); a lost plate makes the spectra
    those of a plate at the stop, so the command reports it instead of a silent result."""
    for n in range(len(clock["time"])):
        for c in model.coordinates:
            touch = c.scale / c.port_units[1]
            if abs(clock[f"x_{c.name}"][n]) > limit * touch:
                return {"held": False, "lost_at_period": n, "coordinate": c.name,
                        "value": float(clock[f"x_{c.name}"][n]), "limit": limit * touch}
    return {"held": True, "limit_fraction_of_touch": limit}


def gravity_balance(clock: dict, d: Design, skip: int = 0) -> dict:
    """Momentum balance on z between the clock samples a = skip and b = N - 2: the mean
    electrostatic force implied by the bits (the model's centre force of each bit pattern x the
    feedback duty, plus the sense-phase force) against m g + m (v_b - v_a) / (t_b - t_a), with
    v from central differences of x_z, + the damping impulse B(0) (x_b - x_a) / (t_b - t_a) (exact
    for a dashpot; a film branch adds its force change / corner, negligible for corners far above
    the loop's motion). Samples sit mid-feedback, so the end periods count half. An applied tone
    force and the thermal noise force are not included (the first averages out only over whole
    tone periods; the second's impulse is ~1e-3 of m g T at 100 Pa over 128 periods)."""
    pats = np.stack([clock[f"bits_{c}"] for c in CHANNELS], axis=1)
    lookup = {tuple(r["pattern"]): r["fz"] * 1e-6 for r in d.table}
    fz = np.array([lookup[tuple(p)] for p in pats.tolist()])
    a, b = skip, len(fz) - 2
    if b - a < 8:
        raise ValueError(f"too few clock samples after skipping {skip} for a force balance")
    weights = np.ones(b - a + 1)
    weights[[0, -1]] = 0.5
    sense = d.sense_force[0] * duty(d.t, d.t.sense_on, d.t.sense_off)
    mean = float(np.dot(weights, fz[a:b + 1]) / (b - a) * d.duty + sense)
    x = clock["x_z"] * 1e-6                       # x_z port: 1 V = 1 um
    v = lambda n: (x[n + 1] - x[n - 1]) / (2 * d.ts)  # noqa: E731
    inertia = d.mass * (v(b) - v(a)) / ((b - a) * d.ts)
    damping = d.damping * (x[b] - x[a]) / ((b - a) * d.ts)
    need = d.mass * d.g + inertia + damping
    return {"mean_force_n": mean, "weight_n": d.mass * d.g, "inertial_n": float(inertia),
            "damping_n": float(damping), "ratio": float(mean / need), "window": [a, b]}


def plot_spectra(summary: dict, path: Path, title: str) -> Path:
    """PNG of the three normalised spectra (dB re F_fb^2/Hz against log frequency)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    for ax, c in zip(axes, CHANNELS):
        f, p = summary["spectra"][c]
        ax.semilogx(f[1:], 10 * np.log10(p[1:]), lw=0.7)
        ax.axvline(summary["fs_hz"] / 2 / summary["osr"], color="k", ls=":", lw=0.7)
        ax.set_ylabel(f"{c}: dB re F_fb^2/Hz")
        ax.grid(True, which="both", lw=0.3)
    axes[0].set_title(title)
    axes[-1].set_xlabel("frequency (Hz)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_states(clock: dict, path: Path) -> Path:
    """PNG of the coordinates per clock (port units) over the run."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    keys = [k for k in clock if k.startswith("x_")]
    fig, axes = plt.subplots(len(keys), 1, figsize=(8, 1.4 * len(keys) + 1), sharex=True)
    for ax, k in zip(np.atleast_1d(axes), keys):
        ax.plot(clock["time"] * 1e3, clock[k], lw=0.5)
        ax.set_ylabel(k, fontsize=8)
    np.atleast_1d(axes)[-1].set_xlabel("time (ms)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def run(model: MacroModel, lib: Path, out: Path, ts: float, cycles: int, tone: Tone | None = None,
        progress: bool = True, plots: bool = True, skip: int | None = None, simulator: str = "ngspice",
        segment: int | None = None, **choices) -> dict:
    """Design, render, simulate and analyse; write bits .npz, PNGs and summary.json into `out`.
    simulator "ngspice" runs the .lib `lib`; "ngspice-xspice" the model emitted with its plate terms in
    the compiled XSPICE code model (netgen.codemodel); "vacask" the compiled Verilog-A module (the .va next
    to `lib`, else the module emitted from `model`) in the same loop (netgen.sigma_delta_vacask)."""
    if simulator not in SIMULATORS:
        raise ValueError(f"unknown simulator {simulator!r}; choose one of {', '.join(SIMULATORS)}")
    cm = _code_model(progress) if simulator == "ngspice-xspice" else None     # fails before any output
    out.mkdir(parents=True, exist_ok=True)
    d = design(model, ts, **choices)
    extra = {}
    if simulator == "vacask":
        from . import sigma_delta_vacask as sdv
        va = Path(lib).with_suffix(".va")
        va = va if va.exists() else None
        start = time.perf_counter()                   # compile (cached in out/osdi) outside wall_s
        sdv.compile_model(model, out / "osdi", va)
        sdv.compile_blocks(out / "osdi")
        extra["compile_s"] = time.perf_counter() - start
    start = time.perf_counter()
    if simulator == "vacask":
        plot = sdv.run_bench(model, d, out, cycles, tone, progress, va=va)
        extra["vacask"] = sdv.stats(out)
        clock = per_clock(plot, d, cycles, model)
        del plot
        (out / "tran1.raw").unlink(missing_ok=True)
    else:
        control = []
        if cm is not None:
            lib, control = xspice_library(model, out, cm)
        clock, extra["breakpoints"], extra["segments"] = run_segments(model, d, lib, out, cycles, tone, progress,
                                                                      segment, control, LOOP_OF[simulator])
    wall = time.perf_counter() - start
    np.savez_compressed(out / "bitstreams.npz", **clock)
    done = len(clock["time"])                         # fewer than `cycles` if a segment lost the plate
    skip = done // 8 if skip is None else min(skip, done // 2)
    summary = analyse(clock, d, tone, skip=skip)
    summary["levitation"] = levitation(clock, model)
    spectra = summary.pop("spectra")
    np.savez_compressed(out / "spectra.npz", **{f"{c}_{k}": v for c, (fr, p) in spectra.items()
                                                for k, v in (("f", fr), ("psd", p))})
    summary.update({"requested_cycles": cycles, "model": model.name, "coordinates_in_model": [c.name for c in model.coordinates],
                    "thermal_noise": thermal_floor(model, d), "simulator": simulator, **extra, "wall_s": wall, "tone": asdict(tone) if tone else None,
                    "design": {"electrodes": d.electrodes, "table": d.table, "cf": {c["name"]: c["cf"] for c in d.channels},
                               "timing": asdict(d.t), "duty": d.duty, "reltol": d.reltol}})
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    if plots:
        plot_spectra(summary | {"spectra": spectra}, out / "spectra.png",
                     f"{model.name}: T_s = {ts * 1e6:g} us, {cycles} cycles ({simulator})")
        plot_states(clock, out / "coordinates.png")
    return summary | {"spectra": spectra, "clock": clock}


def segment_periods(ts: float, segment: int | None, cycles: int) -> int:
    """Periods per ngspice segment: `segment` if given (0: the whole run in one), else
    SEGMENT_S of simulated time (at least MIN_SEGMENT periods)."""
    if segment == 0:
        return cycles
    return min(cycles, segment if segment else max(MIN_SEGMENT, round(SEGMENT_S / ts)))


def _code_model(progress: bool) -> Path:
    """The netgen_es code model for the installed ngspice (built once, netgen.codemodel)."""
    from . import codemodel
    return codemodel.build(progress=(lambda m: print(m, file=sys.stderr)) if progress else (lambda m: None))


def xspice_library(model: MacroModel, out: Path, cm: Path) -> tuple[Path, list[str]]:
    """The model's .lib in the xspice form (plate terms in the compiled code model `cm`), written
    to `out`, and the .control lines that load the code model."""
    from .codemodel import control_lines
    from .emit_ngspice import subcircuit
    from .model import write_files_atomic
    lib = out / f"{model.name}_xspice.lib"
    write_files_atomic({lib: subcircuit(model, style="xspice")})
    return lib, control_lines(cm)


def run_segments(model: MacroModel, d: Design, lib: Path, out: Path, cycles: int, tone: Tone | None,
                 progress: bool, segment: int | None, control: list[str] = (),
                 loop: str = "analog") -> tuple[dict, dict, dict]:
    """Run the ngspice bench in segments, each restarted at t = 0 from the node state the run
    reached: the per-clock samples, the missed corners, the plan. A segment in which ngspice
    missed an electrode-phase corner is cut at the start of that period, and the next segment
    restarts there with fresh breakpoint chains. A segment that loses the plate is the last
    (its netlist, with its .ic, stays in `out`).
    Why: ngspice 39 chains a periodic PULSE's breakpoints; once a chain breaks the electrode
    currents ring after every ramp, the readout integrates the ringing and the plate falls
    (README "Sigma-delta loop"): restarting at the first missed corner never runs on a broken chain."""
    length = segment_periods(d.ts, segment, cycles)
    states = state_nodes(lib, model, d) if length < cycles else []
    parts, accepted_misses, cuts, runs = [], [], [], 0
    n0, ic, wall0 = 0, None, time.perf_counter()
    while n0 < cycles:
        n = min(length, cycles - n0)
        # progress stops: one per ~100 periods (each `stop when` costs ngspice ~3 time points)
        bench = testbench(model, d, lib.resolve(), n, "sigma_delta.raw", tone, start=n0, ic=ic, states=states,
                          control=control, loop=loop, chunks=max(1, min(50, n // 100)))
        plot = simulate(bench, out, d.ts * n, progress,
                        span=(n0 * d.ts, cycles * d.ts, time.perf_counter() - wall0))
        runs += 1
        t = np.asarray(plot["time"])
        first = missed_corners(t, d, n)["first_period"]
        keep = n if first is None or not states else max(first, 1)
        if keep < n:
            cuts.append({"start": n0, "missed_at": n0 + first})
        if first is not None and first < keep:          # a miss in the first period is kept: progress
            accepted_misses.append(n0 + first)
        part = per_clock(plot, d, keep, model)
        part["time"] = part["time"] + n0 * d.ts
        parts.append(part)
        if states:
            ic = {node: float(np.interp(keep * d.ts, t, plot[f"v({node})"])) for node in states}
        del plot
        (out / "sigma_delta.raw").unlink(missing_ok=True)
        n0 += keep
        if not levitation(part, model)["held"]:
            break
    clock = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    breakpoints = {"periods_with_a_missed_corner": len(accepted_misses),
                   "first_period": accepted_misses[0] if accepted_misses else None,
                   "segments_cut_at_a_missed_corner": cuts}
    plan = {"periods": length, "ngspice_runs": runs, "periods_run": int(n0), "state_nodes": states}
    return clock, breakpoints, plan


def parse_pressure(text: str) -> float:
    """A pressure option: a number in Pa or a quantity string ('100 Pa', '1 mbar', '1 atm')."""
    from .units import parse_quantity
    try:
        value = float(text)
    except ValueError:
        value = parse_quantity(text, "pressure")
    if not value > 0:
        raise ValueError(f"--pressure {text!r} must be positive")
    return value


def thermal_floor(model: MacroModel, d: Design) -> dict:
    """The gas film's Brownian force floor per channel, in the spectra's normalisation:
    S_F = 4 k_B T Re B(0) (damper plus film branches, in band) over the fed-back level squared,
    dB re F_fb^2/Hz; with the model's noise switch (noise sources in the netlist or not)."""
    damping = model.report.get("damping", {})
    temp = float(damping.get("temperature_K", 300.0))
    noise = bool(damping.get("noise", False))
    out = {"noise_sources_emitted": noise, "temperature_K": temp,
           "pressure_Pa": damping.get("squeeze_film", {}).get("pressure_Pa"), "channels": {}}
    if noise:   # measured: `setseed`, `set rndseed` and `.options seed` all leave TRNOISE unseeded
        out["reproducibility"] = ("statistical only: ngspice 39 fills the Gaussian pool of TRNOISE from its "
                                  "process id (trannoise/wallace.c initw) and no seed option reaches it")
    for c in CHANNELS:
        b = float(model.coordinates[_coord_index(model, c)].admittance(0.0).real)
        floor = 10 * np.log10(4 * K_B * temp * b / d.level(c) ** 2) if b > 0 else None
        out["channels"][c] = {"damping_si": b, "thermal_floor_db_per_hz": floor}
    return out


def with_damping(structure, pressure: float | None, film: str | None, noise: bool):
    """The structure with the sigma-delta command's gas and noise options applied to [damping]."""
    from dataclasses import replace

    from .structure import Damping
    if pressure is None and film is None and not noise:
        return structure
    d = structure.damping or Damping()
    if pressure is not None:
        d = replace(d, squeeze_film=True, pressure=pressure)
    if film is not None:
        d = replace(d, squeeze_film=True, film_model=film)
    return replace(structure, damping=replace(d, noise=noise or d.noise))


def model_folder(out: Path, rigid_only: bool, pressure: float | None, film: str | None, noise: bool) -> Path:
    """DIR/model..., one folder per option set, so a cached model never answers for other options."""
    tags = ["model"] + (["rigid"] if rigid_only else []) + ([f"p{pressure:g}Pa"] if pressure is not None else []) \
        + ([film] if film else []) + (["noise"] if noise else [])
    return out / "_".join(tags)


def model_for(structure_path: str | Path, folder: Path, rigid_only: bool = False, rebuild: bool = False,
              progress: bool = True, pressure: float | None = None, film: str | None = None,
              noise: bool = False) -> tuple[MacroModel, Path]:
    """Build the structure's model into `folder` (rigid-body only: modes = 0; gas film at
    `pressure`, thermal noise sources with `noise`), or reuse the .json/.lib (and .va) there
    when they are newer than the structure file."""
    from dataclasses import replace

    from .emit import write_outputs
    from .pipeline import build_model
    from .structure import load_structure

    structure = with_damping(load_structure(structure_path), pressure, film, noise)
    if rigid_only:
        structure = replace(structure, coordinates=replace(structure.coordinates, modes=0))
    js, lib = folder / f"{structure.name}.json", folder / f"{structure.name}.lib"
    fresh = js.exists() and lib.exists() and js.stat().st_mtime > Path(structure_path).stat().st_mtime
    if fresh and not rebuild:
        return MacroModel.load_json(js), lib
    model = build_model(structure, progress=progress)
    write_outputs(model, folder, "all")              # .lib for ngspice, .va for the VACASK path
    return model, lib


def cli(args) -> int:
    """`netgen sigma-delta`: build or reuse the model, run the loop, write DIR/summary.json etc."""
    out = Path(args.output)
    try:
        tone = Tone.parse(args.tone) if args.tone else None
        if args.ts <= 0 or args.cycles < 64:
            raise ValueError(f"need --ts > 0 and --cycles >= 64 (got {args.ts}, {args.cycles})")
        if args.segment is not None and (args.segment < 0 or 0 < args.segment < MIN_SEGMENT):
            raise ValueError(f"--segment {args.segment}: give at least {MIN_SEGMENT} periods per segment, or 0 "
                             f"for one run (the default is {SEGMENT_S * 1e3:g} ms of simulated time)")
        if not RELTOL_RANGE[0] <= args.reltol <= RELTOL_RANGE[1]:
            raise ValueError(f"--reltol {args.reltol} is outside {RELTOL_TEXT} (default 1e-3; 1e-4 for spectra "
                             "you quote: README 'Sigma-delta loop')")
        if not 0 <= args.dither <= 1:
            raise ValueError(f"--dither {args.dither} must be between 0 (none) and 1 (the default is 0.2)")
        pressure = parse_pressure(args.pressure) if args.pressure is not None else None
        if args.model and (args.rigid_only or pressure is not None or args.film or args.noise):
            raise ValueError("--rigid-only, --pressure, --film and --noise rebuild the model from the structure "
                             "file; drop --model")
        if args.noise and args.simulator == "vacask":
            raise ValueError("--noise needs --simulator ngspice: VACASK has no transient noise sources "
                             "(the .va's white_noise acts in noise analyses only)")
    except ValueError as exc:
        print(f"netgen: {exc}", file=sys.stderr)
        return 2
    if args.model:
        model, lib = MacroModel.load_json(args.model), Path(args.model).with_suffix(".lib")
    else:
        model, lib = model_for(args.structure, model_folder(out, args.rigid_only, pressure, args.film, args.noise),
                               args.rigid_only, args.rebuild, not args.quiet, pressure, args.film, args.noise)
    s = run(model, lib, out, args.ts, args.cycles, tone, progress=not args.quiet, plots=not args.no_plots,
            simulator=args.simulator, segment=args.segment, lead=args.lead, dither=args.dither,
            reltol=args.reltol)
    if not args.quiet:
        for c in CHANNELS:
            ch = s["channels"][c]
            snr = f", SNR {ch['snr_db']:.1f} dB" if "snr_db" in ch else ""
            floor = ch["noise_floor_db_per_hz"]
            floor = "n/a (run too short)" if floor is None else f"{floor:.1f} dB/Hz"
            print(f"{c}: bit mean {ch['bit_mean']:+.4f}, in-band floor {floor}"
                  f"{snr}, {len(ch['notches'])} notches, {len(ch['peaks'])} peaks")
        gb = s["gravity_balance"]
        th = s["thermal_noise"]["channels"]
        if any(v["thermal_floor_db_per_hz"] is not None for v in th.values()):
            print("gas-film Brownian force floor (dB re F_fb^2/Hz): " + ", ".join(
                f"{c} {v['thermal_floor_db_per_hz']:.1f}" for c, v in th.items() if v["thermal_floor_db_per_hz"]))
        print(f"mean feedback force / weight = {gb['ratio']:.4f}; wrote {out / 'summary.json'} ({s['wall_s']:.0f} s)")
    lev = s["levitation"]
    if not lev["held"]:
        print(f"netgen: the loop lost the plate at period {lev['lost_at_period']} ({lev['coordinate']} = "
              f"{lev['value']:.4g}, beyond {lev['limit']:.3g} in port units); the spectra describe a plate at "
              f"the stop.{_lost_hint(s)} Results in {out}", file=sys.stderr)
        return 1
    return 0


def _lost_hint(s: dict) -> str:
    """What the summary says about a lost plate: missed breakpoints, partial latch decisions."""
    hints = []
    bp = s.get("breakpoints") or {}
    if bp.get("periods_with_a_missed_corner"):
        hints.append(f"ngspice missed an electrode-phase corner in {bp['periods_with_a_missed_corner']} "
                     f"period(s), first {bp['first_period']} (README 'Sigma-delta loop')")
    seg = s.get("segments") or {}
    if seg.get("state_nodes") and seg.get("periods_run", 0) < s.get("requested_cycles", 0):
        hints.append(f"ngspice stopped after the segment that lost it ({seg['periods_run']} of "
                     f"{s['requested_cycles']} periods; its netlist with the restart state is DIR/sigma_delta.cir)")
    partial = {c: v.get("partial_latches") for c, v in s["channels"].items() if v.get("partial_latches")}
    if partial:
        hints.append(f"partial latch decisions {partial}")
    return (" Diagnostics: " + "; ".join(hints) + ".") if hints else ""


def add_parser(sub) -> None:
    """The `sigma-delta` subcommand's arguments."""
    p = sub.add_parser("sigma-delta", help="run the paper's sigma-delta levitation loop in ngspice or VACASK, "
                       "with spectra")
    p.add_argument("structure", help="structure description (TOML)")
    p.add_argument("-o", "--output", required=True, help="output folder (bitstreams.npz, spectra, summary.json)")
    p.add_argument("--ts", type=float, default=1e-6, help="sampling period T_s in s (default 1e-6)")
    p.add_argument("--cycles", type=int, default=4096, help="number of sampling periods (default 4096)")
    p.add_argument("--tone", help="sinusoidal force COORD:AMPLITUDE:FREQ (amplitude in the f_ port unit, uN or nN*m)")
    p.add_argument("--rigid-only", action="store_true", help="drop the eigenmodes (model built with modes = 0)")
    p.add_argument("--model", help="use this model .json (with the .lib, and for VACASK the .va, next to it) "
                   "instead of building")
    p.add_argument("--simulator", choices=SIMULATORS, default="ngspice",
                   help="ngspice with the .lib (default); ngspice-xspice: ngspice with the model's plate terms in "
                   "the compiled XSPICE code model (netgen codemodel; about 4x faster); or VACASK with the compiled "
                   "Verilog-A module: the same loop, for spectra-length runs")
    p.add_argument("--rebuild", action="store_true", help="rebuild the model even if DIR/model is up to date")
    p.add_argument("--pressure", help="gas pressure of the squeeze film in both gaps, e.g. '100 Pa', '1 mbar', "
                   "'1 atm' (turns squeeze-film damping on; gas and temperature from [damping])")
    p.add_argument("--film", choices=("incompressible", "compressible"),
                   help="squeeze-film model (compressible: Maxwell branches, for squeeze numbers above about 1)")
    p.add_argument("--noise", action="store_true", help="thermal force noise of the damping (ngspice trnoise); "
                   "summary.json gives the resulting Brownian floor per channel")
    p.add_argument("--lead", type=float, default=0.8, help="lead-compensator coefficient a in y = a*prev - cur")
    p.add_argument("--dither", type=float, default=0.2,
                   help="comparator dither amplitude, a fraction of the one-period feedback displacement "
                        "a_fb*T_s^2 (a sine near f_s/2 per channel; 0 = none; default 0.2)")
    p.add_argument("--reltol", type=float, default=1e-3,
                   help="relative tolerance of the simulator (default 1e-3; README 'Sigma-delta loop' on how it "
                        "moves the in-band floors: 1e-4 for spectra you quote)")
    p.add_argument("--segment", type=int, default=None,
                   help="ngspice: run in segments of this many periods, each restarted at t = 0 from the "
                        "state the run reached (and cut at any missed breakpoint: README 'Sigma-delta loop'); "
                        f"0 = one run; default {SEGMENT_S * 1e3:g} ms of simulated time")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or summary output")
    p.set_defaults(func=cli)
