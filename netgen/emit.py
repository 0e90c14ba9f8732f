"""Write a MacroModel's outputs (netlists + JSON) into a folder, atomically."""

from __future__ import annotations

from pathlib import Path

from .emit_ngspice import subcircuit
from .emit_veriloga import module
from .model import MacroModel, write_files_atomic

EMITTERS = {"ngspice": (".lib", subcircuit), "veriloga": (".va", module)}


def write_outputs(model: MacroModel, folder: Path, fmt: str = "ngspice") -> list[Path]:
    """Emit the requested dialects and the model JSON into `folder` (all or nothing); return the paths written."""
    chosen = list(EMITTERS) if fmt == "all" else [fmt]
    if fmt != "all" and fmt not in EMITTERS:
        raise ValueError(f"unknown netlist format {fmt!r}; choose one of {', '.join([*EMITTERS, 'all'])}")
    # render everything before writing anything: a failing emitter or model leaves no output
    texts = {folder / f"{model.name}{EMITTERS[f][0]}": EMITTERS[f][1](model) for f in chosen}
    texts[folder / f"{model.name}.json"] = model.json_text()
    write_files_atomic(texts)
    return list(texts)
