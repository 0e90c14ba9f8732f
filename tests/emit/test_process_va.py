"""The process parameters in the Verilog-A module (netgen.emit.veriloga with netgen.emit.process), compiled
by openvaf-r and run through OSDI in ngspice 46 (its _osdi.lib, which forwards the instance's
parameters to a .model card per instance) and in VACASK, for examples/piston_process.toml (a rigid
plate on a given 2 N/m spring, 2 um above one electrode, fringe "none": C = eps A / gap exactly).

- static deflection under 2 V at three values of each parameter (tscale, temp, dg_drive): OSDI
  against the B-source .lib in the same ngspice and both against the closed-form equilibrium
  k z = eps A V^2 / (2 (g + dg - z)^2) (brentq to 1e-24 m; the given spring: tscale and temp move
  nothing). Bound:
  ngspice stops Newton when each node moved less than reltol |v| + vntol; at the quadratic
  convergence of this smooth one-unknown problem the last iterate is much closer than that step,
  so each solution lies within NEWTON = reltol |x| + vntol of the root and two within twice that
  (the 1/P fit is exact to round-off: 1e-12 relative on top).
- the resonance at that bias from .ac (1/H = k_eff - m w^2 + i w b, three frequencies): OSDI
  against the .lib and against sqrt(k_eff / m) / 2 pi with k_eff = k - eps A V^2 / (g + dg - z)^3,
  m = M tscale. The AC solve is linear (round-off, 1e-9 after the least squares); the operating
  point's Newton error dz moves k_eff by 3 k_es dz / (g + dg - z), i.e. f0 by half that over k_eff:
  the bound is that (near 2e-8 at reltol 1e-6) plus 1e-9, under the acceptance bound 1e-4.
- .noise of the unbiased damped piston through OSDI in ngspice 46 and in VACASK: the displacement
  PSD against 4 k_B T b |H(f)|^2 over the resonance with T = temp + 273.15 K, b = alpha M tscale,
  m = M tscale. The white_noise source is exact in the small-signal analysis (a sign error of the
  compiler would flip or null the PSD, not scale it by a few %): 1e-6 relative (both simulators
  write doubles; the acceptance bound is 2 %).
- an out-of-range value (from [lo:hi] of the declared range) is refused by the simulator.
- the parameters the piston lacks (escale, the squeeze film's temperature law, two gap sets on
  degree-2 fits, three coordinates): tests/model/test_process.py's proof mass through OSDI against
  its .lib in ngspice 46 (deflection, .ac response, .noise), and its three coordinates' stiffness and
  damping at (escale, temp) across both ranges against the closed-form scalings K ~ E (1 + tc dT) and
  b ~ mu_eff(T) (test_proof_mass_modulus_and_viscosity_laws_against_closed_forms). escale, temp and
  dg against absolute closed forms (a mass on clamped-guided beams): tests/emit/test_process_osdi_closed.py.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from netgen import emit
from netgen.core.constants import EPS0, K_B
from netgen.core.errors import SimulationError
from netgen.emit import ngspice as emit_ngspice
from netgen.emit import osdi
from netgen.sim.ngspice import run_ngspice
from netgen.structure import load_structure, parse_structure
from tests.fixtures import NGSPICE, ROOT
from tests.fixtures import shared_model as build_model
from tests.oracles.process_cases import PROOF
from tests.oracles.process_forms import ac_fit
from tests.oracles.spice_decks import vacask_piston_noise

ALPHA = 3000.0  # 1/s: the Rayleigh alpha M of examples/piston_process.toml
SPRING = 2.0  # N/m, the given spring
GAP = 2e-6  # m
BIAS = 2.0  # V on the drive electrode (pull-in near 3.1 V at dg = -0.2 um)
RELTOL, VNTOL = 1e-6, 1e-12  # the static runs' Newton tolerances (x_z in um: 1 V = 1 um)
POINTS = [("tscale", v) for v in (0.9, 1.0, 1.1)] + [("temp", v) for v in (-40.0, 26.85, 125.0)]
POINTS += [("dg_drive", v) for v in (-2e-7, 0.0, 3e-7)]


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The model, its .lib and `--format osdi` (the .va compiled by openvaf-r) in one folder."""
    model = build_model(load_structure(ROOT / "examples/piston_process.toml"))
    folder = tmp_path_factory.mktemp("process_va")
    (folder / "piston_process.lib").write_text(emit_ngspice.subcircuit(model))
    emit.write_outputs(model, folder, "osdi")
    return model, folder


