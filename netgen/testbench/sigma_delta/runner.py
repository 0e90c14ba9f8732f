"""A sigma-delta run from a model to its outputs: design, simulate on a back end, analyse, write
bitstreams.npz, spectra.npz, summary.json and the PNGs; and the model a run uses, built or reused.

BACKENDS maps `--simulator` to the back end that runs the loop: ngspice with the behavioural-
source loop, ngspice with both code models (the model's electrostatics and the compiled loop),
VACASK with the compiled Verilog-A model, or ngspice with that model and VACASK's loop blocks
through OSDI. Adding one is a module beside ngspice.py and
vacask.py and one line here.
"""

from __future__ import annotations

import json
import time
import tomllib
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from ...build import build_key, build_model
from ...core.errors import LoopError, SimulatorNotFound, StructureError
from ...core.reader import Reader
from ...emit import write_outputs
from ...emit.osdi import target_cpu
from ...model import MacroModel
from ...runtime.folders import MANIFEST, OutputFolder, check_manifest
from ...sim.ngspice import identity as ngspice_identity
from ...sim.ngspice import version as ngspice_version
from ...sim.vacask import stats as vacask_stats
from ...sim.vacask import tools as vacask_tools
from ...structure import Damping, load_structure
from . import ngspice, osdi, report, vacask
from .analysis import analyse, levitation, per_clock, thermal_floor
from .loop import FILTERS, Choices, Design, Tone, design
from .loopfile import InputSpec, LoopSettings, LoopSpec
from .options import TIMEOUT
from .plots import plot_spectra, plot_states


@dataclass(frozen=True)
class Backend:
    """prepare(model, lib, out, progress, cpu) -> state: what must exist before the timed run (code
    models built, Verilog-A compiled for openvaf-r's target `cpu`), failing before any output; run(model, design, lib, out,
    request, state) -> (clock, extra summary entries): the RunRequest's cycles, tone (the one the
    run simulates), progress and segment."""

    prepare: Callable[..., dict]
    run: Callable[..., tuple[dict, dict]]
    help: str


def _no_preparation(model: MacroModel, lib: Path, out: Path, progress: bool, cpu: str) -> dict:
    return {}


def _code_models(model: MacroModel, lib: Path, out: Path, progress: bool, cpu: str) -> dict:
    return {"cms": ngspice.code_models(progress)}


def _run_ngspice(model: MacroModel, d: Design, lib: Path, out: Path, r: RunRequest, state: dict) -> tuple[dict, dict]:
    """The behavioural-source loop around the .lib, or (with code models) the compiled loop around
    the xspice .lib, or (osdi) the blocks.va loop around the _osdi.lib, in segments
    (ngspice.run_segments). The B-source .lib runs with KLU where the ngspice has it (25 % less
    CPU on ngspice 46; the OSDI and code-model forms gain nothing or are not built for it)."""
    cycles, tone, progress, segment = r.cycles, r.tone, r.progress, r.segment
    control, loop, klu = [], "analog", False
    if "cms" in state:
        lib, control = ngspice.xspice_library(r.nominal or model, out, state["cms"])
        loop = "xspice"
    elif "osdi" in state:  # osdi.prepare: the _osdi.lib and its pre_osdi lines
        lib, control, loop = state["osdi"]["lib"], state["osdi"]["control"], "osdi"
        segment = 0  # one run: .ic cannot reach the module's states (osdi.py)
    else:
        klu = ngspice_version().klu
    settings = ngspice.Settings(
        loop, control, klu, segment=segment, timeout=state.get("timeout", TIMEOUT), instance=r.instance
    )
    clock, breakpoints, segments = ngspice.run_segments(model, d, lib, out, cycles, tone, progress, settings)
    return clock, {
        "breakpoints": breakpoints,
        "segments": segments,
        "ngspice": ngspice_identity(),
        "solver": "klu" if klu else "sparse",
        **({"target_cpu": state["target_cpu"]} if "target_cpu" in state else {}),
    }


def _compile_osdi(model: MacroModel, lib: Path, out: Path, progress: bool, cpu: str) -> dict:
    return {"osdi": osdi.prepare(model, lib, out, progress, cpu), "target_cpu": cpu}


def _compile_vacask(model: MacroModel, lib: Path, out: Path, progress: bool, cpu: str) -> dict:
    """Compile the model (the .va next to `lib`, else the emitted module) and the loop blocks for
    openvaf-r's target `cpu`, cached in out/osdi, outside the run's wall time."""
    va = Path(lib).with_suffix(".va")
    va = va if va.exists() else None
    start = time.perf_counter()
    vacask.compile_model(model, out / "osdi", va, cpu)
    vacask.compile_blocks(out / "osdi", cpu)
    return {"va": va, "compile_s": time.perf_counter() - start, "target_cpu": cpu}


