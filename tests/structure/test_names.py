"""The name policy (netgen.core.names) at read time: names that mean something to SPICE, Verilog-A or
VACASK, or to a run's own files, are refused with exit 2 naming the file, the key, the name and
the fix, in a structure file and in a model JSON (--model). The expectations are the dialects'
own rules (ngspice ground 0/gnd, case-insensitive names; the Verilog-AMS keyword list)."""

from __future__ import annotations

import json
import re

import pytest

from netgen.cli import commands as cli
from netgen.core.errors import ModelError, StructureError
from netgen.model import MacroModel
from netgen.structure import parse_structure
from tests.fixtures import NETLISTS, ROOT

PISTON = ROOT / "examples" / "piston.toml"
SPICE = ["gnd", "GND", "0x", "Plate", "plate", "f_z", "x_z", "a_in", "xs_z", "u_z", "sg_1", "p_drive_1", "ca_z", "clk"]
VERILOG_A = ["input", "module", "electrical", "ground", "begin", "end", "V", "I", "exp", "inf", "ddt", "branch", "real"]


def piston(electrode: str = "drive", name: str = "piston") -> str:
    text = PISTON.read_text(encoding="utf-8").replace('name = "piston"', f'name = "{name}"', 1)
    return re.sub(r'name = "drive"', f'name = "{electrode}"', text, count=1)


@pytest.mark.parametrize("name", [n for n in SPICE + VERILOG_A if n != "0x"])
def test_reserved_electrode_names_are_refused(name):
    with pytest.raises(StructureError) as err:
        parse_structure(piston(name), "p.toml")
    text = str(err.value)
    assert "electrodes[0].name" in text and repr(name) in text and "fix:" in text


@pytest.mark.parametrize("name", ["summary", "spectra", "sigma_delta", "module", "input"])
def test_reserved_model_names_are_refused(name):
    with pytest.raises(StructureError) as err:
        parse_structure(piston(name=name), "p.toml")
    assert "name" in str(err.value) and repr(name) in str(err.value)


def test_case_only_duplicates_are_refused():
    """drv and DRV are one node to SPICE: refused even on opposite sides."""
    second = piston("drv").replace(
        "[coordinates]", '[[electrodes]]\nname = "DRV"\nside = "above"\ngap = "2 um"\n\n[coordinates]', 1
    )
    with pytest.raises(StructureError) as err:
        parse_structure(second, "p.toml")
    assert "electrodes[1].name" in str(err.value) and "case-insensitively" in str(err.value)


def test_suggested_names_are_accepted():
    """The fix's example name passes the policy (it is not refused in turn)."""
    for name in ["f_z", "gnd", "input"]:
        with pytest.raises(StructureError) as err:
            parse_structure(piston(name), "p.toml")
        example = re.search(r"e\.g\. (\w+)", str(err.value)).group(1)
        parse_structure(piston(example), "p.toml")


@pytest.mark.parametrize("name", ["gnd", "Plate", "f_z", "input", "V"])
def test_model_json_with_reserved_electrode_is_refused(name, tmp_path, capsys):
    """A model JSON edited to use a reserved electrode name: exit 2 on --format veriloga, never 70."""
    doc = json.loads((NETLISTS / "levitated_disk.json").read_text())
    old = doc["electrodes"][0]["name"]
    text = re.sub(rf'"{old}"', f'"{name}"', json.dumps(doc))
    path = tmp_path / "m.json"
    path.write_text(text)
    with pytest.raises(ModelError) as err:
        MacroModel.load_json(path)
    assert "electrodes[0].name" in str(err.value) and repr(name) in str(err.value)
    assert cli.main(["sigma-delta", str(PISTON), "--model", str(path), "-o", str(tmp_path / "o"), "-q"]) == 2
    assert not (tmp_path / "o").exists()
