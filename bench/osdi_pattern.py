"""The stamp pattern of the compiled model and the LU fill it causes: the Jacobian entries openvaf-r
declares in the module's OSDI descriptor (per row kind, and the contact damper's force-node x
velocity entries), and the nonzeros of ngspice 46's factored matrix (`mdump`) in the OSDI
sigma-delta testbench (osdi loop blocks, 2 periods) around the emitted module and around the floor.

    NETGEN_NGSPICE=~/.cache/netgen/ngspice-46/bin/ngspice .venv/bin/python bench/osdi_pattern.py [--va FILE]

--va reads another Verilog-A text of the module for the descriptor count (the LU count is always
the emitted module's). Measured (reference disk, 2026-12-06): 59 nodes, 459 entries, 49 of them
the contact damper's fn_<q> x u_<w> (zero unless a stop is touched); LU 888 nonzeros in 117
unknowns, the floor 361 in 110.
"""

from __future__ import annotations

import argparse
import ctypes as C
import re
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path

from sigma_delta import MODEL_JSON, library, osdi_control

from netgen.emit import osdi, veriloga
from netgen.model import MacroModel
from netgen.sim.ngspice import ngspice_path
from netgen.testbench import sigma_delta as sd
from netgen.testbench.sigma_delta import ngspice as sdn


class _Node(C.Structure):
    _fields_ = (
        [("name", C.c_char_p), ("units", C.c_char_p), ("residual_units", C.c_char_p)]
        + [(n, C.c_uint32) for n in ("resist", "react", "resist_lim", "react_lim")]
        + [("is_flow", C.c_bool)]
    )


class _Entry(C.Structure):
    _fields_ = [("row", C.c_uint32), ("col", C.c_uint32), ("react_off", C.c_uint32), ("flags", C.c_uint32)]


class _Descriptor(C.Structure):
    """The head of an OSDI 0.4 descriptor (name, nodes, Jacobian entries)."""

    _fields_ = [
        ("name", C.c_char_p),
        ("num_nodes", C.c_uint32),
        ("num_terminals", C.c_uint32),
        ("nodes", C.POINTER(_Node)),
        ("num_jacobian_entries", C.c_uint32),
        ("jacobian_entries", C.POINTER(_Entry)),
    ]


def entries(osdi_file: Path) -> tuple[list[str], list[tuple[str, str]]]:
    """Node names and the (row, column) Jacobian entries of the first module in an .osdi file."""
    lib = C.CDLL(str(osdi_file))
    d = C.cast(C.addressof(C.c_char.in_dll(lib, "OSDI_DESCRIPTORS")), C.POINTER(_Descriptor))[0]
    names = [d.nodes[i].name.decode() for i in range(d.num_nodes)]
    pairs = [(names[e.row], names[e.col]) for e in d.jacobian_entries[: d.num_jacobian_entries]]
    return names, pairs


def kind(node: str) -> str:
    """The row/column kind of a module node: its name's prefix (electrodes and the plate: 'electrical')."""
    found = re.match(r"(fn|xs|u|f|x|flow|a|w)_|flow\(", node)
    return (found.group(1) or "flow") if found else "electrical"


def lu_nonzeros(model: MacroModel, variant: str, folder: Path) -> tuple[int, int]:
    """(unknowns, nonzeros) of ngspice's factored matrix after 2 periods of the OSDI loop around `variant`."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "model.lib").write_text(library(model, variant))
    control = osdi_control(model, variant, "osdi", folder / "osdi")
    net = sdn.testbench(
        model,
        sd.design(model, 1e-6),
        folder / "model.lib",
        2,
        "bench.raw",
        settings=sdn.Settings("osdi", control, chunks=1),
    )
    (folder / "bench.cir").write_text(re.sub(r"(?m)^(tran .*)$", r"\1\nmdump lu.txt", net))
    with open(folder / "bench.log", "w") as log:  # ngspice -b may exit 1 after a complete run
        subprocess.run([ngspice_path(), "-b", "bench.cir"], cwd=folder, stdout=log, stderr=subprocess.STDOUT)
    lines = (folder / "lu.txt").read_text().splitlines()
    return int(lines[2].split()[0]), len(lines) - 3


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--va", type=Path, help="count the entries of this .va instead of the emitted module")
    ap.add_argument("--model", default=str(MODEL_JSON))
    args = ap.parse_args()
    model = MacroModel.load_json(args.model)
    with tempfile.TemporaryDirectory(prefix="osdi-pattern-") as tmp:
        text = args.va.read_text() if args.va else veriloga.module(model, noise=False)
        names, pairs = entries(osdi.compiled(text, model.name, Path(tmp) / "osdi"))
        damper = sum(kind(r) == "fn" and kind(c) == "u" for r, c in pairs)
        print(f"{len(names)} nodes, {len(pairs)} Jacobian entries ({damper} force node x velocity: the contact damper)")
        for k, n in sorted(Counter(kind(r) for r, _ in pairs).items()):
            print(f"    rows {k:10s} {n:4d}")
        for variant in ("osdi", "floor"):
            size, nnz = lu_nonzeros(model, variant, Path(tmp) / variant)
            print(f"{variant}: LU {nnz} nonzeros in {size} unknowns")
    return 0


if __name__ == "__main__":
    sys.exit(main())
