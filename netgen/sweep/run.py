"""Running a sweep: each run in its own folder through an executor (local processes or Dask),
finished runs with the same settings reused, results gathered into results.csv, sweep.json and
the figure's PNG."""

from __future__ import annotations

import csv
import json
import os
import re
import shutil
import signal
import sys
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

from tqdm import tqdm

from ..build import build_model
from ..emit import write_outputs
from ..sim.ngspice import identity, same_build
from ..structure import parse_structure
from ..testbench import sigma_delta as sd
from .plan import RunSpec, plan
from .plots import plot
from .spec import CHANNELS, METRICS, Sweep


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


def _same_ngspice(summary: dict) -> bool:
    """A finished run is reused only if it ran in the ngspice this sweep runs (or in none)."""
    ran = summary.get("ngspice")
    return not ran or same_build(ran, identity())


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
    row["ngspice"] = (s.get("ngspice") or {}).get("version")        # the ngspice the run ran in (None: VACASK)
    row["error"] = record.get("error") or ""
    row["dir"] = spec.dir
    return row


def run_sweep(structure_path: str | Path, sweep: Sweep, out: Path, ex, progress: bool = True) -> list[dict]:
    """Plan, run (through the executor `ex`), gather: the rows of results.csv, in run order."""
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
        if old.get("key") == spec.key and not (folder / "error.txt").exists() and _same_ngspice(summary):
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
    plot(figure_path(out, sweep), rows, sweep)
    return rows


def figure_path(out: Path, sweep: Sweep) -> Path:
    """DIR/<figure>_vs_<x>.png."""
    return out / f"{sweep.figure.replace('.', '_')}_vs_{re.sub(r'[^A-Za-z0-9_]+', '_', sweep.x).strip('_')}.png"


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
