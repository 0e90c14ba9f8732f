"""Reading TOML tables with errors that point at the file, line and key, and say the fix."""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from typing import TypeGuard

from .errors import InputError, StructureError
from .files import did_you_mean
from .text import is_identifier, text_problem
from .units import SI_NAME, UnitError, example, parse_quantity


class Reader:
    """Knows the file text so errors can point at a line; raises StructureError (or `error`)."""

    def __init__(self, path: str, text: str, error: type[InputError] = StructureError):
        self.path, self.lines, self.error = path, text.splitlines(), error

    def fail(self, where: str, problem: str, fix: str) -> InputError:
        return self.error(self.path, where, problem, fix, self.line_of(where))

    def line_of(self, where: str) -> int | None:
        """Best-effort line number of a dotted key such as 'electrodes[1].gap' or
        'electrostatics.bem.levels': the line that sets it, else the header (or key) line of the
        nearest table above it that the file writes; None if the file writes none of them."""
        entries, arrays = toml_entries(self.lines)
        want = key_target(where, arrays)
        best, depth = None, 0
        for no, path in entries:
            if len(path) > depth and want[: len(path)] == path:
                best, depth = no, len(path)
        return best


# a TOML key (bare, "basic" or 'literal'), a dotted key path, a [table] / [[array]] header, a key line
KEY = r'"(?:[^"\\]|\\.)*"|\'[^\']*\'|[A-Za-z0-9_-]+'
KEY_PATH = rf"(?:{KEY})(?:\s*\.\s*(?:{KEY}))*"
HEADER = re.compile(rf"^\[(\[)?\s*({KEY_PATH})\s*\]\]?\s*(#.*)?$")
ASSIGN = re.compile(rf"^({KEY_PATH})\s*=")


def key_names(path: str) -> tuple[str, ...]:
    """The names of a TOML key path ('a . "b" .c' -> a, b, c); a quoted name's dots split too,
    since the `where` strings of the errors write every level with a dot."""
    return tuple(n for m in re.finditer(KEY, path) for n in m.group(0).strip("\"'").split("."))


def toml_entries(lines: list[str]) -> tuple[list[tuple[int, tuple]], set[tuple[str, ...]]]:
    """(line, path) of every table header and key line of a TOML text, a path being the names
    with the element index after each array of tables ([[electrodes]] twice: electrodes, 1); and
    the name paths of the arrays of tables. Lines inside multi-line strings are passed over."""
    entries: list[tuple[int, tuple]] = []
    counts: dict[tuple[str, ...], int] = {}
    table: tuple = ()
    in_string = False
    for no, raw in enumerate(lines, start=1):
        line = raw.strip()
        quotes = line.count('"""') + line.count("'''")
        if in_string:
            in_string = quotes % 2 == 0
            continue
        head, assign = HEADER.match(line), ASSIGN.match(line)
        if head:
            names = key_names(head.group(2))
            if head.group(1):
                counts[names] = counts.get(names, -1) + 1
            table = indexed(names, counts)
            entries.append((no, table))
        elif assign:
            entries.append((no, table + key_names(assign.group(1))))
            in_string = quotes % 2 == 1
    return entries, set(counts)


def indexed(names: tuple[str, ...], counts: dict[tuple[str, ...], int]) -> tuple:
    """A header's path: after each array of tables among its prefixes, that array's current
    element (a [electrodes.x] after the second [[electrodes]] belongs to electrodes, 1)."""
    out: list = []
    for k, name in enumerate(names, start=1):
        out += [name, counts[names[:k]]] if names[:k] in counts else [name]
    return tuple(out)


def key_target(where: str, arrays: set[tuple[str, ...]]) -> tuple:
    """The path of an error's `where` ('electrodes[1].gap' -> electrodes, 1, gap; '[[electrodes]]'
    -> electrodes, 0): an array of tables named without an index means its first element."""
    parts = re.findall(r"\[\d+\]|[A-Za-z0-9_-]+", where)
    out: list = []
    names: tuple[str, ...] = ()
    for k, part in enumerate(parts):
        if part.startswith("["):
            out.append(int(part[1:-1]))
            continue
        out.append(part)
        names += (part,)
        if names in arrays and not (k + 1 < len(parts) and parts[k + 1].startswith("[")):
            out.append(0)
    return tuple(out)


