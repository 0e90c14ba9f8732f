"""The gap offset dg_<set> in the _xspice.lib (netgen.emit.xspice.gap_columns: the set's plate terms
and stops read an extra state column xg_<set> = xs_z - sign dg / L_z of the compiled code model)
against the B-source .lib, which reads the same shift exactly (netgen.emit.process), at three dg
across the range, on the piston of examples/piston_process.toml, in ngspice 39 as installed (the
code model is built for it).

- .op at 2 V on the drive electrode: both forms solve the same equations (the same fit, clamp and
  scaling); each stops Newton at reltol 1e-6 / vntol 1e-12 on x_z (um, up to 0.25 here): the two
  roots within twice that bound, 2 (1e-6 * 0.25 + 1e-12) um = 5e-13 m, taken as 1e-12 m.
- .ac from f_z to x_z at the same bias: 1/H = k_eff - m w^2 + i w b; k_eff = k - dF/dz depends on
  the operating point through the electrostatic spring eps A V^2 / (g + dg - z)^3, whose relative
  change over the deflection's Newton error (5e-13 m over g - z >= 1.8 um) is 3 x 3e-7 = 1e-6 of
  the electrostatic part: 1e-6.
- the contact stop with dg: the plate pushed onto the electrode by 10 uN rests where the .lib's
  does (tests/emit/test_process_stops.py checks the .lib against the balance), within the same
  Newton bound on x_z (about 2.3 um): 1e-11 m.
"""

from __future__ import annotations

import numpy as np
import pytest

from netgen.structure import load_structure
from tests.fixtures import ROOT
from tests.fixtures import shared_model as build_model
from tests.oracles.process_forms import libs, run

DGS = (-2e-7, 0.0, 3e-7)


@pytest.fixture(scope="module")
def model():
    return build_model(load_structure(ROOT / "examples/piston_process.toml"))


@pytest.mark.parametrize("dg", DGS)
def test_xspice_deflection_and_ac_match_the_lib(model, tmp_path, dg):
    forms = libs(model, tmp_path)
    got = {}
    for form, inc in forms.items():
        op = run(inc, dg, "2", "DC 0\n.op", tmp_path / f"op_{form}")
        ac = run(inc, dg, "2", "DC 0 AC 1\n.ac lin 3 5k 30k", tmp_path / f"ac_{form}")
        w = 2 * np.pi * np.real(ac["frequency"])
        inv = 1.0 / ac["v(xz)"]
        (k, m), *_ = np.linalg.lstsq(np.stack([np.ones_like(w), -(w**2)], axis=1), inv.real, rcond=None)
        got[form] = (float(op["v(xz)"].real[0]) * 1e-6, k, m)
    assert got["xspice"][0] == pytest.approx(got["lib"][0], abs=1e-12)
    assert got["lib"][0] < -1e-8  # the bias pulls the plate down: dg matters
    assert got["xspice"][1] == pytest.approx(got["lib"][1], rel=1e-6, abs=0)
    assert got["xspice"][2] == pytest.approx(got["lib"][2], rel=1e-9, abs=0)


@pytest.mark.parametrize("dg", DGS)
def test_xspice_stop_follows_dg(model, tmp_path, dg):
    forms = libs(model, tmp_path)
    z: dict[str, float] = {}
    for form, inc in forms.items():
        z[form] = float(run(inc, dg, "0", "DC -10\n.op", tmp_path / form)["v(xz)"].real[0]) * 1e-6
    assert z["xspice"] == pytest.approx(z["lib"], abs=1e-11)
    assert -z["lib"] > 2e-6 + dg  # on the shifted stop
