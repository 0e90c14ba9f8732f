"""Run ngspice in batch mode and read its binary raw file.

A subprocess per run keeps a simulator crash or hang out of the caller's process and lets
runs go in parallel. Failures become SimulationError with the reason, the time and node
when ngspice names them, and the path of the saved netlist to reproduce the run.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np

INSTALL_HINT = "install it with: apt-get install -y ngspice libngspice0   (Debian/Ubuntu, as root)"


class SimulatorNotFound(RuntimeError):
    """ngspice is not installed or not on PATH."""


class SimulationError(RuntimeError):
    """ngspice failed; the message names the cause and the saved netlist."""


@dataclass
class Plot:
    """One analysis result: vector name -> array (real or complex)."""
    title: str
    name: str
    vectors: dict[str, np.ndarray]

    def __getitem__(self, key: str) -> np.ndarray:
        key = key.lower()
        for candidate in (key, f"v({key})"):
            if candidate in self.vectors:
                return self.vectors[candidate]
        else:
            raise KeyError(f"no vector {key!r} in plot {self.name!r}; have {sorted(self.vectors)[:20]}...")


def ngspice_path() -> str:
    """Path of the ngspice executable, or a clear error with the install command."""
    path = shutil.which("ngspice")
    if not path:
        raise SimulatorNotFound(f"ngspice is not installed (not found on PATH); {INSTALL_HINT}")
    return path


def read_raw(path: str | Path) -> list[Plot]:
    """Parse an ngspice raw file (binary or ascii), possibly holding several plots."""
    data = Path(path).read_bytes()
    plots, pos = [], 0
    while pos < len(data):
        header, pos, binary = _read_header(data, pos)
        if header is None:
            break
        names = header["names"]
        nvar, npts = len(names), header["points"]
        complex_ = "complex" in header["flags"]
        width = 2 if complex_ else 1
        if binary:
            count = nvar * npts * width
            arr = np.frombuffer(data, dtype="<f8", count=count, offset=pos)
            pos += count * 8
        else:
            arr, pos = _read_ascii_values(data, pos, nvar, npts, complex_)
        arr = arr.reshape(npts, nvar, width)
        values = arr[..., 0] + 1j * arr[..., 1] if complex_ else arr[..., 0]
        vectors = {n.lower(): np.array(values[:, k]) for k, n in enumerate(names)}
        plots.append(Plot(header["title"], header["plotname"], vectors))
    return plots


def _read_header(data: bytes, pos: int) -> tuple[dict | None, int, bool]:
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


_FAILURES = [
    (re.compile(r"timestep too small.*?(?:time\s*=\s*([0-9.eE+-]+))?.*?(?:timestep\s*=\s*[0-9.eE+-]+)?"
                r"(?:.*?trouble with node\s*\"?([\w.#:]+)\"?)?", re.I | re.S), "timestep too small"),
    (re.compile(r"singular matrix:?\s*check nodes?\s*([\w.#:]+)?", re.I), "singular matrix"),
    (re.compile(r"no convergence in dc|gmin stepping failed|source stepping failed", re.I),
     "no DC convergence"),
]


def diagnose(log: str) -> str | None:
    """Summarise an ngspice failure from its log: cause, node and time when present."""
    for pattern, what in _FAILURES:
        match = pattern.search(log)
        if match:
            details = []
            node = re.search(r"trouble with node\s*\"?([\w.#:]+)", log, re.I) or \
                re.search(r"check node[s]?\s*([\w.#:]+)", log, re.I)
            when = re.search(r"time\s*=\s*([0-9.eE+-]+)", log[match.start():], re.I)
            if node:
                details.append(f"node {node.group(1)}")
            if when and what == "timestep too small":
                details.append(f"at t = {when.group(1)} s")
            return what + (f" ({', '.join(details)})" if details else "")
    for line in log.splitlines():
        if re.search(r"\berror\b|fatal|unknown (?:subckt|model|device)", line, re.I) and \
                "no error" not in line.lower():
            return line.strip()
    return None


def run_batch(argv: list[str], workdir: Path, netlist_path: Path, netlist: str, raw: Path,
              timeout: float, reproduce: str) -> subprocess.CompletedProcess:
    """Write the netlist, clear a stale raw file, run a batch simulator in `workdir`; a hang
    past `timeout` becomes a SimulationError naming the command that reproduces it."""
    workdir.mkdir(parents=True, exist_ok=True)
    netlist_path.write_text(netlist)
    if raw.exists():
        raw.unlink()
    try:
        return subprocess.run(argv, cwd=workdir, capture_output=True, text=True, timeout=timeout,
                              stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        raise SimulationError(f"{Path(argv[0]).name} did not finish within {timeout:.0f} s; "
                              f"reproduce with: {reproduce}") from None


def run_ngspice(netlist: str, workdir: str | Path, name: str = "circuit", timeout: float = 3600.0) -> list[Plot]:
    """Write `netlist` to workdir/name.cir, run ngspice -b, return the plots of name.raw."""
    exe = ngspice_path()
    workdir = Path(workdir)
    cir, raw, log = workdir / f"{name}.cir", workdir / f"{name}.raw", workdir / f"{name}.log"
    proc = run_batch([exe, "-b", "-r", str(raw), str(cir)], workdir, cir, netlist, raw, timeout,
                     f"ngspice -b {cir}")
    text = proc.stdout + proc.stderr
    log.write_text(text)
    problem = diagnose(text)
    aborted = re.search(r"simulation\(s\) aborted|analysis .*failed|no convergence", text, re.I)
    if proc.returncode != 0 or not raw.exists() or aborted or (problem and _fatal(problem)):
        raise SimulationError(f"ngspice failed: {problem or f'exit code {proc.returncode}'}; "
                              f"log {log}; reproduce with: ngspice -b {cir}")
    return read_raw(raw)


def _fatal(problem: str) -> bool:
    """Warnings ngspice recovers from (a singular first Newton step fixed by gmin stepping)
    are not failures; an aborted analysis is, even when a partial raw file exists."""
    return problem.startswith("timestep too small")
