"""The options of `netgen build` and `netgen simulate`, each declared once (netgen.core.options.Option):
their argparse arguments (netgen.runtime.arguments.add_options) and their checks come from
build_options and simulate_options, as the sigma-delta command's come from
netgen.testbench.sigma_delta.options. The command line passes the registries they name (the
emitters, the simulators: stages the runtime does not import)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from ..core.options import Option, by_name
from .executor import SCHEDULER_HELP

TIMEOUT_MAX = 1e7  # s (116 days): a limit, not a typo of one


def format_check(requested: Callable[[str], list[str]]) -> Callable[[str, dict], str | None]:
    """--format's check: one or more formats joined by commas (`requested`, netgen.emit.requested:
    its ValueError's message is the problem)."""

    def problem(text: str, context: dict) -> str | None:
        try:
            requested(text)
        except ValueError as exc:
            return str(exc)
        return None

    return problem


def nonempty(text: str, context: dict) -> str | None:
    """A text option that must not be empty."""
    return None if text.strip() else "is empty"


def build_options(emitters: Mapping[str, Any], requested: Callable[[str], list[str]]) -> dict[str, Option]:
    """`netgen build`'s options; `emitters`: netgen.emit.EMITTERS (the --format help), `requested`:
    netgen.emit.requested (its check)."""
    return by_name(
        [
            Option(
                "structure",
                "the structure description (TOML), e.g. examples/levitated_disk.toml",
                type="text",
                example="examples/levitated_disk.toml",
                flag="structure",
            ),
            Option(
                "output",
                "the output folder for <name>.lib and <name>.json",
                type="folder",
                example="out",
                flag="--output",
                short="-o",
                required=True,
            ),
            Option(
                "format",
                "the netlist dialects to write, one or several joined by commas (e.g. all,osdi)",
                type="text",
                default="ngspice",
                example="ngspice,osdi",
                flag="--format",
                cross=format_check(requested),
                usage=": "
                + "; ".join(f"{k}: {e.help}" for k, e in emitters.items())
                + "; all: every dialect the model has but osdi and fmu (they compile)",
            ),
            Option(
                "native",
                "compile the .osdi for this machine's CPU (openvaf-r --target_cpu native: faster, but it may not "
                "load elsewhere); default: the x86-64 baseline, which runs anywhere (the manifest names the target)",
                type="bool",
                flag="--native",
            ),
            Option("quiet", "no progress or summary output", type="bool", flag="--quiet", short="-q"),
            Option("no_plots", "skip the PNG figures (mode shapes, fit errors)", type="bool", flag="--no-plots"),
            Option(
                "max_minutes",
                "the limit in minutes of a sample design's estimated sampling and fit time (printed before the "
                "work): a design over it is refused (exit 2)",
                low=0.0,
                open_low=True,
                default=60.0,
                example="60",
                flag="--max-minutes",
                metavar="MIN",
            ),
            Option(
                "strict",
                "refuse (exit 2, nothing written) a model whose capacitance fit misses [fit] tolerance",
                type="bool",
                flag="--strict",
            ),
            Option(
                "scheduler",
                "where the capacitance samples are computed (default: serially in this process)",
                type="text",
                example="processes:2",
                flag="--scheduler",
                metavar="SPEC",
                cross=nonempty,
                usage=f": {SCHEDULER_HELP}",
            ),
            Option(
                "sample_store",
                "the folder that keeps finished sample chunks; a re-run with the same inputs reuses them",
                type="folder",
                example="samples",
                flag="--sample-store",
                metavar="DIR",
            ),
        ]
    )


def simulate_options(simulators: Mapping[str, Any]) -> dict[str, Option]:
    """`netgen simulate`'s options; `simulators`: netgen.sim.SIMULATORS (the --simulator choices)."""
    return by_name(
        [
            Option(
                "netlist",
                "the netlist with its analyses (ngspice .cir, or a VACASK .sim)",
                type="file",
                example="run.cir",
                flag="netlist",
            ),
            Option(
                "output",
                "the run folder: the raw file and log",
                type="folder",
                example="run",
                flag="--output",
                short="-o",
                required=True,
            ),
            Option(
                "simulator",
                "the circuit simulator",
                type="choice",
                choices=tuple(simulators),
                default="ngspice",
                example="ngspice",
                flag="--simulator",
                usage=": " + "; ".join(f"{k}: {s.help}" for k, s in simulators.items()),
            ),
            Option(
                "timeout",
                "the wall time before the run is stopped",
                quantity="time",
                low=0.0,
                high=TIMEOUT_MAX,
                open_low=True,
                default=3600.0,
                example="600",
                flag="--timeout",
            ),
            Option("quiet", "no summary output", type="bool", flag="--quiet", short="-q"),
        ]
    )
