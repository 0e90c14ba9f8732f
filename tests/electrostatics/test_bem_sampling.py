"""BEM sampling at scale (netgen.electrostatics.bem_sampling): a 25-point grid of a reduced
problem (a 100 um disk between two electrodes, coordinates z and tilt_x, coarse meshes) through
a 1-worker Dask LocalCluster (its diagonal) equals the serial result; a rerun reuses every
stored point.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("bempp_cl")
pytest.importorskip("distributed")

from netgen.electrostatics.bem_sampling import sample_maxwell  # noqa: E402
from netgen.electrostatics.sampling import ChunkStore, sampling_grid  # noqa: E402
from netgen.runtime.executor import DaskExecutor
from tests.oracles.bem_reduced import GAP, R, reduced  # noqa: E402


@pytest.fixture(scope="module")
def problem():
    """The prepared problem, its 5 x 5 grid (+-30 % of the gap in z, tilt closing 30 % at the
    rim) and the serial result."""
    p = reduced()
    x = sampling_grid(2, 5, 0.3)
    q = x * np.array([GAP, GAP / R])
    return p, q, sample_maxwell(p, q)


def test_serial_grid_is_physical(problem):
    """25 points, symmetric matrices; C(top) rises with z; z -> -z swaps top and bottom."""
    p, q, serial = problem
    assert len(serial.matrix) == 25 and np.isfinite(serial.matrix).all()
    assert np.abs(serial.matrix - serial.matrix.transpose(0, 2, 1)).max() < 1e-6 * np.abs(serial.matrix).max()
    c = serial.plate_electrode.reshape(5, 5, 2)
    assert (np.diff(c[:, 2, 0]) > 0).all() and (np.diff(c[:, 2, 1]) < 0).all()
    assert c[::-1, 2, 1] == pytest.approx(c[:, 2, 0], rel=1e-3, abs=0)
    assert (serial.order == serial.order[0]).all() or serial.order.max() <= 12


@pytest.mark.slow
def test_dask_equals_serial_and_a_rerun_computes_nothing(problem, tmp_path):
    """Through a 1-worker LocalCluster, on every sixth point of the grid (5: its diagonal, both
    coordinates moving; each point is solved alone, so a subset's matrices are the serial run's
    rows): the worker process's matrices equal the serial ones bit for bit; a rerun computes
    nothing. One worker, because a fresh worker's first point is mostly bempp-cl's numba compiles
    (about 25 s each, uncached); a killed worker losing no point is tested on the multipole extractor, whose solves compile nothing
    (tests/electrostatics/test_fastcap_dask.py::test_a_killed_worker_loses_no_point)."""
    p, q, serial = problem
    q, serial_matrix, serial_coarse = q[::6], serial.matrix[::6], serial.coarse[::6]
    store = ChunkStore(tmp_path)
    ex = DaskExecutor(None, 1)
    try:
        parallel = sample_maxwell(p, q, executor=ex, store=store)
    finally:
        ex.close()
    assert np.array_equal(parallel.matrix, serial_matrix)
    assert np.array_equal(parallel.coarse, serial_coarse)
    again = sample_maxwell(p, q, store=store)
    assert again.computed == [] and len(again.reused) == len(q) == 5
    assert np.array_equal(again.matrix, serial_matrix)
