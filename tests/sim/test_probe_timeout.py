"""The ngspice probes (netgen.sim.ngspice.version, has_osdi) run through the one runner
(netgen.core.process) within the command's time limit: a hanging ngspice and the child it
started are killed, and the user gets a clear error naming the binary and the fix."""

from __future__ import annotations

import contextlib
import io
import os
import time

import pytest

from netgen.cli.commands import main
from netgen.core.errors import SimulatorNotFound
from netgen.sim import ngspice

from .test_process import gone

HANG = """#!/bin/sh
sleep 60 &
echo $! > "{pidfile}"
wait
"""


def fake(tmp_path, mark: str):
    """A fake `ngspice` that starts a child (its pid in tmp_path/child) and hangs; unique per test
    so that the probe's cache (keyed on path and mtime) never answers for it."""
    exe = tmp_path / mark / "ngspice"
    exe.parent.mkdir()
    exe.write_text(HANG.format(pidfile=tmp_path / "child"))
    exe.chmod(0o755)
    return exe


def child(tmp_path) -> int:
    """The pid the fake wrote."""
    return int((tmp_path / "child").read_text())


def test_a_hanging_version_probe_is_killed_at_the_timeout_with_its_child(tmp_path):
    """version() under probe_timeout(1): the error within 1 s plus the runner's reaping (a 3 s
    ceiling on a loaded 2-core machine), naming the binary, the limit and the fix; the child is gone."""
    exe = fake(tmp_path, "a")
    start = time.monotonic()
    with ngspice.probe_timeout(1.0), pytest.raises(SimulatorNotFound, match=r"did not finish within 1 s.*--timeout"):
        ngspice.version(str(exe))
    assert time.monotonic() - start < 3.0
    assert gone(child(tmp_path))


def test_the_osdi_probe_is_limited_too(tmp_path):
    """has_osdi() runs the same way: killed at the limit with its child."""
    exe = fake(tmp_path, "b")
    with ngspice.probe_timeout(1.0), pytest.raises(SimulatorNotFound, match="did not finish within 1 s"):
        ngspice.has_osdi(str(exe))
    assert gone(child(tmp_path))


def test_simulate_timeout_bounds_the_probe(tmp_path, monkeypatch):
    """`netgen simulate --timeout 2` with NETGEN_NGSPICE at a fake that answers the run but hangs
    on --version: exit 3 with the message within the limit, no child left behind."""
    exe = tmp_path / "c" / "ngspice"
    exe.parent.mkdir()
    exe.write_text(
        '#!/bin/sh\nif [ "$1" = "--version" ]; then\n'
        + HANG.format(pidfile=tmp_path / "child").split("\n", 1)[1]
        + "fi\nexit 1\n"
    )
    exe.chmod(0o755)
    (tmp_path / "rc.cir").write_text("rc\nR1 1 0 1k\nV1 1 0 1\n.op\n.end\n")
    monkeypatch.setenv(ngspice.ENV, str(exe))
    err = io.StringIO()
    start = time.monotonic()
    with contextlib.redirect_stderr(err):
        code = main(["simulate", str(tmp_path / "rc.cir"), "-o", str(tmp_path / "run"), "--timeout", "2"])
    assert code == 3, err.getvalue()
    assert time.monotonic() - start < 5.0  # 2 s limit, plus one probe, plus start-up
    assert "--version did not finish within 2 s" in err.getvalue()
    assert gone(child(tmp_path))


def test_the_default_limit_is_unchanged_and_a_real_ngspice_answers():
    """The real ngspice on PATH answers within the default limit (30 s) through the runner."""
    if not os.environ.get("PATH") or ngspice.shutil.which("ngspice") is None:
        pytest.skip("no ngspice on PATH")
    v = ngspice.version(ngspice.shutil.which("ngspice"))
    assert v.major >= 39 and ngspice.PROBE_TIMEOUT.get() == 30.0
