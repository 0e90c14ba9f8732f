"""How a netgen process ends when it does not finish. SIGINT and SIGTERM are one interrupt: both
raise Interrupted (a KeyboardInterrupt) in the main thread, so every `finally` and every
transaction (netgen.runtime.folders.OutputFolder) cleans up the same way whichever signal stopped the run;
`held()` defers them over a few renames that must not be cut in half. An unexpected exception
becomes a crash log (`crash_log`) and one line. Standard library only: the console entry
(netgen.cli) installs this before any heavy import."""

from __future__ import annotations

import signal
import sys
import threading
from contextlib import contextmanager

TYPE_CHECKING = False
if TYPE_CHECKING:  # typing and pathlib cost ~10 ms at start-up
    from collections.abc import Iterator
    from pathlib import Path

SIGNALS = (signal.SIGINT, signal.SIGTERM)
CRASH_LOG = "netgen-crash.log"
# exit codes of a run that did not finish: interrupted (128 + SIGINT, as shells report Ctrl-C) and
# an internal error (EX_SOFTWARE of sysexits.h)
EXIT_INTERRUPTED = 130
EXIT_INTERNAL = 70


class Interrupted(KeyboardInterrupt):
    """The run was stopped by SIGINT (Ctrl-C) or SIGTERM; `signum` says which. `message`, when a
    stage has cleaned up after the signal and knows what is left (a sweep: which runs finished,
    how to resume), is the one line the error boundary (netgen.cli.commands.report_interrupt) prints; the
    exit code is EXIT_INTERRUPTED either way. str() is the signal's name."""

    def __init__(self, signum: int = signal.SIGINT, message: str | None = None):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum
        self.message = message


# the signals that have arrived since install(): an extension module's import turns the
# KeyboardInterrupt it is cut by into an ImportError or RuntimeError, which is still an interrupt
ARRIVED: list[int] = []


def _raise(signum: int, frame) -> None:
    """The handler of both signals: an Interrupted exception where the main thread is."""
    ARRIVED.append(signum)
    raise Interrupted(signum)


def interrupted(exc: BaseException) -> Interrupted | None:
    """The interrupt behind `exc`: itself, one in its chain of causes, or (for an exception raised
    while a signal was being handled, e.g. an import cut short) the signal that arrived."""
    seen: BaseException | None = exc
    while seen is not None:
        if isinstance(seen, KeyboardInterrupt):
            return seen if isinstance(seen, Interrupted) else Interrupted(signal.SIGINT)
        seen = seen.__cause__ or seen.__context__
    return Interrupted(ARRIVED[-1]) if ARRIVED else None


def install() -> dict:
    """SIGINT and SIGTERM raise Interrupted in the main thread (no-op in other threads); the
    handlers they had, for `restore`. An Interrupted that lands in a finaliser (a __del__, a
    weakref callback), where Python prints and drops exceptions, is not printed: `check()`
    acts on it at the next checkpoint."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    ARRIVED.clear()
    previous: dict = {"unraisable": sys.unraisablehook}
    sys.unraisablehook = _unraisable
    # a signal ignored since the start stays ignored (a background job of a script, nohup)
    previous |= {s: signal.signal(s, _raise) for s in SIGNALS if signal.getsignal(s) is not signal.SIG_IGN}
    return previous


def restore(previous: dict) -> None:
    """Put back the handlers `install` replaced."""
    for s, handler in previous.items():
        if s == "unraisable":
            sys.unraisablehook = handler
        else:
            signal.signal(s, handler)


def _unraisable(info) -> None:
    """sys.unraisablehook: an interrupt dropped in a finaliser stays silent (check() raises it)."""
    if not isinstance(info.exc_value, KeyboardInterrupt):
        sys.__unraisablehook__(info)


def check() -> None:
    """A checkpoint: raise Interrupted if a signal arrived that nothing acted on (it landed in a
    finaliser, or in code that swallowed the exception), so a run never goes on, or commits,
    after it was told to stop."""
    if ARRIVED:
        raise Interrupted(ARRIVED[-1])


def quiet() -> None:
    """Ignore SIGINT/SIGTERM from here on: the run is over and only exiting is left, which a
    signal would turn into a traceback from the interpreter's shutdown."""
    if threading.current_thread() is threading.main_thread():
        for s in SIGNALS:
            signal.signal(s, signal.SIG_IGN)


@contextmanager
def held() -> Iterator[None]:
    """Defer SIGINT/SIGTERM until the block is done (a commit's renames, a cleanup), then deliver
    the first one that came to the handler it had (install's raises Interrupted; the default
    one of SIGTERM ends the process). Outside the main thread: no deferral."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    arrived: list[int] = []
    previous = {s: signal.signal(s, lambda n, f: arrived.append(n)) for s in SIGNALS}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        if arrived:
            deliver(arrived[0], previous[signal.Signals(arrived[0])])


def deliver(signum: int, handler) -> None:
    """Act on a deferred signal as its handler would have."""
    if callable(handler):
        handler(signum, None)
    elif handler == signal.SIG_DFL:
        signal.raise_signal(signum)


def crash_log(exc: BaseException, folder: str | Path | None = None) -> Path | None:
    """Write the traceback of `exc` (with the command line and time) to CRASH_LOG in `folder`,
    else the working folder, else the temp folder; the path written, None if none could be.
    (Its imports are here: the module loads before everything else and must load fast.)"""
    import os
    import tempfile
    import time
    import traceback
    from pathlib import Path

    text = (
        f"netgen crashed at {time.strftime('%Y-%m-%d %H:%M:%S %z')}\n"
        f"command: {' '.join(sys.argv)}\nworking folder: {os.getcwd()}\n\n" + "".join(traceback.format_exception(exc))
    )
    for place in (folder, ".", tempfile.gettempdir()):
        if place is None or not Path(place).is_dir():
            continue
        path = Path(place) / CRASH_LOG
        try:
            path.write_text(text, encoding="utf-8")
            return path.resolve()
        except OSError:
            continue
    return None


def internal_error(exc: BaseException, folder: str | Path | None = None) -> int:
    """Report an unexpected exception in one line on stderr, its traceback in a crash log."""
    log = crash_log(exc, folder)
    where = f"the traceback is in {log}" if log else "no crash log could be written"
    first = (str(exc).splitlines() or [""])[0][:200]
    print(
        f"netgen: internal error ({type(exc).__name__}: {first}); {where}; please report it with that file",
        file=sys.stderr,
    )
    return EXIT_INTERNAL
