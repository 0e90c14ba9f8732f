"""Options declared once: an Option says what a setting is (type, unit, range with open or closed
ends, default, help) and where a user writes it (command-line flag, [loop] key, sweep parameter);
its `read` is the one check the command line, the file readers and the sweep all apply, so a value
gets the same verdict and the same message wherever it is written (only the name differs: the flag
or the key as the user wrote it). The argparse arguments (netgen.runtime.arguments.add_options), the
readers' checks, the records that carry the values (Record: one attribute per declared option) and
the docs' option tables (markdown_table) are derived from the declarations.

Imports nothing of netgen but errors and units (no argparse, no stage).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from .units import RANGES, SI_NAME, UnitError, in_range, parse_quantity

# a plain number as written: digits, one point, an exponent; no underscores, no inf/nan, no spaces
NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
INTEGER = re.compile(r"[-+]?\d+")
TEXTS = ("text", "file", "folder")  # the types whose value is the text as written


class OptionError(ValueError):
    """A value an Option refuses: `problem` (naming the flag or key) and `fix`."""

    def __init__(self, problem: str, fix: str):
        self.problem, self.fix = problem, fix
        super().__init__(f"{problem}; {fix}")


def shown(value: object) -> str:
    """A value as quoted in a message: repr (control and bidi characters escaped), at most 60 chars."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def as_written(option: Option, text: str) -> object:
    """Command-line text as the value a file would hold: a whole number for an int option (strictly),
    else the text itself (numbers and quantity strings are read by Option.read)."""
    return int(text) if option.type == "int" and INTEGER.fullmatch(text.strip()) else text


def number(text: str) -> float | None:
    """A plain number written as text (strictly: no underscores, inf or nan), else None."""
    return float(text) if NUMBER.fullmatch(text.strip()) else None


