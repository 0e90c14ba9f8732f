"""Damping and thermal noise (issue 8), against independent references.

- Reynolds solver (scikit-fem) vs closed forms: rigid circular plate b = 3 pi mu a^4 / (2 g^3),
  rectangular plate vs Blech's incompressible double series;
- the pipeline's squeeze-film damping of z vs the closed form with Veijola's mu_eff, both gaps;
- ngspice ring-down of the emitted subcircuit: the decay envelope gives back the specified Q,
  and with squeeze film the damping coefficient of the Reynolds solver;
- ngspice transient with thermal force noise (trnoise, S_F = 4 k_B T b) and no drive: the
  displacement variance of the damped mode is k_B T / k (equipartition).

The simulated structure is a small variant of the reference disk chosen for speed: the same
473 um disk, one eigenmode (2,0c, 97.7 kHz) plus z, one ring of 4 sectors per side, every
electrode and the plate grounded (no electrostatic force), so each ngspice run takes seconds.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from netgen import squeeze_film as sf
from netgen.emit_ngspice import subcircuit
from netgen.model import MacroModel
from netgen.pipeline import build_model
from netgen.simulate import run_ngspice
from netgen.structure import StructureError, parse_structure
from tb import Bench

K_B = 1.380649e-23
MU_AIR = 1.85e-5

SMALL = """
name = "damped_disk"
description = "one-mode disk for the damping tests"
[conductor]
radius = "473 um"
thickness = "10 um"
youngs_modulus = "160 GPa"
poisson_ratio = 0.22
density = "2330 kg/m^3"
[[electrodes]]
name = "top"
side = "above"
gap = "3 um"
rings = [["20 um", "473 um"]]
sectors = 4
slot = "10 um"
[[electrodes]]
name = "bot"
side = "below"
gap = "3 um"
rings = [["20 um", "473 um"]]
sectors = 4
slot = "10 um"
[coordinates]
rigid = ["z"]
modes = ["2,0c"]
[fem]
refine = 5
"""


def small_model(damping: str) -> MacroModel:
    """The small test structure with the given [damping] table body."""
    return build_model(parse_structure(SMALL + "[damping]\n" + damping, "damped_disk.toml"))


def uniform(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Rigid translation: unit gap closing everywhere."""
    return np.ones_like(x)[..., None]


# ------------------------------------------------------------------ Reynolds solver

@pytest.mark.parametrize("radius, gap", [(473e-6, 3e-6), (100e-6, 1e-6)])
def test_reynolds_circular_plate(radius, gap):
    """Rigid disk, p = 0 at the rim: b = 3 pi mu a^4 / (2 g^3) within 2 % (measured 0.08 %)."""
    b = sf.damping_matrix(sf.disk_mesh(radius, 5), uniform, gap, MU_AIR)[0, 0]
    assert b == pytest.approx(sf.circular_plate_closed_form(MU_AIR, radius, gap), rel=0.02)


@pytest.mark.parametrize("length, width", [(1e-3, 1e-3), (2e-3, 0.5e-3), (1e-3, 0.1e-3)])
def test_reynolds_rectangular_plate(length, width):
    """Rigid rectangle, p = 0 on all edges: Blech's series (incompressible limit) within 2 %."""
    b = sf.damping_matrix(sf.rectangle_mesh(length, width, 32), uniform, 2e-6, MU_AIR)[0, 0]
    assert b == pytest.approx(sf.rectangular_plate_series(MU_AIR, length, width, 2e-6), rel=0.02)


def test_blech_series_long_plate_limit():
    """Blech's series tends to the long-plate (1-D) result mu L W^3 / g^3 as L / W grows."""
    length, width, gap = 1.0, 1e-3, 1e-6
    long_plate = MU_AIR * length * width**3 / gap**3
    assert sf.rectangular_plate_series(MU_AIR, length, width, gap) == pytest.approx(long_plate, rel=2e-3)


