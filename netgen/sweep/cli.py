"""`netgen sweep STRUCTURE.toml SWEEP.toml -o DIR`: validate everything, estimate, run, gather."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

from ..runtime.arguments import ArgumentTypeError, add_scheduler_option, output_folder
from ..runtime.executor import executor, planned_workers
from ..structure import load_structure
from .check import check_runs
from .plan import plan
from .run import figure_path, run_sweep
from .size import check_size, estimate
from .spec import MAX_RUNS, load_sweep

RUNS_CEILING = 1_000_000  # --max-runs at most: a planned run takes about 1 kB


def positive_int(text: str) -> int:
    """argparse type of --max-runs: an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if not 1 <= value <= RUNS_CEILING:
        raise ArgumentTypeError(
            f"{text!r} is not an integer between 1 and {RUNS_CEILING} (every run is "
            f"planned in memory first; the default is {MAX_RUNS})"
        )
    return value


def cli(args) -> int:
    """exit 0 (all ran, or --dry-run), 1 (some failed), 2 (bad input: SweepError, StructureError,
    FolderError and ExecutorError reach netgen.cli.commands.main, which reports them), 130 (stopped
    by SIGINT or SIGTERM, resumable)."""
    start = time.perf_counter()
    out = Path(args.output)
    sweep = load_sweep(args.sweep, args.max_runs)
    structure = load_structure(args.structure)
    workers = planned_workers(args.scheduler) or os.cpu_count() or 1
    check_size(sweep, args.max_runs, workers)  # before any list of runs is made
    runs = plan(sweep, args.structure, out)  # path errors before any work
    check_runs(sweep, structure, args.structure, runs)  # every run, before any runs
    line = f"sweep: {estimate(sweep, workers, out).text(workers)}"
    if args.dry_run:  # the answer of a dry run: on stdout
        print(line)
        return 0
    if not args.quiet:
        print(line, file=sys.stderr)
    with executor(args.scheduler) as ex:
        rows = run_sweep(args.structure, sweep, out, ex, progress=not args.quiet, runs=runs)
    bad = [r for r in rows if r["status"] != "ok"]
    if not args.quiet:
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
    p.add_argument(
        "-o", "--output", required=True, type=output_folder, help="output folder (results.csv, runs/, the figure PNG)"
    )
    add_scheduler_option(p, what="the runs run (default: one local process per core)")
    p.add_argument(
        "--max-runs",
        type=positive_int,
        default=MAX_RUNS,
        metavar="N",
        help=f"refuse a sweep of more than N runs (default {MAX_RUNS})",
    )
    p.add_argument(
        "--dry-run",
        action="store_true",
        help="check the sweep file and every run, print the run count and time estimate, run nothing",
    )
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or summary output")
    p.set_defaults(func=cli)
