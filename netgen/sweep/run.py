"""Running a sweep: each run in its own folder through an executor (local processes or Dask),
finished runs with the same settings reused, results gathered into results.csv, sweep.json and
the figure's PNG."""

from __future__ import annotations

import csv
import io
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
from ..core import process as sim_process
from ..core.files import write_atomic
from ..emit import write_outputs
from ..runtime.interrupts import Interrupted
from ..sim.ngspice import identity as ngspice_build
from ..sim.ngspice import same_build
from ..structure import parse_structure
from ..testbench import sigma_delta as sd
from . import processes
from .check import check_model_process, check_model_tones
from .folder import claim, identity
from .plan import RunSpec, plan
from .plots import plot
from .point import at_point
from .spec import DESIGN_CHOICES, METRICS, Sweep, timeout_for

DONE = ".done"  # in a run folder: the run's key, written when the run completed


def run_one(models: dict, spec: RunSpec) -> dict:
    """Work unit: one sigma-delta run in its own folder (structure.toml + model built here when
    the run overrides the structure). Returns {"summary": ..., "attempts": n}. The worker and
    every simulator it starts are recorded in the folder (netgen.sweep.processes), so a retry
    stops exactly those of an earlier attempt and nothing else."""
    folder = Path(spec.dir)
    folder.mkdir(parents=True, exist_ok=True)
    marker = folder / ".attempts"
    try:
        same = json.loads((folder / "run.json").read_text()).get("key") == spec.key
        attempts = int(marker.read_text()) + 1 if same else 1
    except (OSError, ValueError):
        attempts = 1
    processes.reap(folder)  # a simulator an earlier attempt left running
    for p in folder.iterdir():  # a previous attempt's files
        if p.name != ".attempts":
            shutil.rmtree(p) if p.is_dir() and not p.is_symlink() else p.unlink()
    marker.write_text(str(attempts))
    processes.record(folder, os.getpid(), "worker", spec.owner)
    (folder / "run.json").write_text(
        json.dumps(
            {"params": spec.params, "testbench": spec.testbench, "rigid_only": spec.rigid_only, "key": spec.key},
            indent=1,
            default=str,
        )
        + "\n"
    )
    with sim_process.watched(lambda pid: processes.record(folder, pid, "simulator")):
        _simulate(models, spec, folder)
    write_atomic(folder / DONE, spec.key + "\n")  # last: the run is complete
    return {"summary": json.loads((folder / "summary.json").read_text()), "attempts": attempts}


def _simulate(models: dict, spec: RunSpec, folder: Path) -> None:
    """The run itself: its model (shared, or built from its structure.toml), then sd.run."""
    if spec.structure_text is not None:
        (folder / "structure.toml").write_text(spec.structure_text, encoding="utf-8")
        s = parse_structure(spec.structure_text, str(folder / "structure.toml"))
        loop: sd.LoopSpec | None = sd.read_structure_loop(folder / "structure.toml")
        if spec.rigid_only:
            s = replace(s, coordinates=replace(s.coordinates, modes=0))
        model = build_model(s)
        write_outputs(model, folder / "model", "ngspice")
    else:
        model, lib_text = models[spec.rigid_only]
        loop = models.get("loop")
        (folder / "model").mkdir(exist_ok=True)
        (folder / "model" / f"{model.name}.lib").write_text(lib_text, encoding="utf-8")
    lib = folder / "model" / f"{model.name}.lib"
    req = request(spec, loop)
    if spec.process:  # each back end's form takes the point as instance parameters; design and analysis see its numbers
        req = replace(req, instance=tuple(sorted(spec.process.items())), nominal=model)
        model = at_point(model, spec.process)
    sd.run(model, lib, folder, req)


def request(spec: RunSpec, loop) -> sd.RunRequest:
    """The run's RunRequest from its testbench settings (spec.DESIGN_CHOICES and LOOP_CHOICES)."""
    tb = dict(spec.testbench)
    tone = sd.Tone.parse(tb.pop("tone")) if tb.get("tone") else None
    choices = sd.Choices(**{sd.SWEEP[k].name: tb.pop(k) for k in DESIGN_CHOICES if k in tb})
    cycles = int(tb.pop("cycles"))
    return sd.RunRequest(
        tb.pop("ts"),
        cycles,
        tone,
        progress=False,
        plots=spec.plots,
        timeout=spec.timeout or timeout_for(cycles),
        loop=loop,
        choices=choices,
        **tb,
    )


