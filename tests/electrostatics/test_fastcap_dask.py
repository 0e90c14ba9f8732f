"""The multipole extractor (netgen.electrostatics.fastcap) sampled through a 2-worker Dask
LocalCluster (netgen.runtime.executor.DaskExecutor): the prepared extractor is pickled to the
workers, each point is a task, and the fastcap2 problems are built and solved in the worker
processes; a worker killed mid-run loses no point. The reference is the serial path in this
process, on the small disk (100 um radius, 20 um gaps above and below, rigid z; the extractor's
default sizes: 630 / 1072 panels, about 2 s a point).

Tolerance: none, equality bit for bit. A solve is a deterministic function of the panel corners,
the expansion order and the GMRES tolerance: fastcap2_core is single-threaded C++ linking neither
BLAS nor OpenMP (so the workers' OMP_NUM_THREADS=1 changes nothing), the panels reach the workers
pickled bit for bit, and the Richardson step is elementwise numpy. A different CPU model or build
could round the multipole sums differently; the bound there would be the GMRES tolerance
(iter_tol 1e-4 V at 1 V, docs/fastcap.md), not tested here.
"""

from __future__ import annotations

import os
import signal
import threading
import time

import numpy as np
import pytest

pytest.importorskip("fastcap2")
pytest.importorskip("distributed")

from netgen.electrostatics import fastcap  # noqa: E402
from netgen.electrostatics.bem_sampling import sample_maxwell  # noqa: E402
from netgen.electrostatics.sampling import ChunkStore, sample  # noqa: E402
from netgen.geometry.layout import electrodes, plate_outline  # noqa: E402
from netgen.mechanics import mechanics  # noqa: E402
from netgen.runtime.executor import DaskExecutor  # noqa: E402
from netgen.structure import parse_structure  # noqa: E402
from tests.fixtures import SMALL_BEM_DISK  # noqa: E402

UM = 1e-6
Q = np.array([[-6 * UM], [-2 * UM], [2 * UM], [6 * UM]])  # rigid z, up to 30 % of the 20 um gaps


@pytest.fixture(scope="module")
def prepared():
    """The small disk's prepared multipole extractor (default settings)."""
    text = SMALL_BEM_DISK.replace('name = "small_bem"', 'name = "small_fc"').format(extractor="fastcap", extra="")
    s = parse_structure(text, "small_fc.toml")
    m, plate = mechanics(s), plate_outline(s)
    return fastcap.from_structure(s, plate).prepare(electrodes(s), plate, m.basis)


@pytest.fixture(scope="module")
def serial(prepared):
    """The Maxwell matrices at Q in this process (bem_sampling.sample_maxwell without an executor)."""
    return sample_maxwell(prepared, Q)


@pytest.fixture(scope="module")
def dask():
    """A LocalCluster of 2 single-threaded worker processes, closed after the module."""
    ex = DaskExecutor(None, 2)
    yield ex
    ex.close()


def test_maxwell_samples_on_dask_equal_serial(prepared, serial, dask):
    """bem_sampling.sample_maxwell (one point per task) on 2 Dask workers: the Maxwell matrices,
    their coarse levels, error bars and panel counts equal the serial ones bit for bit; the
    plate-top capacitance grows as z closes the top gap (a sign check that the points moved)."""
    parallel = sample_maxwell(prepared, Q, executor=dask)
    assert np.array_equal(parallel.matrix, serial.matrix)
    assert np.array_equal(parallel.coarse, serial.coarse)
    assert np.array_equal(parallel.error, serial.error)
    assert np.array_equal(parallel.elements, serial.elements)
    assert (np.diff(serial.plate_electrode[:, 0]) > 0).all()


def test_build_sampling_on_dask_is_one_point_per_task(prepared, serial, dask, tmp_path):
    """The build's sampling path (sampling.sample with an executor and a store, what `netgen build
    --scheduler local:2 --sample-store DIR` runs): the plate-electrode capacitances equal the serial
    Maxwell matrices' bit for bit, and every point is its own task (PreparedFastcap.points_per_task): one stored chunk per point."""
    store = ChunkStore(tmp_path)
    c = sample(prepared, Q, False, "fastcap samples", executor=dask, store=store)
    assert np.array_equal(c, serial.plate_electrode)
    assert store.log[-1]["computed"] == list(range(len(Q)))
    folder = store.log[-1]["folder"]
    assert all(np.load(ChunkStore.path(folder, k)).shape == (1, 2) for k in range(len(Q)))


def test_a_killed_worker_loses_no_point(prepared, serial, tmp_path):
    """bem_sampling.sample_maxwell with a store on its own 2-worker LocalCluster: one worker
    SIGKILLed once the first point is stored (its nanny starts a new one; the executor submits its
    lost tasks again) loses none: all four present and equal to the serial matrices bit for bit;
    a rerun computes nothing."""
    store = ChunkStore(tmp_path)
    ex = DaskExecutor(None, 2)
    killed: list[int] = []

    def killer(pid: int) -> None:
        """SIGKILL the worker once a point is on disk (each point takes seconds: the rest are queued)."""
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline:
            done = len(list(tmp_path.glob("*/chunk_*.npy")))
            if done >= 1:
                os.kill(pid, signal.SIGKILL)
                killed.append(done)
                return
            time.sleep(0.02)

    try:
        t = threading.Thread(target=killer, args=(list(ex.client.run(os.getpid).values())[0],), daemon=True)
        t.start()
        parallel = sample_maxwell(prepared, Q, executor=ex, store=store)
        t.join(timeout=300)
    finally:
        ex.close()
    assert killed and killed[0] < len(Q), "the worker was killed mid-run"
    assert np.array_equal(parallel.matrix, serial.matrix)
    assert np.array_equal(parallel.coarse, serial.coarse)
    again = sample_maxwell(prepared, Q, store=store)
    assert again.computed == [] and len(again.reused) == len(Q)
    assert np.array_equal(again.matrix, serial.matrix)
