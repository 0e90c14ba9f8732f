"""The rotating-frame terms under the thickness scale tscale (netgen.model.process_loads.inertial_law,
netgen.emit.process.inertial_scale), in the .lib (ngspice 39), the .va through OSDI (ngspice 46) and the FMU: a
proof mass on crab legs over one plate, coordinates z, tilt_x, tilt_y, rate ports w_x, w_y, w_z.
Its Coriolis coupling of the tilts under w_z is the plate's rotary inertia, G_z[tilt_x, tilt_y] =
-2 rho t^3 A / 12: a t^3 law that the mass law (t for the translation) does not give.

Reference: a second build of the structure with the thickness scaled (no [process]): its masses,
stiffnesses, damping and inertial tables (netgen.mechanics.inertial re-run at that thickness).
- .lib and .va (.ac at w_z = OMEGA DC, a torque on tilt_y): the tilts' response solves
  (K - w^2 M + i w D + i w OMEGA G_z + OMEGA^2 S_zz) q = F, the rebuilt model's matrices; the
  cross response x_tilt_x / f_tilt_y is OMEGA G_z over the two diagonal terms, so its relative error
  is G's (exact: 0) plus the diagonal terms' (the laws' stated error eps each, K dominating 1/(1 -
  (f/f0)^2) <= 1.006 at 2 kHz against the tilts' 26 and 84 kHz) plus the complex LU solve's
  round-off (condition ~ K_x / K_y ~ 10 at O(1) node values: 1e-14, held to 1e-9 for ngspice's
  pivoting and the .va's expressions): 2.1 eps + 1e-9.
- FMU (model exchange): at q = 0 and tilt_y's velocity V0, tilt_x's acceleration is -OMEGA G_z V0 /
  M_x: the mass law's error (eps bounds it; the law t + t^3 is exact here) plus round-off: eps + 1e-12.
The unscaled coupling (the model's before the law) is off by tscale^3 - 1 (27 % at 0.9): asserted
far outside the tolerance.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from netgen.emit import ngspice as emit_ngspice
from netgen.emit import osdi
from netgen.sim import fmu
from netgen.sim.ngspice import run_ngspice
from netgen.structure import parse_structure
from tests.fixtures import shared_model as build_model
from tests.oracles.process_inertial import FREQ, OMEGA, PROCESS, SI, T_UM, TSCALES, V0, netlist, reference_ac, structure
from tests.oracles.testbench import using_ngspice


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The model with tscale, its .lib, _osdi.lib and .osdi, and the rebuilt references."""
    folder = tmp_path_factory.mktemp("inertial")
    model = build_model(parse_structure(structure(T_UM) + PROCESS, "gyp.toml"))
    (folder / "gyp.lib").write_text(emit_ngspice.subcircuit(model))
    (folder / "gyp_osdi.lib").write_text(osdi.subcircuit(model))
    (folder / "gyp.osdi").write_bytes(osdi.outputs(model)[".osdi"])
    refs = {t: build_model(parse_structure(structure(T_UM * t), "gyp.toml")) for t in TSCALES}
    return model, folder, refs


def law_error(model) -> float:
    return model.process["tscale"]["max_rel_error"]


@pytest.mark.parametrize("form", ("lib", "osdi"))
@pytest.mark.parametrize("tscale", TSCALES)
def test_coriolis_coupling_follows_the_rebuild(built, tmp_path, form, tscale):
    """The .ac cross response of the tilts under w_z in the .lib and the .va (OSDI) against the
    rebuilt model's (tolerance in the module docstring)."""
    model, folder, refs = built
    if form == "lib":
        text = netlist(str(folder / "gyp.lib"), tscale, "")
    else:
        ctl = f".control\npre_osdi {folder / 'gyp.osdi'}\nset num_threads=1\nrun\nwrite out.raw\n.endc"
        text = netlist(str(folder / "gyp_osdi.lib"), tscale, ctl)
    with using_ngspice("39" if form == "lib" else "46"):  # OSDI: ngspice 46
        got = complex(run_ngspice(text, tmp_path)[0]["v(xtx)"][0]) * SI
    want = reference_ac(refs[tscale], 2 * math.pi * FREQ)
    err = abs(got / want - 1.0)
    assert err <= 2.1 * law_error(model) + 1e-9, (got, want)
    assert abs(tscale**3 - 1.0) > 1e3 * (2.1 * law_error(model) + 1e-9)  # the unscaled G would fail


@pytest.mark.parametrize("tscale", TSCALES)
def test_fmu_coriolis_acceleration(built, tscale):
    """The FMU's tilt_x acceleration at tilt_y's velocity V0 under w_z = OMEGA against -OMEGA G V0 / M
    of the rebuilt model (tolerance in the module docstring)."""
    model, _, refs = built
    ref = refs[tscale]
    names = [c.name for c in ref.coordinates]
    x, y = names.index("tilt_x"), names.index("tilt_y")
    inst = fmu.Instance(fmu.built(model), cosim=False)
    inst.set({"tscale": tscale, "w_z": OMEGA})
    inst.start()
    state = np.zeros(2 * len(names))
    state[len(names) + y] = V0
    inst.set_states(state)
    got = float(inst.get(["qdd_tilt_x"])[0])
    inst.close()
    want = -OMEGA * ref.inertial.gyroscopic["z"][x][y] * V0 / ref.coordinates[x].mass
    assert abs(got / want - 1.0) <= law_error(model) + 1e-12, (got, want)
