"""A sweep's output folder belongs to one sweep: DIR/.sweep.json names it (a hash of the
structure file and every run's settings) and DIR/.lock is held while a sweep writes there. A
re-run of the same sweep resumes; a different sweep into the folder, or a second sweep while
one runs, is refused with the fix, so no folder ever holds one sweep's results.csv beside
another's runs."""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from ..core.errors import InputError
from ..core.files import write_atomic
from .plan import RunSpec

MARKER = ".sweep.json"
LOCK = ".lock"


class FolderError(InputError):
    """An output folder a sweep may not write into (another sweep's, or in use)."""

    what = "output folder"


def identity(structure_path: str | Path, runs: list[RunSpec]) -> str:
    """The sweep's identity: its structure file's bytes and every run's name and settings key
    (not the figure, x or retries: changing those re-plots, it does not change a result)."""
    h = hashlib.sha256(Path(structure_path).read_bytes())
    h.update(json.dumps([(r.name, r.key) for r in runs]).encode())
    return h.hexdigest()[:20]


def _owner(out: Path) -> dict | None:
    """The marker of the sweep the folder belongs to, or None."""
    try:
        d = json.loads((out / MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return d if isinstance(d, dict) else None


def _check(out: Path, ident: str) -> dict | None:
    """Refuse a folder that is a file, another sweep's, or a non-empty folder of something else;
    return the marker of this sweep when the folder already is its folder."""
    move = f"give another -o, or move the folder away first (mv {out} {out}.old)"
    if out.exists() and not out.is_dir():
        raise FolderError(str(out), "-o", "is a file, not a folder", "give a folder path for -o")
    owner = _owner(out) if out.is_dir() else None
    if out.is_dir() and owner is None and any(p.name != LOCK for p in out.iterdir()):
        raise FolderError(
            str(out),
            "-o",
            "the folder is not empty and holds no sweep of netgen "
            f"(no {MARKER}); results written there would mix with its files",
            move,
        )
    if owner is not None and owner.get("id") != ident:
        raise FolderError(
            str(out),
            "-o",
            f"the folder holds another sweep ({owner.get('sweep')} on "
            f"{owner.get('structure')}, {owner.get('runs')} runs); a different structure file or "
            "sweep settings would leave its results beside this sweep's runs",
            move,
        )
    return owner


@contextmanager
def claim(out: Path, ident: str, sweep_path: str, structure_path: str, runs: int) -> Iterator[None]:
    """Hold DIR for this sweep: refuse a folder that is another sweep's, is not a sweep folder
    (and not empty), or is locked by a running sweep; write the marker; keep the lock."""
    _check(out, ident)  # before anything is created there
    out.mkdir(parents=True, exist_ok=True)
    fd = os.open(out / LOCK, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            pid = os.pread(fd, 32, 0).decode(errors="replace").strip()
            raise FolderError(
                str(out),
                "-o",
                f"another netgen sweep (pid {pid or '?'}) is writing into the folder",
                "wait for it to finish (or stop it), or give another -o",
            ) from None
        owner = _check(out, ident)  # again under the lock: a sweep may just have finished
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        if owner is None:
            write_atomic(
                out / MARKER,
                json.dumps(
                    {"id": ident, "sweep": str(sweep_path), "structure": str(structure_path), "runs": runs}, indent=1
                )
                + "\n",
            )
        yield
    finally:
        os.close(fd)  # releases the lock
