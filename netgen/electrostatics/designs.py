"""Sample designs in the scaled coordinates x (the box [-r, r]^n): the paper's full tensor grid,
Smolyak sparse grids on nested Clenshaw-Curtis nodes (points and quadrature weights), and the
space-filling Latin hypercube and Sobol designs of scipy.stats.qmc. Pure functions of their
arguments (seeded), so the same structure gives the same points."""

from __future__ import annotations

import math
from itertools import product

import numpy as np
from scipy.stats import qmc

from ..structure.schema import DESIGNS, default_design, smolyak_count

__all__ = [
    "DESIGNS",
    "default_design",
    "smolyak_count",
    "full_grid",
    "smolyak_points",
    "smolyak_quadrature",
    "latin_hypercube",
    "sobol",
]


def full_grid(ncoords: int, levels: int, half_range: float) -> np.ndarray:
    """Full tensor grid of `levels` values in [-half_range, half_range] per coordinate."""
    axis = np.linspace(-half_range, half_range, levels)
    mesh = np.meshgrid(*([axis] * ncoords), indexing="ij")
    return np.stack([m.ravel() for m in mesh], axis=-1)


# ----------------------------------------------------------------------------- Smolyak sparse grids


def cc_nodes(i: int) -> np.ndarray:
    """Clenshaw-Curtis nodes of 1-D level i on [-1, 1]: {0}, then 2^i + 1 Chebyshev extrema (nested)."""
    if i == 0:
        return np.zeros(1)
    m = 2**i + 1
    x = -np.cos(np.pi * np.arange(m) / (m - 1))
    x[np.abs(x) < 1e-15] = 0.0
    return x


def cc_new_nodes(i: int) -> np.ndarray:
    """The nodes level i adds to level i - 1 (the nested difference)."""
    if i <= 1:
        return cc_nodes(i) if i == 0 else np.array([-1.0, 1.0])
    return cc_nodes(i)[1::2]


def cc_weights(i: int) -> np.ndarray:
    """Clenshaw-Curtis weights of level i for the mean over [-1, 1] (exact for Chebyshev
    polynomials up to the node count minus one, solved in the Chebyshev basis)."""
    x = cc_nodes(i)
    m = len(x)
    k = np.arange(m)
    even = k % 2 == 0
    moments = np.zeros(m)
    moments[even] = 1.0 / (1.0 - k[even].astype(float) ** 2)  # mean of T_k over [-1, 1]
    return np.linalg.solve(np.polynomial.chebyshev.chebvander(x, m - 1).T, moments)


def level_indices(ncoords: int, lo: int, hi: int) -> list[tuple[int, ...]]:
    """Multi-indices i >= 0 with lo <= |i| <= hi, in a fixed (graded, then lexicographic) order."""
    out = []
    for total in range(lo, hi + 1):
        out += [i for i in _compositions(ncoords, total)]
    return out


def _compositions(n: int, total: int) -> list[tuple[int, ...]]:
    """Every n-tuple of non-negative integers summing to `total`, lexicographically descending."""
    if n == 1:
        return [(total,)]
    return [(first,) + rest for first in range(total, -1, -1) for rest in _compositions(n - 1, total - first)]


def smolyak_points(ncoords: int, level: int, half_range: float = 1.0) -> np.ndarray:
    """The Smolyak sparse grid of `level` (nested Clenshaw-Curtis, level 1 = centre and the 2n
    axis points at +-half_range, which the 3-level grid also has) as a disjoint union of the
    tensor products of each level's new nodes; deterministic order."""
    blocks = [np.array(list(product(*[cc_new_nodes(k) for k in i]))) for i in level_indices(ncoords, 0, level)]
    return half_range * np.concatenate(blocks, axis=0).reshape(-1, ncoords)


def smolyak_quadrature(ncoords: int, level: int) -> tuple[np.ndarray, np.ndarray]:
    """Points and weights of the Smolyak quadrature for the mean over [-1, 1]^n (combination
    technique: sum over lo <= |i| <= level of (-1)^(level-|i|) C(n-1, level-|i|) times the tensor
    rules). Exact for polynomials of total degree 2 level + 1 (Novak and Ritter 1996)."""
    weights: dict[tuple[float, ...], float] = {}
    for i in level_indices(ncoords, max(0, level - ncoords + 1), level):
        coef = (-1) ** (level - sum(i)) * math.comb(ncoords - 1, level - sum(i))
        for combo in product(*[list(zip(cc_nodes(k), cc_weights(k))) for k in i]):
            key = tuple(float(p) for p, _ in combo)
            weights[key] = weights.get(key, 0.0) + coef * math.prod(w for _, w in combo)
    pts = smolyak_points(ncoords, level)
    return pts, np.array([weights.get(tuple(float(v) for v in p), 0.0) for p in pts])


# ----------------------------------------------------------------------------- space-filling designs


def latin_hypercube(ncoords: int, count: int, half_range: float, seed: int) -> np.ndarray:
    """Seeded Latin hypercube (scipy.stats.qmc): one point in each of `count` equal slices per coordinate."""
    u = qmc.LatinHypercube(d=ncoords, seed=np.random.default_rng(seed)).random(count)
    return half_range * (2.0 * u - 1.0)


def sobol(ncoords: int, count: int, half_range: float, seed: int) -> np.ndarray:
    """Seeded scrambled Sobol points (scipy.stats.qmc), `count` a power of two (a balanced net)."""
    m = int(round(math.log2(count)))
    u = qmc.Sobol(d=ncoords, scramble=True, seed=np.random.default_rng(seed)).random_base2(m)
    return half_range * (2.0 * u - 1.0)
