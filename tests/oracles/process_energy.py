"""The clamped-clamped beam of tests/emit/test_process_energy.py at scaled thickness and modulus, its static
rest under FORCE by fsolve and the laws' stated bound; shared with bench/process_terms.py."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.optimize import fsolve

ROOT = Path(__file__).resolve().parents[2]

FORCE = 40e-6  # N on f_m1 (1 V = 1 uN): 0.97 um linear at the nominal 41.4 N/m
CASES = [(0.9, 1.0), (1.1, 1.0), (1.0, 0.5), (1.1, 1.5)]  # (tscale, escale)
PROCESS = '\n[process]\nparameters = ["tscale", "escale"]\n'


def text(tscale: float = 1.0, escale: float = 1.0) -> str:
    """examples/cc_beam.toml at the thickness and modulus scaled."""
    t = (ROOT / "examples" / "cc_beam.toml").read_text()
    t = t.replace('thickness = "2 um"', f'thickness = "{2.0 * tscale!r} um"')
    return t.replace('youngs_modulus = "169 GPa"', f'youngs_modulus = "{169.0 * escale!r} GPa"')


def rest(model, energy: float = 1.0) -> np.ndarray:
    """q (m) where K q + energy dU/dq = FORCE e_m1 (nonlinear_force is -dU/dq) (the model's own laws, no voltage)."""
    k = np.array([c.stiffness for c in model.coordinates])
    scale = np.array(model.scales)
    f = np.zeros(len(k))
    f[0] = FORCE

    def residual(q: np.ndarray) -> np.ndarray:
        return (k * q - energy * model.nonlinear_force((q / scale)[None, :])[0] - f) / FORCE

    return fsolve(residual, f / k, xtol=1e-13)


def bound(model) -> float:
    return model.process["tscale"]["max_rel_error"] + model.process["strain_energy"]["max_rel_error"]
