"""The sigma-delta levitation loop in VACASK: the fast path for spectra-length runs.

The same circuit, loop design and timing as the ngspice bench (netgen.testbench.sigma_delta.loop,
templates/sigma_delta/tb.vacask.j2), with the macromodel as its compiled Verilog-A module
(netgen.emit.veriloga) and the loop circuitry as the small Verilog-A modules of blocks.va beside
this module (VACASK has no behavioural sources): electrode drivers that also feed their
currents into the charge amplifiers, integrators with reset, samplers, the lead filter +
comparator + clocked latch, and the smooth sampler/latch/reset clock windows. The electrode
phases are vsource pulses, as in the ngspice bench.

simulate() returns a Plot whose node voltages answer to the ngspice bench's vector names (time,
v(b_<channel>), v(y_<channel>), v(x_<coordinate>)), so analysis.per_clock()/analyse() and
everything after them are the same code for both simulators. The raw file is read through a
memory map (a 2^16-cycle run writes ~1 GB) and deleted by the caller after the per-clock sampling.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ... import __version__
from ...core.paths import vacask_string
from ...core.templating import render
from ...emit import veriloga
from ...emit.common import check_names
from ...emit.osdi import GENERIC
from ...model import MacroModel
from ...sim.rawfile import Plot
from ...sim.vacask import compiled, print_progress, run_vacask
from . import filters
from .inputs import input_text, mechanical_inputs, tone_unit
from .loop import Design, Tone

BLOCKS = Path(__file__).resolve().parent / "blocks.va"
TEMPLATE = "sigma_delta/tb.vacask.j2"
LOG = "sigma_delta.vacask.log"
# VACASK options: the ngspice bench's reltol and chgtol (maxstep is given on the analysis:
# docs/simulators.md, 'VACASK netlists'). The rest set the step control; each was measured with
# bench/vacask_options.py against the checks of tests/testbench/test_sigma_delta_vacask.py (the
# mechanics against solve_ivp over 48 periods: z 6 %, tilts and modes 1.5 % of their peak; the noise
# shaping, which sees the readout's accuracy; the momentum balance; clean latches), and the set
# against the 2^16-period spectrum (docs/performance.md):
# - tran_fbr: after every pulse corner VACASK restarts with a backward-Euler step, and every step
#   between two corners is at most tran_fbr of their distance. Only the ramps need short steps (the
#   V^2 impulse of a feedback ramp: VACASK's default 0.25 on every interval made each feedback
#   impulse 0.45 % short and z 15 % off), so the cap is VACASK's largest, 1/3, and the ramps get
#   their own bound from the clock module (RAMP_STEPS).
# - abstol=1e-6 (A; VACASK's default 1e-12): the tolerance of the flow unknowns, here the electrode
#   currents, which are algebraic (C dV/dt jumps at every ramp corner). VACASK's LTE check runs over
#   every unknown and extrapolates the current from the corner's own point, which holds the ramp's
#   current: at 1e-12 it rejected a point after each feedback corner and restarted the step at 1/4.
#   The charges, the readout's node voltages and the mechanics keep their tolerances (chgtol, vntol,
#   reltol against each unknown's own largest value; relref="allglobal", which refers them to the
#   largest of all, lost the readout's accuracy: noise shaping 2 dB against the test's 15 dB).
# - tran_lteratio=100: the remaining steps are set by the corners, the clock windows and maxstep.
# Against the previous options (tran_fbr=0.15 tran_lteratio=30 abstol=1e-12, no ramp
# bounds): 67 time points per period instead of 99, 31 % fewer instructions per period (valgrind).
# A state-space filter's sample-and-holds (blocks.va's sd_statefilter) bound their own steps in their
# windows (WINDOW_STEP): with the LTE check alone (these options or the previous ones) steps jumped
# into the windows and each update was off by up to 15 % of the state's peak
# (tests/testbench/test_sd_orders_loop.py). The gyroscope's drive block (a Device) needs no bound: its
# drive loop's checks hold with these options (tests/testbench/test_gyro_drive.py).
OPTIONS = "reltol={reltol!r} chgtol=1e-18 tran_fbr=0.3333 tran_lteratio=100 abstol=1e-6"
# a feedback step (Timing.fb_edge 0) in VACASK: its pulse source needs a rise time, so the step has
# edges of this fraction of T_s (their V^2 impulse is 2/3 of a step's: 0.08 % of the feedback at the
# default timing, a gain the reference, which takes the step as exact, does not have)
STEP_RISE = 1e-3
# Appended to OPTIONS in every bench (later settings win), e.g. "tran_fbr=0.25".
EXTRA_OPTIONS = ""
# The step bounds on the feedback ramps and on the sense ramps, as fractions of each ramp (blocks.va's
# sd_clocks: hfb, hs; None: no bounds, the cap tran_fbr alone): the feedback ramps' V^2 impulse sets
# z's error, the sense ramps the (3,0) modes' (bench/vacask_options.py; docs/performance.md).
RAMP_STEPS: tuple[float, float] | None = (0.12, 0.25)
# The step bound in the state-space filter's sample-and-hold windows (blocks.va's sd_statefilter hw), a
# fraction of T_s (0.83 of the switch's time constant C_s / g = 0.012 T_s at the default design); None:
# no bound (bench/vacask_loops.py).
WINDOW_STEP: float | None = 0.01


def blocks_source() -> str:
    """Text of blocks.va beside this module (the loop circuitry modules)."""
    return BLOCKS.read_text(encoding="utf-8")


def compile_model(model: MacroModel, cache: Path, va: Path | None = None, cpu: str = GENERIC) -> Path:
    """OSDI of the macromodel: the given .va, or the module netgen.emit.veriloga renders from the
    model (the same text the build writes; the Verilog-A tests keep the two identical), for
    openvaf-r's target `cpu` (netgen.emit.osdi.target_cpu)."""
    if va is not None and Path(va).exists():
        text = Path(va).read_text(encoding="utf-8")
    else:
        text = veriloga.module(model)
    return compiled(text, model.name, cache, cpu)