@pytest.fixture
def ngspice46(monkeypatch):
    """Run ngspice 46 (the OSDI-capable one .ci/setup installs)."""
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])


def run(folder: Path, form: str, params: dict, analysis: str, bias: float, workdir: Path):
    """One ngspice run of X1 (drive, grounded plate, force port fz, output xz) in `form` (lib, osdi)."""
    ps = " ".join(f"{k}={v}" for k, v in params.items())
    lib = folder / ("piston_process.lib" if form == "lib" else "piston_process_osdi.lib")
    control = ""
    if form == "osdi":
        control = (
            f".control\npre_osdi {folder / 'piston_process.osdi'}\nset num_threads=1\nrun\nwrite circuit.raw\n.endc"
        )
    net = f"""* process parameters, {form}
.include {lib}
X1 drive 0 fz xz piston_process {ps}
Vd drive 0 DC {bias}
Vf fz 0 DC 0 AC 1
.options reltol={RELTOL} vntol={VNTOL}
{analysis}
{control}
.end
"""
    return run_ngspice(net, workdir / form)


def equilibrium(area: float, dg: float) -> float:
    """The closed-form static deflection (m, towards the electrode: negative z) at BIAS."""
    return -brentq(
        lambda z: SPRING * z - EPS0 * area * BIAS**2 / (2 * (GAP + dg - z) ** 2),
        0.0,
        (GAP + dg) / 3,
        xtol=1e-24,
        rtol=1e-15,
    )


@pytest.mark.parametrize(("name", "value"), POINTS)
def test_static_deflection_and_resonance(built, ngspice46, tmp_path, name, value):
    model, folder = built
    c, area = model.coordinates[0], model.electrodes[0].area
    dg, tscale = (value if name == "dg_drive" else 0.0), (value if name == "tscale" else 1.0)
    z_ref = equilibrium(area, dg)
    x, f0 = {}, {}
    for form in ("lib", "osdi"):
        x[form] = float(np.real(run(folder, form, {name: value}, ".op", BIAS, tmp_path / "op")[0]["v(xz)"][0])) * 1e-6
        k, m, _ = ac_fit(run(folder, form, {name: value}, ".ac lin 3 5k 30k", BIAS, tmp_path / "ac")[0])
        f0[form] = math.sqrt(k / m) / (2 * math.pi)
    newton = (RELTOL * abs(z_ref) * 1e6 + VNTOL) * 1e-6  # m: one solution's bound
    assert abs(x["osdi"] - x["lib"]) <= 2 * newton
    for form in x:
        assert abs(x[form] - z_ref) <= newton + 1e-12 * abs(z_ref), form
    gap = GAP + dg + z_ref
    k_es = EPS0 * area * BIAS**2 / gap**3
    k_eff = SPRING - k_es
    f_ref = math.sqrt(k_eff / (c.mass * tscale)) / (2 * math.pi)
    bound = 0.5 * 3 * k_es * 2 * newton / gap / k_eff + 1e-9
    print(
        f"{name}={value}: x OSDI - .lib {x['osdi'] - x['lib']:.1e} m, OSDI - closed form {x['osdi'] - z_ref:.1e} m "
        f"(bound {newton:.1e}); f0 OSDI/.lib - 1 {f0['osdi'] / f0['lib'] - 1:.1e}, "
        f"OSDI/closed form - 1 {f0['osdi'] / f_ref - 1:.1e} (bound {bound:.1e})"
    )
    assert bound < 1e-4  # the acceptance bound
    assert f0["osdi"] == pytest.approx(f0["lib"], rel=bound)
    for form in f0:
        assert f0[form] == pytest.approx(f_ref, rel=bound), form


