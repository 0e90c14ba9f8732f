"""Where new kinds join: each stage's registry is what the parser, the build and the command line
read, so a kind added there works end to end, and an unknown kind is an error that lists the
known ones. References: closed forms (parallel plate, a resistive divider) and the structure
file's own port list."""

from __future__ import annotations

import dataclasses

import pytest

from netgen import electrostatics, emit, mechanics
from netgen.build import build_model
from netgen.cli import commands as cli
from netgen.core.constants import EPS0
from netgen.core.errors import StructureError, SweepError
from netgen.electrostatics.parallel_plate import ParallelPlateExtractor
from netgen.model import MacroModel
from netgen.sim import SIMULATORS
from netgen.structure import CONDUCTORS, load_structure, parse_structure
from netgen.sweep import parse_sweep
from netgen.testbench import TESTBENCHES
from netgen.testbench.sigma_delta import BACKENDS
from tests.fixtures import NETLISTS, ROOT

PISTON = ROOT / "examples" / "piston.toml"


def piston_text(**replace: str) -> str:
    """examples/piston.toml with `key = value` lines replaced (or added to [electrostatics])."""
    text = PISTON.read_text(encoding="utf-8")
    for key, value in replace.items():
        text = text.replace("[electrostatics]\n", f"[electrostatics]\n{key} = {value}\n")
    return text


# ----------------------------------------------------------------------------- conductor kinds


def test_every_conductor_kind_has_mechanics():
    assert set(CONDUCTORS) == set(mechanics.KINDS)


def test_unknown_conductor_kind_lists_the_known_ones():
    text = PISTON.read_text(encoding="utf-8").replace('kind = "piston"', 'kind = "comb_drive"')
    with pytest.raises(StructureError) as info:
        parse_structure(text, "comb.toml")
    assert "conductor.kind" in str(info.value) and all(k in str(info.value) for k in CONDUCTORS)


def test_a_kind_the_mechanics_stage_does_not_know_is_a_clear_error(monkeypatch):
    monkeypatch.delitem(mechanics.KINDS, "piston")
    with pytest.raises(
        StructureError, match=r"(?s)conductor kind 'piston' has no mechanics.*fix: use one of free_disk"
    ):
        mechanics.mechanics(load_structure(PISTON))


# ----------------------------------------------------------------------------- extractors


