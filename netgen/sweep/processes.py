"""The processes a sweep starts, and only those: each run folder keeps a record (.processes, JSON
lines) of the worker that ran it and of every simulator that worker started (through
netgen.core.process.watched), each with its PID, process group, /proc start time and host. A
retry or a resume signals a recorded process only while that PID still names the same process
(same start time, same host): a user's shell or editor whose working directory is inside a run
folder is never touched. SIGTERM and SIGINT of the sweep become netgen.runtime.interrupts.Interrupted
(held while the executor holds its locks), which run_sweep turns into stopped workers, killed
simulators, a resumable folder and an Interrupted that says so."""

from __future__ import annotations

import json
import os
import signal
import socket
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from ..core.process import start_time
from ..runtime.interrupts import Interrupted

RECORDS = ".processes"


def me() -> dict:
    """This process as a record: PID, start time, host."""
    return {"pid": os.getpid(), "start": start_time(os.getpid()), "host": socket.gethostname()}


def is_running(rec: dict) -> bool:
    """Is the recorded process still the same process (same host, PID and start time)?"""
    return (
        rec.get("host") == socket.gethostname()
        and rec.get("start") is not None
        and start_time(int(rec["pid"])) == rec["start"]
    )


def record(folder: Path, pid: int, role: str, owner: dict | None = None) -> None:
    """Append a process to the run folder's record (flushed to disk before it matters)."""
    rec = {"pid": pid, "start": start_time(pid), "host": socket.gethostname(), "role": role}
    try:
        rec["pgid"] = os.getpgid(pid)
    except OSError:
        return  # already gone: nothing to record
    if owner:
        rec["owner"] = owner
    with open(folder / RECORDS, "a", encoding="utf-8") as fh:
        fh.write(json.dumps(rec) + "\n")
        fh.flush()
        os.fsync(fh.fileno())


def records(folder: Path) -> list[dict]:
    """The run folder's process records (unreadable lines skipped)."""
    try:
        lines = (folder / RECORDS).read_text(encoding="utf-8").splitlines()
    except OSError:
        return []
    out = []
    for line in lines:
        try:
            rec = json.loads(line)
        except ValueError:
            continue
        if isinstance(rec, dict) and isinstance(rec.get("pid"), int):
            out.append(rec)
    return out


def reap(folder: Path, workers: bool = False) -> list[int]:
    """SIGKILL the recorded simulators of `folder` that still run, and its recorded worker if
    the sweep that owned it is gone (or `workers`); wait until they are gone. Returns the PIDs
    signalled. Never signals anything that is not in the record."""
    killed = []
    for rec in records(folder):
        if rec["pid"] == os.getpid() or not is_running(rec):
            continue
        if rec.get("role") == "worker" and not workers and is_running(rec.get("owner") or {}):
            continue  # a live worker of a live sweep: not ours to stop here
        try:
            if rec.get("role") == "simulator" and os.getpgid(rec["pid"]) == rec.get("pgid") == rec["pid"]:
                os.killpg(rec["pid"], signal.SIGKILL)  # the simulator and whatever it started
            else:
                os.kill(rec["pid"], signal.SIGKILL)
            killed.append(rec)
        except OSError:
            continue
    deadline = time.monotonic() + 10
    while any(is_running(r) for r in killed) and time.monotonic() < deadline:
        time.sleep(0.02)
    return [r["pid"] for r in killed]


@contextmanager
def stop_on_signals() -> Iterator[None]:
    """Within: SIGTERM and SIGINT raise netgen.runtime.interrupts.Interrupted in the main thread (elsewhere: nothing changes)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: object) -> None:
        raise Interrupted(signum)  # deferred while the executor holds its pool's locks (interrupts.held)

    old = {s: signal.signal(s, handler) for s in (signal.SIGTERM, signal.SIGINT)}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)
