"""accelerometer_xyz's own (2-D cell, field2d) combs under etch in the emitted forms: the .lib (ngspice
39 and 46), the _xspice.lib (netgen_es code model, ngspice 39) and the .va through OSDI (ngspice 46).
Each comb's fit is read at the state shifted by the geometric 2 etch plus a fitted effective part
across its fingers (netgen.model.etch_combs); its contact stops follow the geometric shift alone
(stop_shift: nodes of their own in the code model, offsets in the .lib and the .va).

Tolerances:
- comb xp_t's C at rest from .ac of its current (no bias: no force, the mass still) against the Python
  law (netgen.model.process.capacitance_at, the arithmetic the emitters render): the forms evaluate
  the same polynomial at the same shifted state, round-off: 1e-9.
- xp_t's sidewall stop at rest in the .lib: its penetration node reads -(1.5 um + 2 etch) / 1.5 um
  (the geometric shift, not the effective one, which would put it 0.14 etch nearer), within STOP_REL
  (1e-11: the offset read to 11 digits); the mass pushed onto it at the model's rest (rest_exact),
  the .lib within REST_REL (2.5e-10: its B-source coefficients read to 11 digits), the _xspice.lib,
  OSDI and VACASK (at its default tolerances: the rest is where every element is linear) within
  FULL_REL (1e-12); the mechanics and stops are the textbook case's, so are the derivations in
  tests/emit/test_process_etch_forms.py, next to the constants.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from netgen import emit
from netgen.build import build_model
from netgen.emit import ngspice as emit_ngspice
from netgen.model.process import capacitance_at
from netgen.sim.ngspice import run_ngspice
from netgen.structure import parse_structure
from netgen.testbench.sigma_delta import ngspice as sdn
from tests.emit.test_process_etch_forms import (
    FULL_REL,
    REST_REL,
    STOP_REL,
    comb_deck,
    push_deck,
    rest_exact,
    rest_x,
    sidewall_stop,
    vacask_rest,
)
from tests.fixtures import NGSPICE
from tests.oracles.process_cases import PERFORATED_ETCHES, control_block, xyz_text


@pytest.fixture(scope="module")
def xyz():
    """accelerometer_xyz with its field2d combs and etch declared (the etched cells' tables ship)."""
    text = xyz_text(process='[process]\nparameters = ["etch"]\n').replace(
        'comb_model = "textbook"', 'comb_model = "field2d"'
    )
    return build_model(parse_structure(text, "xyz.toml"))


def check_rest(xyz, plot, etch: float) -> None:
    """xp_t's C at rest against the Python law (round-off)."""
    cap = abs(float(np.imag(plot["i(vp)"])[0])) / (2 * math.pi * 1e3)
    k = [f.electrode for f in xyz.capacitances].index("xp_t")
    assert cap == pytest.approx(capacitance_at(xyz, np.zeros((1, xyz.ncoords)), etch)[0, k], rel=1e-9, abs=0)


def test_law_has_effective_shift(xyz):
    """The case exercises what the forms must render apart: a fitted shift beside the stops' geometric one."""
    law = next(r for r in xyz.process["etch"]["capacitance"] if r["electrode"] == "xp_t")
    assert law["stop_shift"] == {"x": -2.0, "y": -2.0} and law["shift"]["x"] != -2.0


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_rest_lib(xyz, tmp_path, ngspice_version, etch):
    (tmp_path / "xyz.lib").write_text(emit_ngspice.subcircuit(xyz))
    check_rest(xyz, run_ngspice(comb_deck(str(tmp_path / "xyz.lib"), etch), tmp_path)[0], etch)


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_rest_xspice(xyz, tmp_path, etch):
    xlib, control = sdn.xspice_library(xyz, tmp_path, sdn.code_models(False))
    check_rest(
        xyz, run_ngspice(comb_deck(str(xlib.resolve()), etch, control_block(control, "ac.raw")), tmp_path)[0], etch
    )


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_rest_osdi(xyz, tmp_path, monkeypatch, etch):
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    emit.write_outputs(xyz, tmp_path, "osdi")
    pre = [f"pre_osdi {tmp_path / 'accelerometer_xyz.osdi'}"]
    deck = comb_deck(str(tmp_path / "accelerometer_xyz_osdi.lib"), etch, control_block(pre, "ac.raw"))
    check_rest(xyz, run_ngspice(deck, tmp_path / "run")[0], etch)


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_stop_lib(xyz, tmp_path, ngspice_version, etch):
    """xp_t's sidewall stop at rest at the geometric widened gap (STOP_REL)."""
    (tmp_path / "xyz.lib").write_text(emit_ngspice.subcircuit(xyz))
    plot = run_ngspice(push_deck(str(tmp_path / "xyz.lib"), etch, push=0.0), tmp_path)[0]
    sg = float(np.real(plot[f"v(x1.sg_{sidewall_stop(xyz) + 1})"])[0])
    assert sg == pytest.approx(-(1.5e-6 + 2 * etch) / 1.5e-6, rel=STOP_REL, abs=0)


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_stop_pushed_lib(xyz, tmp_path, ngspice_version, etch):
    """The .lib pushed onto the stop rests at rest_exact (REST_REL: its 11-digit coefficients)."""
    (tmp_path / "xyz.lib").write_text(emit_ngspice.subcircuit(xyz))
    got = rest_x(run_ngspice(push_deck(str(tmp_path / "xyz.lib"), etch), tmp_path)[0])
    assert got == pytest.approx(rest_exact(xyz, etch), rel=REST_REL, abs=0)


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_stop_xspice(xyz, tmp_path, etch):
    """The code model's stops read their own geometric-shift columns: rest_exact in ngspice 39 (FULL_REL)."""
    xlib, control = sdn.xspice_library(xyz, tmp_path, sdn.code_models(False))
    got = rest_x(run_ngspice(push_deck(str(xlib.resolve()), etch, control_block(control, "op.raw")), tmp_path)[0])
    assert got == pytest.approx(rest_exact(xyz, etch), rel=FULL_REL, abs=0)


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_stop_osdi(xyz, tmp_path, monkeypatch, etch):
    """The .va through OSDI (ngspice 46) pushed rests at rest_exact (FULL_REL)."""
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    emit.write_outputs(xyz, tmp_path, "osdi")
    pre = [f"pre_osdi {tmp_path / 'accelerometer_xyz.osdi'}"]
    deck = push_deck(str(tmp_path / "accelerometer_xyz_osdi.lib"), etch, control_block(pre, "op.raw"))
    got = rest_x(run_ngspice(deck, tmp_path / "run")[0])
    assert got == pytest.approx(rest_exact(xyz, etch), rel=FULL_REL, abs=0)


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_stop_vacask(xyz, tmp_path, etch):
    """The same module in VACASK (its default tolerances: the rest is where every element is linear,
    tests/emit/test_process_etch_forms.test_comb_stop_vacask) rests at rest_exact (FULL_REL)."""
    assert vacask_rest(xyz, tmp_path, etch) == pytest.approx(rest_exact(xyz, etch), rel=FULL_REL, abs=0)
