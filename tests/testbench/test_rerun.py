"""A `netgen sigma-delta` output folder reruns by hand: per back end, a 64-period run, then the
folder moved and its kept netlist run there by the same simulator binary in a subprocess
(`ngspice -b sigma_delta.cir`, `vacask sigma_delta.sim`), and that rerun's bits equal the ones
the run recorded in bitstreams.npz. The rerun's raw file is read with netgen.sim.rawfile and its
latch node b_<channel> sampled at the recorded clock instants (bitstreams.npz "time") against the
mid level; netgen's runner and analysis are not on that path. Moving the folder first also shows
that nothing the netlist loads is named by an absolute path into it (nor into the staging folder
the run wrote it in, netgen.runtime.folders.OutputFolder).
"""

from __future__ import annotations

import shutil
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from netgen.cli import commands as cli
from netgen.model import MacroModel
from netgen.runtime.folders import STAGING
from netgen.sim import vacask as sim_vacask
from netgen.sim.rawfile import read_raw
from netgen.testbench.sigma_delta import vacask
from tests.fixtures import NGSPICE, ROOT

MODEL = ("levitated_disk.json", "levitated_disk.lib", "levitated_disk.va")
# (back end, ngspice release): the B-source loop on both releases, the code models on 39 only
# (46: no matching source, exit 3), OSDI on 46 only (39 loads OSDI 0.3 only); VACASK has none
CASES = [("ngspice", "39"), ("ngspice", "46"), ("ngspice-xspice", "39"), ("ngspice-osdi", "46"), ("vacask", None)]


@pytest.fixture(scope="module")
def compiled(tmp_path_factory) -> Path:
    """The model's and the loop blocks' OSDI, compiled once (openvaf-r, ~20 s) and copied into
    each run's DIR/osdi, the cache the run would fill itself (netgen.emit.osdi.compiled)."""
    cache = tmp_path_factory.mktemp("osdi_cache")
    model = MacroModel.load_json(ROOT / "netlists" / MODEL[0])
    vacask.compile_model(model, cache, ROOT / "netlists" / MODEL[2])
    vacask.compile_blocks(cache)
    return cache


def rerun(folder: Path, simulator: str, release: str | None) -> Path:
    """Run the kept netlist in `folder` with the binary the run used; the raw file it wrote.
    ngspice 39 exits 1 after a .control run that wrote its raw file (it finds no analysis outside
    .control), so success is the raw file, as for netgen.sim.ngspice.run_control."""
    if simulator == "vacask":
        cmd, raw = [sim_vacask.tools()[1], "sigma_delta.sim"], folder / "tran1.raw"
    else:
        cmd, raw = [shutil.which(NGSPICE[release]), "-b", "sigma_delta.cir"], folder / "sigma_delta.raw"
    raw.unlink(missing_ok=True)
    done = subprocess.run(cmd, cwd=folder, capture_output=True, text=True, timeout=120)
    assert raw.exists(), f"{cmd} in {folder}: exit {done.returncode}\n{done.stdout[-2000:]}{done.stderr[-2000:]}"
    return raw


@pytest.mark.parametrize("simulator, release", CASES, ids=[f"{s}-{r or 'vacask'}" for s, r in CASES])
def test_kept_netlist_reruns_by_hand_with_the_recorded_bits(simulator, release, request, tmp_path, monkeypatch):
    """The moved folder's netlist reruns and its bits equal bitstreams.npz, period by period."""
    if release:
        monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE[release])
    out = tmp_path / "run"
    (out / "model").mkdir(parents=True)  # the model where a build puts it: DIR/model
    for name in MODEL:
        shutil.copy(ROOT / "netlists" / name, out / "model" / name)
    if simulator in ("vacask", "ngspice-osdi"):
        shutil.copytree(request.getfixturevalue("compiled"), out / "osdi")  # compiled only for these
    start = time.perf_counter()
    code = cli.main(
        [
            "sigma-delta",
            str(ROOT / "examples" / "levitated_disk.toml"),
            "--model",
            str(out / "model" / MODEL[0]),
            "--simulator",
            simulator,
            "--cycles",
            "64",
            "--no-plots",
            "-q",
            "-o",
            str(out),
        ]
    )
    assert code == 0
    kept = (out / ("sigma_delta.sim" if simulator == "vacask" else "sigma_delta.cir")).read_text()
    assert STAGING not in kept, "the kept netlist names the run's staging folder"
    assert str(tmp_path) not in kept, "the kept netlist names DIR by its absolute path"
    moved = out.rename(tmp_path / "moved")
    plot = read_raw(rerun(moved, simulator, release))[0]
    recorded = np.load(moved / "bitstreams.npz")
    channels = [k.removeprefix("bits_") for k in recorded.files if k.startswith("bits_")]
    assert channels == ["z", "tilt_x", "tilt_y"]
    for c in channels:
        level = np.interp(recorded["time"], np.asarray(plot["time"]), np.asarray(plot[f"v(b_{c})"]))
        bits = np.where(level > 0.5, 1, -1)
        assert len(bits) == 64 and np.array_equal(bits, recorded[f"bits_{c}"]), (
            c,
            np.flatnonzero(bits != recorded[f"bits_{c}"]),
        )
    print(f"{simulator} {release or ''}: run and rerun {time.perf_counter() - start:.1f} s")


def test_a_failed_runs_netlist_reruns_in_its_failed_folder(compiled, tmp_path):
    """A run stopped by --timeout keeps its netlist in DIR/sigma-delta.failed/, where netgen's
    message says to reproduce it: VACASK runs it there to the end, the compiled models reached
    through the kept link osdi -> ../osdi (netgen.runtime.folders.OutputFolder)."""
    out = tmp_path / "run"
    shutil.copytree(compiled, out / "osdi")
    code = cli.main(
        [
            "sigma-delta",
            str(ROOT / "examples" / "levitated_disk.toml"),
            "--model",
            str(ROOT / "netlists" / MODEL[0]),
            "--simulator",
            "vacask",
            "--cycles",
            "64",
            "--timeout",
            "0.01",
            "-q",
            "-o",
            str(out),
        ]
    )
    assert code == 1
    failed = out / "sigma-delta.failed"
    plot = read_raw(rerun(failed, "vacask", None))[0]
    assert np.asarray(plot["time"])[-1] == pytest.approx(64e-6, rel=1e-6)  # --ts 1e-6, 64 periods
