"""Proof masses on flexures: each flexure type's k_x, k_y, k_z against its closed form from the
literature and against the 3-D frame solve of the same suspension (netgen.mechanics.frame), the
perforated mass's inertia against a brute-force integral, and the rigid in-plane modes of a
built, emitted model ringing down freely in ngspice 39 and 46 at sqrt(k/m), with k the
clamped-guided beams' closed form and m the hand-computed mass."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from netgen.build import build
from netgen.emit import ngspice as emit_ngspice
from netgen.mechanics import flexures, proof_mass
from netgen.mechanics.frame import Frame, Section
from netgen.sim.ngspice import run_ngspice
from netgen.structure import StructureError, parse_structure
from netgen.structure.flexures import Flexure
from tests.fixtures import Bench

E, NU, RHO = 160e9, 0.22, 2330.0

FLEXURES = {
    "clamped_guided": Flexure("clamped_guided", 150e-6, 2e-6, 2e-6, "y"),
    "clamped_guided_x": Flexure("clamped_guided", 120e-6, 3e-6, 2e-6, "x"),
    "folded": Flexure("folded", 150e-6, 2e-6, 2e-6, "y", truss_width=10e-6, spacing=8e-6),
    "crab_leg": Flexure("crab_leg", 100e-6, 2e-6, 2e-6, "y", thigh_length=60e-6, thigh_width=2e-6),
    "crab_leg_x": Flexure("crab_leg", 80e-6, 2.5e-6, 2e-6, "x", thigh_length=120e-6, thigh_width=3e-6),
}


def test_frame_element_reproduces_the_beam_formulas():
    """One member: clamped-guided 12 EI/L^3 (both planes), cantilever 3 EI/L^3, axial EA/L, torsion GJ/L."""
    s = Section(2e-6, 3e-6, E, E / (2 * (1 + NU)))
    f = Frame()
    f.member((0.0, 0.0), (100e-6, 0.0), s, 6)
    f.clamped.add(f.node(0.0, 0.0))
    f.tied.add(f.node(100e-6, 0.0))
    k = f.body_stiffness((100e-6, 0.0, 0.0))
    L = 100e-6
    assert k[1, 1] == pytest.approx(12 * E * s.thickness * s.width**3 / 12 / L**3, rel=1e-9)
    assert k[2, 2] == pytest.approx(12 * E * s.width * s.thickness**3 / 12 / L**3, rel=1e-9)
    c = np.linalg.inv(k)
    assert 1 / c[1, 1] == pytest.approx(3 * E * s.i_inplane / L**3, rel=1e-9)
    assert 1 / c[0, 0] == pytest.approx(E * s.area / L, rel=1e-9)
    assert 1 / c[3, 3] == pytest.approx(s.shear_modulus * s.torsion / L, rel=1e-9, abs=0)


@pytest.mark.parametrize("name", sorted(FLEXURES))
def test_flexure_closed_forms_match_the_frame_solve(name):
    """k_x, k_y, k_z of each flexure type: closed form (netgen.mechanics.flexures, sources named
    there) against the frame solve of the same suspension with rigid trusses, within 1 %; the
    closed-form numbers checked by hand for the straight and folded beams."""
    f = FLEXURES[name]
    closed = flexures.closed_form(f, E, NU)
    solved = flexures.frame_stiffness(f, 200e-6, 150e-6, E, NU, rigid_truss=True)
    for axis in ("x", "y", "z"):
        assert solved[axis] == pytest.approx(closed[axis], rel=0.01), axis
    across = "x" if f.axis == "y" else "y"
    n = {"clamped_guided": 4, "folded": 2}.get(f.type)
    if n:
        assert closed[across] == pytest.approx(n * E * f.thickness * f.width**3 / f.length**3, rel=1e-12, abs=0)
        assert closed["z"] == pytest.approx(n * E * f.width * f.thickness**3 / f.length**3, rel=1e-12, abs=0)
    assert solved["coupling"] < 1e-6  # four mirrored units: no coupling between coordinates


def test_crab_leg_limits():
    """A crab leg with a vanishing thigh is a clamped-guided shin across it (12 EI/L^3 each), and
    the closed form is symmetric in shin and thigh for equal legs (k_x = k_y)."""
    f = Flexure("crab_leg", 100e-6, 2e-6, 2e-6, "y", thigh_length=1e-9, thigh_width=2e-6)
    assert flexures.closed_form(f, E, NU)["x"] == pytest.approx(4 * E * 2e-6 * 8e-18 / 1e-12, rel=1e-4)
    g = Flexure("crab_leg", 100e-6, 2e-6, 2e-6, "y", thigh_length=100e-6, thigh_width=2e-6)
    k = flexures.closed_form(g, E, NU)
    assert k["x"] == pytest.approx(k["y"], rel=1e-12, abs=0)


def test_perforated_mass_inertia_against_a_brute_force_integral():
    """Mass and moments of inertia of a 300 x 200 um mass with 4 um holes on a 10 um grid against
    a 3000 x 2000 midpoint sum over the solid/hole indicator."""
    text = STRUCTURE.replace('hole = "0 um"', 'hole = "4 um"').replace('hole_pitch = "0 um"', 'hole_pitch = "10 um"')
    c = parse_structure(text, "pm.toml").conductor
    n = (3000, 2000)
    x = (np.arange(n[0]) + 0.5) / n[0] * c.length - c.length / 2
    y = (np.arange(n[1]) + 0.5) / n[1] * c.width - c.width / 2
    X, Y = np.meshgrid(x, y, indexing="ij")
    nx, ny = c.holes()
    hx = np.abs((X + nx * c.hole_pitch / 2) % c.hole_pitch - c.hole_pitch / 2) < c.hole / 2
    hy = np.abs((Y + ny * c.hole_pitch / 2) % c.hole_pitch - c.hole_pitch / 2) < c.hole / 2
    solid = ~(hx & hy & (np.abs(X) < nx * c.hole_pitch / 2) & (np.abs(Y) < ny * c.hole_pitch / 2))
    da = c.length * c.width / solid.size
    m = RHO * c.thickness * da * solid.sum()
    inert = proof_mass.inertia(c)
    assert c.mass == pytest.approx(m, rel=1e-3, abs=0)
    assert inert["rot_z"] == pytest.approx(RHO * c.thickness * da * np.sum(solid * (X**2 + Y**2)), rel=1e-3, abs=0)
    assert inert["tilt_x"] == pytest.approx(
        RHO * c.thickness * da * np.sum(solid * Y**2) + m * c.thickness**2 / 12, rel=1e-3, abs=0
    )


STRUCTURE = """
name = "pm"
[conductor]
kind = "proof_mass"
length = "300 um"
width = "200 um"
thickness = "2 um"
density = 2330
youngs_modulus = "160 GPa"
poisson_ratio = 0.22
hole = "0 um"
hole_pitch = "0 um"
[conductor.flexure]
type = "clamped_guided"
axis = "y"
length = "100 um"
width = "2 um"
[[electrodes]]
name = "xs"
kind = "transverse_comb"
orientation = "y"
fingers = 10
width = "2 um"
gap = "2 um"
length = "40 um"
overlap = "25 um"
side = "+"
center = ["0 um", "130 um"]
[coordinates]
rigid = ["x", "y", "rot_z"]
[electrostatics]
fringe = "none"
comb_model = "textbook"
"""


def body_by_hand() -> tuple[float, float]:
    """Mass and I_zz of STRUCTURE's body: the 300 x 200 x 2 um plate, m (L^2 + W^2) / 12, and comb
    xs's 10 moving fingers (2 x 40 um, pitch 3 (w + g) = 12 um, centres at y = 130 + 25 / 2 - 40 / 2
    = 122.5 um), each m_f (a^2 + b^2) / 12 + m_f r^2 (parallel axis)."""
    m = RHO * 300e-6 * 200e-6 * 2e-6
    i_zz = m * ((300e-6) ** 2 + (200e-6) ** 2) / 12
    m_f = RHO * 2e-6 * 40e-6 * 2e-6
    for k in range(10):
        cx, cy = (k - 4.5) * 12e-6, 122.5e-6
        i_zz += m_f * (((2e-6) ** 2 + (40e-6) ** 2) / 12 + cx * cx + cy * cy)
    return m + 10 * m_f, i_zz


def ring_down(model, lib: Path, workdir: Path, coordinate: str, freq: float, periods: int = 12) -> float:
    """Frequency (Hz) of the free ring-down of one coordinate released at t = 10 ns from the static
    deflection of a force (0.05 of its touching amplitude), from the mean of the zero-crossing periods."""
    c = next(c for c in model.coordinates if c.name == coordinate)
    force = 0.05 * c.scale * c.stiffness / c.port_units[3]
    t_end = periods / freq
    bench = Bench(
        model,
        lib,
        sources={f"f_{coordinate}": f"PWL(0 {force!r} 10n {force!r} 11n 0)", "plate": "0"},
        options="reltol=1e-7 abstol=1e-15 vntol=1e-12",
    )
    plot = run_ngspice(bench.netlist(f".tran {t_end / 4000!r} {t_end!r} 0 {t_end / 4000!r}"), workdir)[0]
    t, x = plot["time"], plot[f"x1.xs_{coordinate}"]
    s = np.sign(x)
    k = np.flatnonzero(s[1:] != s[:-1])
    zeros = t[k] - x[k] * (t[k + 1] - t[k]) / (x[k + 1] - x[k])
    return 1.0 / (2 * float(np.mean(np.diff(zeros))))


@pytest.mark.parametrize("release", ["39", "46"])
def test_in_plane_modes_ring_down_at_sqrt_k_over_m(tmp_path, release, monkeypatch):
    """x (beams bent across), y (beams stretched along) and rot_z ring down in ngspice at
    sqrt(k/m) within 0.1 %: k from the clamped-guided closed forms 4 E t w^3 / L^3 and
    4 E w t / L, rot_z against the model's k_rot / I_zz; m and I_zz by hand (body_by_hand)."""
    from netgen.sim import ngspice as sim_ngspice
    from tests.fixtures import NGSPICE

    monkeypatch.setenv(sim_ngspice.ENV, NGSPICE[release])
    b = build(parse_structure(STRUCTURE, "pm.toml"))
    lib = tmp_path / "pm.lib"
    lib.write_text(emit_ngspice.subcircuit(b.model))
    m, i_zz = body_by_hand()
    k = {"x": 4 * E * 2e-6 * (2e-6) ** 3 / (100e-6) ** 3, "y": 4 * E * 2e-6 * 2e-6 / 100e-6}
    rot = next(c for c in b.model.coordinates if c.name == "rot_z")
    expected = {
        "x": math.sqrt(k["x"] / m),
        "y": math.sqrt(k["y"] / m),
        "rot_z": math.sqrt(rot.stiffness / i_zz),
    }
    for name, w in expected.items():
        f = ring_down(b.model, lib, tmp_path, name, w / (2 * math.pi))
        assert f == pytest.approx(w / (2 * math.pi), rel=1e-3), name


