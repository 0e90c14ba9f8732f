"""Files in and out: atomic writes (all or nothing), TOML documents, CSV tables and .npz archives
with errors that name the file and line (binary, non-UTF-8, truncated or pickled data included)."""

from __future__ import annotations

import csv
import difflib
import errno
import io
import json
import os
import re
import stat
import tempfile
import tomllib
import zipfile
import zlib
from dataclasses import dataclass
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


def cache_root() -> Path:
    """netgen's cache folder: NETGEN_CACHE, else $XDG_CACHE_HOME/netgen (~/.cache/netgen). Each
    kind of derived file (code models, OSDI modules, comb tables) keeps a subfolder keyed by content."""
    base = os.environ.get("NETGEN_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "netgen"
    )
    return Path(base)


def umask() -> int:
    """This process's umask (read without changing it for longer than the call)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


TOML_FIX = "correct the TOML syntax at that line (strings need quotes, tables [name], arrays [a, b])"


def toml_document(text: str, path: str, error: type[InputError] = StructureError, fix: str = TOML_FIX) -> dict:
    """tomllib.loads after the nesting check (check_depth), with a syntax error raised as `error` naming the file, the line and the
    fix; shared by the structure and sweep files."""
    check_depth(text, path, error)
    try:
        return tomllib.loads(text)
    except RecursionError:
        raise error(path, "nesting", "nested too deeply to parse", fix) from None
    except tomllib.TOMLDecodeError as exc:
        line = re.search(r"line (\d+)", str(exc))
        raise error(path, "TOML syntax", str(exc), fix, int(line.group(1)) if line else None) from None


@dataclass
class CsvTable:
    """A CSV table read by read_csv: the header, the numeric columns (`values`, one row per data
    line), the file line of each row (`lines`) and the text columns by name."""

    header: list[str]
    header_line: int
    values: np.ndarray
    lines: np.ndarray
    text: dict[str, np.ndarray]


# what one input file may hold (bytes): a structure, loop or sweep file is a page of TOML; a model
# JSON or a couplings file a few MB; an imported table or matrix (CSV, .npz, .mtx) a FEM mesh's data
LIMITS = {"toml": 4 << 20, "json": 64 << 20, "table": 512 << 20}
MAX_DEPTH = 64  # nesting of arrays/tables/objects in a TOML or JSON input (examples: at most 4)
FILE_KINDS = {
    stat.S_IFIFO: "a named pipe (FIFO)",
    stat.S_IFCHR: "a character device",
    stat.S_IFBLK: "a block device",
    stat.S_IFSOCK: "a socket",
    stat.S_IFDIR: "a folder",
}


def read_bytes(path: str | Path, where: str, what: str, error: type[InputError], kind: str = "toml") -> bytes:
    """The one reader of input files: a regular file only (a FIFO, device or folder is refused
    before it can block or stream forever), at most LIMITS[kind] bytes (checked on the size and
    again on what is read), errors naming the file and the fix."""
    limit = LIMITS[kind]
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except ValueError:  # a NUL character in the path
        raise error(repr(str(path)), where, "the path holds a NUL character", f"give the path of {what}") from None
    except OSError as exc:
        raise error(str(path), where, f"cannot read: {os_reason(exc)}", f"give the path of {what}") from None
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        raise error(
            str(path),
            where,
            f"{FILE_KINDS.get(stat.S_IFMT(mode), 'not a regular file')}, not {what}",
            f"give the path of {what} (a regular file)",
        )
    with os.fdopen(fd, "rb") as fh:
        try:
            data = fh.read(limit + 1)
        except OSError as exc:
            raise error(str(path), where, f"cannot read: {os_reason(exc)}", f"give the path of {what}") from None
    if len(data) > limit:
        raise error(
            str(path),
            where,
            f"larger than {limit} bytes ({limit >> 20} MiB), the limit for {what}",
            f"give {what} of at most {limit >> 20} MiB (docs/structure-files.md, Limits)",
        )
    return data


def os_reason(exc: OSError) -> str:
    """An OSError's reason in words (a symlink loop, a missing file), without a traceback."""
    if exc.errno == errno.ELOOP:
        return "a loop of symbolic links"
    return exc.strerror or str(exc)


def read_text(
    path: str | Path, where: str, what: str, error: type[InputError] = StructureError, kind: str = "toml"
) -> str:
    """A data file's text (read_bytes' limits; a UTF-8 byte-order mark is accepted): binary data
    (NUL bytes) and non-UTF-8 bytes become `error` naming the file and the byte offset, instead of
    a UnicodeDecodeError."""
    data = read_bytes(path, where, what, error, kind)
    nul = data.find(b"\0")
    if nul >= 0:
        raise error(
            str(path), where, f"binary data (a NUL byte at offset {nul}), not {what}", f"give {what} as UTF-8 text"
        )
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise error(
            str(path),
            where,
            f"not UTF-8 text (byte 0x{data[exc.start]:02x} at offset {exc.start})",
            f"save {what} as UTF-8 (e.g. from a spreadsheet: CSV UTF-8)",
        ) from None


# strings and comments (whose brackets do not nest) and the brackets that do
TOML_TOKENS = re.compile(r'"""[\s\S]*?"""|\'\'\'[\s\S]*?\'\'\'|"(?:[^"\\\n]|\\.)*"|\'[^\'\n]*\'|#[^\n]*|[\[\]{}]')
JSON_TOKENS = re.compile(r'"(?:[^"\\]|\\.)*"|[\[\]{}]')