@dataclass(frozen=True)
class Option:
    """One option. type: "float" (a number, or a quantity string of kind `quantity`), "int",
    "choice" (one of `choices`), "bool", "text", or a path: "file" (to read) or "folder" (to write
    into; both checked by the command line, netgen.runtime.arguments); low/high: the range (None:
    unbounded), each end open or closed; zero: what 0 means where it is allowed outside the range
    (None: it is not). flag / loop_key / sweep: the command-line flag (a name without dashes: a
    positional argument), the [loop] key (dotted below [loop]) and the sweep parameter that set it
    (None: not there); short, metavar, required, usage: the flag's short form, value name, whether
    it must be given and the text --help adds to `help`. role: the record the value is carried in
    (e.g. "design": the sigma-delta loop's Choices). cross(value, context) -> problem or None: a
    check against other settings (context: the names of the settings known where it is read)."""

    name: str
    help: str
    type: str = "float"
    quantity: str = "dimensionless"
    low: float | None = None
    high: float | None = None
    open_low: bool = False
    open_high: bool = False
    default: object = None
    default_text: str = ""
    example: str = ""
    choices: tuple[str, ...] = ()
    zero: str | None = None
    flag: str | None = None
    loop_key: str | None = None
    sweep: str | None = None
    cross: Callable[[Any, dict], str | None] | None = None
    role: str = ""
    short: str | None = None
    metavar: str | None = None
    required: bool = False
    usage: str = ""

    @property
    def unit(self) -> str:
        """The SI unit of a float option ('' for dimensionless numbers)."""
        return SI_NAME[self.quantity] if self.type == "float" else ""

    def range_text(self) -> str:
        """The range as written in messages and docs: '(0, 1] s', 'between 64 and 16777216'."""
        if self.type == "choice":
            return "one of " + ", ".join(self.choices)
        if self.low is None and self.high is None:
            return "any finite number" if self.type == "float" else "any"
        if self.type == "int":
            text = f"between {self.low:.0f} and {self.high:.0f}" if self.high is not None else f">= {self.low:.0f}"
        else:
            lo = "-inf" if self.low is None else f"{self.low:g}"
            hi = "inf" if self.high is None else f"{self.high:g}"
            left = "(" if self.open_low or self.low is None else "["
            right = ")" if self.open_high or self.high is None else "]"
            text = f"{left}{lo}, {hi}{right}" + (f" {self.unit}" if self.unit else "")
        return text + (f" (or 0: {self.zero})" if self.zero else "")

    def inside(self, v: float) -> bool:
        """Whether the number v lies in the range (0 too when `zero` allows it)."""
        if self.zero and v == 0:
            return True
        lo_ok = self.low is None or (v > self.low if self.open_low else v >= self.low)
        hi_ok = self.high is None or (v < self.high if self.open_high else v <= self.high)
        return math.isfinite(v) and lo_ok and hi_ok

    def example_as(self, named: str) -> str:
        """The example value written as a flag (`--ts 1e-6`) or a key (`ts = 1e-6`)."""
        return f"{named} {self.example}" if named.startswith("-") else f"{named.rsplit('.', 1)[-1]} = {self.example}"

    def fix(self, named: str) -> str:
        """The fix of a refused value, written the way the user wrote the setting."""
        if self.type in TEXTS:
            return f"give {self.help}, e.g. {self.example_as(named)}"
        rng = self.range_text()
        return f"give {self.help} {'in ' if rng[0] in '([' else ''}{rng}, e.g. {self.example_as(named)}"

    def read(self, value: object, named: str, context: dict | None = None) -> Any:
        """The checked value (a float in SI, an int, a choice, a bool or the text) of `value` as
        written (command-line text, or a TOML value) at `named` (the flag or the key), or OptionError."""
        parsed = self.parse(value, named)
        if self.type in ("float", "int") and isinstance(parsed, (int, float)) and not self.inside(parsed):
            outside = "is not" if self.type == "int" else "is outside"
            raise OptionError(f"{named} = {shown(value)} {outside} {self.range_text()}", self.fix(named))
        problem = self.cross(parsed, context or {}) if self.cross else None
        if problem:
            raise OptionError(f"{named} = {shown(value)}: {problem}", self.fix(named))
        return parsed

    def parse(self, value: object, named: str) -> object:
        """The value read as this option's type (before the range), or OptionError."""
        bad = OptionError(f"{named} = {shown(value)} is not {self.what()}", self.fix(named))
        if self.type == "bool":
            if isinstance(value, bool):
                return value
            raise bad
        if isinstance(value, bool) or not isinstance(value, (str, int, float)):
            raise bad
        if self.type == "int":
            if isinstance(value, int):  # a file's integer (a quoted "128" is text; the command line: as_written)
                return value
            raise bad
        if self.type == "choice":
            if value in self.choices:
                return value
            raise OptionError(f"{named} = {shown(value)} is not one of {', '.join(self.choices)}", self.fix(named))
        if self.type in TEXTS:
            if isinstance(value, str):
                return value
            raise bad
        return self.quantity_of(value, named)

    def quantity_of(self, value: str | int | float, named: str) -> float:
        """A float option's value in SI: a number, or a quantity string of its kind."""
        if isinstance(value, (int, float)):
            v = float(value)
        else:
            plain = number(value)
            try:
                v = plain if plain is not None else parse_quantity(value, self.quantity)
            except UnitError as exc:
                raise OptionError(f"{named} = {shown(value)}: {exc}", self.fix(named)) from None
        if not math.isfinite(v):
            raise OptionError(f"{named} = {shown(value)} is not a finite number", self.fix(named))
        try:  # a plain number meets the same physical range as a quantity string (units.RANGES)
            return in_range(v, self.quantity, shown(value)) if self.quantity in RANGES else v
        except UnitError as exc:
            raise OptionError(f"{named} = {shown(value)}: {exc}", self.fix(named)) from None

    def what(self) -> str:
        """What a value of this type is, for 'is not ...'."""
        return {
            "bool": "true or false",
            "int": "a whole number",
            "text": "a text",
            "file": "a file",
            "folder": "a folder",
            "choice": "one of " + ", ".join(self.choices),
        }.get(
            self.type, f"a number (SI) or a {self.quantity} string" if self.quantity != "dimensionless" else "a number"
        )


MARK = "<!-- generated from the option declarations: {} -->"  # the line above a docs page's generated table


