"""`netgen sweep STRUCTURE.toml SWEEP.toml -o DIR`: parameter sweeps and Monte Carlo of the
sigma-delta loop (netgen.sigma_delta), run through netgen.executor (local processes or Dask).

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

import csv
import hashlib
import inspect
import itertools
import json
import math
import os
import re
import shutil
import signal
import sys
import time
import tomllib
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .units import UNITS, UnitError, parse_quantity

METRICS = ("bit_mean", "noise_floor_db_per_hz", "inband_noise_db", "tone_level_db", "snr_db",
           "slope_db_per_decade")
CHANNELS = ("z", "tilt_x", "tilt_y")
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
    "simulator": ("str", None, "circuit simulator of the run (ngspice, ngspice-xspice, vacask)"),
    "reltol": ("dimensionless", lambda v: _reltol_problem(v), "relative tolerance of the simulator"),
}
DESIGN_CHOICES = ("lead", "density", "sense_ratio", "full_scale", "dither", "reltol")


def _reltol_problem(value: float) -> str | None:
    """The range `netgen sigma-delta --reltol` accepts (netgen.sigma_delta.RELTOL_RANGE)."""
    from .sigma_delta import RELTOL_RANGE, RELTOL_TEXT
    lo, hi = RELTOL_RANGE
    return None if lo <= value <= hi else f"must be between {RELTOL_TEXT.replace('..', ' and ')}"


class SweepError(Exception):
    """Invalid sweep file: file, line, key, problem and fix, like StructureError."""

    def __init__(self, path: str, where: str, problem: str, fix: str, line: int | None = None):
        self.path, self.where, self.problem, self.fix, self.line = path, where, problem, fix, line
        loc = f"{path}:{line}" if line else path
        super().__init__(f"{loc}: {where}: {problem}\n  fix: {fix}")


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


class _Lines:
    """Line numbers of keys in the sweep file, for error messages (same rules as structure files)."""

    def __init__(self, path: str, text: str):
        from .structure.reader import Reader
        self.path, self.reader = path, Reader(path, text)

    def fail(self, where: str, problem: str, fix: str) -> SweepError:
        return SweepError(self.path, where, problem, fix, self.reader.line_of(where))


def _close(word: str, options) -> str:
    import difflib
    m = difflib.get_close_matches(word, list(options), n=1, cutoff=0.6)
    return f"did you mean '{m[0]}'? " if m else ""


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
    from .files import toml_document
    rd = _Lines(path, text)
    doc = toml_document(text, path, SweepError, "correct the TOML syntax at that line")
    for key in doc:
        if key not in ("sweep", "fixed", "parameters"):
            raise rd.fail(key, f"unknown key or table '{key}'",
                          f"{_close(key, ['sweep', 'fixed', 'parameters'])}use the tables [sweep], [fixed] "
                          "and [[parameters]]")
    head = doc.get("sweep", {})
    if not isinstance(head, dict):
        raise rd.fail("sweep", "'sweep' must be a table", "write it as a [sweep] section")
    allowed = ["figure", "x", "mode", "samples", "seed", "retries", "plots"]
    for key in head:
        if key not in allowed:
            raise rd.fail(f"sweep.{key}", f"unknown key '{key}'",
                          f"{_close(key, allowed)}allowed keys in [sweep]: {', '.join(allowed)}")
    sweep = Sweep(path, [], {})
    if "figure" in head:
        if head["figure"] not in FIGURES:
            raise rd.fail("sweep.figure", f"figure {head['figure']!r} is not a result column",
                          f"{_close(str(head['figure']), FIGURES)}use one of {', '.join(FIGURES)}")
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
        sweep.fixed[name] = _check_value(rd, f"fixed.{name}", name, value)[0]

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
            raise rd.fail(f"fixed.{n}", f"{n!r} is both fixed and swept", f"remove it from [fixed] or [[parameters]]")
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


def _kind_of(value: Any) -> str:
    """Unit kind of a structure value written as a quantity string ('3 um' -> length)."""
    if isinstance(value, str):
        for kind in UNITS:
            try:
                parse_quantity(value, kind)
                return kind
            except UnitError:
                continue
    return "dimensionless"


def _check_name(rd: _Lines, where: str, name: str) -> None:
    if name.startswith("structure."):
        if not re.fullmatch(r"structure(\.[A-Za-z_][A-Za-z0-9_]*(\[\d+\])?)+", name):
            raise rd.fail(where, f"structure parameter {name!r} is not a dotted path",
                          "write e.g. structure.electrodes.gap or structure.electrodes[0].gap")
        return
    if name not in TESTBENCH:
        raise rd.fail(where, f"unknown parameter {name!r}",
                      f"{_close(name, TESTBENCH)}use a testbench parameter ({', '.join(TESTBENCH)}) "
                      "or structure.<table>.<key>")
    if name == "simulator":
        from . import sigma_delta as sd
        if "simulator" not in inspect.signature(sd.run).parameters:
            raise rd.fail(where, "this netgen's sigma-delta loop runs ngspice only (no simulator choice)",
                          "drop the simulator parameter")


def _check_value(rd: _Lines, where: str, name: str, value: Any) -> tuple[Any, float | None]:
    """Validate one value of parameter `name`; return (value to use, SI number or None)."""
    _check_name(rd, where, name)
    if name.startswith("structure."):
        if isinstance(value, (dict, list)):
            raise rd.fail(where, f"{name}: a structure value must be a number, string or boolean",
                          'write e.g. "3 um" or 3e-6')
        num = None
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            num = float(value)
        elif isinstance(value, str) and _kind_of(value) != "dimensionless":
            num = parse_quantity(value, _kind_of(value))
        return value, num
    kind, check, what = TESTBENCH[name]
    if kind == "bool":
        if not isinstance(value, bool):
            raise rd.fail(where, f"{name} = {value!r} must be true or false", f"write {name} = false")
        return value, float(value)
    if kind == "str":
        if not isinstance(value, str) or not value:
            raise rd.fail(where, f"{name} = {value!r} must be a name", f'write {name} = "ngspice"')
        return value, None
    if kind == "tone":
        from .sigma_delta import Tone
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


def _parameter(rd: _Lines, where: str, p: dict) -> Parameter:
    allowed = ["name", "values", "start", "stop", "num", "scale", "distribution", "mean", "std", "low", "high"]
    for key in p:
        if key not in allowed:
            raise rd.fail(f"{where}.{key}", f"unknown key '{key}'",
                          f"{_close(key, allowed)}allowed keys: {', '.join(allowed)}")
    name = p.get("name")
    if not isinstance(name, str):
        raise rd.fail(f"{where}.name", "missing parameter name", 'add name = "ts" (or structure.electrodes.gap)')
    _check_name(rd, f"{where}.name", name)
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
        return Parameter(name, [_check_value(rd, f"{where}.values", name, v)[0] for v in vals], kind=kind or "")
    if kind in ("bool", "str", "tone"):
        raise rd.fail(where, f"{name} takes a list of values, not a range or distribution",
                      f"write values = [...] for {name}")
    if kind is None:
        sample = p.get("start", p.get("mean", p.get("low")))
        kind = _kind_of(sample)

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
        return Parameter(name, [_check_value(rd, where, name, v)[0] for v in vals], kind=kind)
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


# ----------------------------------------------------------------------------- the runs


@dataclass
class RunSpec:
    """One run: its folder, parameter values (as shown), testbench options and structure text."""
    index: int
    name: str
    dir: str
    params: dict[str, Any]
    testbench: dict[str, Any]
    rigid_only: bool = False
    structure_text: str | None = None
    plots: bool = False
    key: str = ""


def plan(sweep: Sweep, structure_path: str | Path, out: Path) -> list[RunSpec]:
    """The runs of a sweep: grid/zip of the value lists x `samples` Monte Carlo draws (seeded)."""
    lists = [p for p in sweep.parameters if p.values is not None]
    random = [p for p in sweep.parameters if p.distribution]
    combos = list(itertools.product(*[p.values for p in lists])) if sweep.mode == "grid" \
        else list(zip(*[p.values for p in lists]))
    rng = np.random.default_rng(sweep.seed)
    base_text = Path(structure_path).read_text(encoding="utf-8")
    base_doc = tomllib.loads(base_text)
    for name in [n for n in sweep.fixed if n.startswith("structure.")] + \
            [p.name for p in sweep.parameters if p.structure]:
        _set_path(json.loads(json.dumps(base_doc)), name, 0, str(structure_path), sweep.path)
    width = len(str(len(combos) * sweep.samples - 1))
    runs = []
    for combo in combos:
        for _ in range(sweep.samples):
            params = dict(zip([p.name for p in lists], combo))
            for p in random:
                v = float(rng.normal(p.a, p.b) if p.distribution == "normal" else rng.uniform(p.a, p.b))
                params[p.name] = v
            index = len(runs)
            runs.append(_spec(index, f"run_{index:0{width}d}", out, sweep, params, base_doc, structure_path))
    return runs


def _spec(index: int, name: str, out: Path, sweep: Sweep, params: dict, base_doc: dict,
          structure_path: str | Path) -> RunSpec:
    values = {**sweep.fixed, **params}
    tb: dict[str, Any] = {"ts": 1e-6, "cycles": 4096}
    tone = None
    overrides = {}
    rigid = False
    for n, v in values.items():
        if n.startswith("structure."):
            overrides[n] = v
        elif n == "rigid_only":
            rigid = bool(v)
        elif n == "tone":
            tone = v or None
        elif n in ("tone_amplitude", "tone_freq"):
            continue
        elif TESTBENCH[n][0] == "str":
            tb[n] = v
        elif TESTBENCH[n][0] == "int":
            tb[n] = int(v)
        else:
            tb[n] = float(parse_quantity(v, TESTBENCH[n][0]))
    if tone is not None:
        coord, amp, freq = str(tone).split(":")
        amp = str(values.get("tone_amplitude", amp))
        freq = str(parse_quantity(values["tone_freq"], "frequency")) if "tone_freq" in values else freq
        tb["tone"] = f"{coord}:{amp}:{freq}"
    text = None
    if overrides:
        doc = json.loads(json.dumps(base_doc))
        for n, v in overrides.items():
            _set_path(doc, n, v, str(structure_path), sweep.path)
        text = f"# {structure_path} with {', '.join(f'{k} = {v!r}' for k, v in overrides.items())}\n" + to_toml(doc)
    spec = RunSpec(index, name, str(out / "runs" / name), params, tb, rigid, text, sweep.plots)
    spec.key = hashlib.sha256(json.dumps([tb, rigid, text, sweep.plots], sort_keys=True,
                                         default=str).encode()).hexdigest()[:16]
    return spec


def _set_path(doc: dict, name: str, value: Any, structure: str, sweep: str) -> None:
    """Set structure.<path> in the TOML document (a list without [i]: every entry)."""
    parts = re.findall(r"([A-Za-z_][A-Za-z0-9_]*)(?:\[(\d+)\])?", name[len("structure."):])
    targets = [doc]
    for depth, (key, idx) in enumerate(parts):
        last = depth == len(parts) - 1
        nxt = []
        for t in targets:
            if not isinstance(t, dict) or key not in t:
                have = sorted(t) if isinstance(t, dict) else []
                raise SweepError(sweep, name, f"{structure} has no key '{key}' here (has {', '.join(have)})",
                                 f"{_close(key, have)}give a path that exists in the structure file (to sweep "
                                 "an optional key, write it there first with its base value)", _line(sweep, name))
            if last:
                if idx:
                    seq = t.get(key)
                    if not isinstance(seq, list) or int(idx) >= len(seq):
                        raise SweepError(sweep, name, f"{structure}: {key} has no entry {idx}",
                                         "use an index that exists (counting from 0)", _line(sweep, name))
                    seq[int(idx)] = value
                else:
                    t[key] = value
                continue
            v = t[key]
            if idx:
                if not isinstance(v, list) or int(idx) >= len(v):
                    raise SweepError(sweep, name, f"{structure}: {key} has no entry {idx}",
                                     f"{key} has {len(v) if isinstance(v, list) else 0} entries (counting from 0)",
                                     _line(sweep, name))
                nxt.append(v[int(idx)])
            elif isinstance(v, list):
                nxt.extend(v)                          # e.g. every [[electrodes]] table
            else:
                nxt.append(v)
        targets = nxt


def _line(path: str, text: str) -> int | None:
    """First line of the file `path` that mentions `text` (None if unreadable)."""
    try:
        for no, line in enumerate(Path(path).read_text(encoding="utf-8").splitlines(), start=1):
            if text in line:
                return no
    except OSError:
        pass
    return None


def to_toml(doc: dict) -> str:
    """A TOML document (tables, arrays of tables, scalars and arrays) as text."""
    def scalar(v: Any) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, int):
            return str(v)
        if isinstance(v, float):
            return repr(v) if math.isfinite(v) else ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf"))
        if isinstance(v, str):
            return json.dumps(v, ensure_ascii=False)
        if isinstance(v, list):
            return "[" + ", ".join(scalar(x) for x in v) + "]"
        if isinstance(v, dict):
            return "{" + ", ".join(f"{json.dumps(k)} = {scalar(x)}" for k, x in v.items()) + "}"
        raise TypeError(f"cannot write {type(v).__name__} as TOML")

    def table(d: dict, name: str) -> list[str]:
        lines = [f"{json.dumps(k)} = {scalar(v)}" for k, v in d.items() if not _is_table(v)]
        out = [f"[{name}]", *lines, ""] if name else [*lines, ""]
        for k, v in d.items():
            sub = f"{name}.{json.dumps(k)}" if name else json.dumps(k)
            if isinstance(v, dict):
                out += table(v, sub)
            elif _is_table(v):
                for item in v:
                    out += [f"[[{sub}]]"] + table(item, sub)[1:]
        return out
    return "\n".join(table(doc, "")) + "\n"


def _is_table(v: Any) -> bool:
    return isinstance(v, dict) or (isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v))


def _reap(folder: Path) -> None:
    """Kill this machine's processes working in `folder` (an ngspice left running by a worker
    that was killed mid-run) before a retry reuses the folder. Linux /proc only."""
    target = str(folder.resolve())
    for entry in Path("/proc").glob("[0-9]*"):
        try:
            cwd = os.readlink(entry / "cwd")
        except OSError:
            continue
        if (cwd == target or cwd.startswith(target + os.sep)) and int(entry.name) != os.getpid():
            try:
                os.kill(int(entry.name), signal.SIGKILL)
            except OSError:
                pass


def run_one(models: dict, spec: RunSpec) -> dict:
    """Work unit: one sigma-delta run in its own folder (structure.toml + model built here when
    the run overrides the structure). Returns {"summary": ..., "attempts": n}."""
    from . import sigma_delta as sd
    folder = Path(spec.dir)
    folder.mkdir(parents=True, exist_ok=True)
    marker = folder / ".attempts"
    try:
        same = json.loads((folder / "run.json").read_text()).get("key") == spec.key
        attempts = int(marker.read_text()) + 1 if same else 1
    except (OSError, ValueError):
        attempts = 1
    _reap(folder)
    for p in folder.iterdir():                         # a previous attempt's files
        if p.name != ".attempts":
            shutil.rmtree(p) if p.is_dir() and not p.is_symlink() else p.unlink()
    marker.write_text(str(attempts))
    (folder / "run.json").write_text(json.dumps({"params": spec.params, "testbench": spec.testbench,
                                                 "rigid_only": spec.rigid_only, "key": spec.key},
                                                indent=1, default=str) + "\n")
    if spec.structure_text is not None:
        from dataclasses import replace

        from .emit import write_outputs
        from .pipeline import build_model
        from .structure import parse_structure
        (folder / "structure.toml").write_text(spec.structure_text, encoding="utf-8")
        s = parse_structure(spec.structure_text, str(folder / "structure.toml"))
        if spec.rigid_only:
            s = replace(s, coordinates=replace(s.coordinates, modes=0))
        model = build_model(s)
        write_outputs(model, folder / "model", "ngspice")
    else:
        model, lib_text = models[spec.rigid_only]
        (folder / "model").mkdir(exist_ok=True)
        (folder / "model" / f"{model.name}.lib").write_text(lib_text, encoding="utf-8")
    lib = folder / "model" / f"{model.name}.lib"
    tb = dict(spec.testbench)
    tone = sd.Tone.parse(tb.pop("tone")) if tb.get("tone") else None
    ts, cycles = tb.pop("ts"), tb.pop("cycles")
    sd.run(model, lib, folder, ts, int(cycles), tone, progress=False, plots=spec.plots, **tb)
    return {"summary": json.loads((folder / "summary.json").read_text()), "attempts": attempts}


def _attempts(folder: Path) -> int:
    try:
        return int((folder / ".attempts").read_text())
    except (OSError, ValueError):
        return 1


def _row(spec: RunSpec, record: dict) -> dict:
    row: dict[str, Any] = {"run": spec.name, "status": record["status"], "attempts": record.get("attempts", 1)}
    for k, v in spec.params.items():
        row[k] = v
    s = record.get("summary") or {}
    for c in CHANNELS:
        ch = s.get("channels", {}).get(c, {})
        for m in METRICS:
            row[f"{c}.{m}"] = ch.get(m)
    row["gravity_balance.ratio"] = (s.get("gravity_balance") or {}).get("ratio")
    row["wall_s"] = s.get("wall_s")
    row["error"] = record.get("error") or ""
    row["dir"] = spec.dir
    return row


def run_sweep(structure_path: str | Path, sweep: Sweep, out: Path, ex, progress: bool = True) -> list[dict]:
    """Plan, run (through the executor `ex`), gather: the rows of results.csv, in run order."""
    from tqdm import tqdm

    from . import sigma_delta as sd
    from .emit_ngspice import subcircuit
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    runs = plan(sweep, structure_path, out)
    records: dict[int, dict] = {}
    for spec in runs:                                  # finished earlier with the same settings: reuse
        folder = Path(spec.dir)
        try:
            old = json.loads((folder / "run.json").read_text())
            summary = json.loads((folder / "summary.json").read_text())
        except (OSError, ValueError):
            continue
        if old.get("key") == spec.key and not (folder / "error.txt").exists():
            records[spec.index] = {"status": "ok", "summary": summary, "attempts": _attempts(folder), "reused": True}
    todo = [r for r in runs if r.index not in records]
    models = {}
    for rigid in sorted({r.rigid_only for r in todo if r.structure_text is None}):
        model, lib = sd.model_for(structure_path, out / ("model_rigid" if rigid else "model"), rigid,
                                  progress=progress)
        models[rigid] = (model, lib.read_text(encoding="utf-8"))
    if progress and todo:
        print(f"sweep: {len(todo)} run(s) on {ex!r}" + (f", {len(records)} reused" if records else ""),
              file=sys.stderr)
    with tqdm(total=len(runs), initial=len(records), desc="sweep runs", unit="run", disable=not progress,
              file=sys.stderr) as bar:
        for j, outcome in ex.imap_unordered(run_one, todo, shared=models, retries=sweep.retries):
            spec = todo[j]
            folder = Path(spec.dir)
            if outcome.ok:
                rec = {"status": "ok", **outcome.value}
                if not (folder / "summary.json").exists():      # worker on another file system
                    folder.mkdir(parents=True, exist_ok=True)
                    (folder / "summary.json").write_text(json.dumps(rec["summary"], indent=1) + "\n")
            else:
                rec = {"status": "failed", "error": outcome.error, "attempts": max(outcome.attempts, _attempts(folder))}
                folder.mkdir(parents=True, exist_ok=True)
                (folder / "error.txt").write_text(f"{outcome.error}\n\n{outcome.traceback}")
                if progress:
                    tqdm.write(f"sweep: {spec.name} failed: {outcome.error}", file=sys.stderr)
            records[spec.index] = rec
            bar.update(1)
    rows = [_row(spec, records[spec.index]) for spec in runs]
    write_csv(out / "results.csv", rows)
    (out / "sweep.json").write_text(json.dumps({
        "structure": str(structure_path), "sweep": sweep.path, "figure": sweep.figure, "x": sweep.x,
        "mode": sweep.mode, "samples": sweep.samples, "seed": sweep.seed, "fixed": sweep.fixed,
        "parameters": [asdict(p) for p in sweep.parameters],
        "runs": [{**asdict(spec), "structure_text": None, **{k: v for k, v in records[spec.index].items()
                                                           if k != "summary"}} for spec in runs]},
        indent=1, default=str) + "\n")
    plot(out / f"{sweep.figure.replace('.', '_')}_vs_{_slug(sweep.x)}.png", rows, sweep)
    return rows


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_]+", "_", name).strip("_")


def write_csv(path: Path, rows: list[dict]) -> Path:
    cols: list[str] = []
    for r in rows:
        cols += [k for k in r if k not in cols]
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=cols)
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in cols})
    return path


def _number(v: Any) -> float | None:
    if isinstance(v, bool):
        return float(v)
    if isinstance(v, (int, float)):
        return float(v)
    if isinstance(v, str) and v:
        kind = _kind_of(v)
        try:
            return parse_quantity(v, kind)
        except UnitError:
            return None
    return None


def plot(path: Path, rows: list[dict], sweep: Sweep) -> Path | None:
    """PNG of the chosen figure against x: one line per combination of the other swept lists,
    Monte Carlo draws as points; failed runs as crosses on the x axis."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    others = [p.name for p in sweep.parameters if p.values is not None and p.name != sweep.x]
    mc = any(p.distribution for p in sweep.parameters)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    groups: dict[tuple, list[tuple[float, float]]] = {}
    failed = []
    for r in rows:
        x = _number(r.get(sweep.x))
        if x is None:
            continue
        if r["status"] != "ok" or r.get(sweep.figure) is None:
            failed.append(x)
            continue
        groups.setdefault(tuple(r.get(o) for o in others), []).append((x, float(r[sweep.figure])))
    for g, pts in groups.items():
        pts.sort()
        label = ", ".join(f"{o} = {v}" for o, v in zip(others, g)) or None
        ax.plot(*zip(*pts), "o" if mc else "o-", ms=4, label=label)
    if failed:
        ax.plot(failed, [ax.get_ylim()[0] if groups else 0] * len(failed), "rx", label="failed")
    unit = TESTBENCH.get(sweep.x, ("",))[0]
    ax.set_xlabel(f"{sweep.x}" + (f" ({UNITS_SI.get(unit, '')})" if UNITS_SI.get(unit) else ""))
    ax.set_ylabel(sweep.figure)
    xs = [x for pts in groups.values() for x, _ in pts]
    if xs and min(xs) > 0 and max(xs) >= 10 * min(xs):
        ax.set_xscale("log")
    ax.grid(True, which="both", lw=0.3)
    if any(lbl for lbl in ax.get_legend_handles_labels()[1]):
        ax.legend(fontsize=8)
    ax.set_title(f"{sweep.figure} vs {sweep.x} ({len(rows)} runs, {len(failed)} failed)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


UNITS_SI = {"time": "s", "frequency": "Hz", "length": "m"}


# ----------------------------------------------------------------------------- command line


def cli(args) -> int:
    """`netgen sweep`: validate, run, gather; exit 0 (all ran), 1 (some failed), 2 (bad input)."""
    from .executor import executor
    from .structure import load_structure
    start = time.perf_counter()
    try:
        sweep = load_sweep(args.sweep)
        load_structure(args.structure)                          # its errors: exit 2 from cli.main
        plan(sweep, args.structure, Path(args.output))         # path errors before any work
        ex = executor(args.scheduler)
    except SweepError as exc:                       # (ExecutorError is an OSError: cli.main, exit 2)
        print(f"netgen: error in sweep file {exc}", file=sys.stderr)
        return 2
    with ex:
        rows = run_sweep(args.structure, sweep, Path(args.output), ex, progress=not args.quiet)
    bad = [r for r in rows if r["status"] != "ok"]
    if not args.quiet:
        out = Path(args.output)
        print(f"wrote {out / 'results.csv'}")
        print(f"wrote {out / (sweep.figure.replace('.', '_') + '_vs_' + _slug(sweep.x) + '.png')}")
        for r in bad:
            print(f"{r['run']}: failed: {r['error']}")
        print(f"sweep: {len(rows) - len(bad)} of {len(rows)} runs ok, {time.perf_counter() - start:.1f} s")
    return 1 if bad else 0


def add_parser(sub) -> None:
    """The `sweep` subcommand's arguments."""
    from .executor import add_scheduler_option
    p = sub.add_parser("sweep", help="parameter sweep / Monte Carlo of the sigma-delta loop (local processes or Dask)")
    p.add_argument("structure", help="structure description (TOML)")
    p.add_argument("sweep", help="sweep description (TOML), e.g. examples/sweep_ts.toml")
    p.add_argument("-o", "--output", required=True, help="output folder (results.csv, runs/, the figure PNG)")
    add_scheduler_option(p, what="the runs run (default: one local process per core)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or summary output")
    p.set_defaults(func=cli)
