"""The errors netgen reports to a user, each with the exit code the command line gives it.

`cli.main` catches NetgenError (and KeyboardInterrupt, OSError and, as exit 70, the rest) and prints the
message in one line: every class here carries what the user needs (file, key, problem, fix).
"""

from __future__ import annotations


class NetgenError(Exception):
    """Base of the errors the command line reports as a message with `exit_code`."""

    exit_code = 1


class InputError(NetgenError):
    """A bad input file: file, location (line and key), problem and fix, for a one-line report.
    `what` names the kind of file in the command line's message."""

    exit_code = 2
    what = "input file"

    def __init__(self, path: str, where: str, problem: str, fix: str, line: int | None = None):
        self.path, self.where, self.problem, self.fix, self.line = path, where, problem, fix, line
        loc = f"{path}:{line}" if line else path
        super().__init__(f"{loc}: {where}: {problem}\n  fix: {fix}")


class StructureError(InputError):
    """Invalid structure file, or a file it names (an [import] table's data)."""

    what = "structure file"


class SweepError(InputError):
    """Invalid sweep file."""

    what = "sweep file"


class LoopError(InputError):
    """Invalid sigma-delta loop description (a structure file's [loop] table or `--loop` file), or one
    the model cannot close (a channel no electrode senses or drives, feedback that cannot balance
    the input)."""

    what = "loop description"


class ModelError(InputError):
    """Invalid model JSON (netgen.model.validate): a name that is not an identifier, text with
    control characters, a missing or malformed entry."""

    what = "model file"


class DiskFullError(NetgenError, OSError):
    """A run's output could not be written (a full disk, a quota, a read-only file system): its
    partial files are removed; the message names the folder and the fix. Exit 2, like the other
    OSErrors of a run's paths: the fix is the user's (free space or another -o), not netgen's."""

    exit_code = 2


class SimulationError(NetgenError, RuntimeError):
    """A simulator run failed; the message names the cause and the saved netlist."""

    exit_code = 1


class SimulatorNotFound(NetgenError, RuntimeError):
    """A simulator or tool is not installed; the message says how to install it."""

    exit_code = 3


class CodeModelError(SimulatorNotFound):
    """The XSPICE code model could not be built; the message says what is missing and the fix."""


class ExecutorError(NetgenError, OSError):
    """A scheduler that cannot be used (bad spec, Dask missing, scheduler unreachable)."""

    exit_code = 2