def test_unknown_extractor_exits_2_naming_the_key_and_the_known_ones(tmp_path, capsys):
    bad = tmp_path / "fmm3d.toml"  # an extractor netgen does not have
    bad.write_text(piston_text(extractor='"fmm3d"'))
    assert cli.main(["build", str(bad), "-o", str(tmp_path / "out"), "-q"]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "electrostatics.extractor" in err and "parallel_plate" in err and "fix:" in err
    assert not (tmp_path / "out").exists()


def test_a_registered_extractor_is_the_one_the_build_uses(monkeypatch):
    """A second extractor, joined by one registry line: a parallel plate in a medium of twice the
    permittivity. The piston's rest capacitance is then 2 eps0 A / g (closed form) and the
    report names the extractor."""

    class Doubled(ParallelPlateExtractor):
        description = "parallel plate at 2 eps0, no fringe"

    monkeypatch.setitem(electrostatics.EXTRACTORS, "doubled", lambda s, plate: Doubled(eps=2 * EPS0, fringe=None))
    s = parse_structure(piston_text(extractor='"doubled"'), "piston.toml")
    model = build_model(s)
    area, gap = s.conductor.length * s.conductor.width, s.electrode_sets[0].gap
    assert model.capacitances[0].c_ref == pytest.approx(2 * EPS0 * area / gap, rel=1e-12, abs=0)
    assert model.report["electrostatics"]["extractor"] == Doubled.description


# ----------------------------------------------------------------------------- emitters


def test_a_registered_emitter_joins_the_formats(monkeypatch, tmp_path):
    """An emitter of port lists, joined by one line: `netgen build --format ports` writes the
    piston's ports, its one electrode, the plate and z's force and displacement."""
    ports = emit.Emitter(
        ".ports", lambda m: "\n".join(p["name"] for p in m.ports()) + "\n", emit.always, "", "the port list"
    )
    monkeypatch.setitem(emit.EMITTERS, "ports", ports)
    assert cli.main(["build", str(PISTON), "-o", str(tmp_path), "-q", "--no-plots", "--format", "ports"]) == 0
    assert (tmp_path / "piston.ports").read_text().split() == ["drive", "plate", "f_z", "x_z"]
    written = ["piston.json", "piston.manifest.json", "piston.ports", "piston_report.html"]
    assert sorted(p.name for p in tmp_path.iterdir()) == written


def test_unknown_format_is_refused_with_the_choices(tmp_path, capsys):
    model = MacroModel.load_json(NETLISTS / "levitated_disk.json")
    with pytest.raises(
        ValueError,
        match=r"choose one or more \(joined by commas\) of ngspice, veriloga, xspice, "
        r"osdi, xschem, kicad, fmu, all",
    ):
        emit.write_outputs(model, tmp_path, "spectre")
    for bad in ("spectre", "ngspice,spectre", ""):
        with pytest.raises(SystemExit) as info:
            cli.main(["build", str(PISTON), "-o", str(tmp_path / "out"), "--format", bad])
        err = capsys.readouterr().err
        assert (
            info.value.code == 2
            and "argument --format" in err
            and "ngspice, veriloga, xspice, osdi, xschem, kicad, fmu, all" in err
        )
    assert not (tmp_path / "out").exists()


def test_several_formats_are_one_build_and_one_set(tmp_path):
    """--format ngspice,osdi writes both dialects (and the .va the .osdi is compiled from) as one
    set; a dialect named twice, or inside "all" too, is written once."""
    assert cli.main(["build", str(PISTON), "-o", str(tmp_path), "-q", "--no-plots", "--format", "ngspice,osdi"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "piston.json",
        "piston.lib",
        "piston.manifest.json",
        "piston.osdi",
        "piston.va",
        "piston_osdi.lib",
        "piston_report.html",
    ]
    model = MacroModel.load_json(tmp_path / "piston.json")
    assert (
        emit.chosen(model, "all,ngspice,all")
        == emit.chosen(model, "all")
        == ["ngspice", "veriloga", "xspice", "xschem", "kicad"]
    )


def test_a_refused_format_is_left_out_of_all():
    """The xspice form needs 1/P fits: a model with a direct fit gets every other dialect."""
    model = MacroModel.load_json(NETLISTS / "levitated_disk.json")
    fits = [dataclasses.replace(model.capacitances[0], target="direct"), *model.capacitances[1:]]
    bad = dataclasses.replace(model, capacitances=fits)
    assert emit.refusal(bad, "xspice").endswith("fix: " + emit.EMITTERS["xspice"].fix)
    assert emit.refusal(bad, "ngspice") is None and emit.refusal(model, "xspice") is None


# ----------------------------------------------------------------------------- simulators and testbenches


def test_netgen_simulate_runs_each_registered_simulator(tmp_path, capsys):
    """The same resistive divider in each simulator's netlist dialect: V(out) = 3/4 V(in)."""
    netlists = {
        "ngspice": "divider\nV1 in 0 1\nR1 in out 1k\nR2 out 0 3k\n.op\n.end\n",
        "pyspice": "divider\nV1 in 0 1\nR1 in out 1k\nR2 out 0 3k\n.op\n.end\n",  # libngspice, in process
        "vacask": 'divider\nground 0\nload "resistor.osdi"\nmodel r resistor\nmodel vsource vsource\n'
        "v1 (in 0) vsource dc=1\nr1 (in out) r r=1k\nr2 (out 0) r r=3k\n"
        "control\n  analysis op1 op\nendc\n",
    }
    assert set(netlists) == set(SIMULATORS)
    for name, text in netlists.items():
        path = tmp_path / f"divider_{name}.cir"
        path.write_text(text)
        run = tmp_path / f"run_{name}"
        assert cli.main(["simulate", str(path), "-o", str(run), "--simulator", name, "-q"]) == 0
        plot = SIMULATORS[name].run(text, run, "again", 60.0)[0]
        assert plot["out"][0] == pytest.approx(0.75, rel=1e-9), name


def test_every_testbench_is_a_subcommand():
    commands = cli.parser()._subparsers._group_actions[0].choices
    assert set(TESTBENCHES) <= set(commands) and {"build", "simulate", "codemodel", "sweep"} <= set(commands)


def test_sweep_simulator_values_come_from_the_backends():
    text = '[[parameters]]\nname = "simulator"\nvalues = ["ngspice", "spice3"]\n'
    with pytest.raises(SweepError, match=r"simulator = 'spice3' is not one of") as info:
        parse_sweep(text, "sweep.toml")
    assert all(b in str(info.value) for b in BACKENDS)
    assert parse_sweep(text.replace('"spice3"', '"vacask"'), "sweep.toml").parameters[0].values == ["ngspice", "vacask"]
