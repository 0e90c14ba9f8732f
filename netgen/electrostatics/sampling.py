"""Sampling the extractor: the coordinate scales (touching amplitudes), the sample designs
(netgen.electrostatics.designs: the paper's tensor grid, sparse grids, space-filling designs;
seeded held-out points) and the capacitances at those points, in
chunks with a progress bar, serially or through an executor (netgen.runtime.executor), with finished
chunks streamed to a store so a re-run computes only the missing ones.

Parallel sampling splits the points into the same chunks as the serial path and runs each with
the caller's BLAS thread count (OpenBLAS rounds differently with 1 and 2 threads), so each chunk
is the same extractor call and the result is bit for bit the serial one. A ChunkStore keeps one
.npy per chunk, written atomically, under a folder named by a hash of the extractor and the points.
"""

from __future__ import annotations

import hashlib
import io
import math
import pickle
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from ..core.files import write_bytes_atomic
from ..runtime.executor import Executor, SerialExecutor
from . import designs
from .base import PreparedExtractor


@dataclass(frozen=True)
class Rest:
    """The extractor at rest: capacitances (nelectrodes,) F and their gradient in the scaled
    coordinates (nelectrodes, ncoords) F, by central differences (REST_STEP and half of it)."""

    c: np.ndarray
    grad: np.ndarray


REST_STEP = 1e-3  # scaled step of the rest gradient's central differences


@dataclass
class Samples:
    """Scaled sample points and extractor capacitances, touching points removed."""

    x: np.ndarray  # (n, ncoords) grid points kept
    c: np.ndarray  # (n, nelectrodes) F
    excluded: int  # grid points dropped because the plate touches an electrode
    points: np.ndarray | None = None  # every design point, the dropped ones included
    rest: Rest | None = None  # C and dC/dx at rest, which the fit then matches (adaptive design)

    def __add__(self, other: Samples) -> Samples:
        """Both sample sets as one (the adaptive design's growing training set; this one's rest)."""
        pts = None if self.points is None or other.points is None else np.concatenate([self.points, other.points])
        return Samples(
            np.concatenate([self.x, other.x]),
            np.concatenate([self.c, other.c]),
            self.excluded + other.excluded,
            pts,
            self.rest,
        )


def sampling_grid(ncoords: int, levels: int, half_range: float) -> np.ndarray:
    """Full tensor grid of `levels` values in [-half_range, half_range] per coordinate."""
    return designs.full_grid(ncoords, levels, half_range)


def box_factors(sampling, ncoords: int) -> np.ndarray:
    """Each coordinate's half-width of the sampled box over `range` (1 without per-coordinate
    ranges): a design drawn over +-range is multiplied by these, which is exact for 1."""
    return np.array(sampling.factors, dtype=float) if sampling.factors else np.ones(ncoords)


def check_points(sampling, n: int, ncoords: int) -> np.ndarray:
    """Rest and n random points of the fit box in scaled coordinates (q / L; fixed seed: the same
    points for every structure), where the process laws compare re-runs (netgen.build.capacitance_sampler
    extracts there, netgen.model.etch_state fits there)."""
    half = sampling.range * box_factors(sampling, ncoords)
    return np.vstack([np.zeros(ncoords), np.random.default_rng(0).uniform(-1.0, 1.0, (n, ncoords)) * half])


def box_corners(sampling, ncoords: int) -> np.ndarray:
    """The 2^ncoords corners of the fit box in scaled coordinates (q / L), where a state polynomial's
    misfit peaks (netgen.model.process.capacitance_laws checks a beam's overhanging tip there)."""
    half = sampling.range * box_factors(sampling, ncoords)
    signs = np.array(np.meshgrid(*[[-1.0, 1.0]] * ncoords, indexing="ij")).reshape(ncoords, -1).T
    return signs * half


def coordinate_ranges(sampling, names: list[str]) -> np.ndarray:
    """The half-width of each named coordinate's box from [sampling] range (a number, or a table
    whose "*" or the default 0.2 covers the coordinates it does not name)."""
    given = dict(sampling.ranges)
    rest = given.get("*", 0.2) if given else sampling.range
    return np.array([given.get(n, rest) for n in names], dtype=float)


def design_points(sampling, ncoords: int) -> np.ndarray:
    """The points of a structure's [sampling] design (for "adaptive": its starting design, the
    Smolyak level-1 grid, centre and axis ends, plus a Sobol set of 16 (n + 1) points), each
    coordinate within its own range (box_factors)."""
    return unit_design(sampling, ncoords) * box_factors(sampling, ncoords)