def with_table(text: str, name: str, table: str) -> str:
    """A docs page's text with the table below its MARK line `name` replaced by `table` (the table
    ends at the first line that is not a table row); ValueError if the page has no such mark."""
    mark = MARK.format(name) + "\n"
    if mark not in text:
        raise ValueError(f"no line {mark.strip()!r} above the table")
    head, _, rest = text.partition(mark)
    lines = rest.splitlines(keepends=True)
    n = next((i for i, line in enumerate(lines) if not line.startswith("|")), len(lines))
    return head + mark + table + "".join(lines[n:])


def by_name(options: Iterable[Option]) -> dict[str, Option]:
    """The options keyed by name."""
    return {o.name: o for o in options}


def markdown_table(options: Iterable[Option], columns: tuple[str, ...] = ("flag", "loop_key", "sweep")) -> str:
    """The docs' option table: where each option is written, its range, its default and meaning."""
    heads = {"flag": "flag", "loop_key": "`[loop]` key", "sweep": "sweep parameter"}
    rows = [
        "| " + " | ".join([heads[c] for c in columns] + ["range", "default", "meaning"]) + " |",
        "|" + "---|" * (len(columns) + 3),
    ]
    for o in options:
        where = [f"`{getattr(o, c)}`" if getattr(o, c) else "" for c in columns]
        where = [f"`{o.short}`, {w}" if c == "flag" and o.short else w for c, w in zip(columns, where)]
        default = o.default_text or (
            "" if o.default is None else f"{o.default:g}" if o.type == "float" else str(o.default)
        )
        rng = "true, false" if o.type == "bool" else o.type if o.type in TEXTS else o.range_text()
        rows.append("| " + " | ".join(where + [rng, default, o.help]) + " |")
    return "\n".join(rows) + "\n"


class Record:
    """The values of declared options, one attribute per option (None: not given), compared by
    value and immutable; a subclass says which (`declared`, e.g. from the declarations' role) and
    may carry `extra` values that are not options. Adding a declaration adds its attribute."""

    declared: ClassVar[Mapping[str, Option]] = {}
    extra: ClassVar[tuple[str, ...]] = ()
    __slots__ = ("_values",)

    def __init__(self, **given: Any) -> None:
        names = tuple(self.declared) + self.extra
        unknown = sorted(set(given) - set(names))
        if unknown:
            raise TypeError(f"{type(self).__name__} has no option {', '.join(unknown)} (declared: {', '.join(names)})")
        object.__setattr__(self, "_values", {n: given.get(n) for n in names})

    @classmethod
    def of(cls, values: Mapping[str, Any]) -> Any:
        """The record of the names it declares in `values` (e.g. parsed arguments, a sweep's settings)."""
        return cls(**{k: v for k, v in values.items() if k in cls.declared or k in cls.extra})

    def __getattr__(self, name: str) -> Any:
        if name == "_values":  # not yet set (copy, pickle): no recursion
            raise AttributeError(name)
        try:
            return self._values[name]
        except KeyError:
            raise AttributeError(f"{type(self).__name__} has no option {name!r}") from None

    def __setattr__(self, name: str, value: object) -> None:
        raise AttributeError(f"{type(self).__name__} is immutable; build another (over, or_defaults)")

    def __eq__(self, other: object) -> bool:
        return type(other) is type(self) and self._values == other._values

    def __hash__(self) -> int:
        return hash((type(self).__name__, tuple(self._values.items())))

    def __repr__(self) -> str:
        given = ", ".join(f"{k}={v!r}" for k, v in self._values.items() if v is not None)
        return f"{type(self).__name__}({given})"

    def __reduce__(self) -> tuple:
        return (type(self).of, (dict(self._values),))

    def given(self) -> dict[str, Any]:
        """The values given (not None), by name."""
        return {k: v for k, v in self._values.items() if v is not None}

    def over(self, other: Record) -> Any:
        """This record with `other`'s values where this one has none (the names both declare)."""
        return type(self).of(other.given() | self.given())

    def or_defaults(self) -> Any:
        """This record with each missing value its declared default."""
        return type(self).of({k: o.default for k, o in self.declared.items()} | self.given())


def of_role(options: Iterable[Option], role: str) -> dict[str, Option]:
    """The options of one role (a Record's `declared`), by name."""
    return {o.name: o for o in options if o.role == role}
