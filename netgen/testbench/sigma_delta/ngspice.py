"""The sigma-delta loop in ngspice: the netlist (templates/sigma_delta/tb.cir.j2, which
`.include`s the model's .lib like any user testbench), its behavioural-source loop or the
compiled loop (the code model netgen_sdloop beside this module), and long runs in segments
restarted from their state (run_segments)."""

from __future__ import annotations

import itertools
import math
import re
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ... import __version__
from ...core.errors import CodeModelError
from ...core.files import write_files_atomic
from ...core.paths import spice_card
from ...core.templating import render
from ...emit import osdi, xspice
from ...emit.common import check_names
from ...model import MacroModel
from ...sim import codemodel
from ...sim.ngspice import run_control, same_build
from . import filters
from .analysis import levitation, per_clock
from .inputs import input_text, mechanical_inputs, tone_unit
from .loop import Design, Tone
from .options import MIN_SEGMENT, SEGMENT_S
from .vacask import drivers

TEMPLATE = "sigma_delta/tb.cir.j2"
# the testbench's sampler/quantizer/driver blocks: behavioural sources, the netgen_sdloop code model,
# or the Verilog-A modules of blocks.va through OSDI (netgen.testbench.sigma_delta.osdi)
LOOPS = ("analog", "xspice", "osdi")
# the behavioural loop's state-space filters decide a tie y = 0 (the first period from rest, every
# state 0 and d = 0) as bit 0, as the compiled loop and the numpy reference do (bit 1 only for
# y > 0): y is offset by this many comparator widths, so the tanh comparator gives e^-10 there and
# not the half-way level that fed back 0.94 of a bit (measured: the first state 6 % off)
TIE = 5.0
# the comparator inputs v(y_<c>) are saved (per_clock: the latch check against the comparator's
# resolution, analysis.latch_quality) in segments of up to this many periods: 3 more vectors, about
# 7 kB per period in ngspice's memory, which the longest one-segment (OSDI) runs cannot spare
SAVE_Y_PERIODS = 8192


def force_sources(model: MacroModel, d: Design, tone: Tone | None, t0: float = 0.0) -> list[dict]:
    """ngspice source text per input port (`mechanical_inputs`); a tone continues from time t0
    (a segment restarted at t = 0) through the SIN phase, in degrees."""

    def sin(dc: float, t: Tone) -> str:
        phase = 360.0 * math.fmod(t.freq * t0, 1.0)
        return f"SIN({dc!r} {t.amplitude!r} {t.freq!r}" + (f" 0 0 {phase!r})" if phase else ")")

    return [
        {"port": port, "source": sin(dc, t) if t else f"DC {dc!r}"} for port, dc, t in mechanical_inputs(model, d, tone)
    ]


def behavioural_sources(
    forces: list[dict], expressions: dict[str, str], devices: dict[str, str] | None = None
) -> list[dict]:
    """The input sources with element letter V, or B with V=<expression> where one is given, or
    the netlist lines of a device that drives the port instead (`devices`: port -> lines)."""
    devices = devices or {}
    return [
        f
        | (
            {"lines": devices[f["port"]]}
            if f["port"] in devices
            else {"element": "B", "source": f"V={expressions[f['port']]}"}
            if f["port"] in expressions
            else {"element": "V"}
        )
        for f in forces
    ]


