"""Argument types of the command line (argparse `type=`): numbers in their range and the paths a
subcommand reads or writes, checked before any work. A bad value is argparse's exit 2 with a
message that names the argument (argparse adds it), the value and the fix. Standard library
only."""

from __future__ import annotations

import argparse
import math
import os
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path

from ..core.options import Option, OptionError, as_written
from . import executor
from .interrupts import held

# file systems a run folder can never be on: kernel views and device nodes, not storage
VIRTUAL = {
    "proc",
    "sysfs",
    "devtmpfs",
    "devpts",
    "cgroup",
    "cgroup2",
    "debugfs",
    "tracefs",
    "securityfs",
    "pstore",
    "bpf",
    "configfs",
    "fusectl",
    "mqueue",
    "hugetlbfs",
    "binfmt_misc",
    "autofs",
    "efivarfs",
}


# the error an argparse type raises, for the commands' own option types (only the runtime imports argparse)
ArgumentTypeError = argparse.ArgumentTypeError


def number(text: str) -> float:
    """A finite number, or ArgumentTypeError."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def positive(what: str, example: str, upper: float = math.inf) -> Callable[[str], float]:
    """The type of a number that must be > 0 (and <= upper): `what` it is, an `example`."""

    def check(text: str) -> float:
        value = number(text)
        if not 0 < value <= upper:
            limit = f" and at most {upper:g}" if upper < math.inf else ""
            raise argparse.ArgumentTypeError(f"{text!r}: {what} must be greater than 0{limit}; e.g. {example}")
        return value

    return check


def integer(what: str, low: int, high: int, example: str, zero: str | None = None) -> Callable[[str], int]:
    """The type of an integer in [low, high] (or 0 when `zero` says what 0 means)."""

    def check(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number; e.g. {example}") from None
        if value == 0 and zero:
            return 0
        if not low <= value <= high:
            also = f" (or 0: {zero})" if zero else ""
            raise argparse.ArgumentTypeError(f"{value}: {what} must be between {low} and {high}{also}; e.g. {example}")
        return value

    return check


def existing_file(what: str) -> Callable[[str], str]:
    """The type of an input file that must exist and be a readable regular file."""

    def check(text: str) -> str:
        if not text.strip():
            raise argparse.ArgumentTypeError(f"the {what} path is empty; give the file to read")
        path = Path(text)
        if not path.exists():
            raise argparse.ArgumentTypeError(f"{text}: no such file; check the path to the {what}")
        if path.is_dir():
            raise argparse.ArgumentTypeError(f"{text} is a folder; give the {what} file inside it")
        if not os.access(path, os.R_OK):
            raise argparse.ArgumentTypeError(f"{text} is not readable; check its permissions (chmod u+r)")
        return text

    return check


def mount_type(path: Path) -> str:
    """File system type of the mount holding `path` (an absolute, resolved path), '' if unknown."""
    best, kind = "", ""
    try:
        with open("/proc/self/mounts", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                parts = line.split()
                if len(parts) < 3:
                    continue
                point = parts[1].encode().decode("unicode_escape")  # \040 for a space
                inside = str(path) == point or str(path).startswith(point.rstrip("/") + "/")
                if inside and len(point) >= len(best):
                    best, kind = point, parts[2]
    except OSError:
        return ""
    return kind


def output_folder(text: str) -> str:
    """The type of an output folder: not empty, not a file, not on a kernel file system, and
    writable (the folder, or the nearest existing folder it would be created in)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("the folder is empty (''); give a folder to write into, e.g. out")
    link = Path(text).expanduser()
    try:
        if link.is_symlink() and not link.exists():  # dangling, or a loop of links
            raise argparse.ArgumentTypeError(
                f"{text} is a symbolic link to {os.readlink(link)}, which is missing or a loop of links; "
                "remove the link, point it at a folder, or give another folder"
            )
        return _output_folder(text, link.resolve())
    except RuntimeError:  # pathlib's 'Symlink loop' in a folder above it
        raise argparse.ArgumentTypeError(f"{text}: a loop of symbolic links; give another folder") from None
    except OSError as exc:
        raise argparse.ArgumentTypeError(f"{text}: {exc.strerror}; choose a folder you can write to") from None


