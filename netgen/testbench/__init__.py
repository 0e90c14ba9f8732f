"""The testbench stage: circuits that run a macromodel in a simulator and judge the result.

TESTBENCHES maps a `netgen` subcommand to the testbench's command-line module (its
`add_parser(subparsers)` adds the subcommand). Adding a testbench is a package beside
sigma_delta/ (design, back ends on netgen.sim, analysis, cli) and one line here.
"""

from __future__ import annotations

from types import ModuleType

from .sigma_delta import cli as sigma_delta_cli

TESTBENCHES: dict[str, ModuleType] = {
    "sigma-delta": sigma_delta_cli,
}