def compile_blocks(cache: Path, cpu: str = GENERIC) -> Path:
    """OSDI of the loop-circuitry modules (for openvaf-r's target `cpu`)."""
    return compiled(blocks_source(), "sigma_delta_blocks", cache, cpu)


def force_sources(model: MacroModel, d: Design, tone: Tone | None, driven: tuple[str, ...] = ()) -> list[dict]:
    """VACASK vsources per input port (inputs.mechanical_inputs): name, nodes and parameters; the
    ports in `driven` get none (a Device drives them: the gyroscope's drive loop on f_x)."""
    out = []
    for port, dc, t in mechanical_inputs(model, d, tone):
        if port in driven:
            continue
        source = f'type="sine" sinedc={dc!r} ampl={t.amplitude!r} freq={t.freq!r}' if t else f"dc={dc!r}"
        out.append({"name": port, "pos": port, "neg": "0", "source": source})
    return out


@dataclass(frozen=True)
class Device:
    """A compiled Verilog-A device in the bench that drives input ports in place of their vsources
    (the gyroscope's drive loop, netgen.testbench.gyro.run.drive_device): its OSDI file, the model
    card `model` of its `module`, its instance line's text after the name ("(nodes) model params",
    validated identifiers and numbers only) and the `ports` it drives."""

    osdi: Path
    model: str
    module: str
    name: str
    instance: str
    ports: tuple[str, ...]


def merge_options(*texts: str) -> str:
    """key=value option lists merged left to right (VACASK refuses a repeated option)."""
    merged: dict[str, str] = {}
    for text in texts:
        for item in text.split():
            key, sep, value = item.partition("=")
            if not sep:
                raise ValueError(f"VACASK option {item!r} is not key=value")
            merged[key] = value
    return " ".join(f"{k}={v}" for k, v in merged.items())