@pytest.mark.parametrize(
    "edit, where, word",
    [
        (('type = "clamped_guided"', 'type = "spring"'), "conductor.flexure.type", "spring"),
        (('rigid = ["x", "y", "rot_z"]', 'rigid = ["x", "spin"]'), "coordinates.rigid", "spin"),
        (('overlap = "25 um"', 'overlap = "45 um"'), "electrodes[0].overlap", "shorter"),
        (('side = "+"', 'side = "up"'), "electrodes[0].side", "up"),
        (('hole = "0 um"', 'hole = "12 um"'), "conductor.hole_pitch", "hole grid"),
        (('kind = "transverse_comb"', 'kind = "comb"'), "electrodes[0].kind", "comb"),
    ],
)
def test_proof_mass_input_errors(edit, where, word):
    """Mistakes in a proof mass or its combs: StructureError naming the file, key and fix."""
    with pytest.raises(StructureError) as err:
        parse_structure(STRUCTURE.replace(*edit), "bad.toml")
    assert err.value.where == where and word in str(err.value) and err.value.fix


@pytest.mark.parametrize("hole", [0.0, 4e-6])
def test_squeeze_film_of_the_perforated_mass(hole):
    """z damping of the proof mass (incompressible film, holes as a smeared Poiseuille leak,
    netgen.mechanics.squeeze_film.perforation_leak) against the double sine series of the same
    equation on the rectangle within 1 %; holes lower it; in-plane coordinates get none."""
    from netgen.core.constants import GASES
    from netgen.mechanics import mechanics
    from netgen.mechanics import squeeze_film as sf
    from netgen.mechanics.damping import damping

    plate = '[[electrodes]]\nname = "zs"\nside = "below"\ngap = "2 um"\n[coordinates]'
    text = (
        STRUCTURE.replace('rigid = ["x", "y", "rot_z"]', 'rigid = ["x", "z"]').replace("[coordinates]", plate)
        + "[damping]\nsqueeze_film = true\nq_factor = { x = 30 }\n"
    )
    if hole:
        text = text.replace('hole = "0 um"', f'hole = "{hole * 1e6:g} um"').replace(
            'hole_pitch = "0 um"', 'hole_pitch = "10 um"'
        )
    s = parse_structure(text, "pm.toml")
    m = mechanics(s)
    d, _ = damping(s, m)
    mu = sf.effective_viscosity(GASES["air"], 101325.0, 2e-6)
    leak = sf.perforation_leak(2e-6, 2e-6, hole, 10e-6) if hole else 0.0
    ref = sf.rectangular_plate_leaky_series(mu, 300e-6, 200e-6, 2e-6, leak)
    iz = m.names.index("z")
    print(f"hole {hole:g} m: FEM {d[iz]:.6e} N*s/m, series {ref:.6e}, ratio {d[iz] / ref - 1:+.2e}")
    assert d[iz] == pytest.approx(ref, rel=0.01)
    ix = m.names.index("x")
    assert d[ix] == pytest.approx(2 * m.masses[ix] * 2 * math.pi * m.frequencies[ix] / 60, rel=1e-9, abs=0)  # Q only
    if hole:
        assert ref < 0.5 * sf.rectangular_plate_series(mu, 300e-6, 200e-6, 2e-6)