NOISE_POINTS = [(-40.0, 0.9), (26.85, 1.0), (125.0, 1.1)]  # (temp degC, tscale)


def reference_psd(model, f: np.ndarray, temp: float, tscale: float) -> np.ndarray:
    """4 k_B T b |H(f)|^2 of the unbiased piston (m^2/Hz)."""
    w = 2 * np.pi * f
    m = model.coordinates[0].mass * tscale
    b = ALPHA * m
    return 4 * K_B * (temp + 273.15) * b / np.abs(SPRING - m * w**2 + 1j * w * b) ** 2


@pytest.mark.parametrize(("temp", "tscale"), NOISE_POINTS)
def test_noise_through_osdi_in_ngspice46(built, ngspice46, tmp_path, temp, tscale):
    model, folder = built
    plots = run(folder, "osdi", {"temp": temp, "tscale": tscale}, ".noise v(xz) Vf lin 41 5k 25k", 0.0, tmp_path)
    spec = next(p for p in plots if "onoise_spectrum" in p.vectors)
    f = np.real(spec["frequency"])
    got = np.real(spec["onoise_spectrum"]) ** 2 * 1e-12  # V/sqrt(Hz) at x_z (1 V = 1 um) -> m^2/Hz
    ref = reference_psd(model, f, temp, tscale)
    print(f"temp={temp} tscale={tscale}: max |PSD / 4 k_B T b |H|^2 - 1| = {np.max(np.abs(got / ref - 1)):.1e}")
    np.testing.assert_allclose(got, ref, rtol=1e-6)


@pytest.mark.parametrize(("temp", "tscale"), NOISE_POINTS)
def test_noise_in_vacask(built, tmp_path, temp, tscale):
    """VACASK's noise analysis of the same module, the parameters on its model card; onoise is the
    output PSD itself (V^2/Hz)."""
    model, folder = built
    card = f"temp={temp} tscale={tscale}"
    f, psd = vacask_piston_noise(folder / "piston_process.osdi", "piston_process", tmp_path, card)
    got = psd * 1e-12  # um^2/Hz -> m^2/Hz
    ref = reference_psd(model, f, temp, tscale)
    print(f"VACASK temp={temp} tscale={tscale}: max |PSD / 4 k_B T b |H|^2 - 1| = {np.max(np.abs(got / ref - 1)):.1e}")
    np.testing.assert_allclose(got, ref, rtol=1e-6)


def declared_range(text: str, name: str) -> tuple[float, float]:
    """The `from [lo:hi]` of parameter `name` in the module text."""
    m = re.search(rf"parameter real {name} = \S+ from \[(\S+):(\S+)\];", text)
    assert m, name
    return float(m.group(1)), float(m.group(2))


def test_declared_ranges_are_the_model_s(built, ngspice46, tmp_path):
    """The .va declares each parameter with the range of the model's process record (widened by
    netgen.emit.process.SLACK = 1e-9 relative, for the simulators' number parsing: the corners pass),
    and ngspice refuses a value outside it rather than extrapolating the laws."""
    model, folder = built
    text = (folder / "piston_process.va").read_text()
    p = model.process
    dg = p["gaps"][0]["max_m"]
    for name, (lo, hi) in {"tscale": p["tscale"]["range"], "temp": p["temp"]["range_C"], "dg_drive": (-dg, dg)}.items():
        got = declared_range(text, name)
        assert got[0] <= lo and got[1] >= hi, name
        assert got == pytest.approx((lo, hi), rel=2e-9), name
    with pytest.raises(SimulationError, match="exit code"):
        run(folder, "osdi", {"tscale": 1.15}, ".op", BIAS, tmp_path)
    assert "tscale is out of bounds" in (tmp_path / "osdi" / "circuit.log").read_text()


