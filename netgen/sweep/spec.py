"""`netgen sweep STRUCTURE.toml SWEEP.toml -o DIR`: parameter sweeps and Monte Carlo of the
sigma-delta loop (netgen.testbench.sigma_delta), run through netgen.runtime.executor (local processes or Dask).

SWEEP.toml (see examples/sweep_ts.toml):

    [sweep]
    figure = "z.noise_floor_db_per_hz"   # the column plotted against x (see FIGURES)
    x = "ts"                             # parameter on the plot's x axis (default: the first)
    mode = "grid"                        # grid: every combination of the value lists; zip: k-th values together
    samples = 1                          # Monte Carlo draws per grid point (with distributions)
    seed = 1                             # of the Monte Carlo draws
    retries = 2                          # resubmissions of a run whose worker was lost
    plots = false                        # each run's spectra.png / coordinates.png
    timeout = "2 h"                      # wall-clock limit of each simulator call (default: timeout_for)

    [fixed]                              # settings of every run (same names as parameters)
    cycles = 4096
    tone = "z:0.02:2000"
    "structure.fem.refine" = 4           # a structure field (dotted path into STRUCTURE.toml)

    [[parameters]]
    name = "ts"
    values = ["1 us", "2 us", "3.2 us"]  # or start/stop/num (+ scale = "log"), or
                                         # distribution = "normal" (mean, std) / "uniform" (low, high)

Testbench parameters: TESTBENCH below (the `netgen sigma-delta` options). Structure parameters:
"structure.<table>.<key>", e.g. structure.electrodes.gap (every electrode set) or
structure.electrodes[1].gap (one of them); each such run writes its structure.toml and builds
its own model. Runs without structure parameters share one model, built once here and
scattered to the workers once.

Output: DIR/results.csv (one row per run: parameters, status, figures, error), DIR/runs/<run>/
(the run's working directory: summary.json, bitstreams, netlist, log; error.txt if it failed),
DIR/sweep.json (the plan and every run's record) and DIR/<figure>_vs_<x>.png. A run that fails
is recorded with its error and the others go on; a worker lost mid-run is retried. A re-run
into the same DIR reuses the runs that finished with the same settings.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..core.errors import SweepError
from ..core.files import read_bytes, toml_document
from ..core.options import Option, OptionError
from ..core.reader import Reader, did_you_mean
from ..core.text import text_problem
from ..core.units import UNITS, UnitError, parse_quantity
from ..testbench.sigma_delta import CHANNELS, OPTIONS, SWEEP, read_tone
from . import point as process_point

METRICS = ("bit_mean", "noise_floor_db_per_hz", "inband_noise_db", "tone_level_db", "snr_db", "slope_db_per_decade")
# result columns: <channel>.<metric> for any channel of the loop (the disk's z, tilt_x, tilt_y are
# listed; figure_ok accepts every coordinate name) and the run's own figures
RUN_FIGURES = ("gravity_balance.ratio", "wall_s")
FIGURES = tuple(f"{c}.{m}" for c in CHANNELS for m in METRICS) + RUN_FIGURES


def figure_ok(name: str) -> bool:
    """A result column: a run figure, or <coordinate>.<metric> (the loop's channels are its coordinates)."""
    c, dot, m = name.partition(".")
    return name in RUN_FIGURES or (bool(dot) and m in METRICS and re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", c) is not None)


MAX_RETRIES = 10
MAX_RUNS = 10_000  # default of `netgen sweep --max-runs`
PROCESS_PATHS = ("parameters", "rebuild")  # [sweep] process: how process.<name> values reach a run
# the parameter kinds of the sweep's table: a quantity kind (units.UNITS), or these
KINDS = {"int": "int", "choice": "str", "text": "tone", "bool": "bool"}


def testbench_table(sweep: dict[str, Option]) -> dict[str, tuple[str, Option, str]]:
    """The testbench parameters: (kind, its declared option, what it is) by sweep name, derived from the
    sigma-delta options (netgen.testbench.sigma_delta.options: the flags and [loop] keys of the same settings)."""
    return {name: (KINDS.get(o.type, o.quantity), o, o.help) for name, o in sweep.items()}


TESTBENCH = testbench_table(SWEEP)
SWEEP_TIMEOUT = OPTIONS["timeout"]  # [sweep] timeout: each simulator call's limit, as --timeout


def design_choices(sweep: dict[str, Option]) -> tuple[str, ...]:
    """The parameters that are the loop design's choices (sigma_delta.Choices: the options of role "design")."""
    return tuple(name for name, o in sweep.items() if o.role == "design")


DESIGN_CHOICES = design_choices(SWEEP)
LOOP_CHOICES = ("feedback_voltage", "acceleration")  # netgen.testbench.sigma_delta.RunRequest: over its LoopSpec


# ----------------------------------------------------------------------------- sweep file


@dataclass
class Parameter:
    """One swept quantity: a list of values (grid / zip) or a distribution (Monte Carlo)."""

    name: str
    values: list | None = None  # raw values (as written) for lists, SI numbers for ranges
    distribution: str | None = None  # "normal" or "uniform"
    a: float = 0.0  # mean or low (SI)
    b: float = 0.0  # std or high (SI)
    kind: str = ""

    @property
    def structure(self) -> bool:
        return self.name.startswith("structure.")


@dataclass
class Sweep:
    path: str
    parameters: list[Parameter]
    fixed: dict[str, Any]
    figure: str = "z.noise_floor_db_per_hz"
    x: str = ""
    mode: str = "grid"
    samples: int = 1
    seed: int = 1
    retries: int = 2
    plots: bool = False
    timeout: float | None = None  # s per simulator call; None: timeout_for(cycles)
    # process.<name> parameters: "parameters" = one [process] build, each run's point as instance
    # parameters; "rebuild" = the structure rebuilt at each point (the reference)
    process: str = "parameters"


def load_sweep(path: str | Path, max_runs: int = MAX_RUNS) -> Sweep:
    """Read and validate a sweep file; raises SweepError naming file, line, key and fix."""
    path = Path(path)
    try:
        data = read_bytes(path, "file", "a sweep file", SweepError)  # regular file, size cap
    except OSError as exc:
        raise SweepError(
            str(path),
            "file",
            f"cannot read the sweep file ({exc.strerror or exc})",
            "give the path of an existing SWEEP.toml (see examples/sweep_ts.toml)",
        ) from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise SweepError(
            str(path),
            "file",
            f"not UTF-8 text (byte {exc.start} is 0x{data[exc.start]:02x})",
            "save the sweep file as UTF-8 TOML (see examples/sweep_ts.toml)",
        ) from None
    if "\x00" in text:
        raise SweepError(
            str(path),
            "file",
            f"a NUL byte at offset {text.index(chr(0))}: not a text file",
            "give a TOML sweep file (see examples/sweep_ts.toml)",
        )
    return parse_sweep(text, str(path), max_runs)


def parse_sweep(text: str, path: str = "<string>", max_runs: int = MAX_RUNS) -> Sweep:
    """Validate sweep-file text into a Sweep; raises SweepError naming file, line, key and fix.
    `max_runs` bounds every value list (a range's num) before it is made."""
    rd = Reader(path, text, SweepError)
    doc = toml_document(text, path, SweepError, "correct the TOML syntax at that line")
    for key in doc:
        if key not in ("sweep", "fixed", "parameters"):
            raise rd.fail(
                key,
                f"unknown key or table '{key}'",
                f"{did_you_mean(key, ['sweep', 'fixed', 'parameters'])}use the tables [sweep], [fixed] "
                "and [[parameters]]",
            )
    head = doc.get("sweep", {})
    sweep = _read_head(rd, head, path)
    _read_fixed(rd, doc, sweep)
    names = _read_parameters(rd, doc, sweep, max_runs)
    _check_combination(rd, sweep, head, names)
    _check_skip(rd, sweep)
    return sweep


def _read_head(rd: Reader, head: Any, path: str) -> Sweep:
    """The [sweep] table: figure, mode, samples, seed, retries, timeout and plots."""
    if not isinstance(head, dict):
        raise rd.fail("sweep", "'sweep' must be a table", "write it as a [sweep] section")
    allowed = ["figure", "x", "mode", "samples", "seed", "retries", "plots", "timeout", "process"]
    for key in head:
        if key not in allowed:
            raise rd.fail(
                f"sweep.{key}",
                f"unknown key '{key}'",
                f"{did_you_mean(key, allowed)}allowed keys in [sweep]: {', '.join(allowed)}",
            )
    sweep = Sweep(path, [], {})
    if "figure" in head:
        if not isinstance(head["figure"], str) or not figure_ok(head["figure"]):
            raise rd.fail(
                "sweep.figure",
                f"figure {head['figure']!r} is not a result column",
                f"{did_you_mean(str(head['figure']), FIGURES)}use one of {', '.join(FIGURES)}",
            )
        sweep.figure = head["figure"]
    if "mode" in head:
        if not isinstance(head["mode"], str) or head["mode"] not in ("grid", "zip"):
            raise rd.fail(
                "sweep.mode",
                f"mode {head['mode']!r} is not 'grid' or 'zip'",
                "grid runs every combination of the value lists, zip pairs their k-th values",
            )
        sweep.mode = head["mode"]
    if "process" in head:
        if head["process"] not in PROCESS_PATHS:
            raise rd.fail(
                "sweep.process",
                f"process {head['process']!r} is not 'parameters' or 'rebuild'",
                "parameters: one build, the process.* values as instance parameters; rebuild: a build per run",
            )
        sweep.process = head["process"]
    for key, lo, hi in (("samples", 1, None), ("seed", 0, None), ("retries", 0, MAX_RETRIES)):
        if key in head:
            v = head[key]
            if isinstance(v, bool) or not isinstance(v, int) or v < lo or (hi is not None and v > hi):
                span = f">= {lo}" if hi is None else f"between {lo} and {hi}"
                raise rd.fail(f"sweep.{key}", f"{key} = {v!r} must be an integer {span}", f"write {key} = {max(lo, 1)}")
            setattr(sweep, key, v)
    if "timeout" in head:
        sweep.timeout = _timeout(rd, head["timeout"])
    if "plots" in head:
        if not isinstance(head["plots"], bool):
            raise rd.fail("sweep.plots", "plots must be true or false", "write plots = false")
        sweep.plots = head["plots"]

    return sweep


def _read_fixed(rd: Reader, doc: dict, sweep: Sweep) -> None:
    """The [fixed] table: every value checked as its option declares."""
    fixed = doc.get("fixed", {})
    if not isinstance(fixed, dict):
        raise rd.fail("fixed", "'fixed' must be a table", "write it as a [fixed] section")
    for name, value in _flatten(fixed):
        sweep.fixed[name] = check_value(rd, f"fixed.{name}", name, value)[0]


def _read_parameters(rd: Reader, doc: dict, sweep: Sweep, max_runs: int) -> list[str]:
    """The [[parameters]] entries, each swept once and not also fixed; returns their names."""
    params = doc.get("parameters", [])
    if not isinstance(params, list) or not all(isinstance(p, dict) for p in params) or not params:
        raise rd.fail(
            "parameters",
            "no [[parameters]] entries",
            'add at least one [[parameters]] table with name = "ts" and values = ["1 us", "2 us"]',
        )
    for k, p in enumerate(params):
        sweep.parameters.append(_parameter(rd, f"parameters[{k}]", p, max_runs))
    names = [p.name for p in sweep.parameters]
    for n in names:
        if names.count(n) > 1:
            raise rd.fail("parameters", f"parameter {n!r} is swept twice", "give each parameter once")
        if n in sweep.fixed:
            raise rd.fail(f"fixed.{n}", f"{n!r} is both fixed and swept", "remove it from [fixed] or [[parameters]]")
    return names


def _check_combination(rd: Reader, sweep: Sweep, head: Any, names: list[str]) -> None:
    """What the parameters allow together: zip lengths, samples with a distribution, x, the tone."""
    lists = [p for p in sweep.parameters if p.values is not None]
    if sweep.mode == "zip" and not lists:
        raise rd.fail(
            "sweep.mode",
            "zip pairs the k-th values of the value lists, and there is none (a distribution alone would give 0 runs)",
            'write mode = "grid" (samples = N draws of the distributions), or give a parameter values = [...]',
        )
    if sweep.mode == "zip" and len({len(p.values) for p in lists}) > 1:
        raise rd.fail(
            "sweep.mode",
            f"zip needs value lists of equal length (got {', '.join(f'{p.name}: {len(p.values)}' for p in lists)})",
            'give every list the same number of values, or use mode = "grid"',
        )
    random = [p for p in sweep.parameters if p.distribution]
    if sweep.samples > 1 and not random:
        raise rd.fail(
            "sweep.samples",
            f"samples = {sweep.samples} repeats identical runs (no distribution)",
            'drop samples, or give a parameter a distribution = "normal" (mean, std)',
        )
    sweep.x = head.get("x", names[0])
    if not isinstance(sweep.x, str) or sweep.x not in names:
        raise rd.fail("sweep.x", f"x = {sweep.x!r} is not a swept parameter", f"use one of {names}")
    tone = sweep.fixed.get("tone") or next((p.values[0] for p in lists if p.name == "tone"), None)
    for n in ("tone_amplitude", "tone_freq"):
        if (n in names or n in sweep.fixed) and not tone:
            raise rd.fail(
                n,
                f"{n} changes the test tone, but no tone is given",
                'add tone = "z:0.02:2000" (COORD:AMPLITUDE:FREQ) to [fixed]',
            )


def _timeout(rd: Reader, value: Any) -> float:
    """[sweep] timeout: the wall-clock limit of each simulator call (the --timeout option's check)."""
    try:
        return SWEEP_TIMEOUT.read(value, "timeout")
    except OptionError as exc:
        raise rd.fail("sweep.timeout", exc.problem, exc.fix) from None


def timeout_for(cycles: int) -> float:
    """Default wall-clock limit of one simulator call: 10 min plus 1 s per period, 14 times the
    full disk model's per-period cost measured on a loaded machine (bench/sweep_processes.py
    --calibrate: 0.071 s), so only a hung or runaway simulator reaches it."""
    return 600.0 + 1.0 * cycles


def _check_skip(rd: Reader, sweep: Sweep) -> None:
    """skip must leave half the periods: the runner would silently clip it to cycles // 2."""
    cycles = (
        [sweep.fixed.get("cycles", 4096)]
        if "cycles" in sweep.fixed
        else next((p.values for p in sweep.parameters if p.name == "cycles"), [4096])
    )
    skips = (
        [sweep.fixed["skip"]]
        if "skip" in sweep.fixed
        else next((p.values for p in sweep.parameters if p.name == "skip"), [])
    )
    where = (
        "fixed.skip"
        if "skip" in sweep.fixed
        else next((f"parameters[{k}].values" for k, p in enumerate(sweep.parameters) if p.name == "skip"), "skip")
    )
    for s in skips:
        if s > min(cycles) // 2:
            raise rd.fail(
                where,
                f"skip = {s} is more than half of cycles = {min(cycles)}",
                f"give skip <= {min(cycles) // 2} (periods left out at the start of the spectra)",
            )


def _flatten(table: dict, prefix: str = "") -> list[tuple[str, Any]]:
    """[fixed] entries as (dotted name, value): `structure.fem.refine = 4` nests in TOML."""
    out = []
    for k, v in table.items():
        name = f"{prefix}{k}"
        if isinstance(v, dict) and (prefix or k == "structure"):
            out += _flatten(v, name + ".")
        else:
            out.append((name, v))
    return out


def kind_of(value: Any) -> str:
    """Unit kind of a structure value written as a quantity string ('3 um' -> length)."""
    if isinstance(value, str):
        for kind in UNITS:
            try:
                parse_quantity(value, kind)
                return kind
            except UnitError:
                continue
    return "dimensionless"


def check_name(rd: Reader, where: str, name: str) -> None:
    if name.startswith("process."):
        if not process_point.known(name.split(".", 1)[1]):
            raise rd.fail(
                where,
                f"{name!r} is not a process parameter a sweep moves (process.tscale, process.escale, "
                "process.temp, process.etch, process.dg_<set>)",
                "sweep one of those (dg_<set>: the name of an electrode set above or below), or rebuild with "
                "structure.<table>.<key>",
            )
        return
    if name.startswith("structure."):
        if not re.fullmatch(r"structure(\.[A-Za-z_][A-Za-z0-9_]*(\[\d+\])?)+", name):
            raise rd.fail(
                where,
                f"structure parameter {name!r} is not a dotted path",
                "write e.g. structure.electrodes.gap or structure.electrodes[0].gap",
            )
        return
    if name not in TESTBENCH:
        raise rd.fail(
            where,
            f"unknown parameter {name!r}",
            f"{did_you_mean(name, TESTBENCH)}use a testbench parameter ({', '.join(TESTBENCH)}) "
            "or structure.<table>.<key>",
        )


def process_value(rd: Reader, where: str, name: str, value: Any) -> float:
    """One value of process.<name> in its unit (netgen.sweep.point.unit): tscale and escale ratios to
    the nominal, temp in degC, etch and dg_<set> lengths (m, or a quantity such as "50 nm")."""
    kind = process_point.unit(name.split(".", 1)[1])
    number = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if kind == "m" and isinstance(value, str):
        try:
            return parse_quantity(value, "length")
        except UnitError as exc:
            raise rd.fail(where, f"{name} = {value!r}: {exc}", f'write a length, e.g. {name} = "50 nm"') from None
    if kind == "ratio" and not (number and 0 < value < 10):
        raise rd.fail(where, f"{name} = {value!r} is not a ratio to the nominal", f"write e.g. {name} = 1.05")
    if kind == "degC" and not (number and value > -273.15):
        raise rd.fail(where, f"{name} = {value!r} is not a temperature in degC", f"write e.g. {name} = 85")
    if kind == "m" and not (number and abs(value) < 1e-3):
        raise rd.fail(where, f"{name} = {value!r} is not a length in m", f'write e.g. {name} = 5e-8 or "50 nm"')
    return float(value)


def check_value(rd: Reader, where: str, name: str, value: Any) -> tuple[Any, float | None]:
    """Validate one value of parameter `name`; return (value to use, SI number or None)."""
    check_name(rd, where, name)
    if isinstance(value, str) and text_problem(value):  # e.g. structure.description: header text
        raise rd.fail(
            where,
            f"{name}: the value {text_problem(value)}",
            "write it as one line of printable text (no line breaks, tabs or other control characters)",
        )
    if name.startswith("process."):
        v = process_value(rd, where, name, value)
        return v, v
    if name.startswith("structure."):
        if isinstance(value, (dict, list)):
            raise rd.fail(
                where, f"{name}: a structure value must be a number, string or boolean", 'write e.g. "3 um" or 3e-6'
            )
        if isinstance(value, str) and any(ord(ch) < 32 or ord(ch) == 127 for ch in value):
            raise rd.fail(
                where,
                f"{name}: the value {value!r} holds control characters (a newline, tab, ...)",
                "write the value on one line, printable characters only",
            )
        num = None
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            num = float(value)
        elif isinstance(value, str) and kind_of(value) != "dimensionless":
            num = parse_quantity(value, kind_of(value))
        return value, num
    kind, option, _ = TESTBENCH[name]
    if kind == "tone":
        return _tone(rd, where, value), None
    try:
        v = option.read(value, name)
    except OptionError as exc:
        raise rd.fail(where, exc.problem, exc.fix) from None
    return v, (None if kind == "str" else float(v))


def _tone(rd: Reader, where: str, value: Any) -> str:
    """A tone COORD:AMPLITUDE:FREQ checked as --tone is (options.read_tone; f_s/2 in check.py)."""
    if value in ("", None):
        return ""
    try:
        coord, _, _ = read_tone(value, "tone")
    except OptionError as exc:
        raise rd.fail(where, exc.problem, exc.fix) from None
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", coord):
        raise rd.fail(
            where,
            f"tone {value!r}: {coord!r} is not a coordinate name",
            'name a coordinate of the model, e.g. "z:0.02:2000" or "tilt_x:0.5:1000"',
        )
    return value


def _number(rd: Reader, where: str, p: dict, key: str, kind: str) -> float:
    """A range's or distribution's number at `key`, in the unit of the parameter's kind."""
    if key not in p:
        raise rd.fail(f"{where}.{key}", f"missing key '{key}'", f"add {key} = <number or quantity>")
    try:
        v = (
            float(p[key])
            if isinstance(p[key], (int, float)) and not isinstance(p[key], bool)
            else parse_quantity(p[key], "dimensionless" if kind == "int" else kind)
        )
    except UnitError as exc:
        raise rd.fail(f"{where}.{key}", str(exc), f"write {key} in the unit of {p['name']}") from None
    if not math.isfinite(v):
        raise rd.fail(f"{where}.{key}", f"{key} is not finite", f"give a finite {key}")
    return v


def _parameter(rd: Reader, where: str, p: dict, max_runs: int = MAX_RUNS) -> Parameter:
    """One [[parameters]] entry: its name and its values list, range or distribution, checked."""
    allowed = ["name", "values", "start", "stop", "num", "scale", "distribution", "mean", "std", "low", "high"]
    for key in p:
        if key not in allowed:
            raise rd.fail(
                f"{where}.{key}",
                f"unknown key '{key}'",
                f"{did_you_mean(key, allowed)}allowed keys: {', '.join(allowed)}",
            )
    name = p.get("name")
    if not isinstance(name, str) or not name:
        raise rd.fail(f"{where}.name", "missing parameter name", 'add name = "ts" (or structure.electrodes.gap)')
    check_name(rd, f"{where}.name", name)
    forms = [
        f
        for f, keys in (("values", ["values"]), ("range", ["start", "stop", "num"]), ("distribution", ["distribution"]))
        if any(k in p for k in keys)
    ]
    if len(forms) != 1:
        raise rd.fail(
            where,
            f"parameter {name!r} needs exactly one of values, start/stop/num or distribution (got {forms or 'none'})",
            'e.g. values = ["1 us", "2 us"]',
        )
    kind = TESTBENCH[name][0] if name in TESTBENCH else None
    if forms[0] == "values":
        vals = p["values"]
        if not isinstance(vals, list) or not vals:
            raise rd.fail(f"{where}.values", "values must be a non-empty list", 'write values = ["1 us", "2 us"]')
        return Parameter(name, [check_value(rd, f"{where}.values", name, v)[0] for v in vals], kind=kind or "")
    if kind in ("bool", "str", "tone"):
        raise rd.fail(
            where, f"{name} takes a list of values, not a range or distribution", f"write values = [...] for {name}"
        )
    if kind is None:
        sample = p.get("start", p.get("mean", p.get("low")))
        kind = kind_of(sample)

    if forms[0] == "range":
        return _range(rd, where, p, kind, max_runs)
    return _distribution(rd, where, p, kind)


def _range(rd: Reader, where: str, p: dict, kind: str, max_runs: int) -> Parameter:
    """A start/stop/num entry: its values on a linear or log scale, each checked."""
    name = p["name"]
    start, stop = _number(rd, where, p, "start", kind), _number(rd, where, p, "stop", kind)
    num = p.get("num")
    if isinstance(num, bool) or not isinstance(num, int) or num < 1:
        raise rd.fail(f"{where}.num", f"num = {num!r} must be an integer >= 1", "write num = 4")
    if num > max_runs:
        raise rd.fail(
            f"{where}.num",
            f"num = {num} values alone exceed the sweep's limit of {max_runs} runs",
            f"give num <= {max_runs} (or raise the limit with --max-runs)",
        )
    scale = p.get("scale", "linear")
    if scale not in ("linear", "log"):
        raise rd.fail(f"{where}.scale", f"scale {scale!r} is not 'linear' or 'log'", 'write scale = "log"')
    if scale == "log" and (start <= 0 or stop <= 0):
        raise rd.fail(f"{where}.start", "a log range needs start and stop > 0", 'use scale = "linear"')
    vals = (np.geomspace if scale == "log" else np.linspace)(start, stop, num).tolist()
    if kind == "int":
        vals = [int(round(v)) for v in vals]
    return Parameter(name, [check_value(rd, where, name, v)[0] for v in vals], kind=kind)


def _distribution(rd: Reader, where: str, p: dict, kind: str) -> Parameter:
    """A normal (mean, std) or uniform (low, high) entry."""
    name = p["name"]
    dist = p["distribution"]
    if dist not in ("normal", "uniform"):
        raise rd.fail(
            f"{where}.distribution",
            f"distribution {dist!r} is not 'normal' or 'uniform'",
            'write distribution = "normal" (mean, std) or "uniform" (low, high)',
        )
    if kind == "int":
        raise rd.fail(
            f"{where}.distribution",
            f"{name} is an integer; it cannot be drawn from a distribution",
            "give it values = [...]",
        )
    a, b = (
        (_number(rd, where, p, "mean", kind), _number(rd, where, p, "std", kind))
        if dist == "normal"
        else (_number(rd, where, p, "low", kind), _number(rd, where, p, "high", kind))
    )
    if (dist == "normal" and b < 0) or (dist == "uniform" and b < a):
        raise rd.fail(
            where,
            "std must be >= 0" if dist == "normal" else "high must be >= low",
            "correct the distribution's parameters",
        )
    return Parameter(name, None, dist, a, b, kind)
