"""The perforated plates' fill shift under etch (netgen.model.etch_fill): accelerometer_xyz's z plates
(examples/accelerometer_xyz with textbook combs, tests/oracles/process_cases.xyz_text) read their fit
at z shifted by k etch (an effective gap change: the holes' fill factor's etch change depends on the
gap), times their ratio pc; their contact stops stay at the drawn gap. Checked against full rebuilds
at the etched sizes and in every emitted form: the .lib (ngspice 39 and 46), the _xspice.lib (ngspice
39), the .va through OSDI (ngspice 46) and the FMU.

References and tolerances:
- the law against the rebuilt model at 100 points of the fit box (the same physical displacements) at
  etch -0.1, 0.04, 0.1 um: each model's fit is within its stated error of the extractor, and the law
  within its stated capacitance error of the extractor at the etched structure, so the bound is the
  sum of the three (the nominal's and the rebuild's fit errors, the law's stated error); the issue's
  acceptance (within the fit tolerance, 1.7e-4 here; the constant ratio alone: 5.3e-4) beside it;
- C of zs at rest from .ac of its current (no DC bias: no force, the mass still) against the
  MacroModel's own law (netgen.model.process.capacitance_at): the forms render its arithmetic; the AC
  solve is linear, the printed coefficients 16-17 digits: 1e-9;
- the FMU's charge of zs at rest under 1 V against the same law: its terms summed in another order,
  1e-12 (tests/emit/test_fmu.py);
- zs's contact stop at rest: its penetration node sg_j = a_j . xs - 1 reads exactly -1 (the stop at
  the drawn gap; an etch shift applied to it would read -1 + k etch / L_z, 3e-3 off at 0.1 um): .op
  round-off, 1e-12.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from netgen.emit import ngspice as emit_ngspice
from netgen.model.process import capacitance_at
from netgen.sim import fmu
from netgen.sim.ngspice import run_ngspice
from netgen.structure import parse_structure
from netgen.testbench.sigma_delta import ngspice as sdn
from tests.fixtures import NGSPICE
from tests.fixtures import shared_model as build_model
from tests.oracles.process_cases import ETCH_PROCESS, PERFORATED_ETCHES, control_block, osdi_form, xyz_text

PROCESS = ETCH_PROCESS


@pytest.fixture(scope="module")
def xyz():
    return build_model(parse_structure(xyz_text(process=PROCESS), "xyz.toml"))


def test_plates_carry_a_fill_shift(xyz):
    """zs below and zt above shift z by opposite amounts, marked fill; the combs keep theirs."""
    laws = {r["electrode"]: r for r in xyz.process["etch"]["capacitance"]}
    assert laws["zs"]["fill"] and laws["zt"]["fill"]
    assert laws["zs"]["shift"]["z"] == pytest.approx(-laws["zt"]["shift"]["z"], rel=1e-9)
    assert laws["zs"]["shift"]["z"] > 0.0  # the wider holes lose relatively more charge at the larger gap
    assert "fill" not in laws["xp_t"]


def test_law_against_rebuilds(xyz):
    """Capacitances at 100 points of the box against the rebuilt models (module docstring)."""
    x = np.random.default_rng(5).uniform(-0.15, 0.15, (100, xyz.ncoords))
    fit = max(f.max_rel_error for f in xyz.capacitances)
    worst = 0.0
    for etch in PERFORATED_ETCHES:
        model = build_model(parse_structure(xyz_text(etch), "xyz.toml"))
        ref = model.capacitance(x * xyz.scales / model.scales)
        err = float(np.max(np.abs(capacitance_at(xyz, x, etch) / ref - 1)))
        bound = (
            fit + max(f.max_rel_error for f in model.capacitances) + xyz.process["etch"]["capacitance_max_rel_error"]
        )
        assert err <= bound, (etch, err, bound)
        worst = max(worst, err)
    assert worst <= fit, worst


def zs_deck(include: str, etch: float, control: str = "") -> str:
    """.ac of zs's current at rest (every other pin at 0 V)."""
    pins = "0 0 0 0 0 0 0 0 d 0 p " + " ".join(f"0 x{k}" for k in range(6)) + " 0 0 0"
    return f"""* zs cap
.include {include}
Vd d 0 DC 0 AC 1
Vp p 0 0
X1 {pins} accelerometer_xyz etch={etch!r}
.ac lin 1 1k 1k
{control}
.end
"""