def unit_design(sampling, ncoords: int) -> np.ndarray:
    """The design's points over +-range in every coordinate."""
    o, r = sampling, sampling.range
    if o.design == "grid":
        return designs.full_grid(ncoords, o.levels, r)
    if o.design == "sparse":
        return designs.smolyak_points(ncoords, o.level, r)
    if o.design == "lhs":
        return designs.latin_hypercube(ncoords, o.points, r, o.seed)
    if o.design == "sobol":
        return designs.sobol(ncoords, o.points, r, o.seed)
    start = designs.sobol(ncoords, 1 << (16 * (ncoords + 1) - 1).bit_length(), r, o.seed)[: 16 * (ncoords + 1)]
    return np.concatenate([designs.smolyak_points(ncoords, 1, r), start])[: o.points]


def holdout_points(
    ncoords: int, count: int, half_range: float, seed: int, factors: np.ndarray | None = None
) -> np.ndarray:
    """Uniform random points inside the sampled box (held out from the fit); `factors` as box_factors."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(-half_range, half_range, size=(count, ncoords))
    return x if factors is None else x * factors


def touch_amplitudes(prepared: PreparedExtractor, ncoords: int, gaps: np.ndarray) -> np.ndarray:
    """Amplitude of each coordinate alone at which the plate first touches an electrode."""
    probe = 1e-3 * float(np.min(gaps))
    amps = np.full(ncoords, np.inf)
    for v in range(ncoords):
        for sign in (1.0, -1.0):
            q = np.zeros((1, ncoords))
            q[0, v] = sign * probe
            closing = (gaps - prepared.min_gap(q)[0]) / probe  # gap closed per unit amplitude
            with np.errstate(divide="ignore"):
                reach = np.where(closing > 1e-12, gaps / closing, np.inf)
            amps[v] = min(amps[v], float(reach.min()))
    return amps


def coordinate_scales(prepared: PreparedExtractor, names: list[str], gaps: np.ndarray) -> np.ndarray:
    """Touching amplitude of each coordinate (the scale of its sampled state x = q / L)."""
    scales = touch_amplitudes(prepared, len(names), np.asarray(gaps, dtype=float))
    if not np.all(np.isfinite(scales)):
        bad = [n for n, a in zip(names, scales) if not math.isfinite(a)]
        raise ValueError(f"coordinates {bad} never move the plate towards an electrode; they cannot be sampled")
    return scales


CORNER_REACH = 1.0  # the default box's worst corner closes at most this fraction of a gap


def corner_closure(prepared: PreparedExtractor, scales: np.ndarray) -> float:
    """Largest fraction of its gap any watched electrode point closes at a corner of the scaled
    box [-1, 1]^n: max_j sum_v |phi_jv L_v| / g_j. The local gap is affine in q
    (PreparedExtractor.probe_points), so the worst corner is this sum, exactly."""
    p = prepared.probe_points()
    if len(p.gap) == 0:
        return 0.0
    return float(np.max(np.abs(p.phi * scales[None, :]).sum(axis=1) / p.gap))


def box_range(prepared: PreparedExtractor, scales: np.ndarray, requested: float) -> float:
    """The default [sampling] range: `requested` unless the box's corners would then close more than
    CORNER_REACH of a gap (many coordinates combined: the free disk from 9), else CORNER_REACH over
    the corner closure, rounded down to two digits. Past contact the plate-sum form cannot follow
    the capacitance, and the fits miss by tens of percent."""
    reach = corner_closure(prepared, scales) * requested
    if reach <= CORNER_REACH:
        return requested
    r = CORNER_REACH * requested / reach
    return math.floor(r * 100.0) / 100.0 if r >= 0.01 else float(f"{r:.2g}")


def sample(
    prepared: PreparedExtractor,
    q: np.ndarray,
    progress: bool,
    desc: str,
    chunk: int = 256,
    executor: Executor | None = None,
    store: ChunkStore | str | Path | None = None,
) -> np.ndarray:
    """Capacitances at many coordinate points, in chunks, with a progress bar on stderr.
    With an executor the chunks run there, and with a store (a folder) each finished chunk is
    saved and a re-run reuses it; the values are the serial ones bit for bit."""
    if executor is not None or store is not None:
        return sample_chunks(prepared, q, progress, desc, chunk, executor, store)
    out = []
    with tqdm(total=len(q), desc=desc, unit="pt", disable=not progress, file=sys.stderr, leave=False) as bar:
        for k in range(0, len(q), chunk):
            out.append(prepared.capacitance(q[k : k + chunk]))
            bar.update(min(chunk, len(q) - k))
    return np.concatenate(out, axis=0)


def sample_points(
    prepared: PreparedExtractor, x: np.ndarray, scales: np.ndarray, progress: bool, desc: str, **parallel
) -> Samples:
    """Extractor capacitances at scaled points x; points where the plate touches are dropped.
    `parallel`: executor= and store= of sample()."""
    c = sample(prepared, x * scales, progress, desc, **parallel)
    touching = np.isnan(c).any(axis=1)  # e.g. grid corners where the combined motion closes a gap
    return Samples(x[~touching], c[~touching], int(touching.sum()), x)


def sample_grid(s, prepared: PreparedExtractor, scales: np.ndarray, progress: bool = False, **parallel) -> Samples:
    """The fit's samples at the structure's design (netgen.electrostatics.designs) over +-range of
    the touching amplitudes: the paper's levels^ncoords tensor grid by default."""
    x = design_points(s.sampling, len(scales))
    out = sample_points(prepared, x, scales, progress, "capacitance samples", **parallel)
    if s.sampling.design == "adaptive":  # its budget grows to pay for the rest rows
        out.rest = rest_of(prepared, scales)
    return out


