"""The fitted strain energy under the process parameters (netgen.model.process.energy_law, the factor
pu of netgen.emit.process): the clamped-clamped beam of examples/cc_beam.toml with tscale and escale,
its mid-plane stretching energy U = E w t (int w'^2 / 2)^2 / 2L (so pu = escale tscale for shapes
independent of t: no residual stress here), in the .lib (ngspice 39), the .va through OSDI (ngspice 46)
and the FMU.

Reference: a second build with the thickness and the modulus scaled (no [process]); its static
deflection under FORCE on f_m1 (no voltage), K q + dU/dq = F solved by scipy's fsolve (xtol 1e-13).
FORCE deflects m1 by 0.97 um linear, half the thickness: the linear deflection is 3 to 36 % off over
the cases and the energy unscaled 0.5 to 12 % (bench/process_terms.py; both asserted well outside).

Tolerances: a relative error eps_K in K and eps_U in U moves the deflection by at most eps_K + eps_U
relative (both restoring forces grow with it), the laws' stated errors; ngspice's Newton at reltol
1e-10 (vntol 1e-12 V on um-valued nodes: 1e-12 relative to the 0.97 um, above the velocity
nodes' rounding floor of a few 1e-15 V that 1e-16 lay under, docs/contact.md) and fsolve's 1e-13: 2e-10
together. FMU (model exchange):
at the reference's rest state the acceleration times M over FORCE is the relative force residual, the
same eps_K + eps_U plus fsolve's 1e-13 and round-off 1e-14.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import fsolve

from netgen.emit import ngspice as emit_ngspice
from netgen.emit import osdi
from netgen.sim import fmu
from netgen.sim.ngspice import run_ngspice
from netgen.structure import parse_structure
from tests.fixtures import shared_model as build_model
from tests.oracles.process_energy import CASES, FORCE, PROCESS, bound, rest, text
from tests.oracles.testbench import using_ngspice


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The model with tscale and escale, its .lib, and the rebuilt references."""
    folder = tmp_path_factory.mktemp("energy")
    model = build_model(parse_structure(text() + PROCESS, "cc_beam.toml"))
    (folder / "cc_beam.lib").write_text(emit_ngspice.subcircuit(model))
    (folder / "cc_beam_osdi.lib").write_text(osdi.subcircuit(model))
    (folder / "cc_beam.osdi").write_bytes(osdi.outputs(model)[".osdi"])
    refs = {case: build_model(parse_structure(text(*case), "cc_beam.toml")) for case in CASES}
    return model, folder, refs


@pytest.mark.parametrize("form", ("lib", "osdi"))
@pytest.mark.parametrize("case", CASES, ids=[f"t{t:g}-e{e:g}" for t, e in CASES])
def test_static_deflection_against_the_rebuild(built, tmp_path, case, form):
    """The .op deflection of m1 under FORCE at (tscale, escale) in the .lib and the .va (OSDI) against
    the rebuilt beam's."""
    model, folder, refs = built
    ctl = f".control\npre_osdi {folder / 'cc_beam.osdi'}\nset num_threads=1\nrun\nwrite out.raw\n.endc"
    net = f"""* stretching at {case}
.include {folder / ("cc_beam.lib" if form == "lib" else "cc_beam_osdi.lib")}
X1 0 0 f1 x1 0 x2 0 x3 cc_beam tscale={case[0]!r} escale={case[1]!r}
Vf f1 0 DC {FORCE * 1e6!r}
.options reltol=1e-10 vntol=1e-12
.op
{ctl if form == "osdi" else ""}
.end
"""
    with using_ngspice("39" if form == "lib" else "46"):  # OSDI: ngspice 46
        got = float(run_ngspice(net, tmp_path)[0]["v(x1)"].real[0]) * 1e-6
    want = rest(refs[case])[0]
    assert abs(got / want - 1.0) <= bound(model) + 2e-10, (got, want)
    ref = refs[case]
    linear = rest(ref, energy=0.0)[0]
    assert abs(linear / want - 1.0) > 0.02  # stretching matters at this load
    # the energy unscaled (pu = 1) would be off by far more than the tolerance
    unscaled = fsolve_unscaled(ref, model)
    assert abs(unscaled / want - 1.0) > 1e3 * (bound(model) + 2e-10)


def fsolve_unscaled(ref, model) -> float:
    """m1's deflection with the rebuild's K and the nominal model's energy (the model before the law)."""
    k = np.array([c.stiffness for c in ref.coordinates])
    scale = np.array(model.scales)
    f = np.zeros(len(k))
    f[0] = FORCE
    sol = fsolve(lambda q: (k * q - model.nonlinear_force((q / scale)[None, :])[0] - f) / FORCE, f / k, xtol=1e-13)
    return float(sol[0])


@pytest.mark.parametrize("case", CASES, ids=[f"t{t:g}-e{e:g}" for t, e in CASES])
def test_fmu_force_balance_at_the_rebuilds_rest(built, case):
    """The FMU's accelerations at the rebuilt beam's rest state vanish to the laws' error."""
    model, _, refs = built
    q = rest(refs[case])
    inst = fmu.Instance(fmu.built(model), cosim=False)
    inst.set({"tscale": case[0], "escale": case[1], "f_m1": FORCE})  # the FMU's inputs are SI
    inst.start()
    inst.set_states(np.concatenate([q, np.zeros_like(q)]))
    acc = np.array(inst.get([f"qdd_{c.name}" for c in model.coordinates]))
    inst.close()
    mass = np.array([c.mass for c in refs[case].coordinates])
    assert np.max(np.abs(acc * mass)) / FORCE <= bound(model) + 1e-13 + 1e-14, acc
