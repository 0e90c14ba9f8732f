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
from typing import Any

import numpy as np
import pytest

from netgen.core.constants import EPS0
from netgen.mechanics import mechanics
from netgen.mechanics.damping import damping
from netgen.model.process import coordinate_values, viscosity_ratio
from netgen.structure import parse_structure
from tests.fixtures import ROOT
from tests.fixtures import shared_model as build_model
from tests.oracles.process_cases import PROOF

PISTON = (ROOT / "examples/piston_process.toml").read_text()


def proof(t: float = 10.0, e: float = 160.0):
    return build_model(parse_structure(PROOF.format(t=t, e=e), "pm.toml"))


def full_rebuild(t: float = 10.0, e: float = 160.0, bot_um: float = 2.0):
    """The whole build (mechanics, electrostatics, fit) of the structure file rewritten at thickness
    t (um), modulus e (GPa) and bottom gap bot_um."""
    text = PROOF.format(t=t, e=e).replace(
        'name = "bot"\nside = "below"\ngap = "2 um"', f'name = "bot"\nside = "below"\ngap = "{bot_um!r} um"'
    )
    return build_model(parse_structure(text, "pm.toml"))


def capacitances_agree(nominal, model, dg: float = 0.0) -> None:
    """C of every electrode at 100 random points of the fit box: the nominal model (plate electrodes:
    unchanged by tscale and escale; the bottom set shifted by dg as the emitters do) against `model`,
    within the larger of the two fits' held-out errors and the sampling tolerance."""
    rng = np.random.default_rng(7)
    scales = np.array([c.scale for c in nominal.coordinates])
    q = rng.uniform(-0.2, 0.2, (100, nominal.ncoords)) * scales
    shift = np.zeros(nominal.ncoords)
    shift[[c.name for c in nominal.coordinates].index("z")] = dg
    got = nominal.capacitance(q / scales)
    bot = [e.name for e in nominal.electrodes].index("bot")
    got[:, bot] = nominal.capacitance((q + shift) / scales)[:, bot]
    ref = model.capacitance(q / np.array([c.scale for c in model.coordinates]))
    errs = [f.max_rel_error for f in nominal.capacitances + model.capacitances]
    np.testing.assert_allclose(got, ref, rtol=max([nominal.sampling["tolerance"], *errs]))


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
    the mass and the flexures) scaled in the structure file (mechanics and damping re-run); the
    damping too (squeeze film: the gap sets it, a solid plate's film does not depend on the
    thickness); the capacitances at 100 points against the full rebuild's (unchanged)."""
    law = nominal.process
    ref = rebuilt(t=10.0 * tau)
    capacitances_agree(nominal, full_rebuild(t=10.0 * tau))
    vals = [coordinate_values(law, v, tscale=tau) for v in range(nominal.ncoords)]
    np.testing.assert_allclose(frequencies(vals), frequencies(ref), rtol=1e-4)
    np.testing.assert_allclose([v[0] for v in vals], [r[0] for r in ref], rtol=1e-4)
    np.testing.assert_allclose([v[2] for v in vals], [r[2] for r in ref], rtol=1e-4)


@pytest.mark.parametrize("e", [0.6, 1.0, 1.4])
def test_escale_against_rebuild(nominal, e):
    """Modal frequencies at escale against a full rebuild with Young's modulus scaled, and its
    capacitances at 100 points (unchanged by the modulus)."""
    vals = [coordinate_values(nominal.process, v, escale=e) for v in range(nominal.ncoords)]
    model = full_rebuild(e=160.0 * e)
    np.testing.assert_allclose(frequencies(vals), [c.frequency_hz for c in model.coordinates], rtol=1e-4)
    capacitances_agree(nominal, model)


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
        assert ratio == pytest.approx(float(viscosity_ratio("air", 101325.0, 2e-6, t0, np.array(tk))), rel=1e-12, abs=0)


def piston(gap_um: float = 2.0):
    return build_model(parse_structure(PISTON.replace('gap = "2 um"', f'gap = "{gap_um} um"'), "piston.toml"))


def shifted_capacitance(model, q: np.ndarray, dg: float) -> np.ndarray:
    """C of the nominal model with the gap offset applied as the emitters do: xs_z - sign dg / L."""
    g = model.process["gaps"][0]
    scale = model.coordinates[0].scale
    return model.capacitance((q - g["sign"] * dg)[:, None] / scale)[:, 0]