def state_nodes(lib: Path, model: MacroModel, d: Design, instance: str = "x1", analog: bool = False) -> list[str]:
    """The nodes that hold the loop's state (capacitor nodes that no port drives): the model's
    internal ones (position, velocity, film branches; read from the .lib, or those of the OSDI
    instance of an _osdi.lib, netgen.emit.osdi.state_node) and the testbench's
    charge amplifiers, samples, latches and filter states (with `analog`, the behavioural
    loop's: also the filters' master nodes, analog_filters). A segment restarted from them
    continues the run."""
    body = Path(lib).read_text().lower().split(f".subckt {model.name.lower()} ", 1)[1].split("\n.ends", 1)[0]
    bench = [f"{kind}_{c['name']}" for c in d.channels for kind in ("ca", "cur", "prev", "b")]
    bench += filters.state_nodes(d.channels)
    if analog:
        bench += [s["m"] for f in analog_filters(d).values() for s in f["states"]]
    if any(line.startswith("n1 ") for line in body.splitlines()):  # the _osdi.lib: the module's internal nodes
        return [osdi.state_node(s, instance) for s in osdi.states(model)] + bench
    ports = {p["name"].lower() for p in model.ports()}
    # a capacitor node on a voltage source (the charge nodes qn_i behind their 0 V ammeters) is set
    # by that source, not a state
    driven = {n for line in body.splitlines() if line.startswith("v") for n in line.split()[1:3]}
    inner = sorted(
        {
            n
            for line in body.splitlines()
            if line.startswith("c")
            for n in line.split()[1:3]
            if n != "0" and n not in ports and n not in driven
        }
    )
    return [f"{instance}.{n}" for n in inner] + bench


@dataclass(frozen=True)
class Settings:
    """How ngspice runs the loop: `loop` "analog": the samplers, quantizers and drivers as
    behavioural sources, "xspice": as the compiled netgen_sdloop, "osdi": as the blocks.va modules
    VACASK runs, loaded through OSDI (`control` loads them); `control`: extra .control lines
    (loading the code model); `klu`: ngspice's KLU solver (.options klu) instead of Sparse 1.3;
    `behavioural`: input ports driven by a B-source expression; `start_state`: the start's node values;
    `chunks`: progress stops per run; `folder`: the one it runs in (the .include of a `lib` inside
    it relative, netgen.core.paths.spice_card); run_segments: `segment` periods per ngspice run
    (None: segment_periods' choice) and each run's wall-clock `timeout` (s)."""

    loop: str = "analog"
    control: Sequence[str] = ()
    klu: bool = False
    chunks: int = 50
    folder: Path | None = None
    segment: int | None = None
    timeout: float = 36000.0
    # input ports driven by a behavioural source instead (port, B-source expression; the gyroscope's
    # drive loop, netgen.testbench.gyro) and the node state of the run's start (the first segment's .ic)
    behavioural: tuple[tuple[str, str], ...] = ()
    # input ports driven by a compiled device instead (port, its netlist lines: an OSDI instance and
    # its .model card; the gyroscope's drive loop in the "osdi" loop, netgen.testbench.gyro.run)
    devices: tuple[tuple[str, str], ...] = ()
    start_state: tuple[tuple[str, float], ...] = ()
    # instance parameters of the model's X line (name, value): a process point of a [process] .lib
    instance: tuple[tuple[str, float], ...] = ()


@dataclass(frozen=True)
class Segment:
    """A segment of a long run: the periods from `start` on, from the node state `ic`, also saving
    the nodes `states` (for the next segment's `ic`)."""

    start: int = 0
    ic: dict[str, float] | None = None
    states: Sequence[str] = field(default_factory=list)


