"""ngspice in batch mode: find it, run a netlist (sim.process), read its raw file (sim.rawfile)
and turn a failure into a SimulationError with the cause, the node and time ngspice names, the
log and the saved netlist to reproduce the run."""

from __future__ import annotations

import re
import shutil
from pathlib import Path
from typing import Callable

from ..errors import SimulationError, SimulatorNotFound
from . import process
from .rawfile import Plot, read_raw

INSTALL_HINT = "install it with: apt-get install -y ngspice libngspice0   (Debian/Ubuntu, as root)"

FAILURES = [
    (re.compile(r"timestep too small.*?(?:time\s*=\s*([0-9.eE+-]+))?.*?(?:timestep\s*=\s*[0-9.eE+-]+)?"
                r"(?:.*?trouble with node\s*\"?([\w.#:]+)\"?)?", re.I | re.S), "timestep too small"),
    (re.compile(r"singular matrix:?\s*check nodes?\s*([\w.#:]+)?", re.I), "singular matrix"),
    (re.compile(r"no convergence in dc|gmin stepping failed|source stepping failed", re.I),
     "no DC convergence"),
]
# a batch analysis that failed (the raw file may still exist); a .control run that aborted
FAILED = re.compile(r"simulation\(s\) aborted|analysis .*failed|no convergence", re.I)
ABORTED = re.compile(r"simulation\(s\) aborted|timestep too small", re.I)


def ngspice_path() -> str:
    """Path of the ngspice executable, or a clear error with the install command."""
    path = shutil.which("ngspice")
    if not path:
        raise SimulatorNotFound(f"ngspice is not installed (not found on PATH); {INSTALL_HINT}")
    return path


def diagnose(log: str) -> str | None:
    """Summarise an ngspice failure from its log: cause, node and time when present."""
    for pattern, what in FAILURES:
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


def fatal(problem: str) -> bool:
    """Warnings ngspice recovers from (a singular first Newton step fixed by gmin stepping)
    are not failures; an aborted analysis is, even when a partial raw file exists."""
    return problem.startswith("timestep too small")


def run_ngspice(netlist: str, workdir: str | Path, name: str = "circuit", timeout: float = 3600.0) -> list[Plot]:
    """Write `netlist` to workdir/name.cir, run ngspice -b, return the plots of name.raw."""
    exe = ngspice_path()
    workdir = Path(workdir)
    cir, raw, log = _files(workdir, name, netlist, f"{name}.raw")
    done = process.run([exe, "-b", "-r", str(raw), str(cir)], workdir, timeout, f"ngspice -b {cir}", "ngspice")
    log.write_text(done.output)
    problem = diagnose(done.output)
    if done.returncode != 0 or not raw.exists() or FAILED.search(done.output) or (problem and fatal(problem)):
        raise SimulationError(f"ngspice failed: {problem or f'exit code {done.returncode}'}; "
                              f"log {log}; reproduce with: ngspice -b {cir}")
    return read_raw(raw)


def run_control(netlist: str, workdir: str | Path, name: str, raw_name: str, timeout: float = 36000.0,
                on_line: Callable[[str], None] | None = None) -> Plot:
    """Run a netlist whose .control block runs its analyses and writes `raw_name` itself (e.g.
    pausing for progress lines, which `on_line` sees as they are printed); return that plot.
    ngspice exits 1 after a paused-and-resumed run: success is a complete raw file."""
    workdir = Path(workdir)
    cir, raw, log = _files(workdir, name, netlist, raw_name)
    reproduce = f"cd {workdir} && ngspice -b {cir.name}"
    done = process.run(process.line_buffered([ngspice_path(), "-b", cir.name]), workdir, timeout, reproduce,
                       "ngspice", on_line=on_line)
    log.write_text(done.output)
    if not raw.exists() or ABORTED.search(done.output):
        raise SimulationError(f"ngspice failed: {diagnose(done.output) or f'exit code {done.returncode}'}; "
                              f"log {log}; reproduce with: {reproduce}")
    return read_raw(raw)[0]


def _files(workdir: Path, name: str, netlist: str, raw_name: str) -> tuple[Path, Path, Path]:
    """Write the netlist into workdir, clear a stale raw file; (netlist, raw, log) paths."""
    workdir.mkdir(parents=True, exist_ok=True)
    cir, raw, log = workdir / f"{name}.cir", workdir / raw_name, workdir / f"{name}.log"
    cir.write_text(netlist)
    raw.unlink(missing_ok=True)
    return cir, raw, log