def pull_in(model, dg: float, k: float | None = None) -> float:
    """max over q of sqrt(2 k q / C'(q)) towards the electrode (q < 0 for the electrode below); k the
    model's stiffness unless given."""
    scale = model.coordinates[0].scale
    q = -np.linspace(1e-4, 0.55, 20001) * scale
    h = 1e-6 * scale
    dc = (shifted_capacitance(model, q + h, dg) - shifted_capacitance(model, q - h, dg)) / (2 * h)
    v2 = 2 * (model.coordinates[0].stiffness if k is None else k) * q / dc
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
    print(
        f"dg={dg_nm:g} nm: {v_model:.10g} V, closed form {v_model / v_closed - 1:.1e}, rebuilt {v_model / v_rebuilt - 1:.1e}"
    )
    assert v_model == pytest.approx(v_closed, rel=5e-4)


def pull_in_z(model, electrode: str, k: float, dg: float) -> float:
    """Pull-in voltage of `electrode` (below) along z alone: the maximum over the travel q < 0 of
    sqrt(2 k q / C'(q)), its C read at q - sign dg as the emitters shift it; on a 20001-point grid
    refined by a parabola through the best three."""
    v = [c.name for c in model.coordinates].index("z")
    scale, i = model.coordinates[v].scale, [e.name for e in model.electrodes].index(electrode)
    sign = next(g["sign"] for g in model.process["gaps"] if electrode in g["electrodes"])

    def cap(q: np.ndarray) -> np.ndarray:
        x = np.zeros((len(q), model.ncoords))
        x[:, v] = (q - sign * dg) / scale
        return model.capacitance(x)[:, i]

    q = -np.linspace(1e-4, 0.55, 20001) * scale
    h = 1e-6 * scale
    v2 = 2 * k * q / ((cap(q + h) - cap(q - h)) / (2 * h))
    j = int(np.argmax(v2))
    a, b, c = v2[j - 1 : j + 2]
    return math.sqrt(b + (c - a) ** 2 / (8 * (2 * b - a - c)))


def proof_z(t: float = 10.0, bot_um: float = 2.0):
    """The proof mass on z alone with one affine plate term per electrode (rigid = ["z"], degree 1:
    C = eps A / (g -+ z) to round-off) and the sampled box reaching the pull-in travel g/3."""
    text = PROOF.format(t=t, e=160.0).replace('rigid = ["z", "tilt_x", "tilt_y"]', 'rigid = ["z"]')
    text = (
        text.replace("degree = 2", "degree = 1")
        .replace("levels = 3", "levels = 5")
        .replace("range = 0.3", "range = 0.6")
    )
    text = text.replace(
        'name = "bot"\nside = "below"\ngap = "2 um"', f'name = "bot"\nside = "below"\ngap = "{bot_um!r} um"'
    )
    return build_model(parse_structure(text, "pm.toml"))


@pytest.fixture(scope="module")
def nominal_z():
    return proof_z()


@pytest.mark.parametrize("tau,dg_nm", [(0.92, -150.0), (1.0, 0.0), (1.08, 200.0)])
def test_pull_in_with_thickness_and_gap(nominal_z, tau, dg_nm):
    """The proof mass's pull-in towards the bottom plate (top at the plate's potential) with tscale
    and dg_bot applied to the nominal model (proof_z): against sqrt(8 k g^3 / (27 eps A)) with k the
    law's z stiffness at tscale (folded flexures bending out of plane: ~ t^3) and g = 2 um + dg,
    within 0.05 % (C = eps A / (g + z) to round-off: what is left is the grid's quadratic error,
    ~1e-9); against a full rebuild at that thickness and gap within 0.2 % (the same two round-offs
    and half the stiffness law's error), its stiffness within twice the law's stated error (the
    cubic's residual at the five re-run thicknesses, 1.6e-4 for these folded flexures, whose truss
    torsion is no power law of t; between the points a smooth residual stays within twice it) and
    its capacitances at 100 points within the fits' held-out errors."""
    law, dg = nominal_z.process, dg_nm * 1e-9
    k = coordinate_values(law, 0, tscale=tau)[1]
    bot = next(e for e in nominal_z.electrodes if e.name == "bot")
    g = 2e-6 + dg
    v_model = pull_in_z(nominal_z, "bot", k, dg)
    v_closed = math.sqrt(8 * k * g**3 / (27 * EPS0 * bot.area))
    assert v_model == pytest.approx(v_closed, rel=5e-4)
    model = proof_z(t=10.0 * tau, bot_um=2.0 + dg_nm * 1e-3)
    v_rebuilt = pull_in_z(model, "bot", model.coordinates[0].stiffness, 0.0)
    print(
        f"tscale={tau} dg={dg_nm:g} nm: {v_model:.10g} V, closed form {v_model / v_closed - 1:.1e}, "
        f"rebuilt {v_model / v_rebuilt - 1:.1e}"
    )
    assert k == pytest.approx(model.coordinates[0].stiffness, rel=2 * law["tscale"]["max_rel_error"])
    assert v_model == pytest.approx(v_rebuilt, rel=2e-3)
    capacitances_agree(nominal_z, model, dg)