def testbench(
    model: MacroModel,
    d: Design,
    lib: str | Path,
    cycles: int,
    raw: str,
    tone: Tone | None = None,
    settings: Settings = Settings(),
    segment: Segment = Segment(),
) -> str:
    """The ngspice netlist of the loop (templates/sigma_delta/tb.cir.j2), run as `settings` say;
    for a `segment` of a long run, its periods from its node state."""
    loop, chunks, start, states = settings.loop, settings.chunks, segment.start, segment.states
    if loop not in LOOPS:
        raise ValueError(f"unknown loop {loop!r}; choose one of {', '.join(LOOPS)}")
    check_names(model)  # names outside comments; the paths below through netgen.core.paths
    if loop != "xspice" and d.t.fb_ramp == 0:
        raise ValueError(
            f"a feedback step (fb_edge = 0) runs in the compiled loop only (--simulator ngspice-xspice), "
            f"not in the {loop!r} loop"
        )
    ic = dict(segment.ic or {})
    card = loop_card(d, start, ic) if loop == "xspice" else None
    if tone:
        tone.unit = tone_unit(model, tone)
    # only what per_clock() reads: ngspice holds every saved vector in memory (measured 27 kB per
    # period with these 11, 1.8 GB for 2^16 periods; with the 3 lead-filter outputs too, over 2 GB)
    saves = ["time"] + [f"v(b_{c})" for c in d.names] + [f"v(x_{c.name})" for c in model.coordinates]
    saves += [f"v({n})" for n in states]
    if loop != "xspice" and cycles <= SAVE_Y_PERIODS:
        saves += [f"v(y_{c})" for c in d.names]
    stop = d.ts * cycles
    progress = [f"{stop * k / chunks:.6e}" for k in range(1, chunks)]
    return render(
        TEMPLATE,
        bench="sigma_delta",
        version=__version__,
        model=model,
        d=d,
        lib=spice_card(lib, settings.folder),
        cycles=cycles,
        ports=[p["name"] for p in model.ports()],
        instance=" ".join(f"{k}={v!r}" for k, v in settings.instance),
        forces=behavioural_sources(
            force_sources(model, d, tone, start * d.ts), dict(settings.behavioural), dict(settings.devices)
        ),
        tone=tone,
        saves=saves,
        raw=raw,
        progress=progress,
        selects=selection_nodes(d),
        start=start,
        ic=ic,
        control=list(settings.control),
        sdloop=card,
        pulses=phase_pulses(d),
        osdi=loop == "osdi",
        klu=settings.klu,
        inputs=input_text(model, d),
        drivers=drivers(d) if loop == "osdi" else [],
        statefilters=(
            filters.statefilter_params(d.channels, d)
            if loop == "osdi"
            else analog_filters(d)
            if loop == "analog"
            else {}
        ),
        windows=filters.filter_windows(d.t),
        tie=TIE * d.vcmp,
    )


def analog_filters(d: Design) -> dict[str, dict]:
    """Per channel with a designed (state-space) filter, the behavioural loop's sources
    (templates/sigma_delta/tb.cir.j2): for each state j a master node m<j>_<ch> that tracks
    A u + bx (cur - x0) + bv (2 bit - 1) through the sampling switch onto C_s in the master
    window, and the state node u<j>_<ch> (filters.state_nodes) that tracks it in the slave
    window; y = c . u + d (cur - x0) - TIE vcmp. The coefficients are the design's numbers (repr).
    The switches are the samplers' (Design.g_switch, time constant 0.012 T_s): each update lands
    within 0.1-0.7 % of the largest update (trapezoidal steps of up to tmax settle geometrically,
    not as e^-t/tau); time constants of 0.025 and 0.05 T_s gave 0.3-1.1 %, 0.1 T_s 17 % (the
    z accelerometer's cifb order 4, 100 periods, reltol 1e-3 and 1e-4)."""
    out = {}
    for ch, f in zip(d.channels, filters.channel_filters(d.channels)):
        if f is None:
            continue
        name, k = ch["name"], f.states
        u = [f"u{j}_{name}" for j in range(k)]
        x = f"(v(cur_{name})-{f.x0!r})"
        v = f"(2*v({ch['bit_node']})-1)"

        def terms(row, extra):
            return " + ".join([f"{float(a)!r}*v({n})" for a, n in zip(row, u) if a] + extra) or "0"

        states = [
            {
                "m": f"m{j}_{name}",
                "u": u[j],
                "next": terms(f.a[j], [f"{float(f.bx[j])!r}*{x}", f"{float(f.bv[j])!r}*{v}"]),
            }
            for j in range(k)
        ]
        tie = [f"{-TIE * d.vcmp!r}"]
        out[name] = {
            "kind": f.kind,
            "order": f.order,
            "states": states,
            "y": terms(f.c, ([f"{float(f.d)!r}*{x}"] if f.d else []) + tie),
        }
    return out