def test_free_body_accelerates_as_newton_says(tmp_path):
    """type = "none": a free proof mass, no springs; a constant force on f_x in ngspice moves it by
    F t^2 / (2 m) (m by hand: plate and moving fingers) within 0.1 % over 20 us, and nothing else moves."""
    import re

    text = re.sub(r"\[conductor.flexure\][^\[]*", '[conductor.flexure]\ntype = "none"\n', STRUCTURE)
    model = build(parse_structure(text, "free.toml")).model
    assert all(c.stiffness == 0.0 for c in model.coordinates)
    lib = tmp_path / "free.lib"
    lib.write_text(emit_ngspice.subcircuit(model))
    m, force, stop = body_by_hand()[0], 0.1e-6, 20e-6  # kg, N (0.1 V on f_x), s
    bench = Bench(model, lib, sources={"f_x": "DC 0.1", "plate": "0"}, options="reltol=1e-7")
    plot = run_ngspice(bench.netlist(f".tran 20n {stop!r} 0 20n uic"), tmp_path)[0]
    x = plot["x1.xs_x"][-1] * model.coordinates[0].scale
    assert x == pytest.approx(force * stop**2 / (2 * m), rel=1e-3, abs=0)
    assert x < 0.2 * model.coordinates[0].scale  # inside the sampled box
    assert abs(plot["x1.xs_y"]).max() < 1e-9 and abs(plot["x1.xs_rot_z"]).max() < 1e-9
