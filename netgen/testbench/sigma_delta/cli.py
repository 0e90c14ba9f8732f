"""`netgen sigma-delta STRUCTURE.toml -o DIR`: the sigma-delta force-feedback loop (the paper's
levitation loop, for any device: the structure's [loop] table or --loop LOOP.toml) around the
structure's macromodel, with spectra (netgen.testbench.sigma_delta.runner)."""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterable
from dataclasses import replace
from pathlib import Path

from ...core.errors import SimulationError
from ...core.options import Option, OptionError
from ...emit.paired import load_pair
from ...model import MacroModel
from ...runtime.arguments import add_options
from ...runtime.folders import OutputFolder
from ...structure import load_structure
from .loop import Choices, Tone
from .loopfile import read_loop_file, read_structure_loop
from .options import OPTIONS, read_tone
from .runner import (
    BuildOptions,
    RunRequest,
    backend_design,
    damping_problem,
    model_folder,
    model_for,
    run,
)

# the run's result set in DIR (sigma-delta.manifest.json names it) and the caches it shares with
# earlier runs there (compiled Verilog-A, by content hash)
RESULTS = "sigma-delta"
SHARED = ("osdi",)
# the files a run writes (its set when a folder from before manifests holds them)
RESULT_FILES = (
    "bitstreams.npz",
    "spectra.npz",
    "summary.json",
    "spectra.png",
    "coordinates.png",
    "sigma_delta.cir",
    "sigma_delta.log",
    "sigma_delta.sim",
    "sigma_delta.vacask.log",
)


def check_arguments(args) -> Tone | None:
    """The checks that involve more than one argument (each flag's own range is its declared
    option's, checked by argparse): the tone below f_s/2, the gas options against the structure,
    and the combinations that cannot run; ValueError naming the flags and the fix."""
    tone = None
    if args.tone is not None:
        try:
            tone = Tone(*read_tone(args.tone, "--tone", args.ts))
        except OptionError as exc:
            raise ValueError(str(exc)) from None
    if args.model and (args.rigid_only or args.pressure is not None or args.film or args.noise):
        raise ValueError(
            "--rigid-only, --pressure, --film and --noise rebuild the model from the structure file; drop --model"
        )
    if args.pressure is not None or args.film is not None:
        check_damping(args)
    if args.segment and args.simulator == "ngspice-osdi":
        raise ValueError(
            f"--segment {args.segment}: --simulator ngspice-osdi runs in one segment (ngspice's "
            ".ic cannot set the OSDI module's internal states a restart needs); drop --segment"
        )
    if args.noise and args.simulator in ("vacask", "ngspice-osdi"):
        raise ValueError(
            f"--noise needs --simulator ngspice: {args.simulator} runs the .va, whose "
            "white_noise acts in noise analyses only (no transient noise sources)"
        )
    return tone


def check_damping(args) -> None:
    """--pressure and --film through the structure's own check of its [damping] table (a device
    whose structure refuses squeeze_film or this film_model in the file refuses the flag too)."""
    structure = load_structure(args.structure)  # StructureError: exit 2
    for name, value in (("pressure", args.pressure), ("film", args.film)):
        if value is not None:
            given = {"pressure": args.pressure if name == "pressure" else None, name: value}
            damping = {"damping": lambda v, g=given: damping_problem(args.structure, structure, **g)}
            try:
                OPTIONS[name].read(value, f"--{name}", damping)
            except OptionError as exc:
                raise ValueError(f"{exc.problem}; drop --{name} for {args.structure}") from None


def run_model(args, out: Path) -> tuple[MacroModel, Path]:
    """The model of the run: --model's, or built (or reused) in DIR/model... with the options."""
    if args.model:
        return load_pair(args.model)  # the .json and its .lib, checked to match (exit 2)
    build = BuildOptions(args.rigid_only, args.pressure, args.film, args.noise)
    return model_for(args.structure, model_folder(out, build), build, rebuild=args.rebuild, progress=not args.quiet)


def cli(args) -> int:
    """`netgen sigma-delta`: build or reuse the model, run the loop, write DIR/summary.json etc."""
    out = Path(args.output)
    try:
        tone = check_arguments(args)
    except ValueError as exc:
        print(f"netgen: {exc}", file=sys.stderr)
        return 2
    loop = read_loop_file(args.loop) if args.loop else read_structure_loop(args.structure)  # LoopError: exit 2
    model, lib = run_model(args, out)
    inputs = [c.name for c in model.coordinates] + (["a_in"] if model.acceleration else [])
    inputs += list(model.inertial.participation)  # a_x, a_y (netgen.model.inertial)
    if tone and tone.coord not in inputs:
        print(
            f"netgen: --tone {args.tone}: the model has no coordinate {tone.coord!r}; choose one of "
            f"{', '.join(inputs)}",
            file=sys.stderr,
        )
        return 2
    request = RunRequest(
        args.ts,
        args.cycles,
        tone,
        progress=not args.quiet,
        plots=not args.no_plots,
        simulator=args.simulator,
        segment=args.segment,
        timeout=args.timeout,
        choices=Choices.of(vars(args)),
        native=args.native,
    )
    # the loop checked against the model before any output (LoopError: exit 2)
    d = backend_design(model, request.ts, loop, tone or loop.input.tone, request.simulator, request.choices)
    s = run_in_folder(args, out, model, lib, replace(request, loop=loop, designed=d))
    if not args.quiet:
        report(s, out)
    lev = s["levitation"]
    if not lev["held"]:
        print(
            f"netgen: the loop lost the plate at period {lev['lost_at_period']} ({lev['coordinate']} = "
            f"{lev['value']:.4g}, beyond {lev['limit']:.3g} in port units); the spectra describe a plate at "
            f"the stop.{lost_hint(s)} Results in {out}",
            file=sys.stderr,
        )
        return 1
    return 0


