"""Hostile paths and colliding output sets: every path netgen writes into simulator input reaches
the simulator as exactly that path or is refused (exit 2, naming the path and the fix); it never
includes another file or runs a command. Each output set owns its files in a folder.

The expectations are written here, independently of netgen.core.paths: what each dialect reads back
was measured on ngspice 39 and 46 (an .include of a resistor, a pre_codemodel of netgen's code
model) and is checked again below against the simulators themselves."""

from __future__ import annotations

import shutil
import subprocess
import unicodedata
from pathlib import Path

import pytest

from netgen.cli import commands as cli
from netgen.core.errors import InputError
from netgen.core.paths import spice_card, spice_command, vacask_string
from netgen.sim import codemodel
from tests.fixtures import NGSPICE, ROOT

PISTON = ROOT / "examples" / "piston.toml"
ACCEL = ROOT / "examples" / "accelerometer_z.toml"
# folder names: spaces, quotes, ; $() backticks, newline, *, unicode, a brace list, history
HOSTILE = [
    "evil dir",
    "two  spaces",
    'dq"uote',
    "sq'uote",
    "semi;colon",
    "dollar$(touch MARK)",
    "back`touch MARK`tick",
    "new\nline",
    "star*glob",
    "ünïcödé 日本",
    "brace{a,b}",
    "bang!1",
    "back\\slash",
]
CARD_BAD = set('"\\;$')  # ngspice 39 cuts a card at ; and $ (inline comments); quotes end the string
COMMAND_BAD = set("'\"\\`${}!;")  # .control: backticks run sh, $ expands, {} and ! expand (39)
VACASK_BAD = set('"\\')


def control(text: str) -> bool:
    return any(unicodedata.category(ch).startswith("C") for ch in text)


def expect(name: str, bad: set[str], collapse: bool = False) -> bool:
    """Whether a folder named `name` must be refused by a dialect that cannot hold `bad`."""
    return control(name) or bool(set(name) & bad) or (collapse and "  " in name)


@pytest.mark.parametrize("name", HOSTILE)
def test_each_writer_quotes_or_refuses(name, tmp_path):
    """Each dialect's writer returns the path inside its quotes, or refuses it with the fix."""
    path = tmp_path / name / "m.lib"
    for writer, bad, quote, collapse in (
        (spice_card, CARD_BAD, '"', False),
        (spice_command, COMMAND_BAD, "'", True),
        (vacask_string, VACASK_BAD, '"', False),
    ):
        if expect(name, bad, collapse):
            with pytest.raises(InputError) as err:
                writer(path)
            assert err.value.where == "path" and "move the files" in str(err.value)
        else:
            assert writer(path) == f"{quote}{path}{quote}"


def run_ngspice(exe: str, deck: str, folder: Path) -> str:
    cir = folder / "t.cir"
    cir.write_text(deck, encoding="utf-8")
    done = subprocess.run([exe, "-b", str(cir)], capture_output=True, text=True, cwd=folder, timeout=60)
    return done.stdout + done.stderr


@pytest.mark.parametrize("release", sorted(NGSPICE))
def test_include_reads_the_named_file_only(release, tmp_path):
    """An .include of a 1 kohm subcircuit in each hostile folder that the writer accepts: ngspice
    reads that file (1 V over 1 kohm: i = -1e-3 A, Ohm's law, printed to 6 digits) and runs no
    command (the marker file is never created); a decoy `evil` beside `evil dir` is never read."""
    if not Path(shutil.which(NGSPICE[release]) or NGSPICE[release]).exists():
        pytest.skip(f"ngspice {release} not installed")
    marker = tmp_path / "MARK"
    (tmp_path / "evil").write_text(f".control\nshell touch {marker}\n.endc\n")
    for name in HOSTILE:
        folder = tmp_path / name  # `touch MARK` would create the marker: ngspice runs in tmp_path
        folder.mkdir()
        (folder / "m.lib").write_text(".subckt r1k a b\nR1 a b 1k\n.ends\n")
        try:
            card = spice_card(folder / "m.lib")
        except InputError:
            assert expect(name, CARD_BAD)
            continue
        out = run_ngspice(
            NGSPICE[release],
            f"t\n.include {card}\nX1 1 0 r1k\nV1 1 0 1\n.op\n.control\nrun\nprint i(v1)\n.endc\n.end\n",
            tmp_path,
        )
        assert "i(v1) = -1.00000e-03" in out, (name, out)
    assert not marker.exists()


