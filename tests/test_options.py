"""Options declared once (netgen.core.options, netgen.testbench.sigma_delta.options): every option that a
user can write in more than one place (a `netgen sigma-delta` flag, a [loop] key, a sweep
parameter) gets the same verdict in each, at and beyond its declared limits. The verdicts come
from the real parsers (the command line's argparse and checks, the loop reader, `netgen sweep
--dry-run`), not from the declarations, so a limit hard-coded in one of them fails here; the
comparison itself is shown to catch a planted difference in each of the three. The docs' option
tables are the tables generated from the declarations, and a throwaway option declared in a copy
of the table appears in the parser, the loop reader, the design's choices, the sweep's table and
the docs' table with nothing else written: adding an option is its declaration plus its use."""

from __future__ import annotations

import importlib
import math
from dataclasses import replace

import pytest

from netgen.cli import commands as cli
from netgen.core.errors import LoopError
from netgen.core.options import Option, of_role, with_table
from netgen.emit import EMITTERS, requested
from netgen.runtime.arguments import Parser
from netgen.runtime.options import build_options, simulate_options
from netgen.sim import SIMULATORS
from netgen.sweep import spec
from netgen.testbench.sigma_delta import Choices, loopfile
from netgen.testbench.sigma_delta import cli as sd_cli
from netgen.testbench.sigma_delta.options import (
    FLAGS,
    OPTIONS,
    SWEEP,
    loop_settings,
    markdown_tables,
    sweep_parameters,
)
from tests.fixtures import ROOT

DISK = str(ROOT / "examples" / "levitated_disk.toml")
TS = 1e-6  # the command line's default T_s, given to every route (f_s/2 = 500 kHz)
# the keys a [loop] table needs beside the one under test
COMPANIONS = {
    "input.force": 'coordinate = "z", amplitude = 0.02, frequency = 1000',
    "input.tone": "amplitude = 1, frequency = 1000",
}


def boundary_values(o: Option) -> list[float]:
    """Each end, the nearest numbers either side of it, a value inside, and the non-finite ones."""
    ends = [e for e in (o.low, o.high) if e is not None]
    near = [math.nextafter(e, d) for e in ends for d in (-math.inf, math.inf)]
    inside = [0.5 * (o.low + o.high)] if o.low is not None and o.high is not None else []
    values = ends + near + inside + [0.0, -1.0, 1.0, 1e300]
    if o.type == "int":
        return sorted({int(v) + d for v in values if abs(v) < 1e18 for d in (-1, 0, 1)})
    if o.name == "tone_freq":  # the upper end is f_s/2 at TS (the cross check), the same everywhere
        values += [0.5 / TS, math.nextafter(0.5 / TS, 0.0)]
    return sorted(set(values))


def toml(v: float) -> str:
    """A number as a TOML (and command-line) literal."""
    return repr(v) if isinstance(v, int) else repr(float(v))


def flag_verdict(o: Option, v: float, tmp_path) -> bool | None:
    """Accepted by `netgen sigma-delta`'s parser and its argument checks (None: no flag)."""
    if o.flag:
        argv = ["sigma-delta", DISK, "-o", str(tmp_path / "o"), f"{o.flag}={toml(v)}"]
    elif o.name in ("tone_amplitude", "tone_freq"):
        tone = f"z:{toml(v)}:1000" if o.name == "tone_amplitude" else f"z:0.02:{toml(v)}"
        argv = ["sigma-delta", DISK, "-o", str(tmp_path / "o"), f"--tone={tone}"]
    else:
        return None
    try:
        args = cli.parser().parse_args(argv)
    except SystemExit:
        return False
    try:
        sd_cli.check_arguments(args)
    except ValueError:
        return False
    return True


def loop_verdict(o: Option, v: float, tmp_path) -> bool | None:
    """Accepted by the loop reader (and, for a tone, its f_s/2 check at TS); None: no [loop] key."""
    if not o.loop_key:
        return None
    table, _, key = o.loop_key.rpartition(".")
    if table in COMPANIONS:
        others = ", ".join(p for p in COMPANIONS[table].split(", ") if not p.startswith(key + " "))
        text = f"[loop.{table.split('.')[0]}]\n{table.split('.')[1]} = {{ {others}, {key} = {toml(v)} }}\n"
    else:
        text = f"[loop{'.' + table if table else ''}]\n{key} = {toml(v)}\n"
    f = tmp_path / "loop.toml"
    f.write_text(text)
    try:
        loopfile.check_input_tone(loopfile.read_loop_file(f), TS)
    except LoopError:
        return False
    return True


def sweep_verdict(o: Option, v: float, tmp_path, capsys) -> bool | None:
    """Accepted by `netgen sweep --dry-run` with the value in [fixed] (None: no sweep parameter)."""
    if not o.sweep:
        return None
    fixed = ("" if o.name == "ts" else f"ts = {TS!r}\n") + (
        'tone = "z:0.02:1000"\n' if o.name.startswith("tone_") else ""
    )
    fixed += "" if o.name == "cycles" else "cycles = 128\n"
    f = tmp_path / "sweep.toml"
    swept = "lead" if o.name != "lead" else "dither"
    f.write_text(f'[fixed]\n{fixed}{o.sweep} = {toml(v)}\n[[parameters]]\nname = "{swept}"\nvalues = [0.5]\n')
    rc = cli.main(["sweep", DISK, str(f), "-o", str(tmp_path / "s"), "--dry-run"])
    capsys.readouterr()
    return rc == 0


