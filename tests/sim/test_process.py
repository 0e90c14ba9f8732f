"""The one runner (netgen.core.process): its wall-clock limit holds when the program prints nothing,
the whole process group goes with it, and output lines and progress ticks arrive while it runs."""

from __future__ import annotations

import os
import sys
import time

import pytest

from netgen.core import process
from netgen.core.errors import SimulationError


def gone(pid: int, within: float = 5.0) -> bool:
    """True once no process `pid` exists (or only its zombie), within `within` seconds."""
    end = time.monotonic() + within
    while time.monotonic() < end:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        try:
            with open(f"/proc/{pid}/stat") as fh:
                if fh.read().split()[2] == "Z":
                    return True
        except OSError:
            return True
        time.sleep(0.05)
    return False


def test_a_silent_hang_is_stopped_at_the_timeout_with_its_children(tmp_path):
    """A program that prints nothing and starts a child: both are killed 1 s in, and the error
    names the program and the command that reproduces the run."""
    script = "sleep 60 & echo $! > child; wait"
    start = time.monotonic()
    with pytest.raises(SimulationError, match=r"hang did not finish within 1 s; reproduce with: again"):
        process.run(["bash", "-c", script], tmp_path, 1.0, "again", "hang")
    assert time.monotonic() - start < 4.0
    assert gone(int((tmp_path / "child").read_text()))


def test_lines_arrive_as_printed_and_ticks_run_in_the_silences(tmp_path):
    code = "import time; print('a', flush=True); time.sleep(1.5); print('b', flush=True)"
    seen, ticks = [], []
    start = time.monotonic()
    done = process.run(
        [sys.executable, "-c", code],
        tmp_path,
        30.0,
        "x",
        watch=process.Watch(
            on_line=lambda line: seen.append((line.strip(), time.monotonic() - start)), on_tick=ticks.append, tick=0.25
        ),
    )
    assert done.returncode == 0 and done.output == "a\nb\n"
    assert [s for s, _ in seen] == ["a", "b"] and seen[0][1] < 1.0 <= seen[1][1]  # 'a' before the sleep
    assert len(ticks) >= 3 and ticks == sorted(ticks)  # ticks during the sleep


def test_exit_code_and_merged_output(tmp_path):
    done = process.run(["bash", "-c", "echo out; echo err >&2; exit 3"], tmp_path, 30.0, "x")
    assert done.returncode == 3 and sorted(done.output.split()) == ["err", "out"]
