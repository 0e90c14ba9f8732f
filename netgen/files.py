"""Files in and out: atomic writes (all or nothing), TOML documents and CSV tables with errors
that name the file and line."""

from __future__ import annotations

import csv
import os
import re
import tempfile
import tomllib
from pathlib import Path

import numpy as np

from .errors import InputError, StructureError


def write_atomic(path: str | Path, text: str) -> None:
    """Write text to `path` via a temp file in the same folder and an atomic rename."""
    write_files_atomic({path: text})


def write_bytes_atomic(path: str | Path, data: bytes) -> None:
    """Write bytes to `path` via a temp file in the same folder and an atomic rename."""
    write_files_atomic({path: data})


def write_files_atomic(files: dict[str | Path, str | bytes]) -> None:
    """Write several files all-or-nothing: every text goes to a temp file next to its target
    first; the renames happen only once all temp files are complete, and a failure removes
    the temp files. Files get the usual permissions (0666 minus the umask)."""
    mode = 0o666 & ~umask()
    staged: list[tuple[str, Path]] = []
    try:
        for path, content in files.items():
            path = Path(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
            staged.append((tmp, path))
            if isinstance(content, bytes):
                with os.fdopen(fd, "wb") as fh:
                    fh.write(content)
            else:
                with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as fh:
                    fh.write(content)
            os.chmod(tmp, mode)
        for tmp, path in staged:
            os.replace(tmp, path)
    except BaseException:
        for tmp, _ in staged:
            if os.path.exists(tmp):
                os.unlink(tmp)
        raise


def umask() -> int:
    """This process's umask (read without changing it for longer than the call)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


TOML_FIX = "correct the TOML syntax at that line (strings need quotes, tables [name], arrays [a, b])"


def toml_document(text: str, path: str, error: type[InputError] = StructureError, fix: str = TOML_FIX) -> dict:
    """tomllib.loads, with a syntax error raised as `error` naming the file, the line and the
    fix; shared by the structure and sweep files."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        line = re.search(r"line (\d+)", str(exc))
        raise error(path, "TOML syntax", str(exc), fix, int(line.group(1)) if line else None) from None


def read_csv(path: str | Path, where: str, text_columns: tuple[str, ...] = (),
             error: type[InputError] = StructureError):
    """A CSV table with a header line: (header, values) with every column numeric, or with
    `text_columns` (header, {"values": numbers, <text column>: strings}). Lines starting with
    '#' are comments. Errors name the file, `where` and the fix."""
    with open(path, newline="", encoding="utf-8") as fh:
        lines = [r for r in csv.reader(fh) if r and not r[0].lstrip().startswith("#")]
    if len(lines) < 2:
        raise error(str(path), where, "no data rows", "write a header line and one row per point")
    header = [h.strip() for h in lines[0]]
    keep = [i for i, h in enumerate(header) if h not in text_columns]
    try:
        values = np.array([[float(r[i]) for i in keep] for r in lines[1:]])
    except (ValueError, IndexError) as exc:
        raise error(str(path), where, f"cannot read the numbers: {exc}", "numbers only, one per column")
    if not text_columns:
        return header, values
    out = {"values": values}
    for name in text_columns:
        if name in header:
            out[name] = np.array([r[header.index(name)].strip() for r in lines[1:]])
    return [header[i] for i in keep] + [h for h in header if h in text_columns], out