def rest_of(prepared: PreparedExtractor, scales: np.ndarray) -> Rest:
    """C and dC/dx at rest from 4n + 1 extractor points (central differences at two steps,
    extrapolated). A loop holds the structure within a
    fraction of a nanometre of rest, where its forces are these slopes; a fit over the box
    misses them by a few 1e-4 (which moves the disk's sigma-delta z loop on or off its lock
    to the mean bit 1/2), so the adaptive design's fits match them (netgen.fit.capacitance.fit_plates).
    The fixed designs do not: with these rows the level-2 sparse grid missed the tolerance at
    9-11 coordinates (2.6e-3 to 3.6e-3, against 1.6e-3 to 1.9e-3 without)."""
    n, h, eye = len(scales), REST_STEP, np.eye(len(scales))
    q = np.concatenate([np.zeros((1, n)), h * eye, -h * eye, 0.5 * h * eye, -0.5 * h * eye]) * scales
    c = prepared.capacitance(q)
    wide = (c[1 : n + 1] - c[n + 1 : 2 * n + 1]) / (2 * h)
    narrow = (c[2 * n + 1 : 3 * n + 1] - c[3 * n + 1 :]) / h
    return Rest(c[0], ((4.0 * narrow - wide) / 3.0).T)  # Richardson: the h^2 error cancels


def sample_holdout(s, prepared: PreparedExtractor, scales: np.ndarray, progress: bool = False, **parallel) -> Samples:
    """Held-out check samples: uniform random points (seeded) inside the sampled box."""
    n = len(scales)
    x = holdout_points(n, s.fit.holdout, s.sampling.range, s.fit.seed, box_factors(s.sampling, n))
    return sample_points(prepared, x, scales, progress, "held-out samples", **parallel)


# Corner checks up to this many coordinates (2^6 = 64 extractor points). A polynomial's misfit peaks at
# the box's corners, which random held-out points miss as n grows (bench/fit_corners.py: the cantilever's
# corners 1.4x, the 6-coordinate accelerometer's 2.1x the random points' maximum); face centres stay below it.
CORNER_CHECKS = 6


def sample_corners(
    s, prepared: PreparedExtractor, scales: np.ndarray, progress: bool = False, **parallel
) -> Samples | None:
    """Check samples at the box's 2^n corners (netgen.fit.capacitance.at_corners adds them to the stated
    error; they are not fit points); None past CORNER_CHECKS coordinates."""
    n = len(scales)
    if n > CORNER_CHECKS:
        return None
    return sample_points(prepared, box_corners(s.sampling, n), scales, progress, "corner checks", **parallel)


# ----------------------------------------------------------------------------- parallel and resumable


def fingerprint(*parts: Any) -> str:
    """sha256 (16 hex digits) of the pickled parts: same inputs, same folder name."""
    h = hashlib.sha256()
    for p in parts:
        if isinstance(p, np.ndarray):
            h.update(repr((p.dtype.str, p.shape)).encode())
            h.update(np.ascontiguousarray(p).tobytes())
        else:
            h.update(pickle.dumps(p, protocol=4))
    return h.hexdigest()[:16]


