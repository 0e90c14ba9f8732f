"""The .lib header's statements for circuit designers, checked against the model and ngspice:
the damping state (Q from the model's mass, stiffness and damping, computed here independently)
and `.include` versus `.lib` loading in ngspice 39 and 46."""

from __future__ import annotations

import dataclasses
import math
import subprocess

import pytest

from netgen.emit.common import damping_text
from netgen.model import MacroModel
from netgen.sim import ngspice
from tests.fixtures import NETLISTS

LIB = NETLISTS / "accelerometer_z" / "accelerometer_z.lib"
JSON = NETLISTS / "accelerometer_z" / "accelerometer_z.json"


def test_undamped_model_says_q_infinite():
    """accelerometer_z.toml has no [damping]: the committed header says so (Q infinite)."""
    model = MacroModel.load_json(JSON)
    assert all(c.damping == 0 and not c.film for c in model.coordinates)
    assert "Q infinite" in damping_text(model)
    assert "Q infinite" in LIB.read_text()


def test_damped_model_states_q():
    """With a damping b the header gives Q = sqrt(k m) / b (the resonator's definition)."""
    model = MacroModel.load_json(JSON)
    c = model.coordinates[0]
    b = 2e-6
    model.coordinates[0] = dataclasses.replace(c, damping=b)
    q = math.sqrt(c.stiffness * c.mass) / b
    assert f"(Q {q:.4g})" in damping_text(model)


def deck(load: str) -> str:
    """A 10-period free-fall transient of the model loaded by `load` (uic: the rest state)."""
    return (
        f"* load test\n{load}\nVa a_in 0 9.81\nX1 top bottom plate f_z x_z a_in accelerometer_z\n"
        "Vt top 0 0\nVb bottom 0 0\nVp plate 0 0\n.tran 1u 21u uic\n"
        ".control\nrun\nmeas tran zend find v(x_z) at=20u\n.endc\n.end\n"
    )


@pytest.mark.parametrize("load, works", [(f".include {LIB.name}", True), (f".lib {LIB.name}", False)])
def test_include_not_lib(ngspice_version, load, works, tmp_path):
    """`.include` loads the model and it falls as g t^2/2 (z = -G a t^2 / (2 m) = -1.962 nm at
    20 us, G = m for a rigid piston; the spring's share is (w0 t)^2/12 = 8e-4 relative); `.lib` with
    no section name does not load it, as the header says."""
    cir = LIB.parent / f"_load_test_{tmp_path.name}.cir"
    cir.write_text(deck(load))
    try:
        out = subprocess.run(
            [ngspice.ngspice_path(), "-b", cir.name], cwd=LIB.parent, capture_output=True, text=True, timeout=120
        )
    finally:
        cir.unlink()
    text = out.stdout + out.stderr
    if works:
        z = float(text.split("zend")[1].split("=")[1].split()[0])  # um
        assert z == pytest.approx(-9.81 * 20e-6**2 / 2 * 1e6, rel=2e-3)
    else:
        assert "zend" not in text or "failed" in text.lower()