def _output_folder(text: str, path: Path) -> str:
    kind = mount_type(path)
    if kind in VIRTUAL:
        raise argparse.ArgumentTypeError(
            f"{text} is on the kernel's {kind} file system, not storage; choose a folder on disk"
        )
    here = path
    while not here.exists():
        here = here.parent
    if not here.is_dir():
        what = "is a file" if here == path else f"is inside {here}, which is a file"
        raise argparse.ArgumentTypeError(f"{text} {what}; give a folder (a new or an existing one)")
    if not writable(here):
        which = "" if here == path else f" (it would be created in {here})"
        raise argparse.ArgumentTypeError(
            f"{text} is not writable{which}; choose a folder you can write to, or fix its permissions"
        )
    return text


def writable(folder: Path) -> bool:
    """Can this process create a file in `folder`? Tried, not guessed (root passes os.access
    on read-only and kernel file systems)."""
    with held():  # no probe file left behind by a signal
        try:
            fd, probe = tempfile.mkstemp(prefix=".netgen-probe-", dir=folder)
        except OSError:
            return False
        os.close(fd)
        os.unlink(probe)
    return True


class Parser(argparse.ArgumentParser):
    """argparse's parser whose errors end with where the arguments are described (argparse's
    own messages, such as an unknown option or a missing value, name the argument but no fix)."""

    def error(self, message: str):
        """Exit 2 with the usage, the message and the help command that lists the arguments."""
        if message.endswith("expected one argument"):
            message += "; a value that starts with '-' is written as --option=VALUE"
        super().error(f"{message} (see: {self.prog} --help)")


def nonempty(what: str, example: str) -> Callable[[str], str]:
    """The type of a text argument that must not be empty."""

    def check(text: str) -> str:
        if not text.strip():
            raise argparse.ArgumentTypeError(f"{what} is empty; give one, e.g. {example}")
        return text

    return check


def option_type(option: Option) -> Callable[[str], object]:
    """The argparse `type=` of a declared option: its own check (netgen.core.options.Option.read), so
    the flag gets the verdict and message its file keys get."""

    def check(text: str) -> object:
        try:
            return option.read(as_written(option, text), option.flag or option.name)
        except OptionError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    check.__name__ = option.name  # argparse names the type in its "invalid <name> value" message
    return check


def add_option(parser: argparse.ArgumentParser, option: Option, **extra) -> None:
    """The argument of a declared option: its flag (and short form), type, default and help (choices
    and the range in the help; `usage` after it); `extra` goes to add_argument as is. An option a
    [loop] key also sets defaults to None on the command line: the file decides, then the default."""
    assert option.flag is not None, f"option {option.name} has no command-line flag"
    default = option.default_text or option.default
    rng = "" if option.type in ("bool", "text", "choice", "file", "folder") else f"; {option.range_text()}"
    text = f"{option.help}{rng} (default: {default})" if default is not None else option.help
    kwargs: dict = {"help": f"{text}{option.usage}"}
    if option.type == "bool":
        kwargs["action"] = "store_true"
    else:
        kwargs["type"] = {"file": existing_file(option.name.replace("_", " ")), "folder": output_folder}.get(
            option.type, option_type(option)
        )
        kwargs["default"] = None if option.loop_key else option.default
        if option.type == "choice":
            kwargs["choices"] = list(option.choices)
            kwargs["type"] = str  # argparse's choices message; the cross check runs where the context is known
    if option.metavar:
        kwargs["metavar"] = option.metavar
    if not option.flag.startswith("-"):  # a positional argument: argparse names it by the flag
        kwargs.pop("default", None)
        parser.add_argument(option.flag, **(kwargs | extra))
        return
    kwargs |= {"dest": option.name} | ({"required": True} if option.required else {})
    parser.add_argument(*((option.short,) if option.short else ()), option.flag, **(kwargs | extra))


def add_options(parser: argparse.ArgumentParser, options: Iterable[Option]) -> None:
    """Every declared option that has a flag, as an argument of `parser` (in declaration order)."""
    for option in options:
        if option.flag:
            add_option(parser, option)


def add_scheduler_option(
    parser: argparse.ArgumentParser, what: str = "the tasks run (default: local processes)"
) -> None:
    """The shared --scheduler option of the build and sweep commands."""
    parser.add_argument(
        "--scheduler",
        metavar="SPEC",
        type=nonempty("--scheduler", "processes:2"),
        help=f"where {what}: {executor.SCHEDULER_HELP}",
    )
