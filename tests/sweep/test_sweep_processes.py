"""A sweep signals only the processes it started, stops cleanly on SIGTERM and SIGINT, and its
folder belongs to one sweep. Real sweeps (rigid disk model, 128 periods, local worker processes,
real ngspice), checked against /proc and against direct sigma_delta.run calls (conftest):
- a process whose working directory is inside a run folder (a user's shell) survives a retry
  and a resume; a recorded simulator of an earlier attempt that still runs is killed; a record
  whose PID now names another process (other start time) is ignored;
- every simulator call has a wall-clock limit (`timeout` in [sweep]): a run past it fails with
  that message, its ngspice is gone, and the sweep reports it (exit 1);
- SIGTERM, then SIGINT to the whole process group (a Ctrl-C) of a running sweep: exit 130 for
  both (as every subcommand), no process the sweep started is left, the folder resumes to the
  reference results;
- a different sweep into that folder, a non-sweep folder, and a second sweep while one holds
  the folder are refused (exit 2) and leave the folder as it was.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from netgen.cli import commands as cli
from netgen.core.process import start_time
from netgen.sweep import load_sweep, plan, processes
from netgen.sweep.folder import claim, identity
from tests.fixtures import ROOT
from tests.sweep.conftest import CYCLES, STRUCTURE, TS, summary

SWEEP = """[sweep]
mode = "zip"
figure = "gravity_balance.ratio"
{head}
[fixed]
cycles = {cycles}
skip = 0
rigid_only = true
[[parameters]]
name = "ts"
values = [{values}]
"""


def _write(path: Path, values: list[float], cycles: int = CYCLES, head: str = "") -> Path:
    path.write_text(SWEEP.format(head=head, cycles=cycles, values=", ".join(repr(v) for v in values)))
    return path


def _descendants(root: int) -> set[tuple[int, int]]:
    """(PID, start time) of every process below `root`, from /proc."""
    children: dict[int, list[tuple[int, int]]] = {}
    for entry in Path("/proc").glob("[0-9]*"):
        try:
            rest = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            children.setdefault(int(rest[1]), []).append((int(entry.name), int(rest[19])))
        except (OSError, ValueError, IndexError):
            continue
    out, todo = set(), [root]
    while todo:
        for kid in children.get(todo.pop(), []):
            out.add(kid)
            todo.append(kid[0])
    return out


def _alive(procs: set[tuple[int, int]]) -> set[tuple[int, int]]:
    return {(p, s) for p, s in procs if start_time(p) == s}


def _running_simulators(out: Path) -> list[dict]:
    return [
        r
        for f in (out / "runs").glob("*")
        for r in processes.records(f)
        if r["role"] == "simulator" and processes.is_running(r)
    ]


def _foreign(cwd: Path, **kw) -> subprocess.Popen:
    return subprocess.Popen(["sleep", "60"], cwd=cwd, **kw)


def test_timeout_and_resume_spare_processes_the_sweep_did_not_start(tmp_path, capsys):
    sweep = _write(tmp_path / "s.toml", [1e-6], cycles=4096, head='timeout = "3 s"')
    out = tmp_path / "out"
    args = ["sweep", str(STRUCTURE), str(sweep), "-o", str(out), "-q", "--scheduler", "serial"]
    assert cli.main(args) == 1  # the run failed, the sweep reported it
    run = out / "runs" / "run_0"
    row = next(csv.DictReader(open(out / "results.csv")))
    assert row["status"] == "failed" and "ngspice did not finish within 3 s" in row["error"], row
    sims = [r for r in processes.records(run) if r["role"] == "simulator"]
    assert len(sims) == 1 and not processes.is_running(sims[0])  # stopped by the timer
    shell = _foreign(run)  # a user's shell in the run folder
    reused = _foreign(run, start_new_session=True)  # a PID the record names, but not its process
    orphan = _foreign(run, start_new_session=True)  # a simulator an attempt left running
    with open(run / processes.RECORDS, "a") as fh:
        fh.write(
            json.dumps(
                {
                    **processes.me(),
                    "pid": reused.pid,
                    "pgid": reused.pid,
                    "role": "simulator",
                    "start": start_time(reused.pid) - 1,
                }
            )
            + "\n"
        )
    processes.record(run, orphan.pid, "simulator")
    try:
        assert cli.main(args) == 1  # resumed: run_0 ran (and timed out) again
        assert orphan.wait(timeout=10) == -signal.SIGKILL
        assert shell.poll() is None and reused.poll() is None  # never signalled
        assert int(next(csv.DictReader(open(out / "results.csv")))["attempts"]) == 2
    finally:
        for p in (shell, reused, orphan):
            p.kill()
            p.wait()
    capsys.readouterr()


def _start(sweep: Path, out: Path) -> subprocess.Popen:
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
        stderr=subprocess.PIPE,
        text=True,
    )


def _interrupt(sweep: Path, out: Path, sig: int, group: bool) -> tuple[int, str, set]:
    """Start the sweep, wait until ngspice runs, send `sig` (to its process group if `group`,
    as a Ctrl-C does); (exit code, stderr, processes it had started that are still alive 10 s on)."""
    p = _start(sweep, out)
    seen: set[tuple[int, int]] = set()
    deadline = time.monotonic() + 180
    while not ((out / "runs").is_dir() and _running_simulators(out)):
        seen |= _descendants(p.pid)
        assert p.poll() is None and time.monotonic() < deadline, "the sweep ended before any ngspice ran"
        time.sleep(0.05)
    seen |= _descendants(p.pid)
    os.killpg(p.pid, sig) if group else p.send_signal(sig)
    _, err = p.communicate(timeout=60)
    end = time.monotonic() + 10  # the forkserver exits once its parent has
    while _alive(seen) and time.monotonic() < end:
        time.sleep(0.1)
    return p.returncode, err, _alive(seen)


@pytest.mark.slow
def test_sigterm_and_ctrl_c_leave_no_process_and_a_folder_that_resumes(tmp_path, serial_runs, capsys):
    sweep = _write(tmp_path / "s.toml", TS[:2])
    out = tmp_path / "out"
    for sig, group in ((signal.SIGTERM, False), (signal.SIGINT, True)):
        rc, err, left = _interrupt(sweep, out, sig, group)
        assert rc == 130 and f"stopped by {signal.Signals(sig).name}" in err, err
        assert not left, f"left running after {signal.Signals(sig).name}: {left}"
        assert not _running_simulators(out)
        rows = list(csv.DictReader(open(out / "results.csv")))
        assert len(rows) == 2 and {r["status"] for r in rows} <= {"ok", "not run"}
        assert (out / ".sweep.json").is_file()
    assert cli.main(["sweep", str(STRUCTURE), str(sweep), "-o", str(out), "-q", "--scheduler", "processes:2"]) == 0
    rows = list(csv.DictReader(open(out / "results.csv")))
    for r, ts in zip(rows, TS[:2]):
        assert r["status"] == "ok" and summary(Path(r["dir"]) / "summary.json") == serial_runs[ts]
    before = {p: p.read_bytes() for p in out.iterdir() if p.is_file()}

    other = _write(tmp_path / "b.toml", TS[2:3])  # sweep B into A's folder
    assert cli.main(["sweep", str(STRUCTURE), str(other), "-o", str(out), "-q"]) == 2
    assert "holds another sweep" in capsys.readouterr().err
    assert {p: p.read_bytes() for p in out.iterdir() if p.is_file()} == before
    assert sorted(p.name for p in (out / "runs").iterdir()) == ["run_0", "run_1"]


def test_a_foreign_or_busy_folder_is_refused(tmp_path, capsys):
    sweep = _write(tmp_path / "s.toml", TS[:1])
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("mine")
    assert cli.main(["sweep", str(STRUCTURE), str(sweep), "-o", str(mine), "-q"]) == 2
    assert "holds no sweep" in capsys.readouterr().err and sorted(os.listdir(mine)) == ["notes.txt"]
    busy = tmp_path / "busy"
    ident = identity(STRUCTURE, plan(load_sweep(sweep), STRUCTURE, busy))
    with claim(busy, ident, str(sweep), str(STRUCTURE), 1):  # the same sweep, writing there now
        assert cli.main(["sweep", str(STRUCTURE), str(sweep), "-o", str(busy), "-q"]) == 2
    assert f"another netgen sweep (pid {os.getpid()})" in capsys.readouterr().err
    assert not (busy / "runs").exists()


@pytest.mark.parametrize("bad", ["0", "-3", "x", "2000000"])
def test_max_runs_must_be_a_sane_count(tmp_path, bad, capsys):
    sweep = _write(tmp_path / "s.toml", TS[:1])
    with pytest.raises(SystemExit) as exc:
        cli.main(["sweep", str(STRUCTURE), str(sweep), "-o", str(tmp_path / "o"), "--max-runs", bad])
    assert exc.value.code == 2 and "--max-runs" in capsys.readouterr().err
