"""The sigma-delta loop in ngspice through OSDI (`--simulator ngspice-osdi`): the model as its
compiled Verilog-A module (netgen.emit.osdi: the _osdi.lib) and the loop's blocks as the
Verilog-A modules VACASK runs (blocks.va beside this module), both compiled by openvaf-r and
loaded with `pre_osdi`; the testbench and its segments are the ngspice bench's
(netgen.testbench.sigma_delta.ngspice, loop "osdi").

The run is one ngspice segment (however long: ~27 kB of saved vectors per period, 1.8 GB for
2^16): ngspice's .ic sets only nodes that exist when the netlist is read, not an OSDI
instance's internal nodes (measured in 46: "IC on non-existent node - n.x1.n1#xs_z, ignored"),
so a segment could not restart from the model's state.

OSDI needs ngspice 44 or later (39-43 load only OSDI 0.3, openvaf-r writes 0.5), and 44 caps an
OSDI instance at 20 nodes: on those, `check` refuses with the version and the alternatives.
"""

from __future__ import annotations

import sys
from pathlib import Path

from ...core.errors import SimulatorNotFound
from ...core.files import write_files_atomic
from ...core.paths import spice_command
from ...emit import osdi
from ...model import MacroModel
from ...sim import ngspice as sim_ngspice
from .vacask import blocks_source, compile_model

ALTERNATIVES = (
    "use --simulator ngspice (the B-source .lib, any ngspice) or --simulator vacask, "
    f"or point {sim_ngspice.ENV} at ngspice 45 or later"
)
# set before the analysis: ngspice's spinit sets 8 threads, and OSDI's load then runs a parallel
# region per call, 10-15x slower on a 2-core machine (design notes, ngspice 44 and 46)
THREADS = "set num_threads=1"


def check(model: MacroModel) -> sim_ngspice.Version:
    """The ngspice netgen runs, if it can load this model through OSDI; else SimulatorNotFound
    (exit 3) naming its version and the alternatives."""
    v = sim_ngspice.version()
    if not v.osdi:
        raise SimulatorNotFound(
            f"{v.label} ({v.path}) cannot load openvaf-r's OSDI 0.5 modules "
            f"(ngspice 39-43 load only OSDI 0.3; 44 and later do); {ALTERNATIVES}"
        )
    limit, n = v.osdi_node_limit, osdi.nodes(model)
    if limit is not None and n > limit:
        raise SimulatorNotFound(
            f"{v.label} ({v.path}) caps an OSDI instance at {limit} nodes and "
            f"{model.name} has {n} ({len(model.ports())} ports, {n - len(model.ports())} "
            f"internal); the cap is gone from ngspice 45 on; {ALTERNATIVES}"
        )
    return v


def prepare(model: MacroModel, lib: Path, out: Path, progress: bool, cpu: str = osdi.GENERIC) -> dict:
    """Refuse an ngspice without OSDI, then compile the model (the .va next to `lib`, else the
    emitted module) and the loop blocks into out/osdi (cached by text and target `cpu`) and write
    the _osdi.lib; the pre_osdi lines name them relative to `out`, where the bench runs and is kept."""
    version = check(model)
    va = Path(lib).with_suffix(".va")
    text = va.read_text(encoding="utf-8") if va.exists() else None
    if progress:
        print(
            f"sigma-delta (ngspice-osdi): compiling the model and the loop blocks with openvaf-r (target cpu "
            f"{cpu}) for {version.label}",
            file=sys.stderr,
        )
    cache = out / "osdi"  # the model text VACASK compiles too
    model_osdi = compile_model(model, cache, va if text is not None else None, cpu)
    blocks_osdi = osdi.compiled(blocks_source(), "sigma_delta_blocks", cache, cpu)
    osdi_lib = out / f"{model.name}_osdi.lib"
    write_files_atomic({osdi_lib: osdi.subcircuit(model)})
    return {
        "lib": osdi_lib,
        "ngspice": version.label,
        "target_cpu": cpu,
        "control": [f"pre_osdi {spice_command(p, out)}" for p in (model_osdi, blocks_osdi)] + [THREADS],
    }
