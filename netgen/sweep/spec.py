"""`netgen sweep STRUCTURE.toml SWEEP.toml -o DIR`: parameter sweeps and Monte Carlo of the
sigma-delta loop (netgen.testbench.sigma_delta), run through netgen.executor (local processes or Dask).

SWEEP.toml (see examples/sweep_ts.toml):

    [sweep]
    figure = "z.noise_floor_db_per_hz"   # the column plotted against x (see FIGURES)
    x = "ts"                             # parameter on the plot's x axis (default: the first)
    mode = "grid"                        # grid: every combination of the value lists; zip: k-th values together
    samples = 1                          # Monte Carlo draws per grid point (with distributions)
    seed = 1                             # of the Monte Carlo draws
    retries = 2                          # resubmissions of a run whose worker was lost
    plots = false                        # each run's spectra.png / coordinates.png

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

from ..errors import SweepError
from ..files import toml_document
from ..structure.reader import Reader, did_you_mean
from ..testbench.sigma_delta import CHANNELS, RELTOL_RANGE, RELTOL_TEXT, SIMULATORS, Tone
from ..text import text_problem
from ..units import UNITS, UnitError, parse_quantity

METRICS = ("bit_mean", "noise_floor_db_per_hz", "inband_noise_db", "tone_level_db", "snr_db",
           "slope_db_per_decade")
FIGURES = tuple(f"{c}.{m}" for c in CHANNELS for m in METRICS) + ("gravity_balance.ratio", "wall_s")

# testbench parameter: (kind, check -> problem or None, what it is)
TESTBENCH: dict[str, tuple[str, Any, str]] = {
    "ts": ("time", lambda v: None if v > 0 else "must be > 0", "sampling period T_s"),
    "cycles": ("int", lambda v: None if v >= 64 else "must be >= 64", "number of sampling periods"),
    "skip": ("int", lambda v: None if v >= 0 else "must be >= 0", "periods skipped before the spectra"),
    "lead": ("dimensionless", lambda v: None, "lead-compensator coefficient"),
    "density": ("dimensionless", lambda v: None if 0 < v < 1 else "must be between 0 and 1",
                "mean z bit that balances gravity"),
    "sense_ratio": ("dimensionless", lambda v: None if v > 0 else "must be > 0", "V_s / V_fb"),
    "full_scale": ("dimensionless", lambda v: None if v > 0 else "must be > 0", "readout full scale"),
    "dither": ("dimensionless", lambda v: None if v >= 0 else "must be >= 0",
               "comparator dither, fraction of a_fb T_s^2"),
    "tone": ("tone", None, "test tone COORD:AMPLITUDE:FREQ"),
    "tone_amplitude": ("dimensionless", lambda v: None, "tone amplitude (f_ port unit)"),
    "tone_freq": ("frequency", lambda v: None if v > 0 else "must be > 0", "tone frequency"),
    "rigid_only": ("bool", None, "drop the eigenmodes"),
    "simulator": ("str", None, f"circuit simulator of the run ({', '.join(SIMULATORS)})"),
    "reltol": ("dimensionless", lambda v: _reltol_problem(v), "relative tolerance of the simulator"),
}
DESIGN_CHOICES = ("lead", "density", "sense_ratio", "full_scale", "dither", "reltol")


def _reltol_problem(value: float) -> str | None:
    """The range `netgen sigma-delta --reltol` accepts (netgen.testbench.sigma_delta.RELTOL_RANGE)."""
    lo, hi = RELTOL_RANGE
    return None if lo <= value <= hi else f"must be between {RELTOL_TEXT.replace('..', ' and ')}"


# ----------------------------------------------------------------------------- sweep file


@dataclass
class Parameter:
    """One swept quantity: a list of values (grid / zip) or a distribution (Monte Carlo)."""
    name: str
    values: list | None = None             # raw values (as written) for lists, SI numbers for ranges
    distribution: str | None = None        # "normal" or "uniform"
    a: float = 0.0                         # mean or low (SI)
    b: float = 0.0                         # std or high (SI)
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


def load_sweep(path: str | Path) -> Sweep:
    """Read and validate a sweep file; raises SweepError naming file, line, key and fix."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SweepError(str(path), "file", f"cannot read the sweep file ({exc.strerror})",
                         "give the path of an existing SWEEP.toml (see examples/sweep_ts.toml)") from None
    return parse_sweep(text, str(path))