def _attempts(folder: Path) -> int:
    try:
        return int((folder / ".attempts").read_text())
    except (OSError, ValueError):
        return 1


def _same_ngspice(summary: dict) -> bool:
    """A finished run is reused only if it ran in the ngspice this sweep runs (or in none)."""
    ran = summary.get("ngspice")
    return not ran or same_build(ran, ngspice_build())


def _row(spec: RunSpec, record: dict) -> dict:
    row: dict[str, Any] = {"run": spec.name, "status": record["status"], "attempts": record.get("attempts", 1)}
    for k, v in spec.params.items():
        row[k] = v
    s = record.get("summary") or {}
    for c, ch in (s.get("channels") or {}).items():
        for m in METRICS:
            row[f"{c}.{m}"] = ch.get(m)
    row["gravity_balance.ratio"] = (s.get("gravity_balance") or {}).get("ratio")
    row["wall_s"] = s.get("wall_s")
    row["ngspice"] = (s.get("ngspice") or {}).get("version")  # the ngspice the run ran in (None: VACASK)
    row["error"] = record.get("error") or ""
    row["dir"] = spec.dir
    return row


def _reused(runs: list[RunSpec]) -> dict[int, dict]:
    """Records of the runs that finished earlier with the same settings (their DONE marker
    holds their key): these are not run again."""
    records: dict[int, dict] = {}
    for spec in runs:
        folder = Path(spec.dir)
        try:
            done = (folder / DONE).read_text().strip()
            summary = json.loads((folder / "summary.json").read_text())
        except (OSError, ValueError):
            continue
        if done == spec.key and not (folder / "error.txt").exists() and _same_ngspice(summary):
            records[spec.index] = {"status": "ok", "summary": summary, "attempts": _attempts(folder), "reused": True}
    return records


def run_sweep(
    structure_path: str | Path, sweep: Sweep, out: Path, ex, progress: bool = True, runs: list[RunSpec] | None = None
) -> list[dict]:
    """Plan, run (through the executor `ex`), gather: the rows of results.csv, in run order.
    The folder must be new, empty or this sweep's (netgen.sweep.folder); SIGTERM or SIGINT stops
    the workers and their simulators, writes what finished and raises netgen.runtime.interrupts.Interrupted with a line
    saying how many runs finished and how to resume (exit 130)."""
    out = Path(out)
    runs = runs if runs is not None else plan(sweep, structure_path, out)
    with (
        claim(out, identity(structure_path, runs), sweep.path, str(structure_path), len(runs)),
        processes.stop_on_signals(),
    ):
        records = _reused(runs)
        try:
            _run(structure_path, sweep, out, ex, progress, runs, records)
        except Interrupted as stop:
            _stop(ex, runs, records)
            rows = _gather(structure_path, sweep, out, runs, records)
            done = sum(r["status"] == "ok" for r in rows)
            raise Interrupted(
                stop.signum,
                f"sweep stopped by {stop}: {done} of {len(runs)} runs finished "
                f"(in {out / 'results.csv'}); run the same command again to run the rest",
            ) from None
        return _gather(structure_path, sweep, out, runs, records)


