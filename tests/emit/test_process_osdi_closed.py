"""escale, temp and dg_<set> of the Verilog-A module (netgen.emit.veriloga with netgen.emit.process),
compiled by openvaf-r, against closed forms (not against the .lib): through OSDI in ngspice 46 (its
_osdi.lib) and in VACASK. The structure is tests/oracles/process_cases.py's GUIDED mass (200 um
square, 5 um thick, on four clamped-guided beams 150 um x 2 um, E = 160 GPa) over one plate wider than
it, 2 um below (fringe "none": C = eps A / (g + dg - s) exactly), with an incompressible squeeze film
and parameters dg, escale, temp (modulus_tc -60 ppm/K, T0 = 300 K, the [damping] default).

One deck per simulator holds an instance per point (three values of each parameter across its declared
range, the ends included; the other parameters nominal), 5 V on each instance's electrode, a unit AC
force on each: one .op and one .ac (three frequencies) cover every point.

Closed forms:
- stiffness k = 4 E w t^3 / L^3 x escale (1 + tc (temp - T0)) (four guided-clamped beams, 12 E I / L^3
  with I = w t^3 / 12; netgen.model.process's modulus law), mass m = rho t A;
- static deflection s towards the plate: k s = eps A V^2 / (2 (g + dg - s)^2) (brentq to 1e-24 m);
- .ac: 1/H = k_eff - m w^2 + i w b with k_eff = k - eps A V^2 / (g + dg - s)^3;
- the squeeze film's damping b(T) / b(T0) = mu_eff(T) / mu_eff(T0): Sutherland mu ~ T^1.5 / (T + S),
  S = 111 K (air: White, Viscous Fluid Flow, table 1-2), the mean free path ~ mu sqrt(T) at fixed
  pressure, Veijola's mu / (1 + 9.638 Kn^1.159) with Kn(T0) = 68 nm / 2 um at 1 atm
  (tests/oracles/fmu_process.viscosity_ratio, written out from the physics).

Tolerances (derived):
- static: Newton stops when each node moved less than reltol |v| + vntol (x_z in um, 1 V = 1 um); at
  the quadratic convergence of this smooth one-unknown problem the last iterate lies within that step
  of the root: NEWTON = (reltol |x| + vntol) um, plus 1e-12 |s| for the frame solve's and the exact 1/P
  fit's round-off (k against the closed form 5e-14, amplified by k / k_eff < 1.1).
- k_eff from the .ac: the AC solve is linear (round-off; 1e-9 after the least squares); the operating
  point's error NEWTON moves k_eff by 3 k_es NEWTON / (g + dg - s): that over k_eff plus 1e-9.
  m: 1e-9 (nothing nonlinear enters it).
- b(T) / b(T0): the viscosity polynomial is 1 at T0 exactly and within its stated misfit
  (model.process["temp"]["viscosity"]["max_rel_error"], 2.5e-6 here: against this same law on 661
  points of the range) elsewhere, so the ratio within that plus 1e-9 per AC fit (two).
  Without the law (pv = 1) b(125 C) / b(T0) would be off by 17 %.
VACASK: the same references at its op's default Newton tolerances with reltol 1e-6 and vntol 1e-12
set in its options (the same bound).

- b(dg) / b(0) = (g / (g + dg))^3 (1 + 9.638 Kn0^1.159) / (1 + 9.638 (Kn0 g / (g + dg))^1.159), the
  Reynolds film's 12 mu_eff / g^3 at the moved gap (tests/oracles/squeeze_film.closed_form;
  tests/emit/test_process_film_dg.py checks the sealed cavity too): rendered exactly, so within the two AC fits' 2e-9 (the film held at
  the drawn gap, 1.245 / 0.815 at these points, had missed by 24 % / 18 %).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from netgen import emit
from netgen.core.constants import EPS0
from netgen.emit import osdi
from netgen.sim.ngspice import run_control
from netgen.sim.rawfile import read_raw
from netgen.sim.vacask import run_vacask
from netgen.structure import parse_structure
from tests.fixtures import NGSPICE
from tests.fixtures import shared_model as build_model
from tests.oracles.fmu_process import viscosity_ratio
from tests.oracles.process_cases import guided
from tests.oracles.squeeze_film import closed_form as film_ratio

E, W, T, L, RHO, SIDE, GAP = 160e9, 2e-6, 5e-6, 150e-6, 2330.0, 200e-6, 2e-6  # GUIDED (SI)
TC, T0 = -60e-6, 300.0  # 1/K, K
BIAS = 5.0  # V on the plate electrode (pull-in near 17.8 V at escale 1, 12.2 V at 0.5 with dg -0.15 um)
RELTOL, VNTOL = 1e-6, 1e-12
FREQS = (10e3, 30e3, 90e3)  # Hz around f0 = 50.8 kHz
PROCESS = '[process]\nparameters = ["dg", "escale", "temp"]\nmodulus_tc = -60e-6\n'
DG_MAX = 0.3 * GAP / 4  # the declared range: a quarter of the fit box (sampling range 0.3 of L = g)
POINTS = [("escale", v) for v in (0.5, 1.0, 1.5)] + [("temp", v) for v in (-40.0, 26.85, 125.0)]
POINTS += [("dg_bot", v) for v in (-DG_MAX, 0.0, DG_MAX)]
IDS = [f"{n}={v:g}" for n, v in POINTS]


def stiffness(escale: float = 1.0, temp: float = T0 - 273.15) -> float:
    """Four guided-clamped beams bending out of plane, E scaled by escale (1 + tc (T - T0))."""
    return 4 * E * escale * (1 + TC * (temp + 273.15 - T0)) * W * T**3 / L**3


def deflection(k: float, dg: float) -> float:
    """s (m, towards the plate) where k s = eps A V^2 / (2 (g + dg - s)^2), the stable root."""
    f = lambda s: k * s - EPS0 * SIDE**2 * BIAS**2 / (2 * (GAP + dg - s) ** 2)  # noqa: E731
    return brentq(f, 0.0, (GAP + dg) / 3, xtol=1e-24, rtol=1e-15)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The model and `--format osdi` (the .va compiled by openvaf-r), about 1 s."""
    text = guided(process=PROCESS).replace("rayleigh = { alpha = 2000 }", "squeeze_film = true")
    model = build_model(parse_structure(text, "cg.toml"))
    folder = tmp_path_factory.mktemp("process_osdi_closed")
    emit.write_outputs(model, folder, "osdi")
    return model, folder


