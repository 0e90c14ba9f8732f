"""One reader of SPICE raw files (ngspice and VACASK write the same format): binary or ascii,
one or several plots, real or complex; or a real binary file memory-mapped, also while a
simulator is still streaming it (the point count is blank until the end: the rows are counted
from the file size)."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.errors import SimulationError


@dataclass
class Plot:
    """One analysis result: vector name (lower case, as the simulator wrote it) -> array."""

    title: str
    name: str
    vectors: dict[str, np.ndarray]

    def __getitem__(self, key: str) -> np.ndarray:
        """A vector by name; `n` and `v(n)` name the same node voltage (ngspice writes v(n),
        VACASK n)."""
        key = key.lower()
        inner = key[2:-1] if key.startswith("v(") and key.endswith(")") else None
        for candidate in (key, f"v({key})", inner):
            if candidate in self.vectors:
                return self.vectors[candidate]
        raise KeyError(f"no vector {key!r} in plot {self.name!r}; have {sorted(self.vectors)[:20]}...")


def read_raw(path: str | Path, mapped: bool = False) -> list[Plot]:
    """The plots of a raw file. mapped: the one plot of a real binary file as memory-mapped
    columns (nothing is loaded until a column is used: a 2^16-period run writes ~1 GB).
    A file that is not a complete raw file (garbage, truncated, cut short by a killed
    simulator) is a SimulationError naming it, never an exception from the parsing."""
    try:
        return [_mapped(Path(path))] if mapped else _plots(Path(path).read_bytes())
    except SimulationError:
        raise
    except (ValueError, IndexError, KeyError, TypeError, UnicodeDecodeError, OverflowError, MemoryError) as exc:
        raise SimulationError(
            f"{path} is not a complete raw file ({type(exc).__name__}: {exc}); the simulator "
            "wrote garbage or was stopped while writing it: rerun it"
        ) from None
    except OSError as exc:
        raise SimulationError(f"cannot read the raw file {path}: {exc.strerror or exc}") from None


def first_plot(path: str | Path, mapped: bool = False, log: str | Path | None = None, reproduce: str = "") -> Plot:
    """The first plot of a simulator's raw file: a SimulationError naming the raw file (and the
    run's log and command) when it is garbage or holds no plot, never an exception of the parsing."""
    where = (f"; log {log}" if log else "") + (f"; reproduce with: {reproduce}" if reproduce else "")
    try:
        plots = read_raw(path, mapped)
    except SimulationError as exc:
        raise SimulationError(f"{exc}{where}") from None
    if not plots:
        raise SimulationError(f"{path} holds no plot: the simulator wrote an empty or garbled raw file{where}")
    return plots[0]


def _plots(data: bytes) -> list[Plot]:
    """Every plot of a raw file's bytes (errors from the checks or the parsing: read_raw)."""
    plots, pos = [], 0
    while pos < len(data):
        header, pos, binary = read_header(data, pos)
        if header is None:
            break
        names = header["names"]
        nvar, npts = len(names), header["points"]
        if nvar < 1 or nvar != header.get("nvar") or npts < 0:
            raise ValueError(f"the header lists {nvar} of {header.get('nvar')} variables and {npts} points")
        complex_ = "complex" in header["flags"]
        width = 2 if complex_ else 1
        if binary:
            count = nvar * npts * width
            if len(data) - pos < count * 8:
                raise ValueError(f"{npts} points need {count * 8} bytes of values, the file has {len(data) - pos}")
            arr = np.frombuffer(data, dtype="<f8", count=count, offset=pos)
            pos += count * 8
        else:
            if data.count(b"\n", pos) < nvar * npts:
                raise ValueError(f"{npts} points of {nvar} variables, fewer value lines in the file")
            arr, pos = _read_ascii_values(data, pos, nvar, npts, complex_)
        arr = arr.reshape(npts, nvar, width)
        values = arr[..., 0] + 1j * arr[..., 1] if complex_ else arr[..., 0]
        vectors = {n.lower(): np.array(values[:, k]) for k, n in enumerate(names)}
        plots.append(Plot(header["title"], header["plotname"], vectors))
    return plots


def read_header(data: bytes, pos: int) -> tuple[dict | None, int, bool]:
    """The header of the plot starting at `pos`: (header, offset of its values, binary?)."""
    header: dict = {"names": [], "flags": "", "title": "", "plotname": "", "points": 0}
    while pos < len(data):
        end = data.index(b"\n", pos)
        line = data[pos:end].decode("latin-1")
        pos = end + 1
        key, _, value = line.partition(":")
        key = key.strip().lower()
        if key == "title":
            header["title"] = value.strip()
        elif key == "plotname":
            header["plotname"] = value.strip()
        elif key == "flags":
            header["flags"] = value.strip().lower()
        elif key == "no. points":
            header["points"] = int(value)
        elif key == "variables":
            nvar = header["nvar"]
            for _ in range(nvar):
                end = data.index(b"\n", pos)
                parts = data[pos:end].decode("latin-1").split()
                header["names"].append(parts[1])
                pos = end + 1
        elif key == "no. variables":
            header["nvar"] = int(value)
        elif key == "binary":
            return header, pos, True
        elif key == "values":
            return header, pos, False
    return None, pos, True


def _read_ascii_values(data: bytes, pos: int, nvar: int, npts: int, complex_: bool) -> tuple[np.ndarray, int]:
    out = np.zeros((npts, nvar, 2))
    for p in range(npts):
        for v in range(nvar):
            end = data.index(b"\n", pos)
            tokens = data[pos:end].decode("latin-1").split()
            pos = end + 1
            text = tokens[-1]
            if complex_:
                re_, im = text.split(",")
                out[p, v] = float(re_), float(im)
            else:
                out[p, v, 0] = float(text)
    return out.reshape(-1), pos


def streaming_header(path: Path) -> tuple[dict, int]:
    """Header and data offset of a real binary raw file, also while it is being written."""
    with open(path, "rb") as fh:
        head = fh.read(1 << 16)
    head = re.sub(rb"(No\. Points:)([ \t]+)\n", lambda m: m.group(1) + b"0".rjust(len(m.group(2))) + b"\n", head)
    try:
        header, pos, binary = read_header(head, 0)
    except (ValueError, IndexError, KeyError) as exc:
        raise SimulationError(f"{path}: not a raw file header ({exc})") from None
    if header is None or not binary or "complex" in header["flags"] or not header["names"]:
        raise SimulationError(f"{path}: expected a real binary raw file")
    rows = (path.stat().st_size - pos) // (8 * len(header["names"]))
    header["points"] = min(header["points"], rows) if header["points"] else rows
    return header, pos


def _mapped(path: Path) -> Plot:
    header, pos = streaming_header(path)
    names = header["names"]
    data = np.memmap(path, dtype="<f8", mode="r", offset=pos, shape=(header["points"], len(names)))
    return Plot(header["title"], header["plotname"], {n.lower(): data[:, k] for k, n in enumerate(names)})


def last_time(path: Path) -> float:
    """Last simulated time in a raw file a simulator is still writing (0 if none yet)."""
    try:
        header, pos = streaming_header(path)
        if header["points"] < 1:
            return 0.0
        with open(path, "rb") as fh:
            fh.seek(pos + (header["points"] - 1) * 8 * len(header["names"]))
            return float(np.frombuffer(fh.read(8), dtype="<f8")[0])
    except (OSError, ValueError, SimulationError):
        return 0.0