# the general electrode driver of blocks.va: up to this many channels per electrode
DRIVER_SLOTS = 4
WIDE_SLOTS = 6  # sd_driver6 (model drv6): an electrode that serves five or six channels
MAX_CHANNELS = WIDE_SLOTS


def drivers(d: Design) -> list[dict]:
    """Per electrode its blocks.va driver instance: nodes, model and parameters. An electrode
    fed back and read by exactly two channels with +-1 (the disk's z and one tilt) is sd_driver
    (model drv: side and sign select the bits and weight the two amplifiers); any other is
    sd_driver4 (model drvn: feedback entries s1..s4, sense weights w1..w4, unused slots on 0),
    or sd_driver6 (model drv6, the same with six slots) when it serves five or six channels."""
    out = []
    for e in d.electrodes:
        used = [k for k, c in enumerate(d.channels) if e["w"][k] or e["sel"][k]]
        if len(used) == 2 and all(e["w"][k] == e["sel"][k] and e["sel"][k] in (1, -1) for k in used):
            a, b = (d.channels[k]["name"] for k in used)
            out.append(
                {
                    "name": e["name"],
                    "model": "drv",
                    "nodes": [e["name"], "phs", "phf", "rst", f"b_{a}", f"b_{b}", f"ca_{a}", f"ca_{b}"],
                    "params": f"vs={d.vs} vfb={d.vfb} side={e['sel'][used[0]]} sign={e['sel'][used[1]]}",
                }
            )
            continue
        if len(used) > WIDE_SLOTS:
            raise ValueError(
                f"electrode {e['name']} serves {len(used)} channels; the Verilog-A driver takes at most {WIDE_SLOTS}"
            )
        width = DRIVER_SLOTS if len(used) <= DRIVER_SLOTS else WIDE_SLOTS
        slots = used + [None] * (width - len(used))
        names = [d.channels[k]["name"] if k is not None else None for k in slots]
        params = [f"vs={d.vs} vfb={d.vfb}"] + [
            f"s{j + 1}={e['sel'][k]} w{j + 1}={e['w'][k]}" for j, k in enumerate(slots) if k is not None
        ]
        out.append(
            {
                "name": e["name"],
                "model": "drvn" if width == DRIVER_SLOTS else "drv6",
                "nodes": [e["name"], "phs", "phf", "rst"]
                + [f"b_{n}" if n else "0" for n in names]
                + [f"ca_{n}" if n else "0" for n in names],
                "params": " ".join(params),
            }
        )
    return out


def saves(model: MacroModel, d: Design) -> list[str]:
    """Node voltages per_clock() and the comparisons need: bits, lead-filter outputs, coordinates."""
    names = [f"b_{c}" for c in d.names] + [f"y_{c}" for c in d.names] + [f"x_{c.name}" for c in model.coordinates]
    return [f"v({n})" for n in names]  # bare node names would be ignored (all nodes saved)