def _run_vacask(model: MacroModel, d: Design, lib: Path, out: Path, r: RunRequest, state: dict) -> tuple[dict, dict]:
    """The same loop in VACASK, one run; the raw file is dropped after the per-clock sampling."""
    cycles = r.cycles
    how = vacask.BenchOptions(
        va=state["va"],
        timeout=state.get("timeout", TIMEOUT),
        cpu=state["target_cpu"],
        instance=r.instance,
        nominal=r.nominal,
    )
    plot = vacask.run_bench(model, d, out, cycles, r.tone, r.progress, how)
    extra = {
        "compile_s": state["compile_s"],
        "target_cpu": state["target_cpu"],
        "vacask": vacask_stats(out / vacask.LOG),
    }
    clock = per_clock(plot, d, cycles, model)
    del plot
    (out / "tran1.raw").unlink(missing_ok=True)
    return clock, extra


BACKENDS: dict[str, Backend] = {
    "ngspice": Backend(_no_preparation, _run_ngspice, "ngspice with the .lib (behavioural sources)"),
    "ngspice-xspice": Backend(
        _code_models,
        _run_ngspice,
        "ngspice with the model's plate terms in the compiled "
        "XSPICE code model and the loop compiled too (netgen codemodel)",
    ),
    "vacask": Backend(_compile_vacask, _run_vacask, "VACASK with the compiled Verilog-A module"),
    "ngspice-osdi": Backend(
        _compile_osdi,
        _run_ngspice,
        "ngspice 45+ with the model and the loop's blocks as Verilog-A compiled by openvaf-r, loaded through OSDI",
    ),
}
SIMULATORS = tuple(BACKENDS)
# the back ends that render a feedback step (Timing.fb_edge = 0; netgen_sdloop's fb_level, VACASK's pulse)
STEP_BACKENDS = ("ngspice-xspice", "vacask")


def simulator_problem(name: str) -> str | None:
    """Why the back end `name` cannot run here (its simulator missing, or an ngspice too old for
    OSDI: osdi.check's verdict), else None; for a sweep's dry run, before any run."""
    try:
        if name == "vacask":
            vacask_tools()
        else:
            v = ngspice_version()
            if name == "ngspice-osdi" and not v.osdi:
                return (
                    f"{v.label} ({v.path}) cannot load openvaf-r's OSDI 0.5 modules (ngspice 44 and later do); "
                    f"{osdi.ALTERNATIVES}"
                )
    except SimulatorNotFound as exc:
        return str(exc)
    return None


def check_backend(d: Design, spec: LoopSpec, simulator: str) -> None:
    """Every channel's loop filter is one this back end renders (FilterKind.backends), else a
    LoopError naming the kind and the back ends that do; likewise a feedback step (Timing.fb_edge 0)."""
    for ch in d.channels:
        kind = FILTERS[ch["filter"]["kind"]]
        if simulator not in kind.backends:
            raise spec.fail(
                f"loop.channels.{ch['name']}.filter.kind",
                f"loop filter {ch['filter']['kind']!r} is not implemented for --simulator {simulator}",
                f"use --simulator {' or '.join(kind.backends)}",
            )
    if d.t.fb_ramp == 0 and simulator not in STEP_BACKENDS:
        raise spec.fail(
            "loop.timing.fb_edge",
            f"a feedback step (fb_edge = 0) is not implemented for --simulator {simulator}",
            f"use --simulator {' or '.join(STEP_BACKENDS)}, or give [loop.timing] fb_edge = 0.02 (ramps)",
        )
    if d.ramp_steps and simulator != "ngspice-xspice":  # the compiled loop's breakpoints (netgen_sdloop)
        raise spec.fail(
            "loop.ramp_steps",
            f"ramp_steps = {d.ramp_steps} is implemented for --simulator ngspice-xspice only, not {simulator}",
            "use --simulator ngspice-xspice, or drop ramp_steps (--ramp-steps)",
        )


