"""The one way netgen runs a simulator or tool: a subprocess per run (a crash or hang stays out
of the caller), in its own process group, with a wall-clock limit enforced by a timer (not by
its output), its merged stdout/stderr read line by line, and optional progress callbacks."""

from __future__ import annotations

import os
import queue
import shutil
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from .errors import SimulationError


@dataclass
class Finished:
    """A run that ended by itself: its exit code, its output and its wall time."""

    returncode: int
    output: str
    wall: float


_WATCHERS = threading.local()  # per thread: callbacks told of each process run() starts


@contextmanager
def watched(callback: Callable[[int], None]) -> Iterator[None]:
    """Within this block (in this thread) callback(pid) is called for every process run()
    starts, right after it starts: a supervisor (netgen.sweep.processes) records exactly the
    processes it caused, to signal only those later."""
    previous = getattr(_WATCHERS, "callbacks", ())
    _WATCHERS.callbacks = (*previous, callback)
    try:
        yield
    finally:
        _WATCHERS.callbacks = previous


def start_time(pid: int) -> int | None:
    """The process's start time in clock ticks since boot (/proc/PID/stat field 22), or None
    if it is gone: with the PID it names one process, never a later one that reuses the PID."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
        return int(stat.rsplit(")", 1)[1].split()[19])
    except (OSError, ValueError, IndexError):
        return None


def line_buffered(argv: list[str]) -> list[str]:
    """argv under `stdbuf -oL -eL` where it exists, so progress lines arrive as they are printed."""
    stdbuf = shutil.which("stdbuf")
    return ([stdbuf, "-oL", "-eL"] if stdbuf else []) + list(argv)


@dataclass(frozen=True)
class Watch:
    """What run reports while the process runs: on_line(line) for each output line as it arrives,
    on_tick(wall seconds) every `tick` s."""

    on_line: Callable[[str], None] | None = None
    on_tick: Callable[[float], None] | None = None
    tick: float = 2.0


def run(
    argv: list[str],
    cwd: str | Path,
    timeout: float,
    reproduce: str,
    name: str = "",
    watch: Watch = Watch(),
    env: dict[str, str] | None = None,
) -> Finished:
    """Run argv in cwd with stdin closed, reporting to `watch` while it runs. Past `timeout` s the process group is
    killed and a SimulationError names the program (`name`, default argv[0]) and the command
    that reproduces the run; an interrupt of the caller kills it too. `env`: its environment
    (default: this process's)."""
    late = SimulationError(
        f"{name or Path(argv[0]).name} did not finish within {timeout:g} s; reproduce with: {reproduce}"
    )
    proc = subprocess.Popen(
        argv,
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        env=env,
        stdin=subprocess.DEVNULL,
        text=True,
        errors="replace",
        start_new_session=True,
    )
    try:
        for callback in getattr(_WATCHERS, "callbacks", ()):
            callback(proc.pid)
    except BaseException:
        _kill(proc)
        raise
    lines: queue.Queue = queue.Queue()
    reader = threading.Thread(target=_pump, args=(proc, lines), daemon=True)
    reader.start()
    start = time.perf_counter()
    out: list[str] = []
    on_line, on_tick, tick = watch.on_line, watch.on_tick, watch.tick
    next_tick = tick
    try:
        while True:
            wall = time.perf_counter() - start
            if wall > timeout:
                raise late
            if on_tick is not None and wall >= next_tick:
                on_tick(wall)
                next_tick = wall + tick
            try:
                line = lines.get(timeout=min(tick, max(timeout - wall, 0.0) + 1e-3))
            except queue.Empty:
                continue
            if line is None:  # output closed: the process is ending
                break
            out.append(line)
            if on_line is not None:
                on_line(line)
        remaining = timeout - (time.perf_counter() - start)
        try:
            proc.wait(timeout=max(remaining, 0.0) + 1e-3)
        except subprocess.TimeoutExpired:
            raise late from None
    finally:
        if proc.poll() is None:
            _kill(proc)
    return Finished(proc.returncode, "".join(out), time.perf_counter() - start)


def _pump(proc: subprocess.Popen, lines: queue.Queue) -> None:
    """Reader thread: every output line into the queue, then None."""
    try:
        assert proc.stdout is not None  # run opens it with stdout=PIPE
        for line in proc.stdout:
            lines.put(line)
    finally:
        lines.put(None)


def _kill(proc: subprocess.Popen) -> None:
    """Kill the run's whole process group (the tool and anything it started) and reap it."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        proc.kill()
    proc.wait()
