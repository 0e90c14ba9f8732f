"""The proof mass's rigid body by hand: the etch-hole count where floating-point `//` falls one
short (400e-6 // 10e-6 is 39), shared by the mass, fill factor, etched copy and FastCap mesh
(netgen.structure.holes.grid_count); and the moving comb fingers' mass and inertia (netgen.mechanics
.proof_mass.finger_inertia) against a finger-by-finger parallel-axis sum written out here, their
share of the internal modes' masses and participations (netgen.mechanics.proof_mass.finger_modes)
against a root-by-root integral, and the moving mass in the contact penalty and the flexure mass
fraction."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.integrate import simpson

from netgen.build import build
from netgen.electrostatics.fastcap_mesh import hole_edges
from netgen.mechanics import mechanics
from netgen.mechanics.base import participation
from netgen.mechanics.rect_plate import conductor_modes
from netgen.model.process import etched
from netgen.structure import parse_structure

RHO, T = 2330.0, 2e-6

BASE = """
name = "mc"
[conductor]
kind = "proof_mass"
length = "400 um"
width = "400 um"
thickness = "2 um"
density = "2330 kg/m^3"
hole = "4 um"
hole_pitch = "0.01 mm"
[conductor.flexure]
type = "clamped_guided"
axis = "y"
length = "100 um"
width = "2 um"
[[electrodes]]
name = "zs"
side = "below"
gap = "2 um"
x = ["-50 um", "50 um"]
y = ["-50 um", "50 um"]
[coordinates]
rigid = ["x", "y", "z", "rot_z", "tilt_x", "tilt_y"]
[electrostatics]
comb_model = "textbook"
"""

# the differential transverse pair: the same fingers, faced on side + (tp) and side - (tn)
TRANSVERSE = """
[[electrodes]]
name = "{name}"
kind = "transverse_comb"
orientation = "y"
fingers = 5
width = "2 um"
gap = "1.5 um"
length = "40 um"
overlap = "30 um"
side = "{side}"
center = ["30 um", "225 um"]"""
COMBS = (
    TRANSVERSE.format(name="tp", side="+")
    + TRANSVERSE.format(name="tn", side="-")
    + """