def parse_sweep(text: str, path: str = "<string>") -> Sweep:
    """Validate sweep-file text into a Sweep; raises SweepError naming file, line, key and fix."""
    rd = Reader(path, text, SweepError)
    doc = toml_document(text, path, SweepError, "correct the TOML syntax at that line")
    for key in doc:
        if key not in ("sweep", "fixed", "parameters"):
            raise rd.fail(key, f"unknown key or table '{key}'",
                          f"{did_you_mean(key, ['sweep', 'fixed', 'parameters'])}use the tables [sweep], [fixed] "
                          "and [[parameters]]")
    head = doc.get("sweep", {})
    if not isinstance(head, dict):
        raise rd.fail("sweep", "'sweep' must be a table", "write it as a [sweep] section")
    allowed = ["figure", "x", "mode", "samples", "seed", "retries", "plots"]
    for key in head:
        if key not in allowed:
            raise rd.fail(f"sweep.{key}", f"unknown key '{key}'",
                          f"{did_you_mean(key, allowed)}allowed keys in [sweep]: {', '.join(allowed)}")
    sweep = Sweep(path, [], {})
    if "figure" in head:
        if head["figure"] not in FIGURES:
            raise rd.fail("sweep.figure", f"figure {head['figure']!r} is not a result column",
                          f"{did_you_mean(str(head['figure']), FIGURES)}use one of {', '.join(FIGURES)}")
        sweep.figure = head["figure"]
    if "mode" in head:
        if head["mode"] not in ("grid", "zip"):
            raise rd.fail("sweep.mode", f"mode {head['mode']!r} is not 'grid' or 'zip'",
                          "grid runs every combination of the value lists, zip pairs their k-th values")
        sweep.mode = head["mode"]
    for key, lo in (("samples", 1), ("seed", 0), ("retries", 0)):
        if key in head:
            v = head[key]
            if isinstance(v, bool) or not isinstance(v, int) or v < lo:
                raise rd.fail(f"sweep.{key}", f"{key} = {v!r} must be an integer >= {lo}", f"write {key} = {max(lo, 1)}")
            setattr(sweep, key, v)
    if "plots" in head:
        if not isinstance(head["plots"], bool):
            raise rd.fail("sweep.plots", "plots must be true or false", "write plots = false")
        sweep.plots = head["plots"]

    fixed = doc.get("fixed", {})
    if not isinstance(fixed, dict):
        raise rd.fail("fixed", "'fixed' must be a table", "write it as a [fixed] section")
    for name, value in _flatten(fixed):
        sweep.fixed[name] = check_value(rd, f"fixed.{name}", name, value)[0]

    params = doc.get("parameters", [])
    if not isinstance(params, list) or not all(isinstance(p, dict) for p in params) or not params:
        raise rd.fail("parameters", "no [[parameters]] entries",
                      'add at least one [[parameters]] table with name = "ts" and values = ["1 us", "2 us"]')
    for k, p in enumerate(params):
        sweep.parameters.append(_parameter(rd, f"parameters[{k}]", p))
    names = [p.name for p in sweep.parameters]
    for n in names:
        if names.count(n) > 1:
            raise rd.fail("parameters", f"parameter {n!r} is swept twice", "give each parameter once")
        if n in sweep.fixed:
            raise rd.fail(f"fixed.{n}", f"{n!r} is both fixed and swept", "remove it from [fixed] or [[parameters]]")
    lists = [p for p in sweep.parameters if p.values is not None]
    if sweep.mode == "zip" and len({len(p.values) for p in lists}) > 1:
        raise rd.fail("sweep.mode", "zip needs value lists of equal length (got "
                      f"{', '.join(f'{p.name}: {len(p.values)}' for p in lists)})",
                      "give every list the same number of values, or use mode = \"grid\"")
    random = [p for p in sweep.parameters if p.distribution]
    if sweep.samples > 1 and not random:
        raise rd.fail("sweep.samples", f"samples = {sweep.samples} repeats identical runs (no distribution)",
                      "drop samples, or give a parameter a distribution = \"normal\" (mean, std)")
    sweep.x = head.get("x", names[0])
    if sweep.x not in names:
        raise rd.fail("sweep.x", f"x = {sweep.x!r} is not a swept parameter", f"use one of {names}")
    tone = sweep.fixed.get("tone") or next((p.values[0] for p in lists if p.name == "tone"), None)
    for n in ("tone_amplitude", "tone_freq"):
        if (n in names or n in sweep.fixed) and not tone:
            raise rd.fail(n, f"{n} changes the test tone, but no tone is given",
                          'add tone = "z:0.02:2000" (COORD:AMPLITUDE:FREQ) to [fixed]')
    return sweep


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
    if name.startswith("structure."):
        if not re.fullmatch(r"structure(\.[A-Za-z_][A-Za-z0-9_]*(\[\d+\])?)+", name):
            raise rd.fail(where, f"structure parameter {name!r} is not a dotted path",
                          "write e.g. structure.electrodes.gap or structure.electrodes[0].gap")
        return
    if name not in TESTBENCH:
        raise rd.fail(where, f"unknown parameter {name!r}",
                      f"{did_you_mean(name, TESTBENCH)}use a testbench parameter ({', '.join(TESTBENCH)}) "
                      "or structure.<table>.<key>")


