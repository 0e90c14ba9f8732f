"""Text from input files as data, never code: the one definition of a printable free-text string
and of a netlist name, and the comment writer every emitted netlist and Verilog-A file uses.

Read time (netgen.core.reader, netgen.model.validate, the import readers, the sweep file)
refuses names that are not identifiers and free text with control characters. Emit time
(netgen.emit.common, the templates through the Jinja filters `comment` and `comment_text` that
netgen.core.templating registers) writes any such text only inside comments: every line starts with
the comment marker and a space, line breaks of any kind start a new comment line, other control
characters are written as escapes (\\x00, \\u2028), and for the C-like markers (Verilog-A,
VACASK: //) backticks, /* and */ are made inert. So even text that skipped validation cannot end a
comment, start a SPICE card, a `.control` block, a `*#` command line or a Verilog-A directive.
"""

from __future__ import annotations

import re
import textwrap
import unicodedata
from typing import TypeGuard

IDENTIFIER = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
OTHER = re.compile(r"[^ -~]")  # anything but printable ASCII: the characters `allowed` looks at
SPICE, C_LIKE = "*", "//"  # the comment markers of the dialects netgen writes
WIDTH = 100  # comment lines are wrapped at this many characters
CONTROL_NAMES = {
    "\n": "line feed",
    "\r": "carriage return",
    "\t": "tab",
    "\x00": "NUL",
    "\x0b": "vertical tab",
    "\x0c": "form feed",
    "\x1b": "escape",
    "\x7f": "delete",
    "\x85": "next line",
}


def is_identifier(name: object) -> TypeGuard[str]:
    """A netlist name: ASCII letters, digits and _, starting with a letter (the whole string:
    a trailing newline is not part of a name)."""
    return isinstance(name, str) and IDENTIFIER.fullmatch(name) is not None


def allowed(ch: str) -> bool:
    """Printable (Unicode letters, marks, numbers, punctuation, symbols) or a space; not a control,
    format (bidi overrides, zero-width), line or paragraph separator, private or unassigned code point."""
    return ch.isprintable() or unicodedata.category(ch) == "Zs"


def text_problem(text: object) -> str | None:
    """Why `text` is not printable one-line free text (e.g. 'contains U+000A (line feed) at
    character 12'), or None if it is."""
    if not isinstance(text, str):
        return f"must be a string, got {type(text).__name__}"
    for match in OTHER.finditer(text):
        i, ch = match.start(), match.group()
        if not allowed(ch):
            name = unicodedata.name(ch, "").lower() or CONTROL_NAMES.get(ch, "a control character")
            return f"contains U+{ord(ch):04X} ({name}) at character {i + 1}"
    return None


def escape(text: str) -> str:
    """`text` with every character that is not `allowed` written as a Python-style escape."""
    return OTHER.sub(
        lambda m: m.group() if allowed(m.group()) else m.group().encode("unicode_escape").decode("ascii"), text
    )


def shown(value: object, limit: int = 60) -> str:
    """`value` for an error message: its repr, escaped (netgen.core.text.escape) and cut at `limit` characters."""
    text = escape(repr(value))
    return text if len(text) <= limit else text[: limit - 3] + "..."


def inert(line: str, marker: str) -> str:
    """One escaped line made harmless after `marker`: for // no backtick (Verilog-A directives),
    no /* or */ (block comments), and for every marker no trailing backslash (line splicing)."""
    if marker == C_LIKE:
        line = re.sub(r"(?<=/)(?=\*)|(?<=\*)(?=/)", " ", line.replace("`", "'"))
    line = line.rstrip()
    return line[:-1] + "\\x5c" if line.endswith("\\") else line


def comment_text(text: object, marker: str = SPICE) -> str:
    """`text` as one line to write inside a comment line that starts with `marker` (line breaks
    and control characters escaped, see `inert`): for a name or path within a header sentence."""
    return inert(escape(str(text)), marker)


def comment_lines(text: object, marker: str = SPICE, width: int = WIDTH) -> str:
    """`text` as comment lines, each '<marker> <line>' (a bare marker for an empty line), wrapped
    at `width`: every line break in the text starts a new comment line, nothing else does."""
    out = []
    for raw in str(text).splitlines() or [""]:
        line = comment_text(raw, marker)
        wrapped = textwrap.wrap(
            line, width - len(marker) - 1, break_on_hyphens=False, replace_whitespace=False, drop_whitespace=True
        ) or [""]
        out += [f"{marker} {inert(part, marker)}".rstrip() for part in wrapped]
    return "\n".join(out)