def test_compiles_without_warnings(built):
    """openvaf-r compiles the module with warnings as errors (netgen.emit.osdi.compile_va's default)."""
    _, folder = built
    out, _ = osdi.compile_va(folder / "piston_process.va", folder / "again.osdi")
    assert out.exists()


@pytest.fixture(scope="module")
def proof_mass(tmp_path_factory):
    """tests/model/test_process.py's proof mass (folded flexures: a modulus law; incompressible squeeze
    film: the viscosity law; plates above and below: two gap sets; three coordinates, degree-2 fits)
    with thermal noise, all four parameters: its .lib and `--format osdi` (a ~20 s build)."""
    text = PROOF.format(t=10.0, e=160.0).replace("squeeze_film = true", "squeeze_film = true\nnoise = true")
    model = build_model(parse_structure(text, "pm.toml"))
    folder = tmp_path_factory.mktemp("process_va_pm")
    (folder / "pm.lib").write_text(emit_ngspice.subcircuit(model))
    emit.write_outputs(model, folder, "osdi")
    return model, folder


def run_pm(folder: Path, form: str, params: str, analysis: str, workdir: Path):
    """One ngspice run of the proof mass (1 V top, 0.5 V bottom, grounded plate, AC force on z)."""
    lib = folder / ("pm.lib" if form == "lib" else "pm_osdi.lib")
    control = ""
    if form == "osdi":
        control = f".control\npre_osdi {folder / 'pm.osdi'}\nset num_threads=1\nrun\nwrite circuit.raw\n.endc"
    net = f"""* proof mass, {form}
.include {lib}
X1 top bot 0 fz xz 0 xtx 0 xty pm {params}
Vt top 0 DC 1
Vb bot 0 DC 0.5
Vf fz 0 DC 0 AC 1
.options reltol={RELTOL} vntol={VNTOL}
{analysis}
{control}
.end
"""
    return run_ngspice(net, workdir / form)


@pytest.mark.parametrize(
    "params",
    [
        "",
        "tscale=1.05 escale=1.3 temp=125 dg_top=2e-8 dg_bot=-3e-8",
        "tscale=0.92 escale=0.7 temp=-40 dg_top=-5e-8 dg_bot=6e-8",
    ],
)
def test_proof_mass_with_all_four_parameters_matches_the_lib(proof_mass, ngspice46, tmp_path, params):
    """The module's escale (pe), temp (pe and the squeeze film's pv), tscale and two gap sets against
    the B-source .lib in ngspice 46: the deflection within twice Newton's stopping bound; the .ac
    response H(f) over 0.5..1.5 f0 within 2 reltol (the operating point's error enters H only through
    the electrostatic stiffness, a fraction of k; the film damps the mode to Q = 0.06: no resonant
    amplification); the .noise amplitude within 2 reltol (the .lib's noise resistors are scaled by
    K_B / ngspice's CODATA-2014 constant, so both forms give 4 K_B T D with the SI K_B)."""
    model, folder = proof_mass
    f0 = model.coordinates[0].frequency_hz
    out = {}
    for form in ("lib", "osdi"):
        op = run_pm(folder, form, params, ".op", tmp_path / "op")[0]
        ac = run_pm(folder, form, params, f".ac lin 21 {0.5 * f0} {1.5 * f0}", tmp_path / "ac")[0]
        plots = run_pm(folder, form, params, f".noise v(xz) Vf lin 21 {0.5 * f0} {1.5 * f0}", tmp_path / "no")
        spec = next(p for p in plots if "onoise_spectrum" in p.vectors)
        out[form] = (float(np.real(op["v(xz)"][0])), np.asarray(ac["v(xz)"]), np.real(spec["onoise_spectrum"]))
    (x_lib, h_lib, n_lib), (x_osdi, h_osdi, n_osdi) = out["lib"], out["osdi"]
    h_err = np.max(np.abs(h_osdi / h_lib - 1))
    n_err = np.max(np.abs(n_osdi / n_lib - 1))
    print(f"[{params}] x OSDI - .lib {x_osdi - x_lib:.1e} um of {x_lib:.3e}; H {h_err:.1e}; noise {n_err:.1e}")
    assert abs(x_osdi - x_lib) <= 2 * (RELTOL * abs(x_lib) + VNTOL)
    assert h_err <= 2 * RELTOL
    assert n_err <= 2 * RELTOL