def phase_pulses(d: Design) -> dict[str, tuple[float, ...]]:
    """PULSE(v1 v2 td tr tf pw per) of the three electrode-phase sources (seconds): phs, the
    sense phase, and fb1, fb2, the feedback phase's basis (Design.feedback_basis)."""
    t, ts, fb = d.t, d.ts, d.feedback_basis
    return {
        "phs": (
            0,
            1,
            ts * (t.sense_on - t.edge / 2),
            ts * t.edge,
            ts * t.edge,
            ts * (t.sense_off - t.sense_on - t.edge),
            ts,
        ),
        "fb1": (0, 1, 0, fb["tr1"], fb["tf"], fb["pw1"], ts),
        "fb2": (0, 1, 0, fb["tr2"], fb["tf"], fb["pw2"], ts),
    }


def loop_card(d: Design, start: int, ic: dict[str, float]) -> dict:
    """The netgen_sdloop instance of the "xspice" loop: its nodes and .model parameters (the
    same blocks, instants and dither as the analog loop; netgen/testbench/sigma_delta/netgen_sdloop). The
    loop's own state (cur, prev, b per channel) is popped from `ic` into its initial values."""
    fb = d.feedback_basis
    names = [c["name"] for c in d.channels]
    init = {kind: [ic.pop(f"{kind}_{n}", 0.0) for n in names] for kind in ("cur", "prev", "b")}
    # an electrode is energised when each channel's bit equals its feedback entry there (loop.groups,
    # loop.selected); one lead coefficient for all channels, or one per channel (leads)
    leads = [c["filter"].get("lead", 0.0) for c in d.channels]  # (a state-space channel: its flt_* path)
    lead = {"lead": leads[0]} if len(set(leads)) == 1 else {"lead": 0.0, "leads": leads}
    params = {
        "ts": d.ts,
        "t_sample": d.t.cur + d.t.sample,
        "t_latch": d.t.clk + d.t.sample,
        **lead,
        "start": float(start),
        "sel": [s for e in d.electrodes for s in e["sel"]],
        "ph_sense": [d.vs, 0.0, 0.0],
        "ph_fb": [0.0, d.vfb * fb["k1"], -d.vfb * fb["k2"]],
        # a feedback step (Timing.fb_ramp 0): V_fb on (fb_on, fb_off], with its own breakpoints
        **({"fb_level": d.vfb, "fb_on": d.t.fb_on, "fb_off": d.t.fb_off} if d.t.fb_ramp == 0 else {}),
        "ph_pulse": [float(v) for v in itertools.chain(*phase_pulses(d).values())],
        # every drive edge in ramp_steps equal steps (Design.ramp_steps; the code model's own breakpoints)
        **({"ramp_steps": int(d.ramp_steps)} if d.ramp_steps else {}),
        "dither_amp": [c["dither_v"] for c in d.channels],
        "dither_step": [float(c["dither_step"]) for c in d.channels],
        "cur0": init["cur"],
        "prev0": init["prev"],
        "b0": init["b"],
        **filters.sdloop_params(d.channels, ic),
    }  # the higher-order channels' filter states
    text = [(k, f"[{' '.join(repr(x) for x in v)}]" if isinstance(v, list) else repr(v)) for k, v in params.items()]
    nodes = [
        [f"ca_{n}" for n in names],
        None,
        [f"drv_{e['name']}" for e in d.electrodes],
        *([f"{kind}_{n}" for n in names] for kind in ("b", "cur", "prev")),
        filters.state_nodes(d.channels) or None,
    ]
    return {"params": params, "text": text, "instance": " ".join(f"[{' '.join(g)}]" if g else "NULL" for g in nodes)}


