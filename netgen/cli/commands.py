"""Command line: `netgen build STRUCTURE.toml -o DIR` and friends. Errors exit with the code of
their class (netgen.core.errors: 2 bad input, 3 missing tool, 1 failed run), never a traceback: an
interrupt (SIGINT or SIGTERM) is 130, anything unexpected 70 with its traceback in a crash log."""

from __future__ import annotations

import argparse
import os
import signal
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from .. import __version__
from ..build import build, figure_names, write_calibration, write_figures
from ..core.errors import InputError, NetgenError, StructureError
from ..emit import EMITTERS, compiles, fmu, osdi, refusal, report, requested, write_outputs
from ..model import FIT_FIX
from ..runtime.arguments import Parser, add_options
from ..runtime.executor import executor
from ..runtime.folders import OutputFolder
from ..runtime.interrupts import EXIT_INTERRUPTED, check, install, internal_error, interrupted, restore
from ..runtime.options import build_options, simulate_options
from ..sim import SIMULATORS, codemodel, netlist_text, ngspice
from ..structure import load_structure
from ..sweep import cli as sweep_cli
from ..testbench import TESTBENCHES
from ..testbench.sigma_delta.ngspice import LOOP_LIBRARY

# ----------------------------------------------------------------------------- netgen build


def _build(args: argparse.Namespace) -> int:
    start = time.perf_counter()
    structure = load_structure(args.structure)
    with sampling(args) as parallel:  # --scheduler / --sample-store (netgen.electrostatics.sampling)
        result = build(structure, progress=not args.quiet, max_minutes=args.max_minutes, **parallel)
    model = result.model
    for warning in structure.warnings:  # netgen.structure.validity
        print(f"netgen: warning: {args.structure}: {warning}", file=sys.stderr)
    if model.fit_warning():  # a fit that misses [fit] tolerance (MacroModel.fit_misses)
        if args.strict:
            raise StructureError(args.structure, "[fit] tolerance", f"{model.fit_problem()} (--strict)", FIT_FIX)
        print(f"netgen: warning: {args.structure}: {model.fit_warning()}", file=sys.stderr)
    note = model.report.get("inertial", {}).get("uncoupled_note")
    if note:  # an inertial input that moves nothing (netgen.mechanics.inertial.report)
        print(f"netgen: note: {args.structure}: {note}", file=sys.stderr)
    for fmt in requested(args.format):
        if fmt != "all" and refusal(model, fmt):
            print(f"netgen: {args.structure}: --format {fmt}: {refusal(model, fmt)}", file=sys.stderr)
            return 2
    cpu = osdi.target_cpu(args.native)
    info = compiled_info(args.format, cpu)
    with OutputFolder(args.output, model.name, info, legacy=build_files(model.name)) as out:
        written = write_outputs(model, out.stage, args.format, cpu)
        if not args.no_plots:
            written += write_figures(result, out.stage)
        written += write_calibration(result, out.stage, figure=not args.no_plots)
        written.append(report.write(model, out.stage, written))  # the one page to open (netgen.emit.report)
        written = out.commit(written)
    if not args.quiet:
        for path in written:
            print(f"wrote {path}")
        worst = max(f.max_rel_error for f in model.capacitances)
        print(
            f"{model.name}: {model.ncoords} coordinates, {len(model.electrodes)} electrodes, "
            f"held-out max capacitance error {worst:.2e}, {time.perf_counter() - start:.1f} s"
        )
    return 0


def chosen_formats(fmt: str) -> list[str]:
    """The formats named in a --format value ("all" counts as none of the compiled ones)."""
    return [f for f in requested(fmt) if f != "all"]


def compiled_info(fmt: str, cpu: str) -> dict:
    """The manifest's record of each compiled form --format writes: its compiler and target cpu."""
    names = chosen_formats(fmt)
    info: dict = {}
    if "osdi" in names:
        info["osdi"] = {"compiler": "openvaf-r", "target_cpu": cpu}
    if "fmu" in names:
        info["fmu"] = {"compiler": " ".join(fmu.compiler() or []), "target_cpu": cpu}
    return info if compiles(fmt) else {}


def build_files(name: str) -> tuple[str, ...]:
    """Every file a build of model `name` can write (its set, for OutputFolder)."""
    extra = (
        f"{name}_tb.sch",
        f"{name}_report.html",
        f"{name}.fmu",
    )  # beside the .sym (netgen.emit.xschem); the report; the .fmu beside _fmu.c
    return tuple(f"{name}{e.suffix}" for e in EMITTERS.values()) + (f"{name}.json",) + figure_names(name) + extra


@contextmanager
def sampling(args: Any) -> Iterator[dict]:
    """The executor= / store= keywords of netgen.build.build from the build options ({} = serial)."""
    spec, store = getattr(args, "scheduler", None), getattr(args, "sample_store", None)
    if spec is None and store is None:
        yield {}
        return
    ex = executor(spec) if spec is not None else None
    try:
        yield {"executor": ex, "store": store}
    finally:
        if ex is not None:
            ex.close()


def _add_build(sub) -> None:
    b = sub.add_parser("build", help="build the macromodel of a structure file and emit netlists")
    add_options(b, build_options(EMITTERS, requested).values())  # declared in netgen.runtime.options
    b.set_defaults(func=_build)


# ----------------------------------------------------------------------------- netgen simulate


