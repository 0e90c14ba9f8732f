"""One execution seam for embarrassingly parallel work: capacitance sampling and sweeps.

`executor(spec)` returns a concurrent.futures-style executor chosen by the user:

    None, "processes", "processes:N"   local worker processes (ProcessPoolExecutor; no Dask needed)
    "serial"                           in this process, one task after the other
    "local:N"                          Dask LocalCluster of N worker processes, 1 thread each
    "tcp://host:port" (tls://, ...)    an existing Dask scheduler (`dask scheduler` + `dask worker`)

Every executor has `submit(fn, *args)` (a Future with .result()), `scatter(obj)` (a handle to a
large shared input, shipped to each worker once, not per task) and `imap_unordered(fn, items,
shared, retries)`, which both users call: it yields (index, Outcome) as tasks finish. Work units
are module-level functions of small picklable items, called as fn(shared, item). An exception
inside a task is an Outcome with its error (it is not retried: it would fail again); a worker
lost mid-task (killed, out of memory, machine gone) is retried up to `retries` times.

Its users: the capacitance sampling (netgen.electrostatics.sampling.sample_chunks) and the
sweeps (netgen.sweep.run).
"""

from __future__ import annotations

import os
import pickle
import signal
import sys
import tempfile
import threading
import time
import traceback
import uuid
from collections.abc import Callable, Iterable, Iterator
from concurrent import futures as cf
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..core.errors import ExecutorError
from .interrupts import held

DASK_INSTALL = "pip install 'netgen[dask]'  (or: pip install 'dask[distributed]')"
SCHEDULER_HELP = (
    "'processes[:N]' (local worker processes), 'serial', 'local:N' (a Dask LocalCluster "
    "of N workers) or a Dask scheduler address tcp://host:port"
)


@dataclass
class Outcome:
    """What one task gave: its value, or the error it raised (type: message) and traceback."""

    value: Any = None
    error: str | None = None
    traceback: str = ""
    attempts: int = 1  # times the task was started (> 1: its worker was lost)

    @property
    def ok(self) -> bool:
        return self.error is None


class WorkerStopped(BaseException):
    """A local worker process got SIGTERM or SIGINT: unwinds its task (whose `finally` blocks
    kill the simulators it started, netgen.core.process.run) and then the worker exits."""


_WORKER = {"local": False, "busy": False}  # per process: a ProcessExecutor worker? in a task?


def _worker_start(registry: str) -> None:
    """Initializer of a ProcessExecutor worker: record its PID and /proc start time in the
    executor's registry (so stop() signals exactly its workers) and stop cleanly on signals."""
    _WORKER["local"] = True
    signal.signal(signal.SIGTERM, _worker_signal)
    signal.signal(signal.SIGINT, _worker_signal)
    with open(registry, "a", encoding="utf-8") as fh:
        fh.write(f"{os.getpid()} {_start_time(os.getpid())}\n")


def _worker_signal(signum: int, frame: Any) -> None:
    """Idle: exit now. In a task: raise WorkerStopped through it; _call then exits."""
    if not _WORKER["busy"]:
        os._exit(128 + signum)
    _WORKER["busy"] = False  # a second signal exits at once
    raise WorkerStopped(signum)


def _start_time(pid: int) -> int | None:
    """/proc/PID/stat field 22 (ticks since boot), or None if the process is gone."""
    try:
        return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[19])
    except (OSError, ValueError, IndexError):
        return None


def _call(fn: Callable, shared: Any, item: Any) -> tuple[str, Any, str]:
    """Run one task inside a worker; exceptions come back as data (never retried)."""
    _WORKER["busy"] = True
    try:
        return "ok", (fn(item) if shared is _NOTHING else fn(_resolve(shared), item)), ""
    except WorkerStopped as stop:
        if _WORKER["local"]:
            os._exit(128 + stop.args[0])
        raise
    except Exception as exc:  # noqa: BLE001 - isolate every task failure
        return "error", f"{type(exc).__name__}: {exc}", traceback.format_exc()
    finally:
        _WORKER["busy"] = False


class _Nothing:
    """Marker: the task has no shared input."""

    def __reduce__(self):
        return (_nothing, ())


def _nothing() -> _Nothing:
    return _NOTHING


_NOTHING = _Nothing()


# ----------------------------------------------------------------------------- shared inputs


@dataclass(frozen=True)
class _SharedFile:
    """Local processes: a large input pickled once to a file; each worker loads it once."""

    token: str
    path: str