@pytest.mark.parametrize("sigma", [1.0, 10.0, 100.0])
def test_compressible_reynolds_vs_blech(sigma):
    """Compressible film on a 1 x 0.5 mm plate at squeeze number sigma = 12 mu w W^2 / (p g^2):
    the complex FEM admittance (damping and gas spring) matches Blech's series within 2 %."""
    length, width, gap, pa = 1e-3, 0.5e-3, 2e-6, 101325.0
    omega = sigma * pa * gap**2 / (12 * MU_AIR * width**2)
    mesh = sf.rectangle_mesh(length, width, 32)
    fem = sf.compressible_admittance(mesh, uniform, 0, gap, MU_AIR, pa, omega)
    ref = sf.rectangular_plate_blech_complex(MU_AIR, length, width, gap, pa, omega)
    assert abs(fem - ref) < 0.02 * abs(ref)
    assert ref.imag < 0 and abs(ref.imag) > 0.05 * ref.real          # the film is also a spring here


def test_pole_residue_model_vs_blech():
    """20-pole Maxwell (pole-residue) network of the same plate: within 2 % of Blech's series
    from sigma = 0.01 to 100 (measured 1.0 % at 100)."""
    length, width, gap, pa = 1e-3, 0.5e-3, 2e-6, 101325.0
    model = sf.pole_residue(sf.rectangle_mesh(length, width, 32), uniform, 0, gap, MU_AIR, pa, poles=20)
    for sigma in (0.01, 1.0, 10.0, 100.0):
        omega = sigma * pa * gap**2 / (12 * MU_AIR * width**2)
        ref = sf.rectangular_plate_blech_complex(MU_AIR, length, width, gap, pa, omega)
        assert abs(model.admittance(omega) - ref) < 0.02 * abs(ref)


def test_pipeline_squeeze_film_z():
    """z of the small disk at 100 Pa: both gaps' closed form with Veijola's mu_eff (Kn = 23)."""
    model = small_model('squeeze_film = true\npressure = "100 Pa"\n')
    kn = 68e-9 * 101325 / 100 / 3e-6
    mu_eff = MU_AIR / (1 + 9.638 * kn**1.159)
    expected = 2 * sf.circular_plate_closed_form(mu_eff, 473e-6, 3e-6)
    assert model.coordinates[0].damping == pytest.approx(expected, rel=0.01)


# ------------------------------------------------------------------ structure file

@pytest.mark.parametrize("table, message", [
    ("q_factor = {m2_0x = 100}", "did you mean 'm2_0c'"),
    ("qfactor = 100", "did you mean 'q_factor'"),
    ("q_factor = {z = 100}", "rigid coordinate"),
    ("q_factor = 0.2", "must exceed 0.5"),
    ("damping_ratio = {m2_0c = 0.1}\nq_factor = {m2_0c = 5}", "both q_factor and damping_ratio"),
    ('gas = "aire"', "did you mean 'air'"),
    ('pressure = "1 psi"', "not a pressure unit"),
    ("rayleigh = {alpha = 1, gama = 2}", "unknown key 'gama'"),
    ("noise = 1", "true or false"),
])
def test_damping_table_errors(table, message):
    """Mistakes in [damping] are StructureErrors naming the key and a fix."""
    with pytest.raises(StructureError, match=message):
        parse_structure(SMALL + "[damping]\n" + table, "damped_disk.toml")


def test_modal_and_rayleigh_damping_in_model():
    """Q, damping ratio and Rayleigh terms become SI damping: b = m w0 / Q + alpha m + beta k."""
    model = small_model("damping_ratio = 0.01\nrayleigh = {alpha = 100.0, beta = 1e-9}\n")
    z, mode = model.coordinates
    w0 = 2 * math.pi * mode.frequency_hz
    assert z.damping == pytest.approx(100.0 * z.mass, rel=1e-12)
    assert mode.damping == pytest.approx(2 * 0.01 * mode.mass * w0 + 100.0 * mode.mass + 1e-9 * mode.stiffness,
                                         rel=1e-12)
    assert MacroModel.from_dict(model.to_dict()).coordinates[1].damping == mode.damping


# ------------------------------------------------------------------ ngspice