def nesting_depth(text: str, tokens: re.Pattern = TOML_TOKENS) -> int:
    """The deepest nesting of [ ] and { } outside strings and comments (before any parser recurses)."""
    depth = deepest = 0
    for m in tokens.finditer(text):
        c = m.group(0)
        if c in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif c in "]}":
            depth = max(depth - 1, 0)
    return deepest


def check_depth(text: str, path: str, error: type[InputError], tokens: re.Pattern = TOML_TOKENS) -> None:
    """Refuse nesting deeper than MAX_DEPTH, naming the depth and the limit."""
    depth = nesting_depth(text, tokens)
    if depth > MAX_DEPTH:
        raise error(
            str(path),
            "nesting",
            f"arrays/tables nested {depth} deep, more than the limit of {MAX_DEPTH}",
            f"flatten the document to at most {MAX_DEPTH} levels (netgen's files need at most 4)",
        )


def json_document(text: str, path: str, error: type[InputError], fix: str) -> object:
    """json.loads after the nesting check, a syntax error raised as `error` naming the file and line."""
    check_depth(text, path, error, JSON_TOKENS)
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise error(str(path), "JSON syntax", f"not JSON: {exc.msg}", fix, exc.lineno) from None
    except RecursionError:
        raise error(str(path), "nesting", "nested too deeply to parse", fix) from None


def read_csv(
    path: str | Path, where: str, text_columns: tuple[str, ...] = (), error: type[InputError] = StructureError
) -> CsvTable:
    """A CSV table with a header line, every column numeric except `text_columns`. Lines starting
    with '#' are comments. Errors (not text, no rows, a repeated or empty column name, a row of the
    wrong length, a cell that is no number) name the file, `where`, the line and the fix."""
    text = read_text(path, where, "a CSV table", error, "table")
    rows = [
        (no, r)
        for no, r in enumerate(csv.reader(io.StringIO(text, newline="")), start=1)
        if r and "".join(r).strip() and not r[0].lstrip().startswith("#")
    ]
    if len(rows) < 2:
        raise error(str(path), where, "no data rows", "write a header line and one row per point")
    header_line, raw = rows[0]
    header = [h.strip() for h in raw]
    for k, h in enumerate(header):
        if not h:
            raise error(str(path), where, f"column {k + 1} of the header has no name", "name every column", header_line)
        if header.index(h) != k:
            raise error(
                str(path), where, f"column {h!r} appears twice in the header", "give each column once", header_line
            )
    keep = [i for i, h in enumerate(header) if h not in text_columns]
    values = np.empty((len(rows) - 1, len(keep)))
    for r, (no, row) in enumerate(rows[1:]):
        if len(row) != len(header):
            raise error(
                str(path),
                where,
                f"row has {len(row)} fields, the header {len(header)}",
                "give one value per column on every line",
                no,
            )
        for j, i in enumerate(keep):
            try:
                values[r, j] = float(row[i])
            except ValueError:
                raise error(
                    str(path),
                    where,
                    f"column {header[i]!r}: {row[i]!r} is not a number",
                    "numbers only (SI units; nan marks a missing value)",
                    no,
                ) from None
    text_out = {
        name: np.array([row[header.index(name)].strip() for _, row in rows[1:]])
        for name in text_columns
        if name in header
    }
    return CsvTable(
        [header[i] for i in keep] + [h for h in header if h in text_columns],
        header_line,
        values,
        np.array([no for no, _ in rows[1:]]),
        text_out,
    )


def load_npz(
    path: str | Path,
    where: str,
    required: tuple[str, ...],
    allowed: tuple[str, ...],
    error: type[InputError] = StructureError,
) -> dict[str, np.ndarray]:
    """The arrays of a NumPy .npz archive (no pickled objects): anything numpy cannot read (an
    empty or truncated file, garbage, a bare .npy), a missing or unknown array becomes `error`
    naming the file and the array."""
    fix = f"save the arrays with numpy.savez(path, {', '.join(f'{k}=...' for k in required)})"
    data = read_bytes(path, where, "a NumPy .npz archive", error, "table")
    try:
        z = np.load(io.BytesIO(data), allow_pickle=False)
    except PermissionError as exc:
        raise error(str(path), where, f"cannot read: {exc.strerror}", "check that the file is readable") from None
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        why = "it is no archive and would need unpickling, which netgen never does" if "pickle" in str(exc) else exc
        raise error(str(path), where, f"not a readable .npz archive ({why})", fix) from None
    if not isinstance(z, np.lib.npyio.NpzFile):
        raise error(str(path), where, "a single .npy array, not an .npz archive", fix)
    with z:
        names = list(z.files)
        missing = [k for k in required if k not in names]
        if missing:
            raise error(str(path), where, f"missing arrays {missing} (the archive has {names})", fix)
        out = {}
        for k in names:
            if k not in allowed:
                raise error(
                    str(path),
                    where,
                    f"unknown array {k!r}",
                    f"{did_you_mean(k, list(allowed))}the arrays allowed: {', '.join(allowed)}",
                )
            try:
                out[k] = z[k]
            except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as exc:
                raise error(
                    str(path),
                    where,
                    f"array {k!r} cannot be read ({exc})",
                    fix + " (plain numbers and strings, no Python objects)",
                ) from None
        return out


def did_you_mean(word: str, options: list[str]) -> str:
    """'did you mean 'x'? ' for the closest option, or ''."""
    close = difflib.get_close_matches(word, options, n=1, cutoff=0.6)
    return f"did you mean '{close[0]}'? " if close else ""