_LOADED: dict[str, Any] = {}  # per worker process: token -> object


def _resolve(handle: Any) -> Any:
    if isinstance(handle, _SharedFile):
        if handle.token not in _LOADED:
            with open(handle.path, "rb") as fh:
                _LOADED.clear()  # keep one shared input per worker
                _LOADED[handle.token] = pickle.load(fh)
        return _LOADED[handle.token]
    return handle  # serial: the object; Dask: already resolved


# ----------------------------------------------------------------------------- executors


class Executor:
    """Common interface; see the module docstring."""

    name = "executor"
    workers = 1

    def submit(self, fn: Callable, *args: Any) -> Any:
        raise NotImplementedError

    def scatter(self, obj: Any) -> Any:
        return obj

    def imap_unordered(
        self, fn: Callable, items: Iterable[Any], shared: Any = _NOTHING, retries: int = 2
    ) -> Iterator[tuple[int, Outcome]]:
        raise NotImplementedError

    def close(self) -> None:
        pass

    def stop(self) -> None:
        """Stop now (SIGTERM/SIGINT of the caller): running tasks end, no queued task starts."""
        self.close()

    def __enter__(self) -> Executor:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<{self.name} executor, {self.workers} worker(s)>"


class SerialExecutor(Executor):
    """Runs every task in this process, in order (debugging, tiny jobs)."""

    name = "serial"

    def submit(self, fn: Callable, *args: Any) -> cf.Future:
        f: cf.Future = cf.Future()
        try:
            f.set_result(fn(*args))
        except Exception as exc:  # noqa: BLE001
            f.set_exception(exc)
        return f

    def imap_unordered(self, fn, items, shared=_NOTHING, retries=2):
        for i, item in enumerate(items):
            status, value, tb = _call(fn, shared, item)
            yield i, Outcome(value if status == "ok" else None, value if status == "error" else None, tb)


def _finished(futs: dict) -> Iterator[Any]:
    """The futures as they finish (like as_completed), waiting in short uninterrupted slices so
    that an interrupt is raised between them, never inside the futures' locks."""
    remaining = set(futs)
    while remaining:
        with held():
            done, remaining = cf.wait(remaining, timeout=0.25, return_when=cf.FIRST_COMPLETED)
        yield from done


def _start_forkserver_ignoring_sigint() -> None:
    """Start the forkserver with SIGINT ignored: Python keeps an inherited SIG_IGN, and the
    forkserver hands it to every worker it forks, so a Ctrl-C while a worker still imports is
    ignored (no KeyboardInterrupt traceback from half-imported modules) until _worker_start
    installs the handler that stops the worker cleanly."""
    import multiprocessing.forkserver

    if threading.current_thread() is not threading.main_thread():
        multiprocessing.forkserver.ensure_running()
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        multiprocessing.forkserver.ensure_running()
    finally:
        signal.signal(signal.SIGINT, previous)