def _run(
    structure_path: str | Path,
    sweep: Sweep,
    out: Path,
    ex,
    progress: bool,
    runs: list[RunSpec],
    records: dict[int, dict],
) -> None:
    """Build the shared models, then run every run not yet in `records` (filled as runs end)."""
    todo = [replace(r, owner=processes.me()) for r in runs if r.index not in records]
    models: dict = {"loop": sd.read_structure_loop(structure_path)}  # the structure's [loop] table
    for rigid in sorted({r.rigid_only for r in todo if r.structure_text is None}):
        build = sd.BuildOptions(rigid_only=rigid)
        model, lib = sd.model_for(structure_path, out / ("model_rigid" if rigid else "model"), build, progress=progress)
        models[rigid] = (model, lib.read_text(encoding="utf-8"))
    check_model_tones(
        sweep, todo, {rigid: [c.name for c in m[0].coordinates] for rigid, m in models.items() if rigid != "loop"}
    )
    check_model_process(sweep, todo, {k: m for k, m in models.items() if k != "loop"})
    if progress and todo:
        print(f"sweep: {len(todo)} run(s) on {ex!r}" + (f", {len(records)} reused" if records else ""), file=sys.stderr)
    with tqdm(
        total=len(runs), initial=len(records), desc="sweep runs", unit="run", disable=not progress, file=sys.stderr
    ) as bar:
        for j, outcome in ex.imap_unordered(run_one, todo, shared=models, retries=sweep.retries):
            spec = todo[j]
            rundir = Path(spec.dir)
            if outcome.ok:
                rec = {"status": "ok", **outcome.value}
                if not (rundir / "summary.json").exists():  # worker on another file system
                    rundir.mkdir(parents=True, exist_ok=True)
                    (rundir / "summary.json").write_text(json.dumps(rec["summary"], indent=1) + "\n")
            else:
                rec = {"status": "failed", "error": outcome.error, "attempts": max(outcome.attempts, _attempts(rundir))}
                rundir.mkdir(parents=True, exist_ok=True)
                (rundir / "error.txt").write_text(f"{outcome.error}\n\n{outcome.traceback}")
                if progress:
                    tqdm.write(f"sweep: {spec.name} failed: {outcome.error}", file=sys.stderr)
            records[spec.index] = rec
            bar.update(1)


def _stop(ex, runs: list[RunSpec], records: dict[int, dict]) -> None:
    """On SIGTERM/SIGINT: ignore further ones while the executor stops its workers, then kill
    any recorded simulator or worker still running in an unfinished run's folder."""
    previous = {s: signal.signal(s, signal.SIG_IGN) for s in (signal.SIGTERM, signal.SIGINT)}
    try:
        ex.stop()
        for spec in runs:
            if spec.index not in records and Path(spec.dir).is_dir():
                processes.reap(Path(spec.dir), workers=True)
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


def _gather(
    structure_path: str | Path, sweep: Sweep, out: Path, runs: list[RunSpec], records: dict[int, dict]
) -> list[dict]:
    """results.csv, sweep.json and the figure, each written atomically, from the runs that
    ended (a run that did not: status "not run", empty figures)."""
    missing = {"status": "not run", "attempts": 0}
    rows = [_row(spec, records.get(spec.index, missing)) for spec in runs]
    write_csv(out / "results.csv", rows)
    write_atomic(
        out / "sweep.json",
        json.dumps(
            {
                "structure": str(structure_path),
                "sweep": sweep.path,
                "figure": sweep.figure,
                "x": sweep.x,
                "mode": sweep.mode,
                "samples": sweep.samples,
                "seed": sweep.seed,
                "fixed": sweep.fixed,
                "parameters": [asdict(p) for p in sweep.parameters],
                "runs": [
                    {
                        **asdict(spec),
                        "structure_text": None,
                        "owner": None,
                        **{k: v for k, v in records.get(spec.index, missing).items() if k != "summary"},
                    }
                    for spec in runs
                ],
            },
            indent=1,
            default=str,
        )
        + "\n",
    )
    plot(figure_path(out, sweep), rows, sweep)
    return rows


def figure_path(out: Path, sweep: Sweep) -> Path:
    """DIR/<figure>_vs_<x>.png."""
    return out / f"{sweep.figure.replace('.', '_')}_vs_{re.sub(r'[^A-Za-z0-9_]+', '_', sweep.x).strip('_')}.png"


def write_csv(path: Path, rows: list[dict]) -> Path:
    """The rows as a CSV table (the union of their keys as columns), written atomically."""
    cols: list[str] = []
    for r in rows:
        cols += [k for k in r if k not in cols]
    fh = io.StringIO(newline="")
    w = csv.DictWriter(fh, fieldnames=cols)
    w.writeheader()
    for r in rows:
        w.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in cols})
    write_atomic(path, fh.getvalue())
    return path
