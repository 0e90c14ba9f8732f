"""Options declared once (netgen.core.options, netgen.testbench.sigma_delta.options): every option that a
user can write in more than one place (a `netgen sigma-delta` flag, a [loop] key, a sweep
parameter) gets the same verdict in each, at and beyond its declared limits. The verdicts come
from the real parsers (the command line's argparse and checks, the loop reader, `netgen sweep
--dry-run`), not from the declarations, so a limit hard-coded in one of them fails here; the
comparison itself is shown to catch a planted difference. The docs' option tables are the
tables generated from the declarations."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from netgen.cli import commands as cli
from netgen.core.errors import LoopError
from netgen.core.options import Option
from netgen.testbench.sigma_delta import cli as sd_cli
from netgen.testbench.sigma_delta import loopfile
from netgen.testbench.sigma_delta.options import FLAGS, OPTIONS, SWEEP, markdown_tables
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


def test_a_planted_difference_is_caught(tmp_path, capsys, monkeypatch):
    """The loop reader given a density range of its own, (0, 1] as it had before the
    declarations: the comparison finds exactly the value 1 accepted there and refused by the sweep."""
    planted = dict(OPTIONS) | {"density": replace(OPTIONS["density"], open_high=False)}
    monkeypatch.setattr(loopfile, "OPTIONS", planted)
    found = disagreements(OPTIONS["density"], tmp_path, capsys)
    assert found == [(1.0, {"loop": True, "sweep": False})]


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
    """The sweep's parameters and the sigma-delta flags with values come from OPTIONS."""
    from netgen.sweep.spec import TESTBENCH

    assert set(TESTBENCH) == set(SWEEP)
    sub = next(a for a in cli.parser()._actions if isinstance(getattr(a, "choices", None), dict))
    actions = {a.option_strings[-1] for a in sub.choices["sigma-delta"]._actions if a.option_strings}
    assert set(FLAGS) <= actions


@pytest.mark.parametrize("doc", ["sigma-delta.md", "sweeps.md"])
def test_the_docs_hold_the_tables_generated_from_the_declarations(doc):
    """docs/sigma-delta.md and docs/sweeps.md contain the generated option tables verbatim
    (regenerate: python -c "from netgen.testbench.sigma_delta.options import markdown_tables; ...")."""
    text = (ROOT / "docs" / doc).read_text(encoding="utf-8")
    assert markdown_tables()[doc] in text
