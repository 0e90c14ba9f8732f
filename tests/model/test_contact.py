"""Pull-in and contact (netgen/model/contact.py): a plate driven into the stop comes to rest there.

- the clamp of the plate terms is the identity in the fitted range, C1, bounded by its floor;
- the stop points make every lone coordinate stop at exactly its touching amplitude xs = +-1;
- 20 V on the upper electrode set (a free plate has no restoring spring, so its pull-in
  voltage is 0 and any bias pulls it in): ngspice and VACASK runs finish and the plate rests
  at the static balance of clamped electrostatic force and penalty spring, which the Python
  model gives independently (scipy root), within 0.2 % of the gap of touch-down.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from netgen.model import MacroModel, contact
from netgen.sim.ngspice import ENV, run_ngspice
from netgen.sim.vacask import VacaskBench, compile_va, run_vacask
from tests.fixtures import EMISSIONS, NGSPICE, ROOT, Bench, emission_id, emitted_library, states

NETLISTS = ROOT / "netlists"
VOLTS = 20.0
STOP = 30e-6  # the plate reaches the stop after about 21 us


@pytest.fixture(scope="module")
def model() -> MacroModel:
    return MacroModel.load_json(NETLISTS / "levitated_disk.json")


def _drive(model: MacroModel) -> np.ndarray:
    return np.array([VOLTS if e.name.startswith("top") else 0.0 for e in model.electrodes])


def test_clamp_is_identity_above_the_knee_c1_and_bounded():
    knee, floor = 0.1, 0.04
    p = np.linspace(-5, 5, 200001)
    pe, slope = contact.clamp(p, knee, floor)
    above = p >= knee
    np.testing.assert_array_equal(pe[above], p[above])
    assert np.all(pe >= floor) and np.all(np.diff(pe) >= 0)
    numeric = np.gradient(pe, p)
    assert np.abs(numeric - slope)[1:-1].max() < 1e-3  # slope is dP_eff/dP, continuous
    pen, w = contact.penetration(p, 0.1)
    assert np.all(pen[p <= 0] == 0) and np.abs(np.gradient(pen, p) - w)[1:-1].max() < 1e-3


def test_model_unchanged_in_the_sampled_box(model):
    """No clamp or stop is active anywhere in the fitted box: forces equal the raw 1/P fit."""
    rng = np.random.default_rng(5)
    x = rng.uniform(-model.sampling["range"], model.sampling["range"], (300, model.ncoords))
    raw = np.stack([f.value(x) for f in model.capacitances], axis=-1)
    np.testing.assert_allclose(model.capacitance(x), raw, rtol=1e-14)
    assert all(not np.any(model.contact_force(xi, np.ones(model.ncoords))) for xi in x)


def test_lone_coordinates_stop_at_their_touching_amplitude(model):
    a = np.array([p["a"] for p in model.contact["points"]])
    np.testing.assert_allclose(a.max(axis=0), 1.0, rtol=1e-9)
    np.testing.assert_allclose(a.min(axis=0), -1.0, rtol=1e-9)
    assert len(a) < 100  # a compact stop set


def _rest_reference(model: MacroModel, x_end: np.ndarray) -> float:
    """xs_z where clamped electrostatic pull and contact push balance (other coordinates as simulated)."""

    def net(z: float) -> float:
        x = x_end.copy()
        x[0] = z
        return model.electrostatic_force(x, _drive(model), 0.0)[0][0] + model.contact_force(x, np.zeros_like(x))[0]

    return brentq(net, 1.0, 1.05, xtol=1e-12)


def _check_rest(model: MacroModel, time: np.ndarray, x: np.ndarray) -> None:
    rest = time > STOP - 5e-6
    assert np.isfinite(x).all()
    z_ref = _rest_reference(model, x[-1])
    assert 1.0 < z_ref < 1.002  # touch-down + tiny penetration
    assert np.abs(x[rest, 0] - z_ref).max() < 1e-4  # at rest, on the static balance
    # the plate rests on the few stop points of the upper side: the undamped modes ring and the
    # tilts follow at a few 1e-3 of their touching amplitudes, never more than 1 %
    assert np.abs(x[rest, 1:]).max() < 1e-2


@pytest.mark.parametrize("release, style", EMISSIONS, ids=[emission_id(e) for e in EMISSIONS])
def test_ngspice_plate_pulled_in_rests_at_the_stop(model, release, style, tmp_path, monkeypatch):
    """Both ngspice emissions: B-sources, and the clamp and stops inside the netgen_es code model;
    the .lib in ngspice 39 and 46."""
    monkeypatch.setenv(ENV, NGSPICE[release])
    lib, control = emitted_library(model, style, tmp_path, NETLISTS / "levitated_disk.lib")
    sources = {e.name: f"DC {VOLTS}" for e in model.electrodes if e.name.startswith("top")} | {"plate": "0"}
    bench = Bench(model, lib, sources=sources, options="reltol=1e-4 chgtol=1e-18", control=control)
    plot = run_ngspice(bench.netlist(f".tran 100n {STOP} 0 100n uic"), tmp_path)[0]
    x, _ = states(plot, model)
    assert plot["time"][-1] == pytest.approx(STOP)  # the run finished
    _check_rest(model, plot["time"], x)


def test_vacask_plate_pulled_in_rests_at_the_stop(model, tmp_path):
    osdi, _ = compile_va(NETLISTS / "levitated_disk.va", tmp_path / "levitated_disk.osdi")
    sources = {e.name: f"dc={VOLTS}" for e in model.electrodes if e.name.startswith("top")} | {"plate": "dc=0"}
    bench = VacaskBench(model, osdi, sources=sources)
    plot = run_vacask(bench.netlist(f'analysis tran1 tran step=100n stop={STOP} maxstep=100n icmode="uic"'), tmp_path)
    x = np.stack([plot[f"x1:xs_{c.name}"] for c in model.coordinates], axis=-1)
    assert plot["time"][-1] == pytest.approx(STOP)
    _check_rest(model, plot["time"], x)
