"""Comb-finger electrodes (netgen.electrostatics.comb, comb_model = "textbook"): the extractor
against the parallel-plate closed forms of a finger array, the fit and the emitted model in
ngspice against (1/2) V^2 dC/dx, and the side instability of a lateral comb in an ngspice DC
sweep against V = sqrt(k g^3 / (2 eps n t L))."""

from __future__ import annotations

import math

import numpy as np
import pytest

from netgen.build import build
from netgen.emit import ngspice as emit_ngspice
from netgen.sim.ngspice import run_ngspice
from netgen.structure import parse_structure
from tests.fixtures import NGSPICE, Bench
from tests.oracles.lateral_comb import L0, LATERAL, G, K, N, T

EPS0 = 8.8541878188e-12  # vacuum permittivity, F/m (CODATA 2022, NIST)


@pytest.fixture(scope="module")
def lateral():
    return build(parse_structure(LATERAL, "comb.toml"))


def test_comb_extractor_against_the_parallel_plate_closed_forms(lateral):
    """Lateral comb: C = 2 n eps t (L0 + x) / g along the fingers and
    n eps t L0 (1/(g - y) + 1/(g + y)) across them; a transverse face alone n eps t L0 / (g - y)."""
    p = lateral.prepared
    x = np.linspace(-5e-6, 5e-6, 7)
    q = np.stack([x, 0 * x], axis=1)
    assert np.allclose(p.capacitance(q)[:, 0], 2 * N * EPS0 * T * (L0 + x) / G, rtol=1e-12)
    y = np.linspace(-0.6e-6, 0.6e-6, 7)
    q = np.stack([0 * y, y], axis=1)
    assert np.allclose(p.capacitance(q)[:, 0], N * EPS0 * T * L0 * (1 / (G - y) + 1 / (G + y)), rtol=1e-12)
    assert np.allclose(p.gradient(np.zeros(2))[0], [2 * N * EPS0 * T / G, 0.0], rtol=1e-6, atol=1e-15)
    scales = [c.scale for c in lateral.model.coordinates]
    assert scales == pytest.approx([20e-6, G], rel=1e-9, abs=0)  # tip clearance, finger gap


def test_fitted_force_along_the_fingers_in_ngspice(lateral, tmp_path):
    """The fitted model's dC/dx within 1 % of 2 n eps t / g, and ngspice's static deflection
    under V on the comb gives k x = (1/2) V^2 dC/dx of the Python model within 0.5 %."""
    model = lateral.model
    x0 = np.zeros((1, 2))
    assert model.capacitance_gradient(x0)[0, 0, 0] == pytest.approx(2 * N * EPS0 * T / G, rel=0.01, abs=0)
    lib = tmp_path / "comb.lib"
    lib.write_text(emit_ngspice.subcircuit(model))
    v = 30.0  # below the side instability (43 V)
    bench = Bench(model, lib, sources={"drive": f"DC {v}", "plate": "0"})
    plot = run_ngspice(bench.netlist(".op"), tmp_path)[0]
    xs = float(plot["x1.xs_x"][0])
    force = 0.5 * v**2 * model.capacitance_gradient(np.array([[xs, 0.0]]))[0, 0, 0]
    assert K * xs * model.coordinates[0].scale == pytest.approx(force, rel=0.005, abs=0)
    assert xs > 1e-3  # the comb pulls the fingers in


@pytest.mark.parametrize("release", ["39", "46"])
def test_side_instability_in_an_ngspice_dc_sweep(tmp_path, release, monkeypatch):
    """A lateral comb held off centre across its fingers by a small force (1e-6 g of static offset):
    in the ngspice DC sweep of its voltage the sideways compliance y / f diverges, and y changes sign
    through infinity, at V = sqrt(k g^3 / (2 eps n t L)) within 0.5 %; the fold of the symmetric comb is
    there (a DC sweep follows the unstable centred branch beyond it, so there is no jump to read).
    The same voltage from a straight-line fit of 1/y against V^2 (y = y0 / (1 - V^2 / V_PI^2)).
    Only y is a coordinate: 1/C = (g^2 - y^2) / (2 n eps t L g) is then a polynomial the fit holds
    exactly (with x too, 1/C is rational in x and a degree-3 fit misses the curvature in y by ~2 %)."""
    from netgen.sim import ngspice as sim_ngspice

    monkeypatch.setenv(sim_ngspice.ENV, NGSPICE[release])
    model = build(parse_structure(LATERAL.replace('rigid = ["x", "y"]', 'rigid = ["y"]'), "comb.toml")).model
    v_ref = math.sqrt(K * G**3 / (2 * EPS0 * N * T * L0))
    lib = tmp_path / "comb.lib"
    lib.write_text(emit_ngspice.subcircuit(model))
    nudge = 1e-6 * G * K / 1e-6  # uN: a 1e-6 g static offset
    bench = Bench(model, lib, sources={"drive": "DC 0", "plate": "0", "f_y": f"DC {nudge!r}"})
    v_max, points = 1.02 * v_ref, 2040
    plot = run_ngspice(bench.netlist(f".dc Vdrive 0 {v_max!r} {v_max / points!r}"), tmp_path)[0]
    v, y = plot["v-sweep"], plot["x1.xs_y"]
    flips = np.flatnonzero((y[:-1] > 0) & (y[1:] < 0))
    assert len(flips), "the sideways compliance does not diverge inside the sweep"
    j = int(flips[0])
    assert 0.5 * (v[j] + v[j + 1]) == pytest.approx(v_ref, rel=0.005)
    low = v < 0.9 * v_ref
    slope, intercept = np.polyfit(v[low] ** 2, 1 / y[low], 1)
    assert math.sqrt(-intercept / slope) == pytest.approx(v_ref, rel=0.005)