def check_value(rd: Reader, where: str, name: str, value: Any) -> tuple[Any, float | None]:
    """Validate one value of parameter `name`; return (value to use, SI number or None)."""
    check_name(rd, where, name)
    if isinstance(value, str) and text_problem(value):        # e.g. structure.description: header text
        raise rd.fail(where, f"{name}: the value {text_problem(value)}",
                      "write it as one line of printable text (no line breaks, tabs or other control characters)")
    if name.startswith("structure."):
        if isinstance(value, (dict, list)):
            raise rd.fail(where, f"{name}: a structure value must be a number, string or boolean",
                          'write e.g. "3 um" or 3e-6')
        num = None
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            num = float(value)
        elif isinstance(value, str) and kind_of(value) != "dimensionless":
            num = parse_quantity(value, kind_of(value))
        return value, num
    kind, check, what = TESTBENCH[name]
    if kind == "bool":
        if not isinstance(value, bool):
            raise rd.fail(where, f"{name} = {value!r} must be true or false", f"write {name} = false")
        return value, float(value)
    if kind == "str":
        if not isinstance(value, str) or not value:
            raise rd.fail(where, f"{name} = {value!r} must be a name", f'write {name} = "ngspice"')
        if name == "simulator" and value not in SIMULATORS:
            raise rd.fail(where, f"simulator = {value!r} is not one of {list(SIMULATORS)}",
                          f"{did_you_mean(value, list(SIMULATORS))}use one of {', '.join(SIMULATORS)}")
        return value, None
    if kind == "tone":
        if value in ("", None):
            return "", None
        try:
            Tone.parse(str(value))
        except ValueError as exc:
            raise rd.fail(where, str(exc), 'write tone = "z:0.02:2000" (coordinate, amplitude, frequency in Hz)')
        return str(value), None
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise rd.fail(where, f"{name} = {value!r} must be an integer", f"write {name} = <integer> ({what})")
        num = float(value)
    else:
        try:
            num = parse_quantity(value, kind)
        except UnitError as exc:
            raise rd.fail(where, f"{name}: {exc}", f"write {name} as a number in SI units or a {kind} "
                          f"string ({what})")
    if not math.isfinite(num) or (check and check(num)):
        raise rd.fail(where, f"{name} = {value!r} {check(num) if math.isfinite(num) else 'is not finite'}",
                      f"give a valid {what}")
    return (int(value) if kind == "int" else num), num


