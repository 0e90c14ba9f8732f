"""Simulator failures become clear messages: missing ngspice, a run that dies with
"timestep too small", an unknown subcircuit; ngspice output that merely contains the word
"error" (which PySpice treats as a failure) is not one. Real ngspice runs, no mocks."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from netgen.cli import commands as cli
from netgen.core.errors import SimulationError, SimulatorNotFound
from netgen.sim.ngspice import ENV, run_ngspice
from netgen.sim.rawfile import read_raw
from tests.fixtures import NGSPICE

# dv/dt = v^2 with v(0) = 1 blows up at t = 1 s: ngspice aborts with "timestep too small" near t = 1
BLOW_UP = """* finite-time blow-up
C1 n 0 1
B1 0 n I=v(n)*v(n)
.ic v(n)=1
.tran 1m 2 uic
.end
"""


def test_missing_ngspice_names_the_install_command(tmp_path, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path))  # an empty folder: no ngspice on PATH
    with pytest.raises(SimulatorNotFound, match=r"apt-get install -y ngspice"):
        run_ngspice(BLOW_UP, tmp_path)


def test_missing_ngspice_in_a_fresh_process_is_a_message_not_a_traceback(tmp_path):
    """The netgen simulate command with PATH stripped: exit 3, the install command, no traceback."""
    cir = tmp_path / "x.cir"
    cir.write_text(BLOW_UP)
    env = dict(os.environ, PATH=str(tmp_path))
    proc = subprocess.run(
        [sys.executable, "-m", "netgen.cli.commands", "simulate", str(cir), "-o", str(tmp_path / "run")],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
    )
    assert proc.returncode == 3, proc.stderr
    assert "apt-get install -y ngspice" in proc.stderr and "Traceback" not in proc.stderr


def test_timestep_too_small_names_node_time_and_saved_netlist(tmp_path):
    with pytest.raises(SimulationError) as info:
        run_ngspice(BLOW_UP, tmp_path, name="blow")
    message = str(info.value)
    assert "timestep too small" in message and "node n" in message
    t = float(message.split("at t = ")[1].split()[0])
    assert 0.99 < t < 1.0  # the analytic blow-up time is 1 s
    saved = tmp_path / "blow.cir"
    assert f"ngspice -b {saved}" in message and saved.read_text() == BLOW_UP


def test_unknown_subcircuit_is_reported(tmp_path):
    with pytest.raises(SimulationError, match="unknown subckt"):
        run_ngspice("* bad\nV1 a 0 1\nX1 a 0 nosuch\n.op\n.end\n", tmp_path)


def test_the_word_error_in_titles_and_nodes_is_not_a_failure(tmp_path):
    netlist = (
        "error budget: the word error in the title and a node name\n"
        "V1 in 0 1\nR1 in error_node 1k\nR2 error_node 0 3k\n.op\n.end\n"
    )
    plot = run_ngspice(netlist, tmp_path)[0]
    assert np.isclose(plot["error_node"][0], 0.75)


def test_cli_reports_a_failed_simulation_with_exit_1(tmp_path):
    cir = tmp_path / "blow.cir"
    cir.write_text(BLOW_UP)
    proc = subprocess.run(
        [sys.executable, "-m", "netgen.cli.commands", "simulate", str(cir), "-o", str(tmp_path / "run")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 1
    assert "timestep too small" in proc.stderr and "node n" in proc.stderr and "Traceback" not in proc.stderr


@pytest.mark.parametrize("release", sorted(NGSPICE))
def test_ngspice_option_selects_the_ngspice_and_the_log_names_it(release, tmp_path, monkeypatch, capsys):
    """`netgen --ngspice PATH simulate` runs that ngspice (NETGEN_NGSPICE unset): the divider's
    0.75 V, the log's first line and the summary name the release, and the option does not
    outlive the command."""
    monkeypatch.delenv(ENV, raising=False)
    cir = tmp_path / "div.cir"
    cir.write_text("divider\nV1 in 0 1\nR1 in mid 1k\nR2 mid 0 3k\n.op\n.end\n")
    assert cli.main(["--ngspice", NGSPICE[release], "simulate", str(cir), "-o", str(tmp_path / "run")]) == 0
    assert np.isclose(read_raw(tmp_path / "run" / "div.raw")[0]["mid"][0], 0.75)
    assert (tmp_path / "run" / "div.log").read_text().startswith(f"netgen: ran ngspice-{release} (")
    assert f"ran ngspice-{release} (" in capsys.readouterr().out
    assert ENV not in os.environ
