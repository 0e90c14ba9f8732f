"""tscale and etch together on accelerometer_xyz's own field2d combs in the emitted forms: each comb's C
times three state factors, the etch one (u = etch / 1 um), the tscale one (tscale - 1) and the cross
factor 1 + (tscale - 1) (u Q1(xs) + u^2 Q2(xs)) (netgen.model.etch_state.cross_laws; nodes pr_<e>_<kind>
and their product pr_<e> in the .lib and the _xspice.lib, variables in the .va, STATE_KIND rows in the
FMU), at the corner (0.9, -0.1 um) where the cross factor is largest, at a displaced state (the factors
are 1 at rest): the .lib in ngspice 39 and 46, the _xspice.lib (ngspice 39), the .va through OSDI
(ngspice 46) and in VACASK, and the FMU.

Tolerances (tests/emit/test_process_etch_field2d_forms.py's helpers and bounds, derived there):
- xp_t's C at the displaced state from .ac without bias against the Python law
  (netgen.model.process.capacitance_at, the arithmetic the forms render): round-off, 1e-9 (FMU 1e-12).
- the forces on x, y, rot_z with 5 V on xp_t against a five-point difference of the law's C, F2D_TOL
  (4.2e-11: the difference's truncation h^4/30 |C^(5)| / |C'| for the same comb fits and state, which
  the factors, 1 to within 1e-2 and quadratic in xs, leave to within that; its round-off 9.8e-12 from
  the fit's 28 terms, the factors' 2 x 28 more products adding under 1e-12; the .op's 1e-12); the law
  without the factors is seen (1e3 x F2D_TOL off), and so is the cross factor alone
  (test_cross_factor_is_seen: the forms' check would catch it missing).
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from netgen.emit import ngspice as emit_ngspice
from netgen.sim.ngspice import run_ngspice
from netgen.structure import parse_structure
from netgen.testbench.sigma_delta import ngspice as sdn
from tests.emit.test_process_etch_field2d_forms import (
    F2D_TOL,
    OUT_OF_PLANE,
    VOLTS,
    check_state,
    check_state_fmu,
    check_state_vacask,
    law_slopes,
    state_deck,
)
from tests.fixtures import NGSPICE
from tests.fixtures import shared_model as build_model
from tests.oracles.process_cases import control_block, osdi_form, xyz_text

POINT = {"tscale": 0.9, "etch": -1e-7}  # the corner where the plain product is 4.3e-3 off


@pytest.fixture(scope="module")
def xyz():
    """accelerometer_xyz with its field2d combs and tscale and etch declared (the cross cells' tables ship)."""
    text = xyz_text(process='[process]\nparameters = ["tscale", "etch"]\n')
    return build_model(parse_structure(text.replace('comb_model = "textbook"', 'comb_model = "field2d"'), "xyz.toml"))


def test_cross_factor_is_seen(xyz):
    """The law's slopes at the displaced state with and without the cross factors differ by far more
    than the forms' check F2D_TOL (else a form that dropped it would pass)."""
    other = copy.deepcopy(xyz)
    for r in other.process["etch"]["capacitance"]:
        r.pop("cross", None)
    xs = np.array([0.03, -0.02, 0.04] + list(OUT_OF_PLANE.values()))
    with_it, without = (0.5 * VOLTS**2 * law_slopes(m, xs, 0.0, param=POINT)[:3] for m in (xyz, other))
    assert np.max(np.abs(with_it - without)) > 1e3 * F2D_TOL * np.max(np.abs(with_it))


def test_state_lib(xyz, tmp_path, ngspice_version):
    (tmp_path / "xyz.lib").write_text(emit_ngspice.subcircuit(xyz))

    def run(xs, bias):
        return run_ngspice(
            state_deck(str(tmp_path / "xyz.lib"), xyz, 0.0, xs, bias, param=POINT), tmp_path / f"r{bias}"
        )

    check_state(xyz, run, 0.0, POINT)


def test_state_xspice(xyz, tmp_path):
    xlib, control = sdn.xspice_library(xyz, tmp_path, sdn.code_models(False))

    def run(xs, bias):
        deck = state_deck(str(xlib.resolve()), xyz, 0.0, xs, bias, control_block(control, "s.raw"), param=POINT)
        return run_ngspice(deck, tmp_path / f"r{bias}")

    check_state(xyz, run, 0.0, POINT)


def test_state_osdi(xyz, tmp_path, monkeypatch):
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    inc, pre = osdi_form(xyz, tmp_path)

    def run(xs, bias):
        deck = state_deck(inc, xyz, 0.0, xs, bias, control_block(pre, "s.raw"), param=POINT)
        return run_ngspice(deck, tmp_path / f"r{bias}")

    check_state(xyz, run, 0.0, POINT)


def test_state_fmu(xyz):
    """The FMU at the displaced state: charge (1e-12) and forces (F2D_TOL) against the law."""
    check_state_fmu(xyz, 0.0, POINT)


def test_state_vacask(xyz, tmp_path):
    """The .va module in VACASK at the point: the forces with 5 V on xp_t against the law's slopes (F2D_TOL)."""
    check_state_vacask(xyz, tmp_path, 0.0, POINT)
