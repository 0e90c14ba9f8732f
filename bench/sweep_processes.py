"""Counts for a sweep's processes and folders: interrupts, concurrent pairs, foreign processes,
timeouts; and the per-period cost behind the sweep's time estimate.

    .venv/bin/python bench/sweep_processes.py [--term 30] [--int 30] [--pairs 10] [--foreign 5] [--calibrate]

Every case runs the real `netgen sweep` (a 4-run T_s sweep of the rigid disk model, 128 periods,
2 local worker processes, real ngspice) as a subprocess and checks /proc and the folder:
- SIGTERM to the sweep / SIGINT to its process group (a Ctrl-C) at a random moment (0-12 s
  after the start: validation, model build, ngspice runs, gathering): the exit code, every
  process the sweep had started (descendants seen in /proc) gone within 10 s, no process with
  its working directory in the folder, no temp file, results.csv (if any) with one row per run
  and only ok / not run statuses, every ok run complete (.done with its key). The next case
  resumes the same folder; a completed folder's summaries must equal direct sigma_delta.run calls.
- concurrent pairs: the same sweep twice at once into one new folder (one runs, the other is
  refused by the lock, or runs after it), and a different sweep at once (refused).
- foreign processes: a `sleep` whose cwd is a run folder survives retries and resumes.
- a hanging simulator: [sweep] timeout stops it by the timer.
Prints one line per case class: tried, tracebacks, wrong outcomes, leftovers. A Ctrl-C while
Python still imports netgen (the first second or two) is Python's KeyboardInterrupt traceback
before netgen.cli.commands.main runs; it is counted apart ("tracebacks during imports").
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from support import ROOT

from netgen.core.process import start_time
from netgen.sweep import load_sweep, plan
from netgen.sweep.folder import MARKER, identity
from netgen.testbench import sigma_delta as sd

STRUCTURE = ROOT / "examples" / "levitated_disk.toml"
TS = [1.0e-6, 1.3e-6, 1.6e-6, 2.0e-6]
SWEEP = """[sweep]
mode = "zip"
[fixed]
cycles = 128
skip = 0
rigid_only = true
{extra}
[[parameters]]
name = "ts"
values = [{values}]
"""


def descendants(root: int) -> set[tuple[int, int]]:
    """(PID, start time) of every process below `root`."""
    kids: dict[int, list[tuple[int, int]]] = {}
    for e in Path("/proc").glob("[0-9]*"):
        try:
            rest = (e / "stat").read_text().rsplit(")", 1)[1].split()
            kids.setdefault(int(rest[1]), []).append((int(e.name), int(rest[19])))
        except (OSError, ValueError, IndexError):
            continue
    out, todo = set(), [root]
    while todo:
        for k in kids.get(todo.pop(), []):
            out.add(k)
            todo.append(k[0])
    return out


def in_folder(folder: Path) -> list[int]:
    """PIDs whose working directory is inside `folder`."""
    target = str(folder.resolve())
    pids = []
    for e in Path("/proc").glob("[0-9]*"):
        try:
            cwd = os.readlink(e / "cwd")
        except OSError:
            continue
        if cwd == target or cwd.startswith(target + os.sep):
            pids.append(int(e.name))
    return pids


def start(sweep: Path, out: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "netgen.cli.commands",
            "sweep",
            str(STRUCTURE),
            str(sweep),
            "-o",
            str(out),
            "-q",
            "--scheduler",
            "processes:2",
        ],
        cwd=ROOT,
        start_new_session=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )


def folder_problems(out: Path, ident: str) -> list[str]:
    """What is wrong with a sweep folder after an interrupt (empty: consistent)."""
    bad = [f"temp file {p}" for p in out.rglob("*") if p.name.endswith(".tmp") or ".tmp." in p.name]
    if not out.exists():
        return bad
    marker = out / MARKER
    if marker.exists() and json.loads(marker.read_text())["id"] != ident:
        bad.append("marker of another sweep")
    if (out / "results.csv").exists():
        rows = list(csv.DictReader(open(out / "results.csv")))
        if len(rows) != len(TS):
            bad.append(f"results.csv has {len(rows)} rows")
        for r in rows:
            if r["status"] not in ("ok", "not run"):
                bad.append(f"{r['run']}: status {r['status']} {r['error'][:80]}")
            if r["status"] == "ok" and not (Path(r["dir"]) / ".done").exists():
                bad.append(f"{r['run']}: ok without .done")
    return bad


def interrupts(n: int, sig: int, group: bool, reference: dict, tmp: Path, tally: dict) -> None:
    """n interrupts at random moments; each resumes the folder of the last until it completes."""
    sweep = tmp / "s.toml"
    sweep.write_text(SWEEP.format(extra="", values=", ".join(map(repr, TS))))
    name = signal.Signals(sig).name + (" to the group" if group else "")
    out, k = tmp / f"{name}_0".replace(" ", "_"), 0
    ident = identity(STRUCTURE, plan(load_sweep(sweep), STRUCTURE, out))
    t = tally.setdefault(
        name,
        {
            "tried": 0,
            "tracebacks": 0,
            "wrong exit": 0,
            "left running": 0,
            "bad folder": 0,
            "completed and equal": 0,
            "completed and different": 0,
        },
    )
    for _ in range(n):
        p = start(sweep, out)
        seen: set = set()
        wait = random.uniform(0, 12)
        end = time.monotonic() + wait
        while time.monotonic() < end and p.poll() is None:
            seen |= descendants(p.pid)
            time.sleep(0.05)
        seen |= descendants(p.pid)
        if p.poll() is None:
            os.killpg(p.pid, sig) if group else p.send_signal(sig)
        _, err = p.communicate(timeout=120)
        t["tried"] += 1
        early = "_run_module_as_main" in err and "line 1" in err and ", in main" not in err
        t["tracebacks during imports"] = t.get("tracebacks during imports", 0) + ("Traceback" in err and early)
        t["tracebacks"] += "Traceback" in err and not early
        if "Traceback" in err and not early:
            print(f"  {name} after {wait:.1f} s: traceback: {err[-1500:]}")
        if p.returncode not in (0, 128 + sig, -sig, 130):
            t["wrong exit"] += 1
            print(f"  {name}: exit {p.returncode}: {err[-300:]}")
        deadline = time.monotonic() + 10
        while any(start_time(q) == s for q, s in seen) and time.monotonic() < deadline:
            time.sleep(0.1)
        left = [q for q, s in seen if start_time(q) == s] + in_folder(out)
        t["left running"] += bool(left)
        problems = folder_problems(out, ident)
        t["bad folder"] += bool(problems)
        if left or problems:
            print(f"  {name} after {wait:.1f} s: left {left}, folder {problems}")
        if p.returncode == 0:  # complete: compare, then a fresh folder
            rows = list(csv.DictReader(open(out / "results.csv")))
            same = all(summary(Path(r["dir"]) / "summary.json") == reference[float(r["ts"])] for r in rows)
            t["completed and equal" if same else "completed and different"] += 1
            k += 1
            out = tmp / f"{name}_{k}".replace(" ", "_")
            ident = identity(STRUCTURE, plan(load_sweep(sweep), STRUCTURE, out))


def summary(path: Path) -> dict:
    d = json.loads(path.read_text())
    d.pop("wall_s")
    return d


def pairs(n: int, tmp: Path, tally: dict) -> None:
    """n pairs of sweeps started at once into one new folder (same sweep; a different one)."""
    a, b = tmp / "a.toml", tmp / "b.toml"
    a.write_text(SWEEP.format(extra="", values=repr(TS[0])))
    b.write_text(SWEEP.format(extra="", values=repr(TS[1])))
    t = tally.setdefault(
        "concurrent pairs",
        {"tried": 0, "tracebacks": 0, "both wrote": 0, "bad folder": 0, "refused (lock or other sweep)": 0},
    )
    for k in range(n):
        out = tmp / f"pair_{k}"
        other = a if k % 2 == 0 else b
        p, q = start(a, out), start(other, out)
        errs = [x.communicate(timeout=600)[1] for x in (p, q)]
        t["tried"] += 1
        t["tracebacks"] += any("Traceback" in e for e in errs)
        rcs = sorted([p.returncode, q.returncode])
        refused = sum("another netgen sweep" in e or "holds another sweep" in e for e in errs)
        t["refused (lock or other sweep)"] += refused
        if rcs == [0, 0] and other is b:
            t["both wrote"] += 1
        winner = a if p.returncode == 0 else other
        ident = identity(STRUCTURE, plan(load_sweep(winner), STRUCTURE, out))
        if not (out / "results.csv").exists():
            t["bad folder"] += 1
            print(f"  pair {k}: exits {rcs}, no results.csv: {[e[-300:] for e in errs]}")
            continue
        rows = list(csv.DictReader(open(out / "results.csv")))
        ts = TS[0] if winner is a else TS[1]
        ok = (
            len(rows) == 1
            and rows[0]["status"] == "ok"
            and float(rows[0]["ts"]) == ts
            and json.loads((out / MARKER).read_text())["id"] == ident
        )
        t["bad folder"] += not ok
        if not ok or rcs not in ([0, 0], [0, 2]):
            print(f"  pair {k}: exits {rcs}, rows {rows}, {[e[-200:] for e in errs]}")


def foreign(n: int, tmp: Path, tally: dict) -> None:
    """A sleep in a run folder across n resumes of a run that times out each time."""
    sweep = tmp / "f.toml"
    sweep.write_text(
        SWEEP.replace("cycles = 128", "cycles = 4096")
        .format(extra="", values=repr(TS[0]))
        .replace("[fixed]", 'timeout = "3 s"\n[fixed]')
    )
    out = tmp / "foreign"
    t = tally.setdefault(
        "foreign process / timeout", {"tried": 0, "foreign killed": 0, "timeout not enforced": 0, "simulator left": 0}
    )
    shell = None
    for k in range(n):
        start_s = time.monotonic()
        p = subprocess.run(
            [sys.executable, "-m", "netgen.cli.commands", "sweep", str(STRUCTURE), str(sweep), "-o", str(out), "-q"],
            cwd=ROOT,
            capture_output=True,
            text=True,
        )
        row = next(csv.DictReader(open(out / "results.csv")))
        t["tried"] += 1
        t["timeout not enforced"] += "did not finish within 3 s" not in row["error"]
        if shell is not None:
            t["foreign killed"] += shell.poll() is not None
        shell = shell or subprocess.Popen(["sleep", "600"], cwd=out / "runs" / "run_0")
        t["simulator left"] += any(start_time(q) for q in in_folder(out) if q != shell.pid)
        print(f"  foreign {k}: exit {p.returncode}, {time.monotonic() - start_s:.1f} s, {row['error'][:60]}")
    if shell is not None:
        shell.kill()


def calibrate(tmp: Path) -> None:
    """Seconds of ngspice per period for the rigid and the full disk model (128 periods)."""
    for rigid in (True, False):
        model, lib = sd.model_for(STRUCTURE, tmp / f"model_{rigid}", sd.BuildOptions(rigid_only=rigid), progress=False)
        s = sd.run(model, lib, tmp / f"cal_{rigid}", sd.RunRequest(1e-6, 128, progress=False, plots=False, skip=0))
        print(
            f"calibrate: {'rigid' if rigid else 'full'} model: {s['wall_s'] / 128:.3f} s per period "
            f"({s['wall_s']:.1f} s for 128)"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--term", type=int, default=30)
    ap.add_argument("--int", type=int, default=30, dest="int_")
    ap.add_argument("--pairs", type=int, default=10)
    ap.add_argument("--foreign", type=int, default=5)
    ap.add_argument("--calibrate", action="store_true")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    random.seed(args.seed)
    tmp = Path(tempfile.mkdtemp(prefix="netgen-sweep-bench-"))
    try:
        if args.calibrate:
            calibrate(tmp)
        tally: dict = {}
        model, lib = sd.model_for(STRUCTURE, tmp / "model_rigid", sd.BuildOptions(rigid_only=True), progress=False)
        reference = {}
        for ts in TS:
            sd.run(model, lib, tmp / f"ref_{ts:g}", sd.RunRequest(ts, 128, progress=False, plots=False, skip=0))
            reference[ts] = summary(tmp / f"ref_{ts:g}" / "summary.json")
        foreign(args.foreign, tmp, tally)
        interrupts(args.term, signal.SIGTERM, False, reference, tmp, tally)
        interrupts(args.int_, signal.SIGINT, True, reference, tmp, tally)
        pairs(args.pairs, tmp, tally)
        for name, counts in tally.items():
            print(f"{name}: " + ", ".join(f"{k} {v}" for k, v in counts.items()))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
