"""The Reynolds squeeze film's damping against gap and temperature, written out from the physics
(tests/emit/test_process_film_dg.py, tests/emit/test_process_osdi_closed.py): a rigid plate's film damps
b = 12 mu_eff R / g^3 (R the outline's alone), Veijola's mu_eff = mu / (1 + 9.638 Kn^1.159) with
Kn = lambda / g, Sutherland's mu ~ T^1.5 / (T + S) and the mean free path lambda = (mu / p)
sqrt(pi k T / 2 m), p fixed (an open cavity) or p0 T / T0 (a sealed one)."""

from __future__ import annotations

import math

from .fmu_process import MEAN_FREE_PATH, SUTHERLAND_AIR

GAP, T0 = 2e-6, 300.0  # m, K: the drawn gap of process_cases.GUIDED and the [damping] default temperature


def closed_form(dg: float, temp_c: float, sealed: bool) -> float:
    """b(g0 + dg, T) / b(g0, T0) of air's film on the gap g0 = GAP (module docstring), T0 = 300 K."""
    t, g = temp_c + 273.15, GAP + dg
    mu = (t / T0) ** 1.5 * (T0 + SUTHERLAND_AIR) / (t + SUTHERLAND_AIR)  # mu(T) / mu(T0)
    pressure = t / T0 if sealed else 1.0  # p(T) / p0
    path = MEAN_FREE_PATH * mu / pressure * math.sqrt(t / T0)  # lambda = (mu / p) sqrt(pi k T / 2 m)
    kn, kn0 = path / g, MEAN_FREE_PATH / GAP
    return mu * (GAP / g) ** 3 * (1.0 + 9.638 * kn0**1.159) / (1.0 + 9.638 * kn**1.159)