def check(xyz, plot, etch: float) -> None:
    cap = abs(float(np.imag(plot["i(vp)"])[0])) / (2 * math.pi * 1e3)
    k = [f.electrode for f in xyz.capacitances].index("zs")
    assert cap == pytest.approx(capacitance_at(xyz, np.zeros((1, xyz.ncoords)), etch)[0, k], rel=1e-9, abs=0)


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_lib(xyz, tmp_path, ngspice_version, etch):
    (tmp_path / "xyz.lib").write_text(emit_ngspice.subcircuit(xyz))
    check(xyz, run_ngspice(zs_deck(str(tmp_path / "xyz.lib"), etch), tmp_path)[0], etch)


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_xspice(xyz, tmp_path, etch):
    xlib, control = sdn.xspice_library(xyz, tmp_path, sdn.code_models(False))
    check(xyz, run_ngspice(zs_deck(str(xlib.resolve()), etch, control_block(control, "ac.raw")), tmp_path)[0], etch)


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_osdi(xyz, tmp_path, monkeypatch, etch):
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    inc, pre = osdi_form(xyz, tmp_path)
    deck = zs_deck(inc, etch, control_block(pre, "ac.raw"))
    check(xyz, run_ngspice(deck, tmp_path / "run")[0], etch)


def test_fmu(xyz):
    """The FMU's charge of zs at rest under 1 V against the law (module docstring)."""
    path, k = fmu.built(xyz), [f.electrode for f in xyz.capacitances].index("zs")
    for etch in PERFORATED_ETCHES:
        inst = fmu.Instance(path, cosim=False)  # etch is fixed after initialization: one instance each
        inst.set({"etch": etch, "V_zs": 1.0})
        inst.start()
        inst.set_states(np.zeros(inst.md.numberOfContinuousStates))
        q = float(inst.get(["Q_zs"])[0])
        inst.close()
        assert q == pytest.approx(capacitance_at(xyz, np.zeros((1, xyz.ncoords)), etch)[0, k], rel=1e-12, abs=0)


def test_stop_stays_at_the_drawn_gap(xyz, tmp_path):
    """zs's stop penetration at rest reads -1 at every etch in the .lib (module docstring)."""
    names = [c.name for c in xyz.coordinates]
    pts = xyz.contact["points"]
    j = next(i for i, p in enumerate(pts) if p["electrode"] == "zs" and p["a"][names.index("z")] != 0.0)
    (tmp_path / "xyz.lib").write_text(emit_ngspice.subcircuit(xyz))
    pins = "0 0 0 0 0 0 0 0 0 0 0 " + " ".join(f"0 x{k}" for k in range(6)) + " 0 0 0"
    for etch in PERFORATED_ETCHES:
        net = f"* stop\n.include {tmp_path / 'xyz.lib'}\nX1 {pins} accelerometer_xyz etch={etch!r}\n.op\n.end\n"
        plot = run_ngspice(net, tmp_path / f"op{etch}")[0]
        assert float(np.real(plot[f"v(x1.sg_{j + 1})"])[0]) == pytest.approx(-1.0, rel=1e-12, abs=0)


def push_deck(include: str, etch: float, control: str = "") -> str:
    """.op of the mass pushed down by 10 uN on f_z (5.4 um of travel on 1.85 N/m): onto zs's stop."""
    pins = "0 0 0 0 0 0 0 0 0 0 0 0 x0 0 x1 0 x2 fz x3 0 x4 0 x5 0 0 0"
    return f"""* push
.include {include}
Vf fz 0 DC -10.0
X1 {pins} accelerometer_xyz etch={etch!r}
.options reltol=1e-12 vntol=1e-12 abstol=1e-20
.op
{control}
.end
"""


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_xspice_stop_stays(xyz, tmp_path, etch):
    """The _xspice.lib's stops (in the code model, reading their electrode's columns) pushed onto zs's
    stop rest where the .lib's do (whose stops read the drawn gap, test_stop_stays_at_the_drawn_gap),
    both in ngspice 39: Newton's convergence at reltol 1e-12 and vntol 1e-12 V (above the velocity
    nodes' rounding floor at a stop, docs/contact.md; 5e-13 of the rest's |x_z| > 2 um), each rest
    within 1.5e-12 of the root, with the two forms' different arithmetic (1e-9). A stop that followed the fill
    shift would rest 6.5 nm (k etch) off: 3e-3 of the travel."""
    (tmp_path / "xyz.lib").write_text(emit_ngspice.subcircuit(xyz))
    ref = float(np.real(run_ngspice(push_deck(str(tmp_path / "xyz.lib"), etch), tmp_path / "lib")[0]["v(x3)"])[0])
    xlib, control = sdn.xspice_library(xyz, tmp_path, sdn.code_models(False))
    block = "\n".join([".control", *control, "set num_threads=1", "run", "write op.raw", ".endc"])
    got = float(np.real(run_ngspice(push_deck(str(xlib.resolve()), etch, block), tmp_path / "x")[0]["v(x3)"])[0])
    assert ref < -2.0  # um: on the stop (the gap is 2 um)
    assert got == pytest.approx(ref, rel=1e-9, abs=0)