def ringdown(model: MacroModel, tmp_path: Path, periods: int = 60) -> tuple[float, float]:
    """Free decay of mode m2_0c from xs = 0.01 in ngspice; envelope decay rate (1/s) and w0."""
    mode = model.coordinates[1]
    lib = tmp_path / "damped.lib"
    lib.write_text(subcircuit(model, noise=False))
    f0 = mode.frequency_hz
    dt = 1 / (100 * f0)
    bench = Bench(model, lib, sources={"plate": "0"}, extra=[".ic v(x1.xs_m2_0c)=0.01"], options="reltol=1e-6")
    plot = run_ngspice(bench.netlist(f".tran {dt} {periods / f0} 0 {dt} uic"), tmp_path)[0]
    return decay_rate(plot["time"], plot["v(x1.xs_m2_0c)"]), 2 * math.pi * f0


def decay_rate(t: np.ndarray, x: np.ndarray) -> float:
    """sigma of the envelope A e^(-sigma t): line fit of log peak heights (parabolic peaks)."""
    i = np.flatnonzero((x[1:-1] > x[:-2]) & (x[1:-1] >= x[2:])) + 1
    y0, y1, y2 = x[i - 1], x[i], x[i + 1]
    denom = y0 - 2 * y1 + y2
    peaks = y1 - (y2 - y0) ** 2 / (8 * denom)
    tp = t[i] + (t[i + 1] - t[i]) * 0.5 * (y0 - y2) / denom
    keep = slice(1, None)                                     # skip the start-up peak
    return -np.polyfit(tp[keep], np.log(peaks[keep]), 1)[0]


def test_ringdown_reproduces_q(tmp_path):
    """Specified Q = 100: Q = w0 / (2 sigma) of the ngspice decay envelope within 2 %."""
    sigma, w0 = ringdown(small_model("q_factor = {m2_0c = 100}\n"), tmp_path)
    assert w0 / (2 * sigma) == pytest.approx(100, rel=0.02)


def test_ringdown_matches_reynolds(tmp_path):
    """Squeeze film only (air, 100 Pa): b = 2 m sigma from the ring-down vs the Reynolds solver, 5 %."""
    model = small_model('squeeze_film = true\npressure = "100 Pa"\n')
    reynolds = model.report["damping"]["squeeze_film"]["diagonal"][1]
    sigma, _ = ringdown(model, tmp_path)
    assert 2 * model.coordinates[1].mass * sigma == pytest.approx(reynolds, rel=0.05)


def test_thermal_noise_equipartition(tmp_path):
    """Noise on, no drive, Q = 1: variance of the mode amplitude over 5 ms (~1500 decay times,
    expected scatter ~3 %) is k_B T / k within 10 %."""
    model = small_model("q_factor = 1\nnoise = true\ntemperature = \"300 K\"\n")
    mode = model.coordinates[1]
    lib = tmp_path / "noisy.lib"
    lib.write_text(subcircuit(model))
    dt = 1 / (50 * mode.frequency_hz)
    bench = Bench(model, lib, sources={"plate": "0"}, options="vntol=1e-15 abstol=1e-20 seed=1")
    plot = run_ngspice(bench.netlist(f".tran {dt} 5m 0 {dt} uic"), tmp_path)[0]
    t, q = plot["time"], plot["v(x1.xs_m2_0c)"] * mode.scale
    settled = np.arange(20 * 2 * mode.mass / mode.damping, t[-1], dt)     # past 20 decay times
    variance = np.var(np.interp(settled, t, q))
    assert variance == pytest.approx(K_B * 300 / mode.stiffness, rel=0.10)


def test_noise_sources_follow_damping():
    """One trnoise source per damped coordinate, rms sqrt(2 k_B T b / dt); none when switched off."""
    model = small_model("q_factor = 2\nnoise = true\n")
    text = subcircuit(model)
    assert text.count("TRNOISE(") == 1 and "params: noise=1" in text      # z is undamped
    assert "TRNOISE(" not in subcircuit(model, noise=False)


def test_veriloga_white_noise_compiles(tmp_path):
    """The Verilog-A module with thermal noise (white_noise per coordinate, PSD from d_<q>)
    compiles with openvaf-r, warnings denied; without noise it has no white_noise."""
    from netgen.emit_veriloga import module
    from netgen.vacask import compile_va

    model = small_model("q_factor = 2\nnoise = true\n")
    va = tmp_path / "noisy.va"
    va.write_text(module(model))
    assert va.read_text().count("white_noise(") == model.ncoords
    compile_va(va)
    assert "white_noise(" not in module(model, noise=False)