class ProcessExecutor(Executor):
    """Local worker processes (concurrent.futures.ProcessPoolExecutor). A pool whose worker
    died is replaced and the tasks it lost are submitted again (up to `retries` times)."""

    name = "processes"

    def __init__(self, workers: int | None = None):
        self.workers = max(1, workers or os.cpu_count() or 1)
        self._pool: cf.ProcessPoolExecutor | None = None
        self._files: list[str] = []
        self._scattered: dict[int, tuple[Any, _SharedFile]] = {}
        fd, self._registry = tempfile.mkstemp(prefix="netgen-workers-", suffix=".txt")
        os.close(fd)

    def pool(self) -> cf.ProcessPoolExecutor:
        if self._pool is None:
            import multiprocessing

            ctx = multiprocessing.get_context("forkserver" if sys.platform.startswith("linux") else None)
            self._pool = cf.ProcessPoolExecutor(
                self.workers, mp_context=ctx, initializer=_worker_start, initargs=(self._registry,)
            )
            if ctx.get_start_method() == "forkserver":
                _start_forkserver_ignoring_sigint()
        return self._pool

    def worker_processes(self) -> list[tuple[int, int]]:
        """(PID, start time) of the workers this executor started that still run."""
        try:
            lines = Path(self._registry).read_text(encoding="utf-8").split("\n")
        except OSError:
            return []
        out = []
        for line in lines:
            pid, _, start = line.partition(" ")
            if pid.isdigit() and start.isdigit() and _start_time(int(pid)) == int(start):
                out.append((int(pid), int(start)))
        return out

    def stop(self):
        """SIGTERM to each worker this executor started (verified by its start time): it unwinds
        its task, which kills its simulator, and exits; SIGKILL to any still there after 10 s."""
        workers = self.worker_processes()
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
        for sig, wait in ((signal.SIGTERM, 10.0), (signal.SIGKILL, 5.0)):
            for pid, start in workers:
                if _start_time(pid) == start:
                    try:
                        os.kill(pid, sig)
                    except OSError:
                        pass
            deadline = time.monotonic() + wait
            while any(_start_time(p) == s for p, s in workers) and time.monotonic() < deadline:
                time.sleep(0.02)
        self.close()

    def submit(self, fn, *args):
        return self.pool().submit(fn, *args)

    def scatter(self, obj):
        """Pickle `obj` once into a temporary file; workers load it on first use."""
        if id(obj) in self._scattered and self._scattered[id(obj)][0] is obj:
            return self._scattered[id(obj)][1]
        fd, path = tempfile.mkstemp(prefix="netgen-shared-", suffix=".pkl")
        with os.fdopen(fd, "wb") as fh:
            pickle.dump(obj, fh, protocol=pickle.HIGHEST_PROTOCOL)
        self._files.append(path)
        handle = _SharedFile(uuid.uuid4().hex, path)
        self._scattered[id(obj)] = (obj, handle)
        return handle

    def imap_unordered(self, fn, items, shared=_NOTHING, retries=2):
        items = list(items)
        if shared is not _NOTHING and not isinstance(shared, _SharedFile):
            shared = self.scatter(shared)
        pending = set(range(len(items)))
        attempts = dict.fromkeys(pending, 0)
        while pending:
            futs = {}
            with held():  # a signal never lands inside the pool's locks
                pool = self.pool()
                for i in sorted(pending):
                    attempts[i] += 1
                    futs[pool.submit(_call, fn, shared, items[i])] = i
            lost = []
            for f in _finished(futs):
                i = futs[f]
                try:
                    status, value, tb = f.result()
                except BrokenProcessPool:
                    lost.append(i)
                    continue
                pending.discard(i)
                yield (
                    i,
                    Outcome(value if status == "ok" else None, value if status == "error" else None, tb, attempts[i]),
                )
            if lost:  # a worker died: new pool, resubmit its tasks
                with held():
                    self._pool.shutdown(wait=False, cancel_futures=True)
                    self._pool = None
                for i in lost:
                    if attempts[i] > retries:
                        pending.discard(i)
                        yield (
                            i,
                            Outcome(
                                None,
                                f"WorkerLost: the worker process died {attempts[i]} times running this task",
                                "",
                                attempts[i],
                            ),
                        )

    def close(self):
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        for path in self._files:
            Path(path).unlink(missing_ok=True)
        self._files.clear()
        self._scattered.clear()
        Path(self._registry).unlink(missing_ok=True)