@dataclass(frozen=True)
class RunRequest:
    """One run's settings: T_s, periods, the tone (else the description's), progress and plots,
    `skip` (periods left out of the spectra; None: an eighth), the BACKENDS name, ngspice's
    `segment`, the simulator `timeout`, the loop description `loop` (None: the model's defaults)
    with a caller's `feedback_voltage` and DC `acceleration` over it, and `designed`: the caller's
    backend_design of the same model, loop, tone and choices (else designed in run)."""

    ts: float
    cycles: int
    tone: Tone | None = None
    progress: bool = True
    plots: bool = True
    skip: int | None = None
    simulator: str = "ngspice"
    segment: int | None = None
    timeout: float = TIMEOUT
    loop: LoopSpec | None = None
    designed: Design | None = None
    choices: Choices = Choices()
    feedback_voltage: float | None = None
    acceleration: float | None = None
    native: bool = False  # compile the Verilog-A for this CPU, not the x86-64 baseline (emit.osdi.target_cpu)
    # instance parameters on the model's line (a process point, netgen.sweep) in every back end's form,
    # and the model those forms are emitted from when `model` is that point's copy (netgen.sweep.point.at_point:
    # the design and analysis read it; emitting it would apply the point twice)
    instance: tuple[tuple[str, float], ...] = ()
    nominal: MacroModel | None = None


def backend_design(
    model: MacroModel, ts: float, loop: LoopSpec, tone: Tone | None, simulator: str, choices: Choices
) -> Design:
    """The loop's design (loop.design with the caller's choices) for this back end: a designed
    filter gets the feedback step where the back end renders one; refused (LoopError) where it
    cannot render the design (check_backend)."""
    d = design(model, ts, choices, spec=loop, tone=tone, step=simulator in STEP_BACKENDS)
    check_backend(d, loop, simulator)
    return d


def overridden(loop: LoopSpec, feedback_voltage: float | None, acceleration: float | None) -> LoopSpec:
    """The loop description with a sweep's (or caller's) feedback voltage and DC acceleration on a_in."""
    if feedback_voltage is not None:
        loop = replace(loop, settings=LoopSettings(feedback_voltage=feedback_voltage).over(loop.settings))
    if acceleration is not None:
        dc = {k: v for k, v in loop.input.dc.items() if k == "a_in"} | {"a_in": acceleration}
        loop = replace(loop, input=InputSpec(dc, loop.input.tone if not loop.input.default else None, default=False))
    return loop


def run(model: MacroModel, lib: Path, out: Path, request: RunRequest) -> dict:
    """Design, simulate and analyse; write bits .npz, PNGs, summary.json and report.html into `out`.
    request.simulator: a BACKENDS name ("ngspice" runs the .lib `lib`; "ngspice-xspice" the model
    emitted with its plate terms in the compiled code model; "vacask" the compiled Verilog-A
    module, the .va next to `lib` or else the module emitted from `model`)."""
    r = request
    simulator, ts, cycles = r.simulator, r.ts, r.cycles
    if simulator not in BACKENDS:
        raise ValueError(f"unknown simulator {simulator!r}; choose one of {', '.join(BACKENDS)}")
    backend = BACKENDS[simulator]
    loop = overridden(r.loop or LoopSpec(), r.feedback_voltage, r.acceleration)
    tone = r.tone or loop.input.tone
    d = r.designed if r.designed is not None else backend_design(model, ts, loop, tone, simulator, r.choices)
    if len(d.channels) > vacask.MAX_CHANNELS and simulator in ("vacask", "ngspice-osdi"):
        raise LoopError(
            loop.source,
            "loop.channels",
            f"{len(d.channels)} channels: the Verilog-A loop takes at most {vacask.MAX_CHANNELS}",
            "close the loop on fewer coordinates, or use --simulator ngspice or ngspice-xspice",
        )
    state = backend.prepare(r.nominal or model, lib, out, r.progress, target_cpu(r.native))  # fails before any output
    state["timeout"] = r.timeout  # the wall-clock limit of each simulator run
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    clock, extra = backend.run(model, d, lib, out, replace(r, tone=tone), state)
    wall = time.perf_counter() - start
    np.savez_compressed(out / "bitstreams.npz", **clock)
    done = len(clock["time"])  # fewer than `cycles` if a segment lost the plate
    skip = done // 8 if r.skip is None else min(r.skip, done // 2)
    summary = analyse(clock, d, tone, skip=skip)
    summary["levitation"] = levitation(clock, model)
    spectra = summary.pop("spectra")
    np.savez_compressed(
        out / "spectra.npz", **{f"{c}_{k}": v for c, (fr, p) in spectra.items() for k, v in (("f", fr), ("psd", p))}
    )
    summary.update(
        {
            "requested_cycles": cycles,
            "model": model.name,
            "coordinates_in_model": [c.name for c in model.coordinates],
            "thermal_noise": thermal_floor(model, d),
            "simulator": simulator,
            **extra,
            "wall_s": wall,
            "tone": asdict(tone) if tone else None,
            "design": {
                "channels": d.names,
                "electrodes": d.electrodes,
                "table": d.table,
                "cf": {c["name"]: c["cf"] for c in d.channels},
                "filters": {c["name"]: c["filter"] for c in d.channels},
                "inputs": d.inputs,
                "balance": d.balance,
                "timing": asdict(d.t),
                "duty": d.duty,
                "reltol": d.reltol,
            },
        }
    )
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    if r.plots:
        plot_spectra(
            summary | {"spectra": spectra},
            out / "spectra.png",
            f"{model.name}: T_s = {ts * 1e6:g} us, {cycles} cycles ({simulator})",
        )
        plot_states(clock, out / "coordinates.png")
    report.write(out, summary)  # the page to open (netgen.testbench.sigma_delta.report)
    return summary | {"spectra": spectra, "clock": clock}


