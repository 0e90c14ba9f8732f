"""Process instance parameters (netgen.model.process, netgen.emit.process): the parametric model
against full rebuilds at the parameter value and against closed forms.

Tolerances: the mass/stiffness laws are cubic polynomials in tscale fitted to the re-run mechanics;
for the power laws of rigid masses (t), beams in bending (t, t^3) and inertia (t, t^3) they are
exact, so the modal frequencies agree to round-off and 1e-4 is the brief's bound, not a measured
margin. The gap offset is an exact shift of z, so with fringe = "none" (pure parallel plates, whose
1/P fit is exact to round-off) the capacitances agree within the fit's own held-out error, and the
pull-in voltage, found by maximising V(q)^2 = 2 k q / C'(q) on a 20001-point grid of q refined by a
parabola through the best three, agrees with sqrt(8 k g^3 / (27 eps A)) to the grid's quadratic
error (about 1e-9), far inside 0.05 %."""

from __future__ import annotations

import math

import numpy as np
import pytest

from netgen.build import build_model
from netgen.core.constants import EPS0
from netgen.mechanics import mechanics
from netgen.mechanics.damping import damping
from netgen.model.process import coordinate_values, viscosity_ratio
from netgen.structure import parse_structure
from tests.fixtures import ROOT

PISTON = (ROOT / "examples/piston_process.toml").read_text()

PROOF = """
name = "pm"
description = "proof mass on folded flexures between plates"
[conductor]
kind = "proof_mass"
length = "300 um"
width = "300 um"
thickness = "{t} um"
density = "2330 kg/m^3"
youngs_modulus = "{e} GPa"
poisson_ratio = 0.22
[conductor.flexure]
type = "folded"
axis = "x"
length = "150 um"
width = "3 um"
truss_width = "10 um"
spacing = "10 um"
[[electrodes]]
name = "top"
side = "above"
gap = "2 um"
[[electrodes]]
name = "bot"
side = "below"
gap = "2 um"
[coordinates]
rigid = ["z", "tilt_x", "tilt_y"]
[sampling]
levels = 3
range = 0.3
[fit]
degree = 2
[electrostatics]
fringe = "none"
[damping]
squeeze_film = true

[process]
parameters = ["dg", "tscale", "escale", "temp"]
"""


def proof(t: float = 10.0, e: float = 160.0):
    return build_model(parse_structure(PROOF.format(t=t, e=e), "pm.toml"))


def rebuilt(t: float = 10.0, e: float = 160.0) -> list[tuple[float, float, float]]:
    """(mass, stiffness, damping) per coordinate of the structure file rewritten at thickness t and
    modulus e: the mechanics and damping stages re-run (the electrostatics do not change with them)."""
    s = parse_structure(PROOF.format(t=t, e=e), "pm.toml")
    m = mechanics(s)
    d, _ = damping(s, m)
    return list(zip(m.masses, m.stiffnesses, d))


@pytest.fixture(scope="module")
def nominal():
    return proof()


def frequencies(mass_stiff) -> np.ndarray:
    return np.array([math.sqrt(k / m) / (2 * math.pi) for m, k, _ in mass_stiff])


@pytest.mark.parametrize("tau", [0.92, 1.0, 1.08])
def test_tscale_against_rebuild(nominal, tau):
    """Modal frequencies and masses of the laws at tscale against a rebuild with the thickness (of
    the mass and the flexures) scaled in the structure file (mechanics and damping re-run); the damping too (squeeze film: the gap
    sets it, a solid plate's film does not depend on the thickness)."""
    law = nominal.process
    ref = rebuilt(t=10.0 * tau)
    vals = [coordinate_values(law, v, tscale=tau) for v in range(nominal.ncoords)]
    np.testing.assert_allclose(frequencies(vals), frequencies(ref), rtol=1e-4)
    np.testing.assert_allclose([v[0] for v in vals], [r[0] for r in ref], rtol=1e-4)
    np.testing.assert_allclose([v[2] for v in vals], [r[2] for r in ref], rtol=1e-4)


@pytest.mark.parametrize("e", [0.6, 1.0, 1.4])
def test_escale_against_rebuild(nominal, e):
    """Stiffness at escale against a rebuild with Young's modulus scaled; frequencies as sqrt(e)."""
    vals = [coordinate_values(nominal.process, v, escale=e) for v in range(nominal.ncoords)]
    np.testing.assert_allclose(frequencies(vals), frequencies(rebuilt(e=160.0 * e)), rtol=1e-4)