def _simulate(args: argparse.Namespace) -> int:
    netlist_text(args.netlist)  # refuses binary input before the simulator sees it
    with ngspice.probe_timeout(args.timeout):
        plots = SIMULATORS[args.simulator].file(Path(args.netlist), Path(args.output), args.timeout)
        if not args.quiet and args.simulator == "ngspice":  # its log's first line records the same
            print(f"ran {ngspice.version().label} ({ngspice.version().path})")
    if not args.quiet:
        for plot in plots:
            points = len(next(iter(plot.vectors.values()), ()))
            print(f"{plot.name}: {len(plot.vectors)} vectors, {points} points")
    return 0


def _add_simulate(sub) -> None:
    r = sub.add_parser("simulate", help="run a netlist in a simulator (batch) and report failures clearly")
    add_options(r, simulate_options(SIMULATORS).values())  # declared in netgen.runtime.options
    r.set_defaults(func=_simulate)


# ----------------------------------------------------------------------------- netgen codemodel


def _codemodel(args: argparse.Namespace) -> int:
    say = (lambda m: None) if args.quiet else (lambda m: print(m, file=sys.stderr))
    cm = codemodel.build(codemodel.MODEL, force=args.force, progress=say)
    loop = codemodel.build(LOOP_LIBRARY, force=args.force, progress=say)  # the sigma-delta testbench's
    print(cm)
    if not args.quiet:
        print("load it with these .control lines:\n  " + "\n  ".join(codemodel.control_lines(cm)), file=sys.stderr)
        print(
            f"(the sigma-delta testbench's compiled loop: {loop}); built for "
            f"{codemodel.record(cm)['ngspice']['version']}, recorded in {ngspice.build_record(cm)}",
            file=sys.stderr,
        )
    return 0


def _add_codemodel(sub) -> None:
    p = sub.add_parser(
        "codemodel",
        help="build the netgen_es XSPICE code model for the installed ngspice "
        "(needed by the xspice .lib and --simulator ngspice-xspice) and print its path",
    )
    p.add_argument("--force", action="store_true", help="rebuild even if the cached build exists")
    p.add_argument("-q", "--quiet", action="store_true", help="print only errors (and the path)")
    p.set_defaults(func=_codemodel)


# ----------------------------------------------------------------------------- the command


def parser() -> argparse.ArgumentParser:
    p = Parser(prog="netgen", description=__doc__)
    p.add_argument("--version", action="version", version=f"netgen {__version__}")
    p.add_argument(
        "--ngspice",
        metavar="PATH",
        help="the ngspice to run and build code models for (default: "
        f"${ngspice.ENV}, else the ngspice on PATH), e.g. ~/.cache/netgen/ngspice-46/bin/ngspice",
    )
    sub = p.add_subparsers(dest="command", required=True)
    _add_build(sub)
    _add_simulate(sub)
    _add_codemodel(sub)
    for testbench in TESTBENCHES.values():
        testbench.add_parser(sub)
    sweep_cli.add_parser(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    """The one error boundary of every subcommand (the `netgen` command runs it through
    netgen.cli): each error class its exit code and one message, SIGINT and SIGTERM exit 130,
    anything else exit 70 with the traceback in a crash log next to the output."""
    previous = install()
    args = None
    try:
        args = parser().parse_args(argv)
        with ngspice.selected(args.ngspice):  # --ngspice: the same setting as NETGEN_NGSPICE
            code = args.func(args)
        check()  # a signal some library swallowed still stops it
        return code
    except InputError as exc:
        print(f"netgen: error in {exc.what} {exc}", file=sys.stderr)
        return exc.exit_code
    except NetgenError as exc:
        prefix = "code model: " if isinstance(exc, codemodel.CodeModelError) else ""
        print(f"netgen: {prefix}{exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt as exc:
        return report_interrupt(exc)
    except BrokenPipeError:  # `netgen ... | head`: the reader went away
        sys.stdout = open(os.devnull, "w")
        return 1
    except OSError as exc:
        print(f"netgen: {os_message(exc)}", file=sys.stderr)
        return 2
    except Exception as exc:
        stop = interrupted(exc)  # e.g. an import in a worker cut by the signal
        return report_interrupt(stop) if stop else internal_error(exc, output_of(args))
    finally:
        restore(previous)


def report_interrupt(exc: KeyboardInterrupt) -> int:
    """One line for a run stopped by SIGINT or SIGTERM (the stage's own line where it cleaned up
    and said what is left, netgen.runtime.interrupts.Interrupted.message); exit 130."""
    message = getattr(exc, "message", None)
    if message:
        print(f"netgen: {message}", file=sys.stderr)
        return EXIT_INTERRUPTED
    which = getattr(exc, "signum", None)
    print(f"netgen: interrupted{f' ({signal.Signals(which).name})' if which else ''}", file=sys.stderr)
    return EXIT_INTERRUPTED


def os_message(exc: OSError) -> str:
    """An OSError as one line with the path and the fix."""
    where = f"{exc.filename}: " if exc.filename else ""
    return (
        f"{where}{exc.strerror or exc}; check that the path exists, that you may read or write it, "
        "and that the disk has room"
    )


def output_of(args: argparse.Namespace | None) -> Path | None:
    """The run's output folder, if it exists (where a crash log goes)."""
    out = getattr(args, "output", None)
    return Path(out) if out and Path(out).is_dir() else None


if __name__ == "__main__":
    sys.exit(main())
