"""The loop-orders comparison's device and loop (tests/testbench/test_loop_orders.py, shared with
bench/loop_orders_spring.py): accelerometer_z's square plate on its spring, in a 4th-order CIFB loop."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

TS = 1e-6
SIDE, GAP, RHO, THICK, K_SPRING = 500e-6, 2e-6, 2330.0, 20e-6, 0.3
MASS = SIDE * SIDE * THICK * RHO
EXAMPLE = ROOT / "examples" / "accelerometer_z.toml"
CIFB4 = (
    '[loop]\nchannels = ["z"]\n[loop.filter]\nkind = "cifb"\norder = 4\nosr = 64\n[loop.input]\nacceleration = 9.81\n'
)
