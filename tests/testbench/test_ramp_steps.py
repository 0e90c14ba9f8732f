"""`ramp_steps` (--ramp-steps, [loop] ramp_steps, a sweep parameter): declared once
(netgen.testbench.sigma_delta.options), it reaches the compiled loop's netgen_sdloop instance, and a
back end that cannot honour it refuses it rather than running without it. What the grid does to
ngspice's time points is tests/testbench/test_sdloop.py's; what it buys in the FMU comparison is
bench/fmu_convergence.py's."""

from __future__ import annotations

import re

import pytest

from netgen.cli import commands as cli
from netgen.core.errors import LoopError
from netgen.model import MacroModel
from netgen.testbench import sigma_delta as sd
from netgen.testbench.sigma_delta import ngspice, runner
from netgen.testbench.sigma_delta.loop import Choices
from tests.fixtures import NETLISTS, ROOT

MODEL = NETLISTS / "accelerometer_z" / "accelerometer_z.json"
STRUCTURE = ROOT / "examples" / "accelerometer_z.toml"
TS = 1e-6


@pytest.fixture(scope="module")
def model():
    return MacroModel.load_json(MODEL)


def test_the_choice_reaches_the_compiled_loop_instance(model):
    """Given: the netgen_sdloop instance line carries ramp_steps=20; not given: no such parameter
    (the code model's default 0, its own step control), so the committed behaviour is unchanged."""
    loop = sd.read_structure_loop(STRUCTURE)
    for steps, want in ((20, "ramp_steps=20"), (None, None)):
        d = runner.backend_design(model, TS, loop, None, "ngspice-xspice", Choices(ramp_steps=steps))
        deck = ngspice.testbench(
            model, d, MODEL.with_suffix(".lib"), 64, "out.raw", settings=ngspice.Settings(loop="xspice")
        )
        found = re.findall(r"ramp_steps=\d+", deck)
        assert found == ([want] if want else []), found


@pytest.mark.parametrize("simulator", ["ngspice", "vacask", "ngspice-osdi"])
def test_other_back_ends_refuse_it_naming_the_key(model, simulator):
    loop = sd.read_structure_loop(STRUCTURE)
    with pytest.raises(LoopError) as info:
        runner.backend_design(model, TS, loop, None, simulator, Choices(ramp_steps=20))
    message = str(info.value)
    assert "loop.ramp_steps" in message and "ngspice-xspice" in message and "fix:" in message


def test_the_flag_is_refused_before_any_output(tmp_path, capsys):
    """The command line: exit 2 with the key and the fix, no output folder."""
    out = tmp_path / "run"
    argv = ["sigma-delta", str(STRUCTURE), "--model", str(MODEL), "--simulator", "vacask", "--ramp-steps", "20"]
    assert cli.main(argv + ["--cycles", "64", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "ramp_steps" in err and "Traceback" not in err
    assert not out.exists()
