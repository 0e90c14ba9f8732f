"""A model JSON given with the .lib it travels with (`netgen sigma-delta --model X.json`): the
.lib must be there and be the one netgen renders from that JSON. The .lib text is a function of
the model alone, so the JSON is re-rendered and compared line by line: a JSON edited beside an
unchanged .lib (or the reverse, or files of two builds) is refused (ModelError, exit 2) naming
both files, the first differing line and the fix, before any simulator sees the pair."""

from __future__ import annotations

from pathlib import Path

from ..core.errors import ModelError
from ..core.files import read_text
from ..core.text import escape
from ..model.macromodel import MacroModel
from . import EMITTERS

REBUILD = "rebuild both with `netgen build STRUCTURE.toml -o DIR` (it writes X.json and X.lib together)"


def load_pair(json_path: str | Path) -> tuple[MacroModel, Path]:
    """The model of `json_path` and its .lib beside it, checked to belong together."""
    model = MacroModel.load_json(json_path)
    lib = Path(json_path).with_suffix(".lib")
    shown = escape(str(lib))
    if not lib.is_file():
        raise ModelError(
            shown,
            "file",
            f"no .lib beside {escape(str(json_path))} (--model runs the .lib the build wrote with it)",
            "keep the .lib next to its .json; " + REBUILD,
        )
    text = read_text(lib, "file", "the model's .lib", ModelError)
    expected = EMITTERS["ngspice"].render(model)
    if text != expected:
        have, want = text.splitlines(), expected.splitlines()
        line = next((i for i, (a, b) in enumerate(zip(have, want)) if a != b), min(len(have), len(want)))
        raise ModelError(
            shown,
            "(document)",
            f"is not the .lib of {escape(str(json_path))} (they differ from line {line + 1}): one of them was "
            "edited by hand, or they come from two builds",
            "restore the edited file, or " + REBUILD,
            line + 1,
        )
    return model, lib