def _parameter(rd: Reader, where: str, p: dict) -> Parameter:
    allowed = ["name", "values", "start", "stop", "num", "scale", "distribution", "mean", "std", "low", "high"]
    for key in p:
        if key not in allowed:
            raise rd.fail(f"{where}.{key}", f"unknown key '{key}'",
                          f"{did_you_mean(key, allowed)}allowed keys: {', '.join(allowed)}")
    name = p.get("name")
    if not isinstance(name, str):
        raise rd.fail(f"{where}.name", "missing parameter name", 'add name = "ts" (or structure.electrodes.gap)')
    check_name(rd, f"{where}.name", name)
    forms = [f for f, keys in (("values", ["values"]), ("range", ["start", "stop", "num"]),
                               ("distribution", ["distribution"])) if any(k in p for k in keys)]
    if len(forms) != 1:
        raise rd.fail(where, f"parameter {name!r} needs exactly one of values, start/stop/num or distribution "
                      f"(got {forms or 'none'})", 'e.g. values = ["1 us", "2 us"]')
    kind = TESTBENCH[name][0] if name in TESTBENCH else None
    if forms[0] == "values":
        vals = p["values"]
        if not isinstance(vals, list) or not vals:
            raise rd.fail(f"{where}.values", "values must be a non-empty list", 'write values = ["1 us", "2 us"]')
        return Parameter(name, [check_value(rd, f"{where}.values", name, v)[0] for v in vals], kind=kind or "")
    if kind in ("bool", "str", "tone"):
        raise rd.fail(where, f"{name} takes a list of values, not a range or distribution",
                      f"write values = [...] for {name}")
    if kind is None:
        sample = p.get("start", p.get("mean", p.get("low")))
        kind = kind_of(sample)

    def number(key: str) -> float:
        if key not in p:
            raise rd.fail(f"{where}.{key}", f"missing key '{key}'", f"add {key} = <number or quantity>")
        try:
            v = float(p[key]) if isinstance(p[key], (int, float)) and not isinstance(p[key], bool) else \
                parse_quantity(p[key], "dimensionless" if kind == "int" else kind)
        except UnitError as exc:
            raise rd.fail(f"{where}.{key}", str(exc), f"write {key} in the unit of {name}")
        if not math.isfinite(v):
            raise rd.fail(f"{where}.{key}", f"{key} is not finite", f"give a finite {key}")
        return v

    if forms[0] == "range":
        start, stop = number("start"), number("stop")
        num = p.get("num")
        if isinstance(num, bool) or not isinstance(num, int) or num < 1:
            raise rd.fail(f"{where}.num", f"num = {num!r} must be an integer >= 1", "write num = 4")
        scale = p.get("scale", "linear")
        if scale not in ("linear", "log"):
            raise rd.fail(f"{where}.scale", f"scale {scale!r} is not 'linear' or 'log'", 'write scale = "log"')
        if scale == "log" and (start <= 0 or stop <= 0):
            raise rd.fail(f"{where}.start", "a log range needs start and stop > 0", 'use scale = "linear"')
        vals = (np.geomspace if scale == "log" else np.linspace)(start, stop, num).tolist()
        if kind == "int":
            vals = [int(round(v)) for v in vals]
        return Parameter(name, [check_value(rd, where, name, v)[0] for v in vals], kind=kind)
    dist = p["distribution"]
    if dist not in ("normal", "uniform"):
        raise rd.fail(f"{where}.distribution", f"distribution {dist!r} is not 'normal' or 'uniform'",
                      'write distribution = "normal" (mean, std) or "uniform" (low, high)')
    if kind == "int":
        raise rd.fail(f"{where}.distribution", f"{name} is an integer; it cannot be drawn from a distribution",
                      "give it values = [...]")
    a, b = (number("mean"), number("std")) if dist == "normal" else (number("low"), number("high"))
    if (dist == "normal" and b < 0) or (dist == "uniform" and b < a):
        raise rd.fail(where, "std must be >= 0" if dist == "normal" else "high must be >= low",
                      "correct the distribution's parameters")
    return Parameter(name, None, dist, a, b, kind)
