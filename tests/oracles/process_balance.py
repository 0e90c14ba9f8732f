"""Static readings of process-parameter tests and benches (tests/model/test_process_pull_in.py,
bench/process_pull_in.py): the pull-in of a modal MacroModel by displacement iteration, and the
levitated disk's gravity balance voltage from a build's fit or its field solution; LawAt, an etch
law at one etch read as a model (tests/model/test_process_etch_beams.py, bench/process_etch_beams.py)."""

from __future__ import annotations

import math

import numpy as np

from netgen.core.constants import G
from netgen.model.process import capacitance_at


def pull_in(model, stiffness: list[float], points: int = 4001) -> float:
    """Pull-in voltage of the electrode set (all electrodes at V, the beam at 0) of a modal model with
    the given stiffnesses: displacement iteration on the first mode's amplitude s towards the
    electrode (V^2(s) = 2 K_1 s / dC/dq_1, the higher modes by fixed point), max over s by a grid of
    `points` up to 0.55 of the first coordinate's touching amplitude, refined by a parabola."""
    k = np.asarray(stiffness)
    scales = model.scales
    grad0 = model.capacitance_gradient(np.zeros((1, model.ncoords))).sum(axis=1)[0]
    s = np.sign(grad0[0]) * np.linspace(1e-4, 0.55, points) * scales[0]
    q = np.zeros((points, model.ncoords))
    q[:, 0] = s
    for _ in range(60):
        g = model.capacitance_gradient(q / scales).sum(axis=1)  # (points, ncoords): all electrodes at V
        v2 = 2 * k[0] * s / g[:, 0]
        new = v2[:, None] * g / (2 * k[None, :])
        new[:, 0] = s
        done = np.max(np.abs(new - q) / scales) < 1e-14
        q = new
        if done:
            break
    i = int(np.argmax(v2))
    a, b, c = v2[i - 1 : i + 2]
    return math.sqrt(b + (c - a) ** 2 / (8 * (2 * b - a - c)))


def top_slope(b, z: float, fitted: bool = True) -> float:
    """sum over the top electrodes of dC/dz (F/m) at z (m), the other coordinates at rest: the
    model's fit, or the field solution the fit was sampled from (the build's prepared extractor)."""
    model = b.model
    top = [i for i, e in enumerate(model.electrodes) if e.name.startswith("top")]
    v = [c.name for c in model.coordinates].index("z")
    q = np.zeros((1, model.ncoords))
    q[0, v] = z
    if fitted:
        return float(model.capacitance_gradient(q / model.scales)[0, top, v].sum())
    return float(np.asarray(b.prepared.gradient(q))[0, top, v].sum())


def balance_voltage(slope: float, mass: float) -> float:
    """The top-electrode voltage (disk and bottom electrodes at 0) whose force on z, 1/2 V^2 slope,
    balances the weight M g."""
    return math.sqrt(2 * mass * G / slope)


# the cantilever's parameter points (the ends of each range), shared by tests/model/test_process_pull_in.py
# and bench/process_pull_in.py
CASES = [
    ("tscale", 0.9),
    ("tscale", 1.1),
    ("escale", 0.5),
    ("escale", 1.5),
    ("temp", -40.0),
    ("temp", 125.0),
]


class LawAt:
    """The etch law's capacitances at one etch (netgen.model.process.capacitance_at: ratio, shifts,
    state factor) with the MacroModel interface process_balance.pull_in reads; the gradient by a
    central difference in the scaled state (h = 1e-5: truncation ~ h^2 d3C/C ~ 1e-10 relative)."""

    def __init__(self, model, etch: float) -> None:
        self.model, self.etch = model, etch
        self.scales, self.ncoords = model.scales, model.ncoords

    def capacitance_gradient(self, xs: np.ndarray) -> np.ndarray:
        """dC/dq (points, electrodes, coordinates) in F/m."""
        h, out = 1e-5, []
        for v in range(self.ncoords):
            step = np.zeros(self.ncoords)
            step[v] = h
            hi = capacitance_at(self.model, xs + step, self.etch)
            lo = capacitance_at(self.model, xs - step, self.etch)
            out.append((hi - lo) / (2 * h * self.scales[v]))
        return np.stack(out, axis=-1)
