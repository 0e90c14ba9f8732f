"""Write a MacroModel's outputs (netlists + JSON) into a folder, atomically."""

from __future__ import annotations

from pathlib import Path

from .emit_ngspice import subcircuit
from .model import MacroModel, write_atomic

EMITTERS = {"ngspice": (".lib", subcircuit)}


def write_outputs(model: MacroModel, folder: Path, fmt: str = "ngspice") -> list[Path]:
    """Emit the requested dialects and the model JSON into `folder`; return the paths written."""
    chosen = list(EMITTERS) if fmt == "all" else [fmt]
    texts = {folder / f"{model.name}{EMITTERS[f][0]}": EMITTERS[f][1](model) for f in chosen}
    json_path = folder / f"{model.name}.json"
    for path, text in texts.items():
        write_atomic(path, text)
    model.save_json(json_path)
    return [*texts, json_path]
