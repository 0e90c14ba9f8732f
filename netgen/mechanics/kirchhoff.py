"""Exact eigenvalues of the free circular Kirchhoff plate (Leissa, NASA SP-160, free edge):
the independent reference of the FEM modes, and the count of eigenpairs a label request needs."""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq
from scipy.special import ive, jv, jvp


def free_edge_determinant(lam: float | np.ndarray, n: int, nu: float) -> float | np.ndarray:
    """Determinant of the free-edge conditions (M_r = V_r = 0) for J_n + C I_n at r = a.

    The I_n column is scaled by exp(-lam) (``ive``) so the determinant stays finite and
    pole-free; its zeros in lam > 0 are the elastic eigenvalues lambda (lambda^2 = omega
    a^2 sqrt(rho h / D)).
    """
    j, dj = jv(n, lam), jvp(n, lam)
    i = ive(n, lam)
    di = 0.5 * (ive(n - 1, lam) + ive(n + 1, lam))
    m_j = -(lam**2) * j - (1 - nu) * (lam * dj - n**2 * j)
    m_i = lam**2 * i - (1 - nu) * (lam * di - n**2 * i)
    v_j = -(lam**3) * dj - (1 - nu) * n**2 * (lam * dj - j)
    v_i = lam**3 * di - (1 - nu) * n**2 * (lam * di - i)
    return m_j * v_i - m_i * v_j


def free_edge_roots(n: int, nu: float, count: int | None = None, stop: float | None = None) -> list[float]:
    """Positive roots lambda of the free-edge equation: the first ``count``, or all below ``stop``.

    Scans lambda on a 0.02 grid (roots are ~pi apart) from 0.05, above the rigid-body root
    lambda = 0 of n = 0, 1, and polishes each sign change with Brent's method.
    """
    roots: list[float] = []
    lo, step, block = 0.05, 0.02, 400
    while (count is None or len(roots) < count) and (stop is None or lo < stop):
        grid = lo + step * np.arange(block + 1)
        f = free_edge_determinant(grid, n, nu)
        for i in np.flatnonzero((f[:-1] * f[1:] < 0) | (f[:-1] == 0)):
            roots.append(
                grid[i] if f[i] == 0 else brentq(free_edge_determinant, grid[i], grid[i + 1], args=(n, nu), xtol=1e-14)
            )
        lo = grid[-1]
    roots = [r for r in roots if stop is None or r <= stop]
    return roots if count is None else roots[:count]


def free_plate_lambda2_exact(n: int, s: int, nu: float) -> float:
    """Exact lambda^2 of the free circular Kirchhoff plate (Leissa NASA SP-160, free edge).

    n nodal diameters, s nodal circles.  For n = 0 and 1 the s = 0 solutions are the rigid
    translation and tilts (lambda = 0), so the first positive root is s = 1.
    """
    if n < 0 or s < 0:
        raise ValueError(f"n and s must be non-negative, got n={n}, s={s}")
    if n < 2 and s == 0:
        raise ValueError(f"({n},0) is a rigid-body motion of the free plate (lambda = 0)")
    index = s if n >= 2 else s - 1
    return free_edge_roots(n, nu, index + 1)[index] ** 2
