"""Command line: `netgen build STRUCTURE.toml -o DIR` and friends. Errors exit 2, never a traceback."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from . import __version__
from .simulate import SimulationError, SimulatorNotFound
from .structure import StructureError


def _build(args: argparse.Namespace) -> int:
    from .emit import write_outputs
    from .pipeline import build, write_figures
    from .structure import load_structure

    start = time.perf_counter()
    structure = load_structure(args.structure)
    from .executor import sampling
    with sampling(args) as parallel:                # --scheduler / --sample-store (netgen.executor)
        result = build(structure, progress=not args.quiet, **parallel)
    model = result.model
    from .emit_ngspice import xspice_refusal
    if args.format == "xspice" and xspice_refusal(model):
        print(f"netgen: {args.structure}: --format xspice: {xspice_refusal(model)}; fix: set target = \"plates\" "
              "in the structure's [fit], or use --format ngspice", file=sys.stderr)
        return 2
    written = write_outputs(model, Path(args.output), args.format)
    if not args.no_plots:
        written += write_figures(result, Path(args.output))
    if not args.quiet:
        for path in written:
            print(f"wrote {path}")
        worst = max(f.max_rel_error for f in model.capacitances)
        print(f"{model.name}: {model.ncoords} coordinates, {len(model.electrodes)} electrodes, "
              f"held-out max capacitance error {worst:.2e}, {time.perf_counter() - start:.1f} s")
    return 0


def _simulate(args: argparse.Namespace) -> int:
    from .simulate import run_ngspice

    netlist = Path(args.netlist).read_text(encoding="utf-8")
    plots = run_ngspice(netlist, Path(args.output), Path(args.netlist).stem, timeout=args.timeout)
    if not args.quiet:
        for plot in plots:
            print(f"{plot.name}: {len(plot.vectors)} vectors, {len(next(iter(plot.vectors.values())))} points")
    return 0


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="netgen", description=__doc__)
    p.add_argument("--version", action="version", version=f"netgen {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    b = sub.add_parser("build", help="build the macromodel of a structure file and emit netlists")
    b.add_argument("structure", help="structure description (TOML), e.g. examples/levitated_disk.toml")
    b.add_argument("-o", "--output", required=True, help="output folder for <name>.lib and <name>.json")
    b.add_argument("--format", choices=["ngspice", "veriloga", "xspice", "all"], default="ngspice",
                   help="netlist dialects to write (xspice: the .lib with the plate terms in the compiled netgen_es "
                        "code model, see `netgen codemodel`)")
    b.add_argument("-q", "--quiet", action="store_true", help="no progress or summary output")
    b.add_argument("--no-plots", action="store_true", help="skip the PNG figures (mode shapes, fit errors)")
    from .executor import add_build_options
    add_build_options(b)
    b.set_defaults(func=_build)
    r = sub.add_parser("simulate", help="run a netlist in ngspice (batch) and report failures clearly")
    r.add_argument("netlist", help="ngspice netlist (.cir) with its analyses")
    r.add_argument("-o", "--output", required=True, help="run folder: the saved netlist, raw file and log")
    r.add_argument("--timeout", type=float, default=3600.0, help="seconds before the run is stopped")
    r.add_argument("-q", "--quiet", action="store_true", help="no summary output")
    r.set_defaults(func=_simulate)
    from .codemodel import add_parser as add_codemodel
    add_codemodel(sub)
    from .sigma_delta import add_parser as add_sigma_delta
    add_sigma_delta(sub)
    from .sweep import add_parser as add_sweep
    add_sweep(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `netgen` console command."""
    args = parser().parse_args(argv)
    try:
        return args.func(args)
    except StructureError as exc:
        print(f"netgen: error in structure file {exc}", file=sys.stderr)
        return 2
    except SimulatorNotFound as exc:
        print(f"netgen: {exc}", file=sys.stderr)
        return 3
    except SimulationError as exc:
        print(f"netgen: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("netgen: interrupted", file=sys.stderr)
        return 130
    except OSError as exc:
        print(f"netgen: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