def test_code_model_loads_from_a_hostile_folder(tmp_path):
    """pre_codemodel of netgen's code model (built for ngspice 39) copied into each hostile folder
    the writer accepts: ngspice loads it (the A device of the library parses and runs: no "couldn't
    be loaded") and runs no command."""
    cm = codemodel.build(progress=lambda m: None)
    if codemodel.record(cm)["ngspice"]["major"] != 39:
        pytest.skip("the cached code model is not built for ngspice 39")
    marker = tmp_path / "MARK"
    for name in HOSTILE:
        folder = tmp_path / name
        folder.mkdir()
        shutil.copy(cm, folder / cm.name)
        try:
            line = codemodel.control_lines(folder / cm.name)[0]
        except InputError:
            assert expect(name, COMMAND_BAD, collapse=True)
            continue
        out = run_ngspice(
            "ngspice", f"t\nR1 1 0 1k\nV1 1 0 1\n.op\n.control\n{line}\nrun\nprint i(v1)\n.endc\n.end\n", tmp_path
        )
        assert "couldn't be loaded" not in out and "i(v1) = -1.00000e-03" in out, (name, out)
    assert not marker.exists()


@pytest.fixture(scope="module")
def evil_model(tmp_path_factory):
    """accelerometer_z built into a folder with a space, and a decoy `evil` beside it that would
    run `shell touch` if ngspice included it (the reproducer of the report)."""
    root = tmp_path_factory.mktemp("m")
    assert cli.main(["build", str(ACCEL), "-o", str(root / "evil dir"), "-q", "--no-plots"]) == 0
    lib = (root / "evil dir" / "accelerometer_z.lib").read_text()
    (root / "evil").write_text(lib + f".control\nshell touch {root / 'PWNED'}\n.endc\n")
    return root


@pytest.mark.parametrize("simulator", ["ngspice", "ngspice-xspice", "ngspice-osdi", "vacask"])
def test_sigma_delta_runs_the_named_model_from_a_folder_with_a_space(simulator, evil_model, monkeypatch):
    """`netgen sigma-delta --model "DIR/evil dir/accelerometer_z.json"` on every back end (OSDI on
    ngspice 46): exit 0, the netlist names the model's own file quoted, the decoy is never read."""
    if simulator == "ngspice-osdi":
        monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    out = evil_model / f"sd {simulator}"
    model = evil_model / "evil dir" / "accelerometer_z.json"
    args = ["sigma-delta", str(ACCEL), "--model", str(model), "-o", str(out), "--cycles", "64", "-q", "--no-plots"]
    assert cli.main([*args, "--simulator", simulator]) == 0
    assert not (evil_model / "PWNED").exists()
    netlist = (out / ("sigma_delta.sim" if simulator == "vacask" else "sigma_delta.cir")).read_text()
    if simulator == "ngspice":
        assert f'.include "{model.with_suffix(".lib")}"' in netlist


def test_output_sets_own_their_files(tmp_path, capsys):
    """Models `a` (--format all) and `a_xspice` in one folder: the second to write a_xspice.lib is
    refused (exit 2, naming both sets) and the first keeps its files; rebuilding `a` with the
    ngspice form only never removes the other set's a_xspice.lib."""
    out = tmp_path / "o"
    a, ax = tmp_path / "a.toml", tmp_path / "ax.toml"
    text = PISTON.read_text()
    a.write_text(text.replace('name = "piston"', 'name = "a"', 1))
    ax.write_text(text.replace('name = "piston"', 'name = "a_xspice"', 1))
    assert cli.main(["build", str(ax), "-o", str(out), "-q", "--no-plots"]) == 0
    before = (out / "a_xspice.lib").read_bytes()
    assert cli.main(["build", str(a), "-o", str(out), "-q", "--no-plots", "--format", "all"]) == 2
    err = capsys.readouterr().err
    assert "'a'" in err and "'a_xspice'" in err and "a_xspice.lib" in err and "another -o folder" in err
    assert (out / "a_xspice.lib").read_bytes() == before and not (out / "a.lib").exists()
    assert cli.main(["build", str(a), "-o", str(out), "-q", "--no-plots"]) == 0
    assert (out / "a_xspice.lib").read_bytes() == before and (out / "a.lib").exists()