# ----------------------------------------------------------------------------- the run's model


@dataclass(frozen=True)
class BuildOptions:
    """The sigma-delta command's options that rebuild the model: rigid-body only (modes = 0), the
    squeeze film's gas `pressure` and `film` model, thermal `noise` sources."""

    rigid_only: bool = False
    pressure: float | None = None
    film: str | None = None
    noise: bool = False


def with_damping(structure, pressure: float | None, film: str | None, noise: bool):
    """The structure with the sigma-delta command's gas and noise options applied to [damping]."""
    if pressure is None and film is None and not noise:
        return structure
    d = structure.damping or Damping()
    if pressure is not None:
        d = replace(d, squeeze_film=True, pressure=pressure)
    if film is not None:
        d = replace(d, squeeze_film=True, film_model=film)
    return replace(structure, damping=replace(d, noise=noise or d.noise))


def damping_problem(path: str | Path, structure, pressure: float | None = None, film: str | None = None) -> str | None:
    """The structure's own verdict (its conductor's check) on a [damping] table with the gas
    options as with_damping applies them: the problem, or None where the file would accept them."""
    text = Path(path).read_text(encoding="utf-8")
    doc = tomllib.loads(text)
    damping = dict(doc.get("damping") or {}) | {"squeeze_film": True}
    damping |= {"pressure": pressure} if pressure is not None else {}
    damping |= {"film_model": film} if film is not None else {}
    try:
        structure.conductor.check(
            Reader(str(path), text),
            doc | {"damping": damping},
            structure.electrode_sets,
            structure.coordinates,
            structure.fem,
        )
    except StructureError as exc:
        return f"{exc.problem} ({structure.name}'s [damping] refuses it as {exc.where})"
    return None


def model_folder(out: Path, build: BuildOptions = BuildOptions()) -> Path:
    """DIR/model..., one folder per option set, so a cached model never answers for other options."""
    tags = (
        ["model"]
        + (["rigid"] if build.rigid_only else [])
        + ([f"p{build.pressure:g}Pa"] if build.pressure is not None else [])
        + ([build.film] if build.film else [])
        + (["noise"] if build.noise else [])
    )
    return out / "_".join(tags)


def model_for(
    structure_path: str | Path,
    folder: Path,
    build: BuildOptions = BuildOptions(),
    *,
    rebuild: bool = False,
    progress: bool = True,
) -> tuple[MacroModel, Path]:
    """Build the structure's model into `folder` with the `build` options (rigid-body only: modes
    = 0; gas film at its pressure, thermal noise sources), or reuse the .json/.lib (and .va) there
    when the set there was built from the same content (netgen.build.build_key, kept in the
    set's manifest): editing only the [loop] table, or touching the file, rebuilds nothing."""
    structure = with_damping(load_structure(structure_path), build.pressure, build.film, build.noise)
    if build.rigid_only:
        structure = replace(structure, coordinates=replace(structure.coordinates, modes=0))
    js, lib = folder / f"{structure.name}.json", folder / f"{structure.name}.lib"
    key = build_key(structure)
    if not rebuild and cached_key(folder, structure.name) == key and js.exists() and lib.exists():
        return MacroModel.load_json(js), lib
    model = build_model(structure, progress=progress)
    with OutputFolder(
        folder, model.name, info={"build_key": key}
    ) as out:  # all or nothing, also against a concurrent run
        write_outputs(model, out.stage, "all")  # .lib for ngspice, .va for the VACASK path
        out.commit()
    return model, lib


def cached_key(folder: Path, name: str) -> str | None:
    """The build key of the model set `name` in `folder` (its manifest's), or None when there
    is none, it predates build keys, or a file of the set is missing or altered."""
    try:
        key = json.loads((folder / f"{name}{MANIFEST}").read_text(encoding="utf-8")).get("build_key")
    except (OSError, ValueError, AttributeError):
        return None
    return key if isinstance(key, str) and not check_manifest(folder, name) else None
