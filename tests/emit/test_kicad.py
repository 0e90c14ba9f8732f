"""The KiCad symbol libraries (netgen.emit.kicad) of the committed netlists, read with a small
s-expression reader and checked against KiCad's published file format (the symbol library
format of KiCad 6, version 20211014: `kicad_symbol_lib`, `symbol` with `property` entries and
unit sub-symbols `<name>_<unit>_<style>` holding `pin TYPE SHAPE (at X Y ANGLE) (length L)
(name ..) (number ..)`) and KiCad's simulator fields (Sim.* of KiCad 7+, Spice_* of KiCad 6).
KiCad itself is not installed (Debian 12's kicad 6.0.11 has no kicad-cli)."""

from __future__ import annotations

import re

import pytest

from tests.emit.test_xschem import LIBS, card

TOKEN = re.compile(r'\(|\)|"(?:[^"\\]|\\.)*"|[^\s()]+')
PIN_TYPES = {"input", "output", "bidirectional", "tri_state", "passive", "free", "unspecified"}
PIN_TYPES |= {"power_in", "power_out", "open_collector", "open_emitter", "no_connect"}


def parse(text: str) -> list:
    """An s-expression as nested lists of atoms (quoted strings unquoted)."""
    stack: list[list] = [[]]
    for tok in TOKEN.findall(text):
        if tok == "(":
            stack.append([])
        elif tok == ")":
            done = stack.pop()
            stack[-1].append(done)
        else:
            stack[-1].append(tok[1:-1] if tok.startswith('"') else tok)
    assert len(stack) == 1 and len(stack[0]) == 1, "unbalanced parentheses"
    return stack[0][0]


def children(node: list, head: str) -> list[list]:
    return [c for c in node[1:] if isinstance(c, list) and c and c[0] == head]


@pytest.mark.parametrize("lib", LIBS, ids=lambda p: p.stem)
def test_kicad_symbol_pins_and_sim_fields_follow_the_subckt(lib):
    """One symbol named as the subcircuit; pin k numbered k and named as port k of the .subckt
    card, of a valid electrical type, on a 1.27 mm grid; the Sim and Spice fields point at the
    .lib's subcircuit with the same pin map."""
    name, ports = card(lib)
    tree = parse(lib.with_suffix(".kicad_sym").read_text(encoding="utf-8"))
    assert tree[0] == "kicad_symbol_lib" and children(tree, "version")[0][1] == "20211014"
    (sym,) = children(tree, "symbol")
    assert sym[1] == name
    props = {p[1]: p[2] for p in children(sym, "property")}
    for required in ("Reference", "Value", "Footprint", "Datasheet"):
        assert required in props
    assert props["Reference"] == "X" and props["Value"] == name
    assert props["Sim.Device"] == "SUBCKT" and props["Sim.Name"] == name
    assert props["Sim.Library"] == props["Spice_Lib_File"] == lib.name
    assert props["Sim.Pins"].split() == [f"{k}={p}" for k, p in enumerate(ports, start=1)]
    assert props["Spice_Primitive"] == "X" and props["Spice_Model"] == name
    assert props["Spice_Node_Sequence"].split() == [str(k) for k in range(1, len(ports) + 1)]
    units = children(sym, "symbol")
    assert all(re.fullmatch(rf"{name}_\d+_\d+", u[1]) for u in units)
    pins = [p for u in units for p in children(u, "pin")]
    assert [children(p, "number")[0][1] for p in pins] == [str(k) for k in range(1, len(ports) + 1)]
    assert [children(p, "name")[0][1] for p in pins] == ports
    for p in pins:
        assert p[1] in PIN_TYPES and p[2] == "line"
        x, y, angle = (float(v) for v in children(p, "at")[0][1:4])
        assert angle in (0, 180) and abs(x / 1.27 - round(x / 1.27)) < 1e-9 and abs(y / 1.27 - round(y / 1.27)) < 1e-9
    ats = [tuple(children(p, "at")[0][1:3]) for p in pins]
    assert len(set(ats)) == len(ats), "two pins at one point"
