"""The contact stop follows the gap offset (netgen.emit.process.stop_offsets): with dg_drive the
piston of examples/piston_process.toml, pushed through its force port past the electrode, comes to
rest at the stop moved by dg, in a static run of the .lib (ngspice 39 and 46) and of the .va
through OSDI (ngspice 46).

Reference: the static balance -k z + F + k_c g pen(p) = 0 with the electrode's surface at
z = -(g + dg): p = (-z - g - dg) / g the penetration as a fraction of the gap and pen the C1 penalty
ramp of netgen.model.contact (written out here from its definition), k = 2 N/m and g = 2 um from the
structure file, k_c and the ramp's width from the model's contact record; no voltage (the plate
terms play no part). F = -10 uN pushes 3 um of spring travel plus a penetration of 1 % of the gap's
worth of k_c, so every dg in range meets the stop in the penalty's linear part.
Tolerance: the .op's Newton stopping test at reltol 1e-6 and vntol 1e-12 on x_z (um, about 2.3)
bounds the last step by 2.3e-12 m; 1e-11 m allows four such steps. Without the stop's offset the
plate would rest at the nominal stop, dg (>= 2e-7 m) away: the test tells the two apart by 2e4.
"""

from __future__ import annotations

import pytest

from netgen import emit
from netgen.emit import ngspice as emit_ngspice
from netgen.structure import load_structure
from tests.fixtures import NGSPICE, ROOT
from tests.fixtures import shared_model as build_model
from tests.oracles.process_forms import GAP, op, resting

DGS = (-2e-7, 0.0, 3e-7)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The model, its .lib and `--format osdi` in one folder."""
    model = build_model(load_structure(ROOT / "examples/piston_process.toml"))
    folder = tmp_path_factory.mktemp("process_stops")
    (folder / "piston_process.lib").write_text(emit_ngspice.subcircuit(model))
    emit.write_outputs(model, folder, "osdi")
    return model, folder


@pytest.mark.parametrize("dg", DGS)
def test_lib_rests_on_the_shifted_stop(built, tmp_path, ngspice_version, dg):
    model, folder = built
    z = op(folder, "lib", dg, tmp_path)
    assert z == pytest.approx(resting(model, dg), abs=1e-11)
    assert -z > GAP + dg  # on the stop, pressed into it


@pytest.mark.parametrize("dg", DGS)
def test_osdi_rests_on_the_shifted_stop(built, tmp_path, monkeypatch, dg):
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    model, folder = built
    assert op(folder, "osdi", dg, tmp_path) == pytest.approx(resting(model, dg), abs=1e-11)
