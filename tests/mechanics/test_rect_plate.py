"""The proof mass's internal modes (netgen.mechanics.rect_plate, [coordinates] modes = N) against
independent references: Leissa's tables of the rectangular plate (A. W. Leissa, "The free
vibration of rectangular plates", J. Sound Vib. 31(3), 257-293, 1973: 36-term Ritz, a/b = 1,
nu = 0.3) for all edges clamped (C-C-C-C) and all edges free (F-F-F-F, Ritz upper bounds), the
converged F-F-F-F values of Gorman's superposition solution (J. Sound Vib. 1978), the exact
all-edges simply supported rectangle (lambda^2 = pi^2 (m^2 + n^2 (a/b)^2), Leissa's eq. for
S-S-S-S), the perforated plate with its holes cut out of the mesh, and an ngspice ring-down of a
mode of a built proof mass (ngspice 39 and 46)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from netgen.build import build
from netgen.emit import ngspice as emit_ngspice
from netgen.mechanics.rect_plate import EffectivePlate, PlateSpec, rect_plate_modes
from netgen.structure import StructureError, parse_structure
from tests.fixtures import ROOT
from tests.mechanics.test_proof_mass import ring_down
from tests.structures import plate_electrode

# lambda^2 = omega a^2 sqrt(rho h / D) of the square plate, nu = 0.3
LEISSA_CCCC = [35.992, 73.413, 73.413, 108.27, 131.64, 132.24]  # Leissa 1973, C-C-C-C, a/b = 1
LEISSA_FFFF = [13.489, 19.789, 24.432, 35.024, 35.024]  # Leissa 1973, F-F-F-F, a/b = 1 (Ritz)
GORMAN_FFFF = [13.468, 19.596, 24.270, 34.801, 34.801, 61.093]  # Gorman 1978, superposition


def square(boundary: str, count: int, elements: int = 24, **kw):
    """Modes of the unit square plate with D = 1 (E chosen for h = 0.01, nu = 0.3) and rho h = 1."""
    h, nu = 0.01, 0.3
    return rect_plate_modes(PlateSpec(1.0, 1.0, h, 12 * (1 - nu**2) / h**3, nu, 1 / h), count, elements, boundary, **kw)


def test_clamped_square_against_leissa():
    """C-C-C-C: the first six lambda^2 within 0.1 % of Leissa's table (his Ritz values are upper
    bounds good to about 0.05 %), the degenerate pair (2,1)/(1,2) equal."""
    got = square("clamped", 6).lambda2
    assert got == pytest.approx(LEISSA_CCCC, rel=1e-3)
    assert got[1] == pytest.approx(got[2], rel=1e-9)


def test_free_square_against_leissa_and_gorman():
    """F-F-F-F (the proof mass's edges): below Leissa's Ritz upper bounds and within 1.2 % of them
    (beam functions converge slowly at free edges), within 0.01 % of Gorman's converged values; the
    modes M-orthogonal to the rigid translation and tilts."""
    m = square("free", 6)
    assert np.all(m.lambda2[:5] < LEISSA_FFFF)
    assert m.lambda2[:5] == pytest.approx(LEISSA_FFFF, rel=1.2e-2)
    assert m.lambda2 == pytest.approx(GORMAN_FFFF, rel=1e-4)
    assert max(m.orthogonality[k] for k in ("phi", "x_phi", "y_phi")) < 1e-9


def test_simply_supported_rectangle_exact():
    """S-S-S-S, a/b = 2: lambda^2 = pi^2 (m^2 + 4 n^2), exact, within 1e-4 for the first five."""
    m = rect_plate_modes(PlateSpec(2.0, 1.0, 0.01, 12 * 0.91 / 1e-6, 0.3, 100.0), 5, 32, "simply_supported")
    exact = sorted(math.pi**2 * (i * i + 4 * j * j) for i in range(1, 6) for j in range(1, 4))[:5]
    assert m.lambda2 == pytest.approx(exact, rel=1e-4)


def test_shape_beyond_the_edge_turns_with_the_edge():
    """A point s beyond an edge (a rigid comb finger clamped there) moves w + s dw/dn: on the S-S-S-S
    plate (a = 2, b = 1) the first mode is cos(pi x / a) cos(pi y / b) (peak 1 at the centre), so
    beyond x = a/2 it is -(pi / a) s cos(pi y / b) and beyond y = b/2 -(pi / b) s cos(pi x / a), exact.
    Within 1e-5 of the slope's peak: the BFS slope converges as h^3 (3.2e-5 at 16 elements along a,
    so 4e-6 at the 32 here; 3.3e-6 seen)."""
    m = rect_plate_modes(PlateSpec(2.0, 1.0, 0.01, 12 * 0.91 / 1e-6, 0.3, 100.0), 1, 32, "simply_supported")
    u, s = np.linspace(-0.45, 0.45, 7), 0.1
    beyond_x = m.shape(np.full_like(u, 1.0 + s), u)[:, 0]
    beyond_y = m.shape(u, np.full_like(u, 0.5 + s))[:, 0]
    assert beyond_x == pytest.approx(-math.pi / 2 * s * np.cos(math.pi * u), abs=1e-5 * math.pi / 2 * s)
    assert beyond_y == pytest.approx(-math.pi * s * np.cos(math.pi * u / 2), abs=1e-5 * math.pi * s)


def test_degenerate_pair_has_definite_parity_and_peak_one():
    """The square's (2,1)/(1,2) pair comes out as one mode even and one odd under x -> -x (the same
    on every machine), each with peak deflection 1."""
    m = square("free", 5)
    rng = np.random.default_rng(3)
    x, y = rng.uniform(-0.5, 0.5, 50), rng.uniform(-0.5, 0.5, 50)
    here, mirror = m.shape(x, y), m.shape(-x, y)
    assert np.abs(mirror[:, 3] - here[:, 3]).max() < 1e-8  # even
    assert np.abs(mirror[:, 4] + here[:, 4]).max() < 1e-8  # odd
    grid = np.linspace(-0.5, 0.5, 41)
    gx, gy = np.meshgrid(grid, grid)
    assert np.abs(m.shape(gx, gy)).max(axis=0) == pytest.approx(1.0, abs=1e-6)


def test_effective_perforated_plate_against_the_holes_in_the_mesh():
    """An 8 x 8 grid of 4 um holes on a 10 um pitch cut out of the mesh: the effective plate
    (mass fraction 0.84, series-strip D factor 0.789) lands closer than the solid plate on each of
    the first five free modes, within 2 % on the bending and twisting modes 1, 2, 4, 5 and 8 % on
    mode 3 (the isotropic model misses the grid's lower Poisson coupling)."""
    a = 80e-6
    p = PlateSpec(a, a, 2e-6, 160e9, 0.22, 2330.0)
    holes = rect_plate_modes(p, 5, elements=1, holes=(4e-6, 10e-6)).frequencies_hz
    eff = rect_plate_modes(p, 5, elements=16, effective=EffectivePlate.of_holes(4e-6, 10e-6)).frequencies_hz
    solid = rect_plate_modes(p, 5, elements=16).frequencies_hz
    err, err_solid = eff / holes - 1, solid / holes - 1
    assert np.all(np.abs(err) < np.abs(err_solid))
    assert np.abs(err[[0, 1, 3, 4]]).max() < 0.02
    assert abs(err[2]) < 0.08


STRUCTURE = (
    """
name = "pm_modes"
[conductor]
kind = "proof_mass"
length = "200 um"
width = "200 um"
thickness = "2 um"
density = 2330
youngs_modulus = "160 GPa"
poisson_ratio = 0.3
[conductor.flexure]
type = "given"
k_z = 1.0
"""
    + plate_electrode("corner", "below", "2 um", ("20 um", "90 um"), ("20 um", "90 um"))
    + """[coordinates]
rigid = ["z"]
modes = 2
acceleration_port = true
[electrostatics]
fringe = "none"
[sampling]
levels = 3
"""
)


@pytest.mark.parametrize("release", ["39", "46"])
def test_first_internal_mode_rings_down_at_gorman_frequency(tmp_path, release, monkeypatch):
    """m1 of a free 200 um square polysilicon plate (nu = 0.3, the twisting mode) rings down in
    ngspice at lambda^2 / (2 pi a^2) sqrt(D / rho h), lambda^2 = 13.468 (Gorman), within 0.1 %;
    the free modes take no frame acceleration (orthogonal to the translation)."""
    from netgen.sim import ngspice as sim_ngspice
    from tests.fixtures import NGSPICE

    monkeypatch.setenv(sim_ngspice.ENV, NGSPICE[release])
    b = build(parse_structure(STRUCTURE, "pm_modes.toml"))
    assert [c.name for c in b.model.coordinates] == ["z", "m1", "m2"]
    lib = tmp_path / "pm.lib"
    lib.write_text(emit_ngspice.subcircuit(b.model))
    d = 160e9 * 2e-6**3 / (12 * (1 - 0.3**2))
    f1 = GORMAN_FFFF[0] / (2 * math.pi * 200e-6**2) * math.sqrt(d / (2330 * 2e-6))
    assert ring_down(b.model, lib, tmp_path, "m1", f1) == pytest.approx(f1, rel=1e-3)
    assert b.model.acceleration[1:] == [0.0, 0.0]
    assert b.model.acceleration[0] == pytest.approx(2330 * 2e-6 * 200e-6**2, rel=1e-9, abs=0)


def test_perforated_mass_takes_the_frame_acceleration_of_its_own_mass():
    """With etch holes, the a_in participation of z is the perforated mass (solid fraction 0.84
    of the rectangle's), the mass the dynamics carries: no 1/0.84 error in the sensitivity."""
    text = STRUCTURE.replace("poisson_ratio = 0.3", 'poisson_ratio = 0.3\nhole = "4 um"\nhole_pitch = "10 um"')
    text = text.replace("modes = 2", "modes = 0")
    s = parse_structure(text, "pm_holes.toml")
    b = build(s)
    solid = 2330 * 2e-6 * (200e-6**2 - 400 * 4e-6**2)
    assert b.model.acceleration[0] == pytest.approx(solid, rel=1e-9, abs=0)
    assert b.model.coordinates[0].mass == pytest.approx(solid, rel=1e-9, abs=0)


@pytest.mark.parametrize("value", ["-1", "13", '"two"', "true", "2.5"])
def test_bad_mode_count_names_the_key(value):
    """modes outside 0..12 or not an integer: a StructureError at coordinates.modes."""
    with pytest.raises(StructureError) as err:
        parse_structure(STRUCTURE.replace("modes = 2", f"modes = {value}"), "pm_modes.toml")
    assert "coordinates.modes" in str(err.value)


def test_flexure_springs_on_the_modes_against_the_plate_with_point_springs():
    """The example's mass (400 um, crab legs, holes, 80 comb fingers) with modes = 3: each mode's
    frequency with the flexures' vertical springs added (first order) and the fingers' mass (rigid
    boxes turning with the edge at their roots: netgen.mechanics.proof_mass.finger_modes) within
    0.2 % of an eigensolve of the effective plate with the springs (k_z / 4 at each attachment
    point) in its stiffness matrix and the fingers' kinetic energy in its mass matrix. The model's
    frequencies are Rayleigh quotients of the free-plate shapes, the eigensolve's shapes adapt and
    keep every coupling: the error is second order in the change, 1.3e-3 on m2 (fingers +28 % of
    its mass, above the eigensolve as Rayleigh's principle has it), 1.6e-4 on m1, 5e-5 on m3 (coupled
    by 4.8 % to z, reported and dropped); without the fingers the model sat 2 % to 9 % off."""
    from scipy.sparse.linalg import eigsh

    from netgen.mechanics import flexures, mechanics, rect_plate
    from netgen.mechanics.free_disk import bending_form, mass_form

    text = (ROOT / "examples" / "accelerometer_xyz.toml").read_text()
    text = text.replace(
        'rigid = ["x", "y", "z", "rot_z", "tilt_x", "tilt_y"]',
        'rigid = ["x", "y", "z", "rot_z", "tilt_x", "tilt_y"]\nmodes = 3',
    )
    s = parse_structure(text, "accelerometer_xyz.toml")
    m, c = mechanics(s), s.conductor
    got = m.frequencies[-3:]
    eff = EffectivePlate.of_holes(c.hole, c.hole_pitch)
    basis = rect_plate.plate_basis(c.length, c.width, rect_plate.ELEMENTS)
    d = c.youngs_modulus * eff.stiffness_factor * c.thickness**3 / (12 * (1 - c.poisson_ratio**2))
    frame = flexures.suspension(c.flexure, c.length / 2, c.width / 2, c.youngs_modulus, c.poisson_ratio)
    ties = np.array([frame.nodes[i][:2] for i in sorted(frame.tied)]).T / c.length
    k_tie = flexures.frame_stiffness(c.flexure, c.length / 2, c.width / 2, c.youngs_modulus, c.poisson_ratio)["z"] / 4
    probe = basis.probes(np.clip(ties, -0.5 + 1e-12, 0.5 - 1e-12))
    K = d / c.length**2 * bending_form(c.poisson_ratio).assemble(basis) + k_tie * (probe.T @ probe)
    M = c.density * eff.density_factor * c.thickness * c.length**2 * mass_form.assemble(basis)
    # the example's fingers by hand: 20 per edge, 2 um wide on a 10.5 um pitch (3 (w + g)) centred on
    # the edge's middle, rigid boxes 40 um long from the edge: a finger point s beyond its root moves
    # w + s dw/dn, so a finger adds m (P^T P + L/2 (P^T D + D^T P) + L^2/3 D^T D) with P the root's
    # values (its width in 8 equal parts) and D their outward slopes (a 1e-6 L one-sided difference)
    across = ((np.arange(20) - 9.5) * 10.5e-6)[:, None] + (np.arange(8) - 3.5)[None, :] * 0.25e-6
    edge = np.full(across.size, c.length / 2)
    length, h = 40e-6 / c.length, 1e-6  # in units of the plate's length, as the basis
    for a, b in ((across.ravel(), edge), (across.ravel(), -edge), (edge, across.ravel()), (-edge, across.ravel())):
        root = np.clip(np.stack([a, b]) / c.length, -0.5 + 1e-12, 0.5 - 1e-12)
        normal = np.array([[0.0], [np.sign(b[0])]]) if abs(b[0]) == c.length / 2 else np.array([[np.sign(a[0])], [0.0]])
        P = basis.probes(root)
        D = (P - basis.probes(root - h * normal)) / h
        mf = c.density * c.thickness * 2e-6 * 40e-6 / 8
        M = M + mf * (P.T @ P + length / 2 * (P.T @ D + D.T @ P) + length**2 / 3 * (D.T @ D))
    mu = np.sort(eigsh(K.tocsc(), k=6, M=M.tocsc(), sigma=-1.0, which="LM", v0=np.ones(basis.N))[0])
    assert len(ties[0]) == 4 and m.report["moving_fingers"] == 80
    assert got == pytest.approx(np.sqrt(mu[3:]) / (2 * math.pi), rel=2e-3)