[[electrodes]]
name = "lr"
kind = "lateral_comb"
orientation = "x"
fingers = 4
width = "3 um"
gap = "2 um"
length = "50 um"
overlap = "20 um"
side = "+"
pitch = "10 um"
center = ["230 um", "-40 um"]
"""
)


# the fingers of COMBS by hand: (root centre x, y on the mass's edge, width, length beyond the
# edge, the axis along the edge); tp/tn: pitch 3 (w + g) = 10.5 um on the top edge y = 200 um, tips
# at 240 um; lr: pitch 10 um on the right edge x = 200 um, roots drawn at 190 um, tips at 240 um
ROOTS = [(30e-6 + (k - 2) * 10.5e-6, 200e-6, 2e-6, 40e-6, "x") for k in range(5)]
ROOTS += [(200e-6, -40e-6 + (k - 1.5) * 10e-6, 3e-6, 40e-6, "y") for k in range(4)]
PLATE = RHO * T * (400e-6**2 - 1600 * 4e-6**2)  # the perforated plate's mass (40 x 40 holes of 4 um)
FINGERS = sum(RHO * T * w * length for _, _, w, length, _ in ROOTS)


def structure(extra: str = "", coordinates: str = ""):
    return parse_structure(BASE.replace("[coordinates]", extra + "[coordinates]" + coordinates), "mc.toml")


def test_hole_count_where_the_pitch_divides_the_side():
    """400 um / 0.01 mm (parsed 3.9999999999999996e-4 / 1e-5, whose `//` is 39.0): 40 x 40 holes, mass
    rho t (L W - 1600 h^2) to round-off; the fill factor, the etched copy's grid and the FastCap mesh's
    rows count the same 40."""
    c = structure().conductor
    assert c.length // c.hole_pitch == 39.0  # the floating-point floor this guards against
    assert c.holes() == (40, 40)
    assert c.mass == pytest.approx(RHO * T * (400e-6**2 - 1600 * 4e-6**2), rel=1e-12)
    assert c.fill_factor == pytest.approx(1 - 1600 * 16 / 160000, rel=1e-12)
    assert etched(structure(), 0.1e-6).conductor.holes() == (40, 40)
    assert len(hole_edges(-c.length / 2, c.length / 2, c.hole, c.hole_pitch)) == 40


def test_moving_fingers_mass_and_inertia_by_hand():
    """A differential transverse pair (tp, tn: the same 5 fingers, faced on either side: counted
    once) at the top edge and a lateral comb whose roots are drawn 10 um inside the right edge (only
    the 40 um beyond it is finger): mass and the six inertias against the plate's (holes by hand,
    their second moments by the grid sum) plus each finger box's m (a^2 + b^2) / 12 + m r^2 (parallel
    axis), to round-off (1e-9); the vertical participation is the whole mass."""
    plain, combed = structure(), structure(COMBS)
    m0 = mechanics(plain)
    boxes = []  # (centre x, centre y, size along x, size along y) by hand from COMBS
    for k in range(5):  # pitch 3 (w + g) = 10.5 um, y from the edge 200 um to the tip 240 um
        boxes.append((30e-6 + (k - 2) * 10.5e-6, 220e-6, 2e-6, 40e-6))
    for k in range(4):  # tips at 240 um, roots at 190 um: 200..240 um beyond the edge
        boxes.append((220e-6, -40e-6 + (k - 1.5) * 10e-6, 40e-6, 3e-6))
    add = dict.fromkeys(m0.names, 0.0)
    for cx, cy, a, b in boxes:
        m = RHO * T * a * b
        for n in ("x", "y", "z"):
            add[n] += m
        add["rot_z"] += m * ((a * a + b * b) / 12 + cx * cx + cy * cy)
        add["tilt_x"] += m * (b * b / 12 + cy * cy + T * T / 12)
        add["tilt_y"] += m * (a * a / 12 + cx * cx + T * T / 12)
    m1 = mechanics(combed)
    assert m1.report["moving_fingers"] == 9
    for n, base, new in zip(m0.names, m0.masses, m1.masses):
        assert new == pytest.approx(base + add[n], rel=1e-9), n
    assert m0.masses[0] == pytest.approx(RHO * T * (400e-6**2 - 1600 * 4e-6**2), rel=1e-12)
    iz = m1.names.index("z")
    assert participation(combed, m1)[iz] == pytest.approx(m1.masses[iz], rel=1e-9)


def test_etched_fingers_narrow_and_follow_the_edge():
    """Under an etch bias e the fingers are w - 2 e wide and keep their length beyond the receding
    edge (root and tip recede together, netgen.model.process.etched_comb): the finger mass by hand."""
    e = 0.2e-6
    plain, combed = etched(structure(), e), etched(structure(COMBS), e)
    extra = mechanics(combed).masses[0] - mechanics(plain).masses[0]
    hand = RHO * T * (5 * (2e-6 - 2 * e) * 40e-6 + 4 * (3e-6 - 2 * e) * 40e-6)
    assert extra == pytest.approx(hand, rel=1e-9)
    assert dataclasses.asdict(combed.conductor)["hole_grid"] == (40, 40)


def test_fingers_on_the_internal_modes_by_root_integrals():
    """With modes = 3 each finger is a rigid box turning with the plate's edge at its root: a point s
    beyond the root moves phi + s dphi/dn (RectPlateModes.shape), so mode v's mass gains
    rho t int int (phi + s theta)^2 ds du = rho t L int (phi^2 + phi theta L + theta^2 L^2 / 3) du and its
    a_in participation rho t L int (phi + theta L / 2) du (the plate's own share is zero: free-plate
    modes are M-orthogonal to 1): phi and theta = dphi/dn at the root by the plate's shape inside it
    (theta a 0.1 nm one-sided difference: off by 0.1 nm |phi''| / 2, <= 0.1 nm k / 2 ~ 2e-6 of theta for
    wavelengths 2 pi / k >= 200 um, its rounding 1e-15 / 0.1 nm ~ 1e-9 of theta),
    across the root by composite Simpson over 400 panels, written out here. The mass gain to 1e-5:
    twice theta's errors (the reference's 2e-6; the code's second-order difference over 1e-4 of
    the plate, (40 nm)^2 |phi'''| / 3 ~ 6e-7 of theta; 2e-6 seen in all), plus the code's
    4-point Gauss rule across the root (exact along the finger: a quadratic in s) at a kink of
    phi'' where an element edge crosses a root, (w / 2)^2 times its relative jump, ~ h_el^2 k^2
    <= (16.7 um)^2 (2 pi / 200 um)^2 ~ 3 %, times (w / 2)^2 k^2 ~ 2e-4: 6e-6 of that finger's
    term at most. The participation within the plate's share that
    netgen.mechanics.base.participation itself sets to 0 as round-off, 1e-6 sqrt(M_v m) (5e-7 seen:
    the quadrature of phi over the plate against its FE mass matrix), plus the same 1e-5 of the
    fingers' share."""
    cols = "\nmodes = 3"
    bare, combed = structure(coordinates=cols), structure(COMBS, cols)
    m0, m1 = mechanics(bare), mechanics(combed)
    modes = conductor_modes(bare.conductor, 3)
    gain, load, scale = np.zeros(3), np.zeros(3), 0.0
    for cx, cy, w, length, along in ROOTS:
        u = np.linspace(-w / 2, w / 2, 401)
        x, y = (cx + u, np.full_like(u, cy)) if along == "x" else (np.full_like(u, cx), cy + u)
        inside = (x, y - 1e-10) if along == "x" else (x - 1e-10, y)  # both edges here face +y or +x
        phi = modes.shape(x, y)
        theta = (phi - modes.shape(*inside)) / 1e-10
        per_length = phi**2 + phi * theta * length + theta**2 * length**2 / 3
        gain += RHO * T * length * simpson(per_length, x=u, axis=0)
        load += RHO * T * length * simpson(phi + theta * length / 2, x=u, axis=0)
        scale += RHO * T * length * w
    idx = [m1.names.index(f"m{k}") for k in (1, 2, 3)]
    assert m1.masses[idx] - m0.masses[idx] == pytest.approx(gain, rel=1e-5, abs=0)
    g = np.array(participation(combed, m1))[idx]
    bound = 1e-6 * np.sqrt(m1.masses[idx] * (PLATE + FINGERS)) + 1e-5 * scale
    assert np.all(np.abs(g - load) <= bound), (g, load, bound)
    assert np.all(np.abs(load) > 100 * bound)  # the fingers' load is what the test sees
    fingers = m1.report["internal_modes"]["comb_fingers"]
    assert fingers["mass_added_rel"] == pytest.approx(list(gain / modes.modal_mass), rel=1e-5, abs=0)
    assert 0.0 < fingers["coupling_to_modes_z_and_tilts_max"] < 0.1


def test_contact_penalty_and_flexure_fraction_carry_the_moving_mass():
    """The stop points' penalty is critically damped against the moving mass m (netgen.model.contact:
    k = m (10 w_s)^2, c = 2 m 10 w_s, so m = c^2 / (4 k) whatever w_s): the plate's and the nine
    fingers' mass by hand, to round-off; the flexures' mass fraction is 4 beams of 100 x 2 x 2 um
    over that same moving mass."""
    combed = structure(COMBS)
    c = build(combed).model.contact
    assert c["damping"] ** 2 / (4 * c["stiffness"]) == pytest.approx(PLATE + FINGERS, rel=1e-12, abs=0)
    frac = mechanics(combed).report["flexure"]["flexure_mass_fraction"]
    assert frac == pytest.approx(4 * 100e-6 * 2e-6 * T * RHO / (PLATE + FINGERS), rel=1e-12, abs=0)