def instances(spice: bool) -> list[str]:
    """Per point an instance with its own electrode, force and output nodes (ngspice or VACASK text)."""
    lines = []
    for i, (name, value) in enumerate(POINTS):
        if spice:
            lines += [
                f"X{i} d{i} 0 f{i} x{i} cg {name}={value!r}",
                f"Vd{i} d{i} 0 DC {BIAS!r}",
                f"Vf{i} f{i} 0 DC 0 AC 1",
            ]
        else:
            lines += [
                f"model m{i} cg {name}={value!r}",
                f"x{i} (d{i} 0 f{i} x{i}) m{i}",
                f"vd{i} (d{i} 0) vsource dc={BIAS!r}",
                f"vf{i} (f{i} 0) vsource dc=0 mag=1",
            ]
    return lines


def ngspice_deck(folder: Path) -> str:
    """One ngspice 46 run: .op then .ac of every instance, written to op.raw and ac.raw."""
    body = "\n".join(instances(True))
    return f"""* escale, temp, dg through OSDI against closed forms
.include {folder / "cg_osdi.lib"}
{body}
.options reltol={RELTOL} vntol={VNTOL}
.control
pre_osdi {folder / "cg.osdi"}
set num_threads=1
op
write op.raw
ac lin 3 {FREQS[0]} {FREQS[-1]}
write ac.raw
.endc
.end
"""


@pytest.fixture(scope="module")
def ngspice_results(built, tmp_path_factory):
    """(x per point in um, .ac plot) from ngspice 46."""
    _, folder = built
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("NETGEN_NGSPICE", NGSPICE["46"])
        work = tmp_path_factory.mktemp("ng46")
        ac = run_control(ngspice_deck(folder), work, "circuit", "ac.raw")
    op = read_raw(work / "op.raw")[0]
    xs = [float(np.real(op[f"v(x{i})"][0])) for i in range(len(POINTS))]
    return xs, {"f": np.real(ac["frequency"]), **{i: np.asarray(ac[f"v(x{i})"]) for i in range(len(POINTS))}}


@pytest.fixture(scope="module")
def vacask_results(built, tmp_path_factory):
    """The same from VACASK (op1.raw and ac1.raw of one run)."""
    _, folder = built
    work = tmp_path_factory.mktemp("vacask")
    net = "\n".join(
        [f'escale temp dg closed forms\nground 0\nload "{folder / "cg.osdi"}"\nmodel vsource vsource']
        + instances(False)
        + [
            "control",
            f"  options reltol={RELTOL} vntol={VNTOL}",
            "  analysis op1 op",
            f'  analysis ac1 ac from={FREQS[0]} to={FREQS[-1]} mode="lin" points=3',
            "endc",
            "",
        ]
    )
    ac = run_vacask(net, work, analysis="ac1")
    op = read_raw(work / "op1.raw")[0]
    xs = [float(np.real(np.atleast_1d(op[f"x{i}"])[0])) for i in range(len(POINTS))]
    return xs, {"f": np.real(ac["frequency"]), **{i: np.asarray(ac[f"x{i}"]) for i in range(len(POINTS))}}


