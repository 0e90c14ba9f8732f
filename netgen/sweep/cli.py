"""`netgen sweep STRUCTURE.toml SWEEP.toml -o DIR`: validate, run, gather."""

from __future__ import annotations

import time
from pathlib import Path

from ..arguments import output_folder
from ..executor import add_scheduler_option, executor
from ..structure import load_structure
from .plan import plan
from .run import figure_path, run_sweep
from .spec import load_sweep


def cli(args) -> int:
    """exit 0 (all ran), 1 (some failed), 2 (bad input: SweepError, StructureError and
    ExecutorError reach netgen.cli.main, which reports them)."""
    start = time.perf_counter()
    sweep = load_sweep(args.sweep)
    load_structure(args.structure)
    plan(sweep, args.structure, Path(args.output))         # path errors before any work
    with executor(args.scheduler) as ex:
        rows = run_sweep(args.structure, sweep, Path(args.output), ex, progress=not args.quiet)
    bad = [r for r in rows if r["status"] != "ok"]
    if not args.quiet:
        out = Path(args.output)
        print(f"wrote {out / 'results.csv'}")
        print(f"wrote {figure_path(out, sweep)}")
        for r in bad:
            print(f"{r['run']}: failed: {r['error']}")
        print(f"sweep: {len(rows) - len(bad)} of {len(rows)} runs ok, {time.perf_counter() - start:.1f} s")
    return 1 if bad else 0


def add_parser(sub) -> None:
    """The `sweep` subcommand's arguments."""
    p = sub.add_parser("sweep", help="parameter sweep / Monte Carlo of the sigma-delta loop (local processes or Dask)")
    p.add_argument("structure", help="structure description (TOML)")
    p.add_argument("sweep", help="sweep description (TOML), e.g. examples/sweep_ts.toml")
    p.add_argument("-o", "--output", required=True, type=output_folder,
                   help="output folder (results.csv, runs/, the figure PNG)")
    add_scheduler_option(p, what="the runs run (default: one local process per core)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or summary output")
    p.set_defaults(func=cli)