def disagreements(o: Option, tmp_path, capsys) -> list[tuple[float, dict]]:
    """The values on which the places that write option `o` give different verdicts."""
    out = []
    for v in boundary_values(o):
        verdicts = {
            "flag": flag_verdict(o, v, tmp_path),
            "loop": loop_verdict(o, v, tmp_path),
            "sweep": sweep_verdict(o, v, tmp_path, capsys),
        }
        given = {k: x for k, x in verdicts.items() if x is not None}
        if len(set(given.values())) > 1:
            out.append((v, given))
    return out


SHARED = [o for o in OPTIONS.values() if o.type in ("float", "int") and o.name != "skip"]


@pytest.mark.parametrize("option", SHARED, ids=[o.name for o in SHARED])
def test_a_limit_is_the_same_for_the_flag_the_loop_key_and_the_sweep_parameter(option, tmp_path, capsys):
    """At each declared end, one step either side of it (math.nextafter), inside and far out."""
    places = [
        option.flag or option.name in ("tone_amplitude", "tone_freq"),
        option.loop_key,
        option.sweep,
    ]
    assert sum(bool(p) for p in places) >= 2 or option.name in ("segment", "timeout", "pressure", "tone_acceleration")
    assert disagreements(option, tmp_path, capsys) == []


def plant(monkeypatch, where: str, table: dict[str, Option]) -> None:
    """The parser (`flag`), the loop reader (`loop`) or the sweep (`sweep`) given the options `table`
    in place of the declarations (the others keep them)."""
    if where == "flag":
        monkeypatch.setattr(sd_cli, "OPTIONS", table)
    elif where == "loop":
        monkeypatch.setattr(loopfile.LoopSettings, "declared", loop_settings(table.values()))
    else:
        for module in (spec, importlib.import_module("netgen.sweep.plan")):
            monkeypatch.setattr(module, "TESTBENCH", spec.testbench_table(sweep_parameters(table.values())))


PLANTED = [  # (where, option, its changed declaration, the disagreements the comparison must find)
    ("loop", "density", {"open_high": False}, [(1.0, {"loop": True, "sweep": False})]),
    (
        "flag",
        "dither",
        {"high": 0.5},
        [(v, {"flag": False, "loop": True, "sweep": True}) for v in (math.nextafter(1.0, 0.0), 1.0)],
    ),
    ("sweep", "reltol", {"open_low": True}, [(1e-7, {"flag": True, "loop": True, "sweep": False})]),
]


@pytest.mark.parametrize("where, name, change, expected", PLANTED, ids=[p[0] for p in PLANTED])
def test_a_planted_difference_is_caught(where, name, change, expected, tmp_path, capsys, monkeypatch):
    """One of the three places given a limit of its own (the density range (0, 1] the loop reader had
    before the declarations; a flag that stops at 0.5; a sweep with an open lower end): the
    comparison finds exactly the values accepted in one place and refused in the others."""
    plant(monkeypatch, where, dict(OPTIONS) | {name: replace(OPTIONS[name], **change)})
    found = disagreements(OPTIONS[name], tmp_path, capsys)
    assert found == expected


# a throwaway design option, as a developer would add one: flag, [loop] key and sweep parameter
GAIN = Option(
    "gain",
    "a throwaway loop gain",
    low=0.0,
    high=2.0,
    open_low=True,
    default=1.0,
    example="1.5",
    flag="--gain",
    loop_key="gain",
    sweep="gain",
    role="design",
)