def proof_z_plain(e: float) -> Any:
    """proof_z rebuilt at modulus e (GPa): a plain build (no squeeze film, which the pull-in does not
    read; [process] with dg alone, so no law re-runs, for pull_in_z's gap sign)."""
    text = PROOF.format(t=10.0, e=e).replace('rigid = ["z", "tilt_x", "tilt_y"]', 'rigid = ["z"]')
    text = (
        text.replace("degree = 2", "degree = 1")
        .replace("levels = 3", "levels = 5")
        .replace("range = 0.3", "range = 0.6")
    )
    text = text.replace("[damping]\nsqueeze_film = true\n", "")
    text = text.replace('parameters = ["dg", "tscale", "escale", "temp"]', 'parameters = ["dg"]')
    assert 'parameters = ["dg"]' in text and "squeeze_film" not in text
    return build_model(parse_structure(text, "pm.toml"))


@pytest.mark.parametrize(
    "escale,temp_c", [(0.5, None), (1.0, None), (1.5, None), (1.0, -40.0), (1.0, 25.0), (1.0, 125.0)]
)
def test_pull_in_with_modulus_and_temperature(nominal_z, escale, temp_c):
    """The proof mass's pull-in towards the bottom plate with escale (0.5, 1, 1.5: its range) or the
    die temperature (-40, 25, 125 degC) applied to the nominal model: the law's stiffness
    escale (1 + tc (T - T0)) a(1) + b(1) (netgen.model.process.coordinate_values).
    - Against sqrt(8 k g^3 / (27 eps A)) with k = k0 escale (1 + tc (T - T0)), k0 the nominal frame
      solve's: linear elasticity makes every frame stiffness proportional to E, so what is left is
      the law's stated escale error on k (half of it on V ~ sqrt(k)) and the grid's quadratic error
      (~1e-9; C = eps A / (g + z) to round-off).
    - Against a full rebuild at the modulus 160 GPa escale (1 + tc (T - T0)) (its own frame solve and
      plate fit): the same, plus the two plate fits' slope errors by Markov's inequality, 4 e / R
      each on the box |z| <= R g (round-off here: e ~ 2e-15)."""
    law = nominal_z.process
    t0 = law["temperature_C"]
    factor = escale * (1 + law["modulus_tc_per_K"] * ((t0 if temp_c is None else temp_c) - t0))
    k = coordinate_values(law, 0, escale=escale, temp_c=temp_c)[1]
    area = next(e for e in nominal_z.electrodes if e.name == "bot").area
    v_model = pull_in_z(nominal_z, "bot", k, 0.0)
    v_closed = math.sqrt(8 * nominal_z.coordinates[0].stiffness * factor * 2e-6**3 / (27 * EPS0 * area))
    model = proof_z_plain(160.0 * factor)
    v_rebuilt = pull_in_z(model, "bot", model.coordinates[0].stiffness, 0.0)
    print(
        f"escale={escale} temp={temp_c}: {v_model:.10g} V, closed form {v_model / v_closed - 1:.1e}, "
        f"rebuilt {v_model / v_rebuilt - 1:.1e}"
    )
    bound = 0.5 * law["escale"]["max_rel_error"] + 1e-9
    assert bound < 5e-4
    assert v_model == pytest.approx(v_closed, rel=bound)
    errors = [f.max_rel_error for f in nominal_z.capacitances + model.capacitances]
    markov = 4 * max(errors) / nominal_z.sampling["range"]
    assert v_model == pytest.approx(v_rebuilt, rel=bound + 1e-9 + 2 * markov)


@pytest.mark.parametrize("temp_c", [-40.0, 25.0, 125.0])
def test_given_spring_pull_in_at_temperature(nominal_piston, temp_c):
    """examples/piston_process.toml at the die temperature: its spring is a given number (no modulus
    behind it), so the law's stiffness stays 2 N/m and the pull-in stays at sqrt(8 k g^3 / (27 eps A))
    (within the grid's quadratic error ~1e-9 and the 1/P fit's round-off; the 0.05 % of the brief is
    the looser bound)."""
    law = nominal_piston.process
    k = coordinate_values(law, 0, temp_c=temp_c)[1]
    assert k == pytest.approx(2.0, rel=1e-12)
    v_closed = math.sqrt(8 * 2.0 * 2e-6**3 / (27 * EPS0 * nominal_piston.electrodes[0].area))
    v_model = pull_in(nominal_piston, 0.0, k)
    print(f"temp={temp_c}: {v_model:.10g} V, closed form {v_model / v_closed - 1:.1e}")
    assert v_model == pytest.approx(v_closed, rel=1e-8)
