"""The runs of a sweep: the grid or zip of the value lists times the Monte Carlo draws (seeded),
each a RunSpec with its folder, testbench options and, for structure parameters, the structure
file's text with the values set (to_toml)."""

from __future__ import annotations

import hashlib
import itertools
import json
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..core.errors import StructureError, SweepError
from ..core.reader import did_you_mean
from ..core.text import comment_text
from ..core.units import parse_quantity
from ..structure import Structure, parse_structure
from .point import problem, rebuild_doc
from .spec import TESTBENCH, Sweep, timeout_for
from .tomltext import to_toml


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
    timeout: float = 0.0  # s, wall-clock limit of each simulator call
    owner: dict | None = None  # the sweep process that runs it (netgen.sweep.processes.me)
    # process point {tscale, escale, temp, etch, dg_<set>} of a run on the shared [process] model (instance parameters);
    # {} = none, or the point rebuilt into structure_text
    process: dict = field(default_factory=dict)


def plan(sweep: Sweep, structure_path: str | Path, out: Path) -> list[RunSpec]:
    """The runs of a sweep: grid/zip of the value lists x `samples` Monte Carlo draws (seeded)."""
    lists = [p for p in sweep.parameters if p.values is not None]
    values = [p.values or [] for p in lists]  # (`or []` only narrows the type: these all have values)
    random = [p for p in sweep.parameters if p.distribution]
    combos = list(itertools.product(*values)) if sweep.mode == "grid" else list(zip(*values))
    rng = np.random.default_rng(sweep.seed)
    base_text = Path(structure_path).read_text(encoding="utf-8")
    base_doc = tomllib.loads(base_text)
    for name in [n for n in sweep.fixed if n.startswith("structure.")] + [
        p.name for p in sweep.parameters if p.structure
    ]:
        _set_path(json.loads(json.dumps(base_doc)), name, 0, str(structure_path), sweep.path)
    width = len(str(len(combos) * sweep.samples - 1))
    runs: list[RunSpec] = []
    for combo in combos:
        for _ in range(sweep.samples):
            params = dict(zip([p.name for p in lists], combo))
            for p in random:
                v = float(rng.normal(p.a, p.b) if p.distribution == "normal" else rng.uniform(p.a, p.b))
                params[p.name] = v
            index = len(runs)
            runs.append(_spec(index, f"run_{index:0{width}d}", out, sweep, params, base_doc, structure_path))
    return runs


def _spec(
    index: int, name: str, out: Path, sweep: Sweep, params: dict, base_doc: dict, structure_path: str | Path
) -> RunSpec:
    values = {**sweep.fixed, **params}
    tb: dict[str, Any] = {"ts": 1e-6, "cycles": 4096}
    tone = None
    overrides = {}
    rigid = False
    point: dict[str, float] = {}
    for n, v in values.items():
        if n.startswith("structure."):
            overrides[n] = v
        elif n.startswith("process."):
            point[n.split(".", 1)[1]] = float(v)
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
    rebuild = bool(point) and sweep.process == "rebuild"
    text = None
    if overrides or rebuild:
        doc = json.loads(json.dumps(base_doc))
        for n, v in overrides.items():
            _set_path(doc, n, v, str(structure_path), sweep.path)
        s = base(doc, structure_path) if rebuild else None
        if s is not None:  # the reference: the structure itself at the point, built without its [process] laws
            for n, v in point.items():
                refused = problem(s, n, v, rebuild=True)
                if refused:
                    raise SweepError(sweep.path, key_of(sweep, f"process.{n}"), f"{name}: {refused[0]}", refused[1])
            doc = rebuild_doc(doc, s, point, (sweep.path, "sweep.process"))
        shown = {**overrides, **{f"process.{k}": v for k, v in point.items()}} if rebuild else overrides
        note = comment_text(f"{structure_path} with {', '.join(f'{k} = {v!r}' for k, v in shown.items())}", "#")
        text = f"# {note}\n" + to_toml(doc)
    spec = RunSpec(
        index,
        name,
        str(out / "runs" / name),
        params,
        tb,
        rigid,
        text,
        sweep.plots,
        timeout=sweep.timeout or timeout_for(tb["cycles"]),
    )
    spec.process = {} if rebuild else point
    spec.key = hashlib.sha256(
        json.dumps(
            [tb, rigid, text, sweep.plots] + ([spec.process] if spec.process else []), sort_keys=True, default=str
        ).encode()
    ).hexdigest()[:16]
    return spec


def base(doc: dict, structure_path: str | Path) -> Structure | None:
    """The run's structure (the file with the run's structure.* values) as parsed, for its rebuild at a
    process point; None where the file refuses the values (netgen.sweep.check reports it with the run)."""
    try:
        return parse_structure(to_toml(doc), str(structure_path))
    except StructureError:
        return None


def key_of(sweep: Sweep, name: str) -> str:
    """The sweep file's key that sets `name`: parameters[k].values if swept, else fixed.<name>."""
    k = next((k for k, p in enumerate(sweep.parameters) if p.name == name), None)
    return f"parameters[{k}].values" if k is not None else f"fixed.{name}"


def _set_path(doc: dict, name: str, value: Any, structure: str, sweep: str) -> None:
    """Set structure.<path> in the TOML document (a list without [i]: every entry)."""
    parts = re.findall(r"([A-Za-z_][A-Za-z0-9_]*)(?:\[(\d+)\])?", name[len("structure.") :])
    targets = [doc]
    for depth, (key, idx) in enumerate(parts):
        last = depth == len(parts) - 1
        nxt = []
        for t in targets:
            if not isinstance(t, dict) or key not in t:
                have = sorted(t) if isinstance(t, dict) else []
                raise SweepError(
                    sweep,
                    name,
                    f"{structure} has no key '{key}' here (has {', '.join(have)})",
                    f"{did_you_mean(key, have)}give a path that exists in the structure file (to sweep "
                    "an optional key, write it there first with its base value)",
                    _line(sweep, name),
                )
            if last:
                if idx:
                    seq = t.get(key)
                    if not isinstance(seq, list) or int(idx) >= len(seq):
                        raise SweepError(
                            sweep,
                            name,
                            f"{structure}: {key} has no entry {idx}",
                            "use an index that exists (counting from 0)",
                            _line(sweep, name),
                        )
                    seq[int(idx)] = value
                else:
                    t[key] = value
                continue
            v = t[key]
            if idx:
                if not isinstance(v, list) or int(idx) >= len(v):
                    raise SweepError(
                        sweep,
                        name,
                        f"{structure}: {key} has no entry {idx}",
                        f"{key} has {len(v) if isinstance(v, list) else 0} entries (counting from 0)",
                        _line(sweep, name),
                    )
                nxt.append(v[int(idx)])
            elif isinstance(v, list):
                nxt.extend(v)  # e.g. every [[electrodes]] table
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