def test_adding_an_option_is_one_declaration(tmp_path, capsys, monkeypatch):
    """GAIN declared in a copy of the table, nothing else written: the command line takes --gain in its
    range (and refuses 3), the [loop] reader takes gain = 1.5 (and refuses 0), the design's Choices
    carry it (the flag's over the file's, else the declared default), the sweep takes it in [fixed]
    and as a parameter, and the docs' tables list it. Its use in loop.design is the one other line."""
    table = dict(OPTIONS) | {"gain": GAIN}
    for where in ("flag", "loop", "sweep"):
        plant(monkeypatch, where, table)
    monkeypatch.setattr(Choices, "declared", of_role(table.values(), "design"))
    p = Parser(prog="netgen")
    sd_cli.add_parser(p.add_subparsers())
    args = p.parse_args(["sigma-delta", DISK, "-o", str(tmp_path / "o"), "--gain", "1.5"])
    with pytest.raises(SystemExit):
        p.parse_args(["sigma-delta", DISK, "-o", str(tmp_path / "o"), "--gain", "3"])
    assert "--gain = '3' is outside (0, 2]" in capsys.readouterr().err
    f = tmp_path / "loop.toml"
    f.write_text("[loop]\ngain = 0.5\n")
    loop = loopfile.read_loop_file(f)
    f.write_text("[loop]\ngain = 0\n")
    with pytest.raises(LoopError, match=r"loop.gain = 0 is outside \(0, 2\]"):
        loopfile.read_loop_file(f)
    chosen = Choices.of(vars(args)).over(loop.settings.or_defaults())
    assert (loop.settings.gain, chosen.gain, Choices().over(loopfile.LoopSettings().or_defaults()).gain) == (
        0.5,
        1.5,
        1.0,
    )
    assert "gain" in spec.design_choices(sweep_parameters(table.values()))
    s = tmp_path / "sweep.toml"
    for i, (text, rc) in enumerate(
        (
            ('[fixed]\ngain = 1.5\n[[parameters]]\nname = "lead"\nvalues = [0.5]\n', 0),
            ('[[parameters]]\nname = "gain"\nvalues = [0.5, 1]\n', 0),
            ('[fixed]\ngain = 3.0\n[[parameters]]\nname = "lead"\nvalues = [0.5]\n', 2),
        )
    ):
        s.write_text("[fixed]\ncycles = 128\n" + text.removeprefix("[fixed]\n"))
        assert cli.main(["sweep", DISK, str(s), "-o", str(tmp_path / f"s{i}"), "--dry-run"]) == rc
    assert "is outside (0, 2]" in capsys.readouterr().err
    assert (
        "| `--gain` | `gain` | `gain` | (0, 2] | 1 | a throwaway loop gain |"
        in markdown_tables(table.values())["sigma-delta.md"]
    )


def test_the_same_value_gets_the_same_message_with_its_own_name(tmp_path, capsys):
    """reltol = 0.5 refused by the flag, the [loop] key and the sweep with one text."""
    problem = OPTIONS["reltol"].fix("x").split("e.g.")[0]
    p = cli.parser()
    with pytest.raises(SystemExit):
        p.parse_args(["sigma-delta", DISK, "-o", str(tmp_path / "o"), "--reltol", "0.5"])
    flag = capsys.readouterr().err
    f = tmp_path / "loop.toml"
    f.write_text("[loop]\nreltol = 0.5\n")
    with pytest.raises(LoopError) as loop:
        loopfile.read_loop_file(f)
    assert "--reltol = '0.5' is outside [1e-07, 0.01]" in flag and problem in flag
    assert "loop.reltol = 0.5 is outside [1e-07, 0.01]" in str(loop.value) and problem in str(loop.value)


def test_every_flag_and_sweep_parameter_is_declared():
    """The sweep's parameters and every argument of `netgen sigma-delta` come from OPTIONS."""
    assert set(spec.TESTBENCH) == set(SWEEP)
    sub = next(a for a in cli.parser()._actions if isinstance(getattr(a, "choices", None), dict))
    actions = {a.option_strings[-1] if a.option_strings else a.dest for a in sub.choices["sigma-delta"]._actions}
    assert actions - {"--help"} == set(FLAGS)


BUILD, SIMULATE = build_options(EMITTERS, requested), simulate_options(SIMULATORS)


@pytest.mark.parametrize("command, declared", [("build", BUILD), ("simulate", SIMULATE)])
def test_every_build_and_simulate_argument_is_declared(command, declared, tmp_path, capsys):
    """`netgen build` and `netgen simulate` take exactly the declared options (netgen.runtime.options),
    and a declared limit is the parser's: --max-minutes and --timeout refused at 0 and taken at 1 ms
    (the smallest time a wall-clock limit is given in), with the declaration's message."""
    sub = next(a for a in cli.parser()._actions if isinstance(getattr(a, "choices", None), dict))
    actions = {a.option_strings[-1] if a.option_strings else a.dest for a in sub.choices[command]._actions}
    assert actions - {"--help"} == {o.flag for o in declared.values()}
    o = declared["max_minutes" if command == "build" else "timeout"]
    first = [command, DISK if command == "build" else str(ROOT / "pyproject.toml"), "-o", str(tmp_path / "o")]
    p = cli.parser()
    assert getattr(p.parse_args(first + [f"{o.flag}=1e-3"]), o.name) == 1e-3
    with pytest.raises(SystemExit):
        p.parse_args(first + [f"{o.flag}=0"])
    assert f"{o.flag} = '0' is outside {o.range_text()}" in capsys.readouterr().err


@pytest.mark.parametrize("doc", ["sigma-delta.md", "sweeps.md"])
def test_the_docs_hold_the_tables_generated_from_the_declarations(doc):
    """docs/sigma-delta.md and docs/sweeps.md hold the generated option tables verbatim below their
    mark (regenerate them: .venv/bin/python -c "from netgen.testbench.sigma_delta.options import
    write_docs; write_docs('docs')")."""
    text = (ROOT / "docs" / doc).read_text(encoding="utf-8")
    assert markdown_tables()[doc] in text
    assert with_table(text, "sigma-delta", markdown_tables()[doc]) == text, (
        "regenerate: python -c \"from netgen.testbench.sigma_delta.options import write_docs; write_docs('docs')\""
    )