@pytest.mark.parametrize("temp_c", [-40.0, 25.0, 125.0])
def test_temperature_laws(nominal, temp_c):
    """The resonance against the modulus' temperature coefficient, f = f0 sqrt(1 + tc (T - T0)), and
    the squeeze-film damping against Sutherland's law written out here (mu ~ T^1.5 / (T + S), S = 111 K
    for air, White table 1-2) with Veijola's rarefaction and lambda ~ mu sqrt(T) (within the
    fitted polynomial's stated error, 1e-4 is its bound)."""
    law = nominal.process
    t0 = law["temperature_C"] + 273.15
    tk = temp_c + 273.15
    tc = law["modulus_tc_per_K"]
    assert tc == -60e-6
    for v, c in enumerate(nominal.coordinates):
        m, k, d = coordinate_values(law, v, temp_c=temp_c)
        assert math.sqrt(k / m) / (2 * math.pi) == pytest.approx(
            c.frequency_hz * math.sqrt(1 + tc * (tk - t0)), rel=1e-9
        )
        mu = (tk / t0) ** 1.5 * (t0 + 111.0) / (tk + 111.0)
        kn0 = 68e-9 / 2e-6
        kn = kn0 * mu * math.sqrt(tk / t0)
        ratio = mu * (1 + 9.638 * kn0**1.159) / (1 + 9.638 * kn**1.159)
        assert d == pytest.approx(c.damping * ratio, rel=1e-4)
        assert ratio == pytest.approx(float(viscosity_ratio("air", 101325.0, 2e-6, t0, np.array(tk))), rel=1e-12)


def piston(gap_um: float = 2.0):
    return build_model(parse_structure(PISTON.replace('gap = "2 um"', f'gap = "{gap_um} um"'), "piston.toml"))


def shifted_capacitance(model, q: np.ndarray, dg: float) -> np.ndarray:
    """C of the nominal model with the gap offset applied as the emitters do: xs_z - sign dg / L."""
    g = model.process["gaps"][0]
    scale = model.coordinates[0].scale
    return model.capacitance((q - g["sign"] * dg)[:, None] / scale)[:, 0]


def pull_in(model, dg: float) -> float:
    """max over q of sqrt(2 k q / C'(q)) towards the electrode (q < 0 for the electrode below)."""
    scale = model.coordinates[0].scale
    q = -np.linspace(1e-4, 0.55, 20001) * scale
    h = 1e-6 * scale
    dc = (shifted_capacitance(model, q + h, dg) - shifted_capacitance(model, q - h, dg)) / (2 * h)
    v2 = 2 * model.coordinates[0].stiffness * q / dc
    i = int(np.argmax(v2))
    a, b, c = v2[i - 1 : i + 2]
    return math.sqrt(b + (c - a) ** 2 / (8 * (2 * b - a - c)))


@pytest.fixture(scope="module")
def nominal_piston():
    return piston()


@pytest.mark.parametrize("dg_nm", [-200.0, 0.0, 250.0])
def test_gap_offset_against_rebuild(nominal_piston, dg_nm):
    """Capacitances at 100 displacements and the pull-in voltage of the nominal model with dg_drive
    against a rebuild with the gap 2 um + dg, and the pull-in against the closed form."""
    m = nominal_piston
    dg = dg_nm * 1e-9
    assert dg == 0 or abs(dg) <= m.process["gaps"][0]["max_m"] * 1.001
    rebuilt = piston(2.0 + dg_nm * 1e-3)
    rng = np.random.default_rng(7)
    q = rng.uniform(-0.25, 0.25, 100) * 2e-6
    c_ref = rebuilt.capacitance(q[:, None] / rebuilt.coordinates[0].scale)[:, 0]
    tol = max(m.sampling["tolerance"], rebuilt.capacitances[0].max_rel_error, m.capacitances[0].max_rel_error)
    np.testing.assert_allclose(shifted_capacitance(m, q, dg), c_ref, rtol=tol)
    v_model, v_rebuilt = pull_in(m, dg), pull_in(rebuilt, 0.0)
    assert v_model == pytest.approx(v_rebuilt, rel=2e-3)
    g = 2e-6 + dg
    v_closed = math.sqrt(8 * 2.0 * g**3 / (27 * EPS0 * m.electrodes[0].area))
    assert v_model == pytest.approx(v_closed, rel=5e-4)
