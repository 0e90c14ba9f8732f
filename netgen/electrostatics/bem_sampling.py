"""BEM sampling at scale (the dense BEM, netgen.electrostatics.bem, or the multipole extractor,
netgen.electrostatics.fastcap): the Maxwell matrix at many coordinate points through the executor
seam (netgen.runtime.executor: local processes or Dask), one point per task, each point stored as it
finishes (netgen.electrostatics.sampling.ChunkStore, one .npy per point under a folder named by
a hash of the meshes, settings and points) so a rerun computes only the missing ones.

Every worker pays bempp's numba JIT once (about 20 s) and then keeps it: workers are long-lived
processes, so the tasks after a worker's first are warm. Each task runs with the caller's BLAS
thread count (sampling.blas_threads), which makes the parallel matrices equal the serial ones.
"""

from __future__ import annotations

import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ..runtime.executor import Executor, SerialExecutor
from .bem import PreparedBem
from .fastcap import PreparedFastcap
from .sampling import ChunkStore, blas_threads, fingerprint

# a stored point: matrix, coarse matrix (n x n each), then these per-solve fields
EXTRA = ("error", "elements", "order", "seconds")


@dataclass
class MaxwellSamples:
    """Maxwell matrices at sample points, the solver's record of each, and what was reused."""

    q: np.ndarray  # (npts, ncoords)
    matrix: np.ndarray  # (npts, n, n) F, conductor 0 the plate
    coarse: np.ndarray  # (npts, n, n) the coarser level
    error: np.ndarray  # (npts,) estimated relative error
    elements: np.ndarray  # (npts,) unknowns of the finest level
    order: np.ndarray  # (npts,) regular quadrature order
    seconds: np.ndarray  # (npts,) wall time of the solve
    names: tuple[str, ...]
    settings: dict = field(default_factory=dict)
    computed: list[int] = field(default_factory=list)
    reused: list[int] = field(default_factory=list)

    @property
    def plate_electrode(self) -> np.ndarray:
        """(npts, n-1) two-terminal plate-electrode capacitances."""
        return -self.matrix[:, 0, 1:]


def pack(m) -> np.ndarray:
    """One solve (bem.MaxwellMatrix) as a (1, 2 n^2 + 4) row."""
    finest = m.settings["solves"][-2 if "panels" in m.settings["solves"][0] else -1]  # fastcap: [levels..., check]
    extra = [m.error, finest.get("elements", finest.get("panels")), finest["order"], m.settings.get("seconds", 0.0)]
    return np.concatenate([m.matrix.ravel(), m.coarse.ravel(), extra])[None, :]


def maxwell_point(prepared: PreparedBem | PreparedFastcap, item: tuple[np.ndarray, int | None]) -> np.ndarray:
    """The work unit: the Maxwell matrix at one point, with the caller's BLAS thread count."""
    q, threads = item
    if threads is None or threads == blas_threads():
        return pack(prepared.maxwell(q))
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=threads, user_api="blas"):
        return pack(prepared.maxwell(q))


def key_of(prepared: PreparedBem | PreparedFastcap, q: np.ndarray) -> str:
    """The store folder's name: a hash of meshes, basis values, settings, permittivity and points
    (a multipole extractor, netgen.electrostatics.fastcap, names its own arrays)."""
    if isinstance(prepared, PreparedFastcap):
        return "fastcap-maxwell-" + fingerprint(
            prepared.names,
            asdict(prepared.settings),
            prepared.eps,
            prepared.thickness,
            *prepared.fingerprint_arrays(),
            q,
        )
    arrays = [
        a
        for lv in prepared.levels
        if lv is not None  # a level over the memory budget is not meshed (PreparedBem)
        for a in (lv.plate.vertices, lv.plate.triangles, lv.phi, *[s.vertices for s in lv.electrodes])
    ]
    return "bem-maxwell-" + fingerprint(
        prepared.names, asdict(prepared.settings), prepared.eps, prepared.thickness, *arrays, q
    )


def sample_maxwell(
    prepared: PreparedBem | PreparedFastcap,
    Q: np.ndarray,
    executor: Executor | None = None,
    store: ChunkStore | str | Path | None = None,
    progress: bool = False,
    desc: str = "BEM samples",
) -> MaxwellSamples:
    """The Maxwell matrix at every row of Q (npts, ncoords): tasks on `executor` (None: in this
    process), each finished point saved in `store` and reused by a rerun; a progress bar on stderr."""
    q = np.ascontiguousarray(np.atleast_2d(Q), dtype=float)
    n = len(prepared.names)
    width = 2 * n * n + len(EXTRA)
    if store is not None and not isinstance(store, ChunkStore):
        store = ChunkStore(Path(store))
    rows: dict[int, np.ndarray] = {}
    folder = None
    if store is not None:
        folder = store.folder(
            key_of(prepared, q),
            {"what": desc, "points": len(q), "conductors": ", ".join(prepared.names), **asdict(prepared.settings)},
        )
        for k in range(len(q)):
            a = store.load(folder, k, 1)
            if a is not None and a.shape == (1, width):
                rows[k] = a
    todo = [k for k in range(len(q)) if k not in rows]
    reused = sorted(rows)
    ex = executor or SerialExecutor()
    with tqdm(total=len(q), desc=desc, unit="solve", disable=not progress, file=sys.stderr, leave=False) as bar:
        bar.update(len(rows))
        if todo:
            threads = blas_threads()
            items = [(q[k], threads) for k in todo]
            for j, out in ex.imap_unordered(maxwell_point, items, shared=prepared):
                k = todo[j]
                if not out.ok:
                    raise RuntimeError(f"{desc}: point {k} (q = {q[k].tolist()}) failed: {out.error}\n{out.traceback}")
                rows[k] = out.value
                if folder is not None:
                    store.save(folder, k, out.value)
                bar.update(1)
    if store is not None:
        store.log.append({"folder": folder, "computed": sorted(todo), "reused": reused})
    return unpack(q, [rows[k] for k in range(len(q))], prepared, todo, reused)


def unpack(
    q: np.ndarray,
    rows: list[np.ndarray],
    prepared: PreparedBem | PreparedFastcap,
    computed: list[int],
    reused: list[int],
) -> MaxwellSamples:
    """MaxwellSamples from the stored rows (pack's layout)."""
    n = len(prepared.names)
    a = np.concatenate(rows, axis=0) if rows else np.zeros((0, 2 * n * n + len(EXTRA)))
    nn = n * n
    settings = {**asdict(prepared.settings), "eps": prepared.eps, "thickness": prepared.thickness}
    return MaxwellSamples(
        q,
        a[:, :nn].reshape(-1, n, n),
        a[:, nn : 2 * nn].reshape(-1, n, n),
        a[:, 2 * nn],
        a[:, 2 * nn + 1].astype(int),
        a[:, 2 * nn + 2].astype(int),
        a[:, 2 * nn + 3],
        prepared.names,
        settings,
        sorted(computed),
        reused,
    )