def check_keys(rd: Reader, where: str, table: dict, allowed: list[str]) -> None:
    """Refuse keys outside `allowed`, with the closest allowed key."""
    for key in table:
        if key not in allowed:
            shown = key or '""'  # an empty key still names a location
            raise rd.fail(
                f"{where}.{shown}" if where else shown,
                f"unknown key '{key}'",
                f"{did_you_mean(key, allowed)}allowed keys here: {', '.join(allowed)}",
            )


def table(rd: Reader, doc: dict, key: str, required: bool) -> dict:
    """A [key] table of the document ({} if absent and optional)."""
    value = doc.get(key)
    if value is None:
        if required:
            raise rd.fail(f"[{key}]", "missing table", f"add a [{key}] table (see examples/levitated_disk.toml)")
        return {}
    if not isinstance(value, dict):
        raise rd.fail(key, f"'{key}' must be a table, got {type(value).__name__}", f"write it as a [{key}] section")
    return value


def quantity(
    rd: Reader,
    t: dict,
    where: str,
    key: str,
    kind: str,
    default: float | None = None,
    check: Callable[[float], str | None] | None = None,
    what: str = "",
) -> float:
    """Read a physical quantity (SI number or unit string), apply a physical-range check."""
    loc = f"{where}.{key}"
    if key not in t:
        if default is None:
            raise rd.fail(
                loc,
                f"missing required key '{key}'",
                f'add {key} = "{example(kind)}"  ({what}, SI units if no unit is given)',
            )
        return default
    try:
        value = parse_quantity(t[key], kind)
    except UnitError as exc:
        raise rd.fail(
            loc, str(exc), f'write {key} = "{example(kind)}" or a number in {SI_NAME[kind] or "plain units"}'
        ) from None
    if not math.isfinite(value):
        raise rd.fail(loc, f"{key} is not finite ({value})", f"give a finite {what or key}")
    if check:
        problem = check(value)
        if problem:
            raise rd.fail(loc, f"{key} = {t[key]!r} {problem}", f"give a physical {what or key}")
    return value


def positive(v: float) -> str | None:
    return None if v > 0 else "must be greater than zero"


def nonnegative(v: float) -> str | None:
    return None if v >= 0 else "must not be negative"


def integer(rd: Reader, t: dict, where: str, key: str, default: int | None, lo: int, hi: int, what: str) -> int:
    """An integer key within lo..hi."""
    loc = f"{where}.{key}"
    if key not in t:
        if default is None:
            raise rd.fail(loc, f"missing required key '{key}'", f"add {key} = <integer {lo}..{hi}> ({what})")
        return default
    value = t[key]
    if isinstance(value, bool) or not isinstance(value, int):
        raise rd.fail(loc, f"{key} must be an integer, got {value!r}", f"write {key} = <integer {lo}..{hi}> ({what})")
    if not lo <= value <= hi:
        raise rd.fail(loc, f"{key} = {value} is outside {lo}..{hi}", f"choose {what} between {lo} and {hi}")
    return value


def choice(rd: Reader, t: dict, where: str, key: str, choices: list[str], default: str | None) -> str:
    """A key whose value is one of `choices`."""
    loc = f"{where}.{key}"
    if key not in t:
        if default is None:
            raise rd.fail(loc, f"missing required key '{key}'", f"add {key} = one of {choices}")
        return default
    value = t[key]
    if value not in choices:
        hint = did_you_mean(str(value), choices)
        raise rd.fail(loc, f"{key} = {value!r} is not one of {choices}", f"{hint}use one of {choices}")
    return value


def flag(rd: Reader, t: dict, where: str, key: str, default: bool, fix: str | None = None) -> bool:
    """A true/false key."""
    value = t.get(key, default)
    if not isinstance(value, bool):
        raise rd.fail(f"{where}.{key}", f"{key} must be true or false, got {value!r}", fix or f"write {key} = true")
    return value


def identifier(name: object) -> TypeGuard[str]:
    """A simple name for netlists: letters, digits and _ (starting with a letter), not 'error'
    (PySpice treats any output line with that word as a simulator error)."""
    return is_identifier(name) and "error" not in name.lower()


def free_text(rd: Reader, where: str, value: object, what: str) -> str:
    """A string that is printable free text (netgen.core.text.text_problem: no line breaks or other
    control characters), since it is written into netlist headers; else the error with the fix."""
    problem = text_problem(value)
    if problem:
        raise rd.fail(
            where,
            f"{what} {problem}",
            f"write {what} as one line of printable text "
            "(no line breaks, tabs or other control characters): it is copied into the netlist headers",
        )
    assert isinstance(value, str)  # text_problem refused every non-string
    return value