PM_POINTS = [(1.0, 26.85), (0.5, 26.85), (1.5, 26.85), (1.0, -40.0), (1.0, 125.0), (1.3, 125.0), (0.7, -40.0)]


def test_proof_mass_modulus_and_viscosity_laws_against_closed_forms(proof_mass, ngspice46, tmp_path):
    """The proof mass's three coordinates through OSDI at (escale, temp) across both ranges, unbiased
    (the coordinates decouple: diagonal K and D, no electrostatic coupling at 0 V), a unit AC force on
    each port of every instance in one ngspice 46 run. Closed forms, not the laws' own numbers: the
    frame is linear elastic without residual stress, so K ~ E exactly and k / k(nominal instance) =
    escale (1 + tc (temp - T0)) (tc = -60 ppm/K, T0 = 300 K); the mass stays; the only damping is the
    squeeze film, so b / b(nominal) = mu_eff(T) / mu_eff(T0) (Sutherland, Veijola: viscosity_ratio of
    tests/oracles/fmu_process.py at the 2 um gaps). Bounds: 1e-9 per AC fit (a linear solve to
    round-off; two fits per ratio) plus the law's stated error: escale's (the A/B split's residual,
    round-off here) for k, the viscosity polynomial's misfit for b (1 at T0 exactly)."""
    from tests.oracles.fmu_process import viscosity_ratio

    model, folder = proof_mass
    law = model.process
    assert law["modulus_tc_per_K"] == -60e-6 and law["temperature_C"] == pytest.approx(26.85, abs=1e-9)
    f0 = [c.frequency_hz for c in model.coordinates]
    ports = [("fz", "xz"), ("ftx", "xtx"), ("fty", "xty")]
    lines = []
    for i, (escale, temp) in enumerate(PM_POINTS):
        nodes = " ".join(f"{f}{i} {x}{i}" for f, x in ports)
        lines.append(f"X{i} 0 0 0 {nodes} pm escale={escale!r} temp={temp!r}")
        lines += [f"V{f}{i} {f}{i} 0 DC 0 AC 1" for f, _ in ports]
    body = "\n".join(lines)
    net = f"""* proof mass escale, temp through OSDI
.include {folder / "pm_osdi.lib"}
{body}
.ac lin 3 {0.5 * min(f0)!r} {1.5 * max(f0)!r}
.control
pre_osdi {folder / "pm.osdi"}
set num_threads=1
run
write circuit.raw
.endc
.end
"""
    plot = run_ngspice(net, tmp_path)[0]
    f = np.real(plot["frequency"])
    kmb = {
        (i, x): ac_fit({"frequency": f, "v(xz)": plot[f"v({x}{i})"]}) for i in range(len(PM_POINTS)) for _, x in ports
    }
    k_tol = 2e-9 + law["escale"]["max_rel_error"]
    b_tol = 2e-9 + law["temp"]["viscosity"]["max_rel_error"]
    for i, (escale, temp) in enumerate(PM_POINTS):
        for _, x in ports:
            (k, m, b), (k0, m0, b0) = kmb[i, x], kmb[0, x]
            e, v = escale * (1 - 60e-6 * (temp - 26.85)), viscosity_ratio(temp, 300.0, 2e-6)
            print(
                f"escale={escale} temp={temp} {x}: k {k / k0 / e - 1:.1e}, m {m / m0 - 1:.1e}, b {b / b0 / v - 1:.1e}"
            )
            assert k / k0 == pytest.approx(e, rel=k_tol), x
            assert m / m0 == pytest.approx(1.0, rel=2e-9), x
            assert b / b0 == pytest.approx(v, rel=b_tol), x
