"""ngspice in batch mode: find it, run a netlist (sim.process), read its raw file (sim.rawfile)
and turn a failure into a SimulationError with the cause, the node and time ngspice names, the
log and the saved netlist to reproduce the run."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from dataclasses import dataclass
from functools import lru_cache
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


ENV = "NETGEN_NGSPICE"


def ngspice_path() -> str:
    """The ngspice netgen runs: $NETGEN_NGSPICE (a path, or a name on PATH) when set, else the
    `ngspice` on PATH; a clear error with the fix when neither is an executable."""
    chosen = os.environ.get(ENV, "").strip()
    if chosen:
        path = shutil.which(os.path.expanduser(chosen))
        if not path:
            raise SimulatorNotFound(f"{ENV}={chosen!r} is not an executable ngspice; point it at one "
                                    f"(e.g. ~/.cache/netgen/ngspice-46/bin/ngspice) or unset it to use "
                                    f"the ngspice on PATH")
        return path
    path = shutil.which("ngspice")
    if not path:
        raise SimulatorNotFound(f"ngspice is not installed (not found on PATH); {INSTALL_HINT}")
    return path


@dataclass(frozen=True)
class Version:
    """What one ngspice binary is: its release and the build options netgen's outputs depend on."""

    path: str
    major: int
    minor: int
    klu: bool

    @property
    def label(self) -> str:
        return f"ngspice-{self.major}" + (f".{self.minor}" if self.minor else "")

    @property
    def osdi(self) -> bool:
        """Loads OpenVAF-reloaded's OSDI 0.4/0.5 (openvaf-r's output): ngspice 44 and later."""
        return self.major >= 44

    @property
    def osdi_node_limit(self) -> int | None:
        """ngspice 44 caps an OSDI instance at 20 nodes; the cap is gone from 45 on."""
        return 20 if self.major == 44 else None


def version(path: str | None = None) -> Version:
    """The version of `path` (default: ngspice_path()), from `ngspice --version`."""
    path = path or ngspice_path()
    return _version(path, os.stat(path).st_mtime_ns)


@lru_cache(maxsize=8)
def _version(path: str, mtime: int) -> Version:
    try:
        out = subprocess.run([path, "--version"], capture_output=True, text=True, timeout=30,
                             stdin=subprocess.DEVNULL).stdout
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise SimulatorNotFound(f"{path} --version failed ({exc}); is it an ngspice?") from exc
    match = re.search(r"ngspice-(\d+)(?:\.(\d+))?", out)
    if not match:
        raise SimulatorNotFound(f"{path} --version printed no ngspice release; point {ENV} at an ngspice")
    return Version(path, int(match.group(1)), int(match.group(2) or 0), "Compiled with KLU" in out)


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
