"""The emit stage: a MacroModel as netlist text for each simulator dialect (no physics here).

EMITTERS maps a `--format` name to its emitter: the file suffix, the function that renders the
model, and the refusal that says why a model has no such form (None: it has). Adding a dialect
is one module here, its template under templates/, and one line in EMITTERS; the command line's
--format choices follow.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from ..files import write_files_atomic
from ..model import MacroModel
from . import ngspice, veriloga, xspice


def always(model: MacroModel) -> str | None:
    """The refusal of a dialect that takes every model."""
    return None


@dataclass(frozen=True)
class Emitter:
    """One dialect: `render(model)` is the file's text, written as <name><suffix>."""
    suffix: str
    render: Callable[[MacroModel], str]
    refusal: Callable[[MacroModel], str | None]
    fix: str                  # what to do about a refusal
    help: str


EMITTERS: dict[str, Emitter] = {
    "ngspice": Emitter(".lib", ngspice.subcircuit, always, "", "ngspice .subckt of behavioural sources"),
    "veriloga": Emitter(".va", veriloga.module, always, "", "Verilog-A module (openvaf-r, VACASK, Spectre, Xyce)"),
    "xspice": Emitter("_xspice.lib", xspice.subcircuit, xspice.refusal,
                      "set target = \"plates\" in the structure's [fit], or use --format ngspice",
                      "the .lib with the plate terms in the compiled netgen_es code model (`netgen codemodel`)"),
}


def formats() -> list[str]:
    """The --format choices: every registered dialect, and "all"."""
    return [*EMITTERS, "all"]


def refusal(model: MacroModel, fmt: str) -> str | None:
    """Why `model` has no `fmt` form, with the fix; None if it has."""
    emitter = EMITTERS[fmt]
    problem = emitter.refusal(model)
    return f"{problem}; fix: {emitter.fix}" if problem else None


def write_outputs(model: MacroModel, folder: Path, fmt: str = "ngspice") -> list[Path]:
    """Emit the requested dialects and the model JSON into `folder` (all or nothing); return the paths written.
    "all" is every dialect the model supports (xspice needs 1/P capacitance fits)."""
    if fmt not in formats():
        raise ValueError(f"unknown netlist format {fmt!r}; choose one of {', '.join(formats())}")
    chosen = [f for f in EMITTERS if not EMITTERS[f].refusal(model)] if fmt == "all" else [fmt]
    # render everything before writing anything: a failing emitter or model leaves no output
    texts = {folder / f"{model.name}{EMITTERS[f].suffix}": EMITTERS[f].render(model) for f in chosen}
    texts[folder / f"{model.name}.json"] = model.json_text()
    write_files_atomic(texts)
    return list(texts)
