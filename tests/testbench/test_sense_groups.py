"""The default sense weights and feedback pattern (netgen.testbench.sigma_delta.loop.groups) take
the signs of dC_i/dq at rest, and an electrode whose dC/dq on a coordinate is only round-off
gets weight 0 there, not a sign: on the xyz proof mass (netlists/accelerometer_xyz) the z plates
do not change with x or y, by the geometry (their dC/dx is 1e-16 of the combs')."""

from __future__ import annotations

import numpy as np

from netgen.model import MacroModel
from netgen.testbench.sigma_delta import loop
from tests.fixtures import ROOT

MODEL = ROOT / "netlists" / "accelerometer_xyz" / "accelerometer_xyz.json"
PLATES = {"zs": -1, "zt": +1}  # below and above the mass: dC/dz < 0 and > 0
COMBS = {"xp_t": +1, "xn_t": -1, "xp_b": +1, "xn_b": -1}  # x combs, signs of dC/dx


def test_round_off_derivatives_give_no_weight():
    """Channels x, y, z by default: x reads its four combs with the signs of dC/dx and neither z
    plate (their dC/dx is round-off); z and no other channel reads the plates, with -1 / +1; the
    feedback pattern is the weights'."""
    model = MacroModel.load_json(MODEL)
    out = {e["name"]: e for e in loop.groups(model, ["x", "y", "z"])}
    for name, sign in PLATES.items():
        assert out[name]["w"] == [0, 0, sign] and out[name]["sel"] == out[name]["w"]
    for name, sign in COMBS.items():
        assert out[name]["w"][0] == sign
    grad = model.capacitance_gradient(np.zeros(model.ncoords))[0]
    x = [c.name for c in model.coordinates].index("x")
    assert np.abs(grad[[e.name for e in model.electrodes].index("zs"), x]) > 0  # not exactly 0: round-off


def test_the_disk_keeps_its_groups():
    """The disk's z reads every electrode (top +1, bottom -1) and each tilt its own sectors."""
    model = MacroModel.load_json(ROOT / "netlists" / "levitated_disk.json")
    out = loop.groups(model, ["z", "tilt_x", "tilt_y"])
    for e in out:
        assert e["w"][0] == (1 if e["name"].startswith("top") else -1)
        assert sum(abs(v) for v in e["w"][1:]) == 1
