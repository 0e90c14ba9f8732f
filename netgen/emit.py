"""Write a MacroModel's outputs (netlists + JSON) into a folder, atomically."""

from __future__ import annotations

from functools import partial
from pathlib import Path

from .emit_ngspice import subcircuit, xspice_refusal
from .emit_veriloga import module
from .model import MacroModel, write_files_atomic

# xspice: the ngspice .lib with the plate terms in the compiled netgen_es code model (netgen.codemodel)
EMITTERS = {"ngspice": (".lib", subcircuit), "veriloga": (".va", module),
            "xspice": ("_xspice.lib", partial(subcircuit, style="xspice"))}


def write_outputs(model: MacroModel, folder: Path, fmt: str = "ngspice") -> list[Path]:
    """Emit the requested dialects and the model JSON into `folder` (all or nothing); return the paths written.
    "all" is every dialect the model supports (xspice needs 1/P capacitance fits)."""
    chosen = [f for f in EMITTERS if not (f == "xspice" and xspice_refusal(model))] if fmt == "all" else [fmt]
    if fmt != "all" and fmt not in EMITTERS:
        raise ValueError(f"unknown netlist format {fmt!r}; choose one of {', '.join([*EMITTERS, 'all'])}")
    # render everything before writing anything: a failing emitter or model leaves no output
    texts = {folder / f"{model.name}{EMITTERS[f][0]}": EMITTERS[f][1](model) for f in chosen}
    texts[folder / f"{model.name}.json"] = model.json_text()
    write_files_atomic(texts)
    return list(texts)
