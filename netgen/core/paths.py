"""The one writer of file paths into simulator input: every path a netlist, a .control block or
a VACASK netlist names (.include, pre_codemodel, pre_osdi, source, VACASK load) goes through
one function per dialect here, so it reaches the simulator as exactly that path or is refused
(InputError, exit 2, naming the path, the characters and the fix).

What each dialect reads back unchanged (measured on ngspice 39 and 46; VACASK: a folder with a
space, tests/test_trust_paths.py):
- ngspice cards (`.include "PATH"`): inside double quotes any printable text but `;` (ngspice 39
  cuts the card there as an inline comment; 46 does not) and `$` (an inline comment before a
  space on 39); `"` and `\\` cannot be written inside the quotes.
- ngspice .control commands (`pre_codemodel 'PATH'`): the command line is parsed like a shell's
  (cshpar): inside single quotes spaces and `*`, `?`, `[`, `<`, `>`, `|`, `&`, `#` are literal,
  but backticks still run a shell command, `$` expands a variable, `{a,b}` expands (39), `!`
  recalls history (39), `;` ends the word (39), and runs of spaces collapse to one.
- VACASK (`load "PATH"`): a double-quoted string: no `"` or `\\`.
Every dialect refuses control characters (line breaks end the card). Characters outside these
sets are refused rather than escaped, since no escape reaches every ngspice version.
"""

from __future__ import annotations

import os
from pathlib import Path

from .errors import InputError
from .text import escape, text_problem

CARD = '"\\;$'  # not allowed in an ngspice card's double-quoted path
COMMAND = "'\"\\`${}!;"  # not allowed in an ngspice .control command's single-quoted path
VACASK = '"\\'  # not allowed in a VACASK double-quoted string
FIX = (
    "move the files to a folder whose path has none of these characters (e.g. rename the folder, "
    "or give another -o folder or --model path)"
)


def placed(path: str | os.PathLike[str], folder: str | Path | None = None) -> str:
    """The text of `path` as the simulator should see it: relative to `folder` (where the
    netlist runs; links not followed, e.g. a staging folder's osdi -> ../osdi,
    netgen.runtime.folders.OutputFolder) when it lies inside it, so the kept netlist reruns from the
    folder the run is moved to; otherwise absolute (symlinks resolved)."""
    if folder is None:
        return str(path)
    inside, base = Path(os.path.abspath(path)), Path(os.path.abspath(folder))
    return str(inside.relative_to(base)) if inside.is_relative_to(base) else str(Path(path).resolve())


def checked(text: str, refused: str, dialect: str, collapse: bool = False) -> str:
    """`text` if it holds no control character, none of `refused` (and, with `collapse`, no run
    of spaces and no leading or trailing space); else the InputError with the fix."""
    problem = text_problem(text)
    bad = sorted({ch for ch in text if ch in refused})
    if problem is None and bad:
        problem = "contains " + " ".join(repr(ch) for ch in bad)
    if problem is None and collapse and ("  " in text or text != text.strip()):
        problem = "has a run of spaces or a leading or trailing space (the command line collapses them)"
    if problem:
        shown = " ".join(repr(ch) for ch in refused)
        raise InputError(
            escape(text),
            "path",
            f"the path {problem}, so {dialect} would not read it back as this path "
            f"(not allowed there: control characters, {shown})",
            FIX,
        )
    return text


def spice_card(path: str | os.PathLike[str], folder: str | Path | None = None) -> str:
    """`path` for an ngspice card, quoted: `.include {spice_card(lib)}`."""
    return '"' + checked(placed(path, folder), CARD, "an ngspice .include card") + '"'


def spice_command(path: str | os.PathLike[str], folder: str | Path | None = None) -> str:
    """`path` for an ngspice .control command, quoted: `pre_codemodel {spice_command(cm)}`,
    `pre_osdi`, `codemodel`, `osdi`, `source`."""
    return "'" + checked(placed(path, folder), COMMAND, "an ngspice .control command", collapse=True) + "'"


def vacask_string(path: str | os.PathLike[str], folder: str | Path | None = None) -> str:
    """`path` for a VACASK netlist, quoted: `load {vacask_string(osdi)}`, `include ...`."""
    return '"' + checked(placed(path, folder), VACASK, "a VACASK netlist") + '"'