@dataclass
class ChunkStore:
    """A folder of finished sample chunks (one .npy each); `log` records per call which chunk
    indices were computed and which reused from disk."""

    root: Path
    log: list[dict] = field(default_factory=list)

    def __post_init__(self):
        self.root = Path(self.root)

    def folder(self, key: str, meta: dict) -> Path:
        d = self.root / key
        d.mkdir(parents=True, exist_ok=True)
        info = d / "inputs.txt"
        if not info.exists():
            write_bytes_atomic(info, "".join(f"{k} = {v}\n" for k, v in meta.items()).encode())
        return d

    @staticmethod
    def path(folder: Path, k: int) -> Path:
        return folder / f"chunk_{k:06d}.npy"

    def load(self, folder: Path, k: int, rows: int) -> np.ndarray | None:
        p = self.path(folder, k)
        if not p.exists():
            return None
        try:
            a = np.load(p, allow_pickle=False)
        except (OSError, ValueError):
            return None  # unreadable: compute it again
        return a if a.shape[0] == rows else None

    def save(self, folder: Path, k: int, a: np.ndarray) -> None:
        buf = io.BytesIO()
        np.save(buf, a, allow_pickle=False)
        write_bytes_atomic(self.path(folder, k), buf.getvalue())


def blas_threads() -> int | None:
    """Threads of this process's BLAS (threadpoolctl), None if unknown. OpenBLAS rounds
    matrix products differently with 1 and 2 threads, so a work unit runs with the caller's
    count: that is what makes parallel samples equal the serial ones bit for bit."""
    try:
        from threadpoolctl import threadpool_info
    except ImportError:
        return None
    counts = [i["num_threads"] for i in threadpool_info() if i.get("user_api") == "blas"]
    return counts[0] if counts else None


def _capacitance_chunk(prepared: Any, item: tuple[np.ndarray, int | None]) -> np.ndarray:
    """One work unit of the sampling: the extractor at a chunk of points, with the caller's
    number of BLAS threads (a pure function of its inputs)."""
    q, threads = item
    if threads is None or threads == blas_threads():
        return prepared.capacitance(q)
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=threads, user_api="blas"):
        return prepared.capacitance(q)


def sample_chunks(
    prepared: Any,
    q: np.ndarray,
    progress: bool,
    desc: str,
    chunk: int = 256,
    executor: Executor | None = None,
    store: ChunkStore | str | Path | None = None,
) -> np.ndarray:
    """sample() through an executor (None: in this process), chunks streamed to `store`; an
    extractor whose points are expensive (a field solver) sets `points_per_task` to cap the chunk."""
    q = np.ascontiguousarray(q, dtype=float)
    chunk = min(chunk, int(getattr(prepared, "points_per_task", chunk)))
    starts = list(range(0, len(q), chunk))
    if store is not None and not isinstance(store, ChunkStore):
        store = ChunkStore(Path(store))
    folder = None
    results: dict[int, np.ndarray] = {}
    if store is not None:
        key = "capacitance-" + fingerprint(type(prepared).__qualname__, prepared, q, chunk)
        folder = store.folder(
            key,
            {
                "what": desc,
                "points": len(q),
                "coordinates": q.shape[1],
                "chunk": chunk,
                "chunks": len(starts),
                "extractor": type(prepared).__qualname__,
            },
        )
        for k, s in enumerate(starts):
            a = store.load(folder, k, min(chunk, len(q) - s))
            if a is not None:
                results[k] = a
    todo = [k for k in range(len(starts)) if k not in results]
    ex = executor or SerialExecutor()
    with tqdm(total=len(q), desc=desc, unit="pt", disable=not progress, file=sys.stderr, leave=False) as bar:
        bar.update(sum(len(a) for a in results.values()))
        if todo:
            threads = blas_threads()
            items = [(q[starts[k] : starts[k] + chunk], threads) for k in todo]
            for j, out in ex.imap_unordered(_capacitance_chunk, items, shared=prepared):
                k = todo[j]
                if not out.ok:
                    raise RuntimeError(
                        f"{desc}: chunk {k} (points {starts[k]}..{starts[k] + len(items[j][0]) - 1}) "
                        f"failed: {out.error}\n{out.traceback}"
                    )
                results[k] = out.value
                if folder is not None:
                    store.save(folder, k, out.value)
                bar.update(len(items[j][0]))
    if store is not None:
        store.log.append(
            {"folder": folder, "computed": sorted(todo), "reused": sorted(set(range(len(starts))) - set(todo))}
        )
    if not starts:
        return prepared.capacitance(q)
    return np.concatenate([results[k] for k in range(len(starts))], axis=0)