class DaskExecutor(Executor):
    """A dask.distributed Client: a LocalCluster ('local:N') or an existing scheduler address."""

    name = "dask"

    def __init__(self, address: str | None = None, workers: int | None = None, client: Any = None):
        distributed = _import_distributed()
        self._cluster = None
        if client is not None:
            self.client = client
        elif address is None:
            import logging

            self._environ = dict(os.environ)
            self._cluster = distributed.LocalCluster(
                n_workers=workers or 2,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                silence_logs=logging.ERROR,
            )
            self.client = distributed.Client(self._cluster)
            restore_environ(self._environ)
        else:
            try:
                self.client = distributed.Client(address, timeout="20s")
            except OSError as exc:
                raise ExecutorError(
                    f"cannot reach the Dask scheduler at {address}: {exc}; start one with "
                    "`dask scheduler` and workers with `dask worker ADDRESS`"
                ) from None
        self._own_client = client is None
        self.workers = max(1, len(self.client.scheduler_info().get("workers", {})))
        self.name = f"dask ({self.client.scheduler.address})"
        self._scattered: dict[int, tuple[Any, Any]] = {}
        self._live: dict = {}  # imap_unordered's running futures (for stop)

    def submit(self, fn, *args):
        return self.client.submit(fn, *args, pure=False)

    def scatter(self, obj):
        """client.scatter once per object, to every worker (broadcast), so that losing one worker
        does not lose the only copy; `_shared` scatters it again if all copies are gone."""
        if id(obj) in self._scattered and self._scattered[id(obj)][0] is obj:
            fut = self._scattered[id(obj)][1]
            if fut.status == "finished":
                return fut
        fut = self.client.scatter([obj], hash=False, broadcast=True)[0]  # a list: a dict is per value
        self._scattered[id(obj)] = (obj, fut)
        return fut

    def _shared(self, obj: Any, handle: Any) -> Any:
        """The live handle of a shared input: `handle`, or a fresh scatter of `obj` if the
        cluster lost it (a killed worker held the last copy; its dependants are cancelled)."""
        if obj is _NOTHING or handle.status == "finished":
            return handle
        return self.scatter(obj)

    def imap_unordered(self, fn, items, shared=_NOTHING, retries=2):
        distributed = _import_distributed()
        items = list(items)
        obj = _NOTHING
        if shared is not _NOTHING and not isinstance(shared, distributed.Future):
            obj, shared = shared, self.scatter(shared)
        handle = [shared]
        attempts = dict.fromkeys(range(len(items)), 0)
        tag = uuid.uuid4().hex[:8]

        def start(i: int):
            attempts[i] += 1
            handle[0] = self._shared(obj, handle[0])
            key = f"{getattr(fn, '__name__', 'task')}-{tag}-{i}-{attempts[i]}"
            return self.client.submit(_call, fn, handle[0], items[i], key=key, pure=False, retries=retries)

        futs = {start(i): i for i in attempts}
        self._live = futs
        done = distributed.as_completed(list(futs))
        for f in done:
            i = futs.pop(f)
            try:
                status, value, tb = f.result()
            except Exception as exc:  # noqa: BLE001 - KilledWorker, lost connection, ...
                if attempts[i] <= retries:  # the scheduler gave up on it: submit it again
                    g = start(i)
                    futs[g] = i
                    done.add(g)
                    continue
                status, value, tb = "error", f"WorkerLost: {type(exc).__name__}: {exc}", ""
            yield i, Outcome(value if status == "ok" else None, value if status == "error" else None, tb, attempts[i])
            f.release()

    def stop(self):
        """Cancel every task of this client; close (a LocalCluster takes its workers down)."""
        try:
            self.client.cancel(list(self._live), force=True)
        except Exception:  # noqa: BLE001 - a lost scheduler: close anyway
            pass
        self.close()

    def close(self):
        for _, fut in self._scattered.values():
            fut.release()
        self._scattered.clear()
        if self._own_client:
            self.client.close()
        if self._cluster is not None:
            self._cluster.close()
            restore_environ(self._environ)  # also after nannies respawned lost workers


def restore_environ(saved: dict[str, str]) -> None:
    """Put os.environ back as it was before a LocalCluster: its nannies write their workers'
    settings (OPENBLAS_NUM_THREADS=1, OMP_NUM_THREADS=1, PYTHONHASHSEED, ...) into this process's
    environment at every worker (re)spawn, and every later subprocess (a `netgen build`, say)
    inherited them; OpenBLAS with 1 thread rounds differently from 2, so such a build was no
    longer byte-identical to one from a clean environment."""
    os.environ.clear()
    os.environ.update(saved)


def _import_distributed():
    try:
        import distributed
    except ImportError:
        raise ExecutorError(f"Dask is not installed; install it with: {DASK_INSTALL}") from None
    return distributed


def executor(spec: str | None = None) -> Executor:
    """The executor a --scheduler value names (see the module docstring)."""
    text = (spec or "processes").strip()
    kind, _, count = text.partition(":")
    if "://" in text:
        return DaskExecutor(text)
    if kind in ("processes", "local", "serial"):
        n = None
        if count:
            try:
                n = int(count)
            except ValueError:
                n = 0
            if n < 1:
                raise ExecutorError(
                    f"--scheduler {text!r}: the worker count must be a positive integer (e.g. {kind}:4)"
                )
        if kind == "serial":
            return SerialExecutor()
        if kind == "processes":
            return ProcessExecutor(n)
        return DaskExecutor(None, n or os.cpu_count() or 2)
    raise ExecutorError(f"--scheduler {text!r} is not understood; use {SCHEDULER_HELP}")


def planned_workers(spec: str | None) -> int | None:
    """The worker count a --scheduler value asks for, without starting anything (None: known
    only once connected, a scheduler address)."""
    text = (spec or "processes").strip()
    kind, _, count = text.partition(":")
    if "://" in text or kind not in ("processes", "local", "serial"):
        return None
    if kind == "serial":
        return 1
    return int(count) if count.isdigit() and int(count) > 0 else (os.cpu_count() or 1)