def selection_nodes(d: Design) -> dict[str, dict[str, str]]:
    """Per feedback electrode the name of its selection node, and per node its expression in the
    restored bits (the channels' bit_node: bz, bx, by for the disk; e.g. sel_zp_tilt_xn =
    v(bz)*(1-v(bx))): the electrodes share the products, so the drivers are cheap few-variable
    B-sources (bench/callgrind.py). An electrode with no feedback entry has none."""
    nodes, of = {}, {}
    for e in d.electrodes:
        used = [(c, s) for c, s in zip(d.channels, e["sel"]) if s]
        if not used:
            continue
        name = "sel_" + "_".join(f"{c['name']}{'p' if s > 0 else 'n'}" for c, s in used)
        nodes[name] = "*".join(f"v({c['bit_node']})" if s > 0 else f"(1-v({c['bit_node']}))" for c, s in used)
        of[e["name"]] = name
    return {"nodes": nodes, "of": of}


def simulate(
    netlist: str,
    workdir: Path,
    stop: float,
    progress: bool = True,
    timeout: float = 36000.0,
    span: tuple[float, float, float] | None = None,
):
    """Run ngspice on the bench, report simulated/wall time from its progress lines; return the plot.
    span (t0, total, wall0): this run continues a segmented one at t0 of total, wall0 s after its start."""
    shown = [0.0]
    start = time.perf_counter()

    def report(line: str) -> None:
        m = re.match(r"netgen-progress\s+([0-9.eE+-]+)", line)
        wall = time.perf_counter() - start
        if m and progress and wall - shown[0] > 2.0 and float(m.group(1)) > 0:
            shown[0] = wall
            t0, total, wall0 = span or (0.0, stop, 0.0)
            t, w = t0 + float(m.group(1)), wall0 + wall
            print(
                f"sigma-delta: simulated {t * 1e3:.3f} / {total * 1e3:.3f} ms, wall {w:.1f} s, "
                f"eta {w * (total / t - 1):.0f} s",
                file=sys.stderr,
                flush=True,
            )

    return run_control(netlist, workdir, "sigma_delta", "sigma_delta.raw", timeout, on_line=report)


def missed_corners(t: np.ndarray, d: Design, cycles: int) -> dict:
    """Did ngspice put a time point on every electrode-phase corner (its PULSE breakpoints)?
    The periods where one is missing (none expected; a lost breakpoint chain lets the
    trapezoidal electrode currents ring after each ramp, which the readout integrates)."""
    tc = ((np.arange(cycles)[:, None] + np.array(d.corners())[None, :]) * d.ts).ravel()
    tc = tc[(tc > 0) & (tc < t[-1])]  # t = 0: the start, not a corner
    j = np.clip(np.searchsorted(t, tc), 1, len(t) - 1)
    gap = np.minimum(np.abs(t[j] - tc), np.abs(t[j - 1] - tc))
    # a point within 1e-3 of the ramp time counts as a hit: the kink then falls inside a step at a
    # fraction gap/step of it, and so does the ringing it leaves (ngspice also lands points a few
    # ps short of a corner and keeps its chains: measured, 1.2 ps short at 1 us, chains intact)
    missed = np.unique((tc[gap > 1e-3 * d.ts * d.t.edge] / d.ts).astype(int))
    return {"periods_with_a_missed_corner": int(len(missed)), "first_period": int(missed[0]) if len(missed) else None}


def segment_periods(ts: float, segment: int | None, cycles: int) -> int:
    """Periods per ngspice segment: `segment` if given (0: the whole run in one), else
    SEGMENT_S of simulated time (at least MIN_SEGMENT periods)."""
    if segment == 0:
        return cycles
    return min(cycles, segment if segment else max(MIN_SEGMENT, round(SEGMENT_S / ts)))


LOOP_LIBRARY = codemodel.Library("netgen_sdloop", Path(__file__).resolve().parent)


