"""The sim stage: running circuit simulators on netlists. One runner (netgen.core.process: wall-
clock limit, output lines, progress), one raw-file reader (netgen.sim.rawfile), one module per
simulator. SIMULATORS maps a `netgen simulate --simulator` name to its netlist runner: adding a
simulator is one module on top of process and rawfile and one line here."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from ..core.errors import InputError
from . import ngspice, pyspice, vacask
from .rawfile import Plot, first_plot, read_raw

# control characters no text netlist holds (tab, newline, form feed and carriage return are text)
BINARY = re.compile(rb"[\x00-\x08\x0e-\x1a\x1c-\x1f]")


class RunNetlist(Protocol):
    """A simulator's run of netlist text in a run folder: the plots of its analyses."""

    def __call__(self, netlist: str, workdir: Path, name: str, timeout: float, /) -> list[Plot]: ...


class RunFile(Protocol):
    """A simulator's run of a netlist file where it is (relative includes resolve against it)."""

    def __call__(self, path: Path, workdir: Path, timeout: float, /) -> list[Plot]: ...


@dataclass(frozen=True)
class Simulator:
    """run(netlist text, run folder, name, timeout s) -> the plots of its analyses;
    run_file(netlist file, run folder, timeout s): the same for a file, run where it is (None:
    its text is run, so relative includes resolve as the simulator resolves them for text)."""

    run: RunNetlist
    help: str
    run_file: RunFile | None = None

    def file(self, path: Path, workdir: Path, timeout: float) -> list[Plot]:
        """Run a netlist file (`netgen simulate`)."""
        if self.run_file is not None:
            return self.run_file(path, workdir, timeout)
        return self.run(netlist_text(path), workdir, Path(path).stem, timeout)


def netlist_text(path: str | Path) -> str:
    """A netlist file's text: UTF-8, or Latin-1 (ngspice and VACASK read bytes; an accented
    comment is fine); binary data (a NUL or other control byte) is an InputError with its offset."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise InputError(
            str(path), "file", f"cannot read it: {exc.strerror or exc}", "check the path and its permissions"
        ) from None
    bad = BINARY.search(data)
    if bad:
        raise InputError(
            str(path),
            f"byte {bad.start()}",
            f"binary data (byte 0x{data[bad.start()]:02x}), not a text netlist",
            "give the netlist's text file (.cir/.sp for ngspice, .sim for VACASK), "
            "not a raw file, an archive or an executable",
        )
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def run_vacask_netlist(netlist: str, workdir: Path, name: str, timeout: float) -> list[Plot]:
    """A VACASK netlist's analyses (`analysis <name> ...` lines in its control block), in order."""
    analyses = re.findall(r"^\s*analysis\s+(\w+)", netlist, re.M) or ["tran1"]
    first = vacask.run_vacask(netlist, workdir, analyses[0], name, timeout)
    return [first] + [first_plot(Path(workdir) / f"{a}.raw") for a in analyses[1:]]


def run_vacask_file(path: Path, workdir: Path, timeout: float) -> list[Plot]:
    """A VACASK netlist file's analyses, run where the file is (includes resolve against its folder)."""
    analyses = re.findall(r"^\s*analysis\s+(\w+)", netlist_text(path), re.M) or ["tran1"]
    first = vacask.run_file(path, workdir, analyses[0], timeout)
    return [first] + [first_plot(Path(workdir) / f"{a}.raw") for a in analyses[1:]]


SIMULATORS: dict[str, Simulator] = {
    "ngspice": Simulator(
        ngspice.run_ngspice, "ngspice in batch mode (a SPICE netlist with its analyses)", ngspice.run_file
    ),
    "pyspice": Simulator(
        pyspice.run_netlist,
        "ngspice's shared library through PySpice, in this process "
        "(the libngspice of the selected ngspice, or $NETGEN_LIBNGSPICE)",
    ),
    "vacask": Simulator(run_vacask_netlist, "VACASK (a Spectre-like netlist with a control block)", run_vacask_file),
}

__all__ = ["SIMULATORS", "Plot", "Simulator", "netlist_text", "read_raw"]