def run_in_folder(args, out: Path, model: MacroModel, lib: Path, request: RunRequest) -> dict:
    """The run inside DIR's result set (all or nothing; a failed run's files kept apart)."""
    info = {
        "arguments": {k: v for k, v in vars(args).items() if isinstance(v, (str, int, float, bool, type(None)))},
        "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
    inside = lib_folder(lib, out)
    with OutputFolder(
        out,
        RESULTS,
        info,
        keep_failed=True,
        shared=SHARED + ((inside,) if inside else ()),
        legacy=RESULT_FILES + (f"{model.name}_xspice.lib", f"{model.name}_osdi.lib"),
    ) as folder:
        staged = folder.stage / inside / Path(lib).name if inside else lib  # through the stage's link
        try:
            s = run(model, staged, folder.stage, request)
        except SimulationError as exc:  # its paths: where the failed run's files are kept
            raise SimulationError(
                folder.failed_path(str(exc)) + f"; the last complete results are still in "
                f"{out} ({folder.manifest.name})"
            ) from None
        folder.commit()
    return s


def report(s: dict, out: Path) -> None:
    """The run's summary lines: per channel bits, floor, SNR; the thermal floor; the balance."""
    for c, ch in s["channels"].items():
        snr = f", SNR {ch['snr_db']:.1f} dB" if "snr_db" in ch else ""
        snr += f", SQNR {ch['sqnr_db']:.1f} dB (sine fit)" if "sqnr_db" in ch else ""
        floor = ch["noise_floor_db_per_hz"]
        floor = "n/a (run too short)" if floor is None else f"{floor:.1f} dB/Hz"
        print(
            f"{c}: bit mean {ch['bit_mean']:+.4f}, in-band floor {floor}"
            f"{snr}, {len(ch['notches'])} notches, {len(ch['peaks'])} peaks"
        )
    gb = s["gravity_balance"]
    th = s["thermal_noise"]["channels"]
    if any(v["thermal_floor_db_per_hz"] is not None for v in th.values()):
        print(
            "gas-film Brownian force floor (dB re F_fb^2/Hz): "
            + ", ".join(
                f"{c} {v['thermal_floor_db_per_hz']:.1f}" for c, v in th.items() if v["thermal_floor_db_per_hz"]
            )
        )
    ratio = (
        f"mean feedback force / weight = {gb['ratio']:.4f}"
        if gb["ratio"] is not None
        else f"mean feedback force - input on {gb['channel']} = {gb['residual_n']:.3g} N"
    )
    print(f"{ratio}; wrote {out / 'summary.json'} ({s['wall_s']:.0f} s)")


def lib_folder(lib: Path, out: Path) -> str | None:
    """The sub-folder of DIR that holds the model's .lib (DIR/model..., model_folder), which the
    staging folder links (OutputFolder shared), so the kept netlist `.include`s it relative to DIR
    and reruns there by hand; None for a .lib elsewhere (--model's: included by its absolute path)."""
    parent, base = Path(os.path.abspath(Path(lib).parent)), Path(os.path.abspath(out))
    return parent.name if parent.parent == base and parent.name not in SHARED else None


def lost_hint(s: dict) -> str:
    """What the summary says about a lost plate: missed breakpoints, partial latch decisions."""
    hints = []
    bp = s.get("breakpoints") or {}
    if bp.get("periods_with_a_missed_corner"):
        hints.append(
            f"ngspice missed an electrode-phase corner in {bp['periods_with_a_missed_corner']} "
            f"period(s), first {bp['first_period']} (docs/sigma-delta.md)"
        )
    seg = s.get("segments") or {}
    if seg.get("state_nodes") and seg.get("periods_run", 0) < s.get("requested_cycles", 0):
        hints.append(
            f"ngspice stopped after the segment that lost it ({seg['periods_run']} of "
            f"{s['requested_cycles']} periods; its netlist with the restart state is DIR/sigma_delta.cir)"
        )
    partial = {c: v.get("partial_latches") for c, v in s["channels"].items() if v.get("partial_latches")}
    if partial:
        hints.append(f"partial latch decisions {partial}")
    return (" Diagnostics: " + "; ".join(hints) + ".") if hints else ""


def add_parser(sub, options: Iterable[Option] | None = None) -> None:
    """The `sigma-delta` subcommand's arguments: every declared option with a flag (`options`, else
    options.OPTIONS)."""
    p = sub.add_parser(
        "sigma-delta",
        help="run the sigma-delta force-feedback loop (the paper's levitation loop, "
        "for any device) in ngspice or VACASK, with spectra",
    )
    add_options(p, OPTIONS.values() if options is None else options)
    p.set_defaults(func=cli)