def fit(f: np.ndarray, h: np.ndarray) -> tuple[float, float, float]:
    """k, m, b from 1/H = k - m w^2 + i w b (H in um/uN = m/N)."""
    w = 2 * np.pi * f
    inv = 1.0 / h
    (k, m), *_ = np.linalg.lstsq(np.stack([np.ones_like(w), -(w**2)], axis=1), inv.real, rcond=None)
    return float(k), float(m), float(np.mean(inv.imag / w))


def check(model, results, i: int, label: str) -> None:
    """Point i's deflection, k_eff and m against the closed forms; b against the viscosity law."""
    name, value = POINTS[i]
    xs, ac = results
    escale = value if name == "escale" else 1.0
    temp = value if name == "temp" else T0 - 273.15
    dg = value if name == "dg_bot" else 0.0
    k = stiffness(escale, temp)
    s = deflection(k, dg)
    newton = (RELTOL * s * 1e6 + VNTOL) * 1e-6  # m
    x = -xs[i] * 1e-6  # x_z (um, +z away from the plate) -> s (m)
    gap = GAP + dg - s
    k_es = EPS0 * SIDE**2 * BIAS**2 / gap**3
    k_eff, bound = k - k_es, 3 * k_es * newton / gap / (k - k_es) + 1e-9
    got_k, got_m, got_b = fit(ac["f"], ac[i])
    print(
        f"{label} {name}={value:g}: s - closed form {x - s:.1e} m (bound {newton + 1e-12 * s:.1e}); "
        f"k_eff {got_k / k_eff - 1:.1e} (bound {bound:.1e}); m {got_m / (RHO * T * SIDE**2) - 1:.1e}"
    )
    assert abs(x - s) <= newton + 1e-12 * s
    assert got_k == pytest.approx(k_eff, rel=bound)
    assert got_m == pytest.approx(RHO * T * SIDE**2, rel=1e-9)
    if name == "temp":
        b0 = fit(ac["f"], ac[POINTS.index(("temp", 26.85))])[2]
        misfit = model.process["temp"]["viscosity"]["max_rel_error"]
        print(f"{label} b / b(T0) against the viscosity law {got_b / b0 / viscosity_ratio(temp, T0, GAP) - 1:.1e}")
        assert misfit < 1e-5  # the polynomial follows the law (a degree-4 fit over 165 K)
        assert got_b / b0 == pytest.approx(viscosity_ratio(temp, T0, GAP), rel=misfit + 2e-9)
    if name == "dg_bot":
        b0 = fit(ac["f"], ac[POINTS.index(("dg_bot", 0.0))])[2]
        print(f"{label} b / b(dg 0) against the film's closed form {got_b / b0 / film_ratio(dg, temp, False) - 1:.1e}")
        assert got_b / b0 == pytest.approx(film_ratio(dg, temp, False), rel=2e-9)


def test_structure_is_the_closed_form_s(built):
    """The model's nominal numbers are the closed forms' (so the points below test the laws): k, m
    to the frame solve's round-off, T0 and the modulus coefficient as declared, the dg range's ends."""
    model, _ = built
    c = model.coordinates[0]
    assert c.stiffness == pytest.approx(stiffness(), rel=1e-12)
    assert c.mass == pytest.approx(RHO * T * SIDE**2, rel=1e-12)
    assert model.process["temperature_C"] == pytest.approx(T0 - 273.15, rel=1e-12)
    assert model.process["modulus_tc_per_K"] == TC
    assert model.process["gaps"][0]["max_m"] == pytest.approx(DG_MAX, rel=1e-9)


@pytest.mark.parametrize("i", range(len(POINTS)), ids=IDS)
def test_osdi_in_ngspice46_against_closed_forms(built, ngspice_results, i):
    check(built[0], ngspice_results, i, "ngspice 46")


@pytest.mark.parametrize("i", range(len(POINTS)), ids=IDS)
def test_osdi_in_vacask_against_closed_forms(built, vacask_results, i):
    check(built[0], vacask_results, i, "VACASK")


def test_compiles_without_warnings(built):
    """openvaf-r compiles the module with warnings as errors (netgen.emit.osdi.compile_va's default)."""
    _, folder = built
    out, _ = osdi.compile_va(folder / "cg.va", folder / "again.osdi")
    assert out.exists()


@pytest.mark.parametrize("simulator", ["ngspice", "vacask"])
def test_damping_at_the_nominal_temperature_is_the_model_s(built, ngspice_results, vacask_results, simulator):
    """At temp = T0 (the default) the viscosity law's ratio is exactly 1: the module's damping is the
    model's own (the Reynolds solve's) to the AC fit's round-off, 1e-9, as every other law is exact at
    its nominal point (netgen.model.process.power_fit). The unconstrained degree-4 fit put 1 + 8.2e-7."""
    model, _ = built
    results = ngspice_results if simulator == "ngspice" else vacask_results
    b = fit(results[1]["f"], results[1][POINTS.index(("temp", 26.85))])[2]
    assert b == pytest.approx(model.coordinates[0].damping, rel=1e-9)
