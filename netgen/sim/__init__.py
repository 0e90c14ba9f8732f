"""The sim stage: running circuit simulators on netlists. One runner (netgen.sim.process: wall-
clock limit, output lines, progress), one raw-file reader (netgen.sim.rawfile), one module per
simulator. SIMULATORS maps a `netgen simulate --simulator` name to its netlist runner: adding a
simulator is one module on top of process and rawfile and one line here."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from . import ngspice, pyspice, vacask
from .rawfile import Plot, read_raw


@dataclass(frozen=True)
class Simulator:
    """run(netlist text, run folder, name, timeout s) -> the plots of its analyses."""
    run: Callable[[str, Path, str, float], list[Plot]]
    help: str


def run_vacask_netlist(netlist: str, workdir: Path, name: str, timeout: float) -> list[Plot]:
    """A VACASK netlist's analyses (`analysis <name> ...` lines in its control block), in order."""
    analyses = re.findall(r"^\s*analysis\s+(\w+)", netlist, re.M) or ["tran1"]
    first = vacask.run_vacask(netlist, workdir, analyses[0], name, timeout)
    return [first] + [read_raw(Path(workdir) / f"{a}.raw")[0] for a in analyses[1:]]


SIMULATORS: dict[str, Simulator] = {
    "ngspice": Simulator(ngspice.run_ngspice, "ngspice in batch mode (a SPICE netlist with its analyses)"),
    "pyspice": Simulator(pyspice.run_netlist, "ngspice's shared library through PySpice, in this process "
                                              "(the libngspice of the selected ngspice, or $NETGEN_LIBNGSPICE)"),
    "vacask": Simulator(run_vacask_netlist, "VACASK (a Spectre-like netlist with a control block)"),
}

__all__ = ["SIMULATORS", "Plot", "Simulator", "read_raw"]
