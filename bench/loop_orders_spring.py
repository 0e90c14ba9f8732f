"""What separates the compiled 4th-order loop's z from the numpy reference's (the comparison
tests/testbench/test_loop_orders.py's test_a_4th_order_loop_in_the_compiled_loop_tracks_the_numpy_loop
made before it checked each period's momentum balance, tests/oracles/loop_orders.momentum_defect):
the circuit's bits replayed through three mechanics, each sampled mid-feedback as the circuit is:
- the reference (tests/oracles/sigma_delta_reference.positions: the period's mean electrostatic spring);
- the same with the spring as it acts, piecewise in the period: K + the feedback plate's -2 F / g
  during the feedback pulse, K + both plates' at V_s during the sense phase, K otherwise;
- the response to the feedback alone (no gravity), the shape a feedback impulse gain error g
  leaves in z (fitted by least squares).

    .venv/bin/python bench/loop_orders_spring.py [PERIODS] [--reltol R]

prints each difference of the circuit's z from a mechanics, of z's peak, and the gain fitted to it
(--reltol: the circuit's, default the loop's 1e-3; what the piecewise spring leaves changes with it,
-3.0e-6 at 1e-3 and +1.6e-6 at 1e-4 on that run's own bits: the circuit's integration, not a
difference of the mechanics).
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy import linalg
from support import loop_orders
from support import sigma_delta_reference as reference

from netgen.build import build_model
from netgen.cli import commands as cli
from netgen.core.constants import EPS0
from netgen.structure import load_structure
from netgen.testbench import sigma_delta as sd
from netgen.testbench.sigma_delta import filters, loopfile

CIFB4, EXAMPLE, GAP, SIDE, TS = (
    loop_orders.CIFB4,
    loop_orders.EXAMPLE,
    loop_orders.GAP,
    loop_orders.SIDE,
    loop_orders.TS,
)


def piecewise(model, d, mech, inp, bits: np.ndarray, phase: float = 0.72) -> np.ndarray:
    """z (um) at (n + phase) T_s with the electrostatic spring piecewise in the period (exact
    state transitions per piece; the ramps taken at their mid-points)."""
    c, t = model.coordinates[0], d.t
    ea = EPS0 * SIDE**2
    k_fb, k_s = -ea * d.vfb**2 / GAP**3, -2 * ea * d.vs**2 / GAP**3
    damping = float(c.admittance(0.0).real)
    edges = sorted({0.0, 1.0, phase, t.sense_on, t.sense_off, t.fb_on, t.fb_off})

    def piece(lo: float, hi: float, bit: int) -> np.ndarray:
        fb = t.fb_on <= lo and hi <= t.fb_off
        k = c.stiffness + (k_fb if fb else 0.0) + (k_s if t.sense_on <= lo and hi <= t.sense_off else 0.0)
        a = np.array([[0, 1, 0], [-k / c.mass, -damping / c.mass, inp.dc + bit * fb * mech.force / c.mass], [0, 0, 0]])
        return linalg.expm(a * (hi - lo) * TS)

    steps = {b: [(hi, piece(lo, hi, b)) for lo, hi in zip(edges[:-1], edges[1:])] for b in (-1, 1)}
    s, out = np.array([0.0, 0.0, 1.0]), np.empty(len(bits))
    for n, bit in enumerate(bits.astype(int)):
        for hi, m in steps[int(bit)]:
            s = m @ s
            if hi == phase:
                out[n] = s[0] * 1e6
    return out


def main(periods: int, extra: list[str]) -> None:
    model = build_model(load_structure(EXAMPLE), progress=False)
    with tempfile.TemporaryDirectory() as tmp:
        loop = Path(tmp) / "loop.toml"
        loop.write_text(CIFB4, encoding="utf-8")
        out = Path(tmp) / "sd"
        args = ["sigma-delta", str(EXAMPLE), "--loop", str(loop), "--simulator", "ngspice-xspice", *extra]
        assert cli.main([*args, "--cycles", str(periods), "-o", str(out), "-q"]) == 0
        clock = dict(np.load(out / "bitstreams.npz"))
        d = sd.design(model, TS, spec=loopfile.read_loop_file(loop))
    mech = filters.mechanics_of(model, d, "z")
    inp = reference.Input(filters.dc_acceleration(model, d, "z"))
    bits, z = clock["bits_z"].astype(float), clock["x_z"]
    shape = reference.positions(mech, bits, reference.Input(0.0), phase=0.72) * 1e6
    peak = np.abs(z).max()
    print(f"z's peak {peak:.3e} um; the feedback's response alone peaks at {np.abs(shape).max() / peak:.0f} times it")
    for name, ref in (
        ("mean spring (the test's reference)", reference.positions(mech, bits, inp, phase=0.72) * 1e6),
        ("spring piecewise in the period", piecewise(model, d, mech, inp, bits)),
    ):
        err = z - ref
        g = float(np.dot(err, shape) / np.dot(shape, shape))
        left = np.abs(err - g * shape).max() / peak
        print(f"{name}: |circuit - it| {np.abs(err).max() / peak:.2e} of the peak; gain {g:.2e}, {left:.1e} left")


if __name__ == "__main__":
    argv = sys.argv[1:]
    count = int(argv.pop(0)) if argv and not argv[0].startswith("-") else 400
    main(count, argv)