def code_models(progress: bool) -> list[Path]:
    """The code-model libraries the compiled loop loads: the model's (netgen_es, for the xspice
    .lib) and the loop's own (netgen_sdloop); each built once (netgen.sim.codemodel) for the
    ngspice that runs. Where none can be built for it: a CodeModelError (exit 3) naming it, the
    ngspice builds the code models exist for, and the alternatives, before anything runs."""
    say = (lambda m: print(m, file=sys.stderr)) if progress else (lambda m: None)
    try:
        return [codemodel.build(codemodel.MODEL, progress=say), codemodel.build(LOOP_LIBRARY, progress=say)]
    except CodeModelError as exc:
        here = codemodel.target()
        there = [w for w in codemodel.built_for(LOOP_LIBRARY) if not same_build(w, here)]
        where = (
            (
                "; netgen's code models here are built for "
                + ", ".join(f"{w['version']} ({w['path']}): run on it with --ngspice {w['path']}" for w in there)
            )
            if there
            else ""
        )
        osdi = " or --simulator ngspice-osdi (the compiled path of this ngspice)" if here["osdi"] else ""
        raise CodeModelError(
            f"--simulator ngspice-xspice loads compiled code models into {here['version']} "
            f"({here['path']}) and none can be built for it{where}; or use --simulator ngspice "
            f"(the .lib){osdi}. Why: {exc}"
        ) from None


def xspice_library(model: MacroModel, out: Path, cms: list[Path]) -> tuple[Path, list[str]]:
    """The model's .lib in the xspice form (plate terms in the compiled code model), written
    to `out`, and the .control lines that load the code-model libraries `cms`."""
    lib = out / f"{model.name}_xspice.lib"
    write_files_atomic({lib: xspice.subcircuit(model)})
    return lib, codemodel.control_lines(*cms)


def run_segments(
    model: MacroModel,
    d: Design,
    lib: Path,
    out: Path,
    cycles: int,
    tone: Tone | None,
    progress: bool,
    settings: Settings = Settings(),
) -> tuple[dict, dict, dict]:
    """Run the ngspice bench in segments, each restarted at t = 0 from the node state the run
    reached: the per-clock samples, the missed corners, the plan. A segment in which ngspice
    missed an electrode-phase corner is cut at the start of that period, and the next segment
    restarts there with fresh breakpoint chains. A segment that loses the plate is the last
    (its netlist, with its .ic, stays in `out`).
    Why: ngspice 39 chains a periodic PULSE's breakpoints; once a chain breaks the electrode
    currents ring after every ramp, the readout integrates the ringing and the plate falls;
    restarting at the first missed corner never runs on a broken chain."""
    length = segment_periods(d.ts, settings.segment, cycles)
    states = state_nodes(lib, model, d, analog=settings.loop == "analog") if length < cycles else []
    parts, accepted_misses, cuts, runs = [], [], [], 0
    n0, ic, wall0 = 0, dict(settings.start_state) or None, time.perf_counter()
    while n0 < cycles:
        n = min(length, cycles - n0)
        # progress stops: one per ~100 periods (each `stop when` costs ngspice ~3 time points)
        run = replace(settings, chunks=max(1, min(50, n // 100)), folder=out)
        bench = testbench(model, d, lib, n, "sigma_delta.raw", tone, run, Segment(n0, ic, states))
        plot = simulate(
            bench,
            out,
            d.ts * n,
            progress,
            settings.timeout,
            span=(n0 * d.ts, cycles * d.ts, time.perf_counter() - wall0),
        )
        runs += 1
        t = np.asarray(plot["time"])
        first = missed_corners(t, d, n)["first_period"]
        keep = n if first is None or not states else max(first, 1)
        if keep < n:
            cuts.append({"start": n0, "missed_at": n0 + first})
        if first is not None and first < keep:  # a miss in the first period is kept: progress
            accepted_misses.append(n0 + first)
        part = per_clock(plot, d, keep, model, start=n0)
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
    breakpoints = {
        "periods_with_a_missed_corner": len(accepted_misses),
        "first_period": accepted_misses[0] if accepted_misses else None,
        "segments_cut_at_a_missed_corner": cuts,
    }
    plan = {"periods": length, "ngspice_runs": runs, "periods_run": int(n0), "state_nodes": states}
    return clock, breakpoints, plan
