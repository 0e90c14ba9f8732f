"""The testbench stage: circuits that run a macromodel in a simulator and judge the result.

TESTBENCHES maps a `netgen` subcommand to the testbench's command-line module (its
`add_parser(subparsers)` adds the subcommand). Adding a testbench is a package beside
sigma_delta/ (design, back ends on netgen.sim, analysis, cli) and one line here.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

from .gyro import cli as gyro_cli
from .sigma_delta import cli as sigma_delta_cli


@runtime_checkable
class TestbenchCommand(Protocol):
    """A testbench's command-line module: `add_parser(subparsers)` adds its subcommand, whose
    handler `cli(args)` returns the exit code."""

    def add_parser(self, sub: Any) -> None: ...

    def cli(self, args: Any) -> int: ...


TESTBENCHES: dict[str, TestbenchCommand] = {
    "sigma-delta": sigma_delta_cli,
    "gyro": gyro_cli,
}
