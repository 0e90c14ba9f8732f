"""Shared by the sweep tests: the reference sigma-delta runs (direct sigma_delta.run calls, no
executor and no sweep code) that every sweep of the same settings must reproduce."""

from __future__ import annotations

import json
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from netgen.testbench import sigma_delta as sd
from tests.fixtures import ROOT, shared

STRUCTURE = ROOT / "examples" / "levitated_disk.toml"
TS = [1.0e-6, 1.3e-6, 1.6e-6, 2.0e-6]
CYCLES = 128


def summary(path: Path) -> dict:
    """A run's summary.json without its wall time."""
    d = json.loads(path.read_text())
    d.pop("wall_s")
    return d


@pytest.fixture(scope="package")
def serial_runs(tmp_path_factory):
    """The reference: direct sigma_delta.run calls (rigid model, CYCLES periods, skip 0), two
    at a time, per T_s in TS; once per session (tests.fixtures.shared: the sweep modules may run
    on both xdist workers)."""
    out = tmp_path_factory.mktemp("serial")

    def runs(settings):
        model, lib = sd.model_for(STRUCTURE, out / "model_rigid", sd.BuildOptions(rigid_only=True), progress=False)

        def one(ts):
            sd.run(model, lib, out / f"ts_{ts:g}", sd.RunRequest(ts, CYCLES, progress=False, plots=False, skip=0))
            return summary(out / f"ts_{ts:g}" / "summary.json")

        with ThreadPoolExecutor(2) as pool:
            return dict(zip(TS, pool.map(one, TS)))

    return shared("serial_runs", (str(STRUCTURE), TS, CYCLES), runs)