def testbench(
    model: MacroModel,
    d: Design,
    model_osdi: Path,
    blocks_osdi: Path,
    cycles: int,
    tone: Tone | None = None,
    options: str = "",
    folder: Path | None = None,
    devices: tuple[Device, ...] = (),
    instance: tuple[tuple[str, float], ...] = (),
    extra_saves: tuple[str, ...] = (),
) -> str:
    """The VACASK netlist of the loop (templates/sigma_delta/tb.vacask.j2); its loads relative to
    `folder`, where it runs, for what lies inside it (netgen.core.paths.vacask_string), else absolute;
    `devices`: Verilog-A devices that drive input ports in place of their vsources; `instance`: the
    module's process parameters (netgen.emit.process.va_params) on its model card (model parameters,
    not instance ones); `extra_saves`: more vectors to save (e.g. a state filter's internal nodes,
    'v("xf_z:u1")'). Step control: OPTIONS, RAMP_STEPS and WINDOW_STEP."""
    check_names(model)  # names outside comments; the paths below through netgen.core.paths
    if tone:
        tone.unit = tone_unit(model, tone)
    statefilters = filters.statefilter_params(d.channels, d)
    if WINDOW_STEP:
        statefilters = {k: f"{v} hw={WINDOW_STEP!r}" for k, v in statefilters.items()}
    ports = ["0" if p["name"] == model.plate else p["name"] for p in model.ports()]
    return render(
        TEMPLATE,
        bench="sigma_delta",
        version=__version__,
        model=model,
        d=d,
        model_osdi=vacask_string(model_osdi if folder else Path(model_osdi).resolve(), folder),
        blocks_osdi=vacask_string(blocks_osdi if folder else Path(blocks_osdi).resolve(), folder),
        cycles=cycles,
        ports=ports,
        forces=force_sources(model, d, tone, tuple(p for dev in devices for p in dev.ports)),
        devices=[
            {
                "osdi": vacask_string(dev.osdi if folder else Path(dev.osdi).resolve(), folder),
                "model": dev.model,
                "module": dev.module,
                "name": dev.name,
                "instance": dev.instance,
            }
            for dev in devices
        ],
        tone=tone,
        saves=saves(model, d) + list(extra_saves),
        drivers=drivers(d),
        instance=" ".join(f"{k}={v!r}" for k, v in instance),
        inputs=input_text(model, d),
        statefilters=statefilters,
        step_rise=STEP_RISE,
        ramp_steps=RAMP_STEPS,
        options=merge_options(OPTIONS.format(reltol=d.reltol), EXTRA_OPTIONS, options),
    )


def simulate(netlist: str, workdir: Path, stop: float, progress: bool = True, timeout: float = 36000.0) -> Plot:
    """Run VACASK on the bench in workdir, report simulated/wall time (from the raw file VACASK
    streams); return the memory-mapped plot of tran1.raw."""
    return run_vacask(
        netlist,
        workdir,
        "tran1",
        "sigma_delta",
        timeout,
        LOG,
        print_progress("sigma-delta (vacask)", stop) if progress else None,
        mapped=True,
    )


@dataclass(frozen=True)
class BenchOptions:
    """How run_bench compiles and runs: the model's .va (None: emitted from the model), the compile
    `cache` (None: out/osdi), extra VACASK `options`, the wall-clock `timeout` (s) and openvaf-r's
    target `cpu`; `devices`: Verilog-A devices driving input ports (Device)."""

    va: Path | None = None
    cache: Path | None = None
    options: str = ""
    timeout: float = 36000.0
    cpu: str = GENERIC
    devices: tuple[Device, ...] = ()
    # the process point (name, value; netgen.sweep) on the model card (the .va's process parameters are
    # model parameters) and the model the module is compiled from when the run's `model` is that
    # point's copy (design, analysis)
    instance: tuple[tuple[str, float], ...] = ()
    nominal: MacroModel | None = None
    saves: tuple[str, ...] = ()  # vectors saved besides saves()'s (testbench's extra_saves)


def run_bench(
    model: MacroModel,
    d: Design,
    out: Path,
    cycles: int,
    tone: Tone | None = None,
    progress: bool = True,
    how: BenchOptions = BenchOptions(),
) -> Plot:
    """Compile (cached, for openvaf-r's target `how.cpu`), render and run the VACASK bench in `out`;
    return its plot."""
    cache = how.cache or out / "osdi"
    model_osdi = compile_model(how.nominal or model, cache, how.va, how.cpu)
    blocks_osdi = compile_blocks(cache, how.cpu)
    bench = testbench(
        model,
        d,
        model_osdi,
        blocks_osdi,
        cycles,
        tone,
        how.options,
        folder=out,
        devices=how.devices,
        instance=how.instance,
        extra_saves=how.saves,
    )
    return simulate(bench, out, d.ts * cycles, progress, how.timeout)
