"""The inertial loads under the etch parameter (netgen.model.process_loads) against hand sums of the
etched body, and the emitted .lib's a_in load against the same hand sum through ngspice.

References:
- the a_in load of the perforated proof mass (tests/oracles/process_cases.PERFORATED: 405 um side, 40 x 40
  holes of 4 um, 2 um thick) at etch e: G(e) = rho t ((L - 2e)^2 - N (h + 2e)^2) (the outline recedes,
  the holes grow on the drawn grid, netgen.model.process.etched), and 0 on the tilts (symmetry);
- accelerometer_xyz (tests/oracles/process_cases.xyz_text: 400 um side, 40 x 40 holes of 4 um, 80
  moving fingers 40 um beyond the edge, 2 um wide; the rate w_z added) at etch e: the moving mass
  M(e) = rho t ((L - 2e)^2 - N (h + 2e)^2 + 80 (w - 2e) l) finger by finger (the fingers narrow and
  keep their length beyond the receding edge, tests/mechanics/test_mass_count.py), and the
  translations' in-plane participation P_x[x] = P_y[y] = M(e), Coriolis G_z[x, y] = -G_z[y, x] =
  2 M(e) in magnitude (2 int rho e_x . (e_z x e_y)) and centrifugal S_zz[x, x] = -M(e) (-int rho
  |e_x|^2); every entry at an etch between the fit points against the terms on the structure etched
  there;
- the crab-leg mass with tilts and rates (tests/oracles/process_inertial) with tscale and etch: at the
  (tscale, etch) corners the tilts' Coriolis coupling, the plate's rotary inertia, against
  -2 rho t^3 (200 um - 2e)^2 / 12, the a_in load against rho t (200 um - 2e)^2, and every entry
  against the terms on the structure scaled and etched there (the mid-plane and rotary parts each
  with its own etch ratio);
- ngspice 39's .op of the emitted .lib at etch e: the deflection under a_in = 9.81 m/s^2 against the
  same circuit loaded instead through its force port with the hand load -G(e) 9.81 N: the spring,
  whatever its etch law, is the same on both sides, so only the load is compared.

Tolerances: the laws are cubics fitted through five etch points to an area that is quadratic in the
etch (exact: the least squares reproduce it up to the Vandermonde matrix's conditioning over
etch / 1 um in [-0.1, 0.1], cond ~ 1e5, times the double round-off 1.1e-16: 1e-11), plus the model's
stated residual of the law (process_loads max_rel_error, 0 here); ngspice's .op converges to its
reltol (1e-9 set) on each of the two runs.
"""

from __future__ import annotations

import numpy as np
import pytest

from netgen.emit import ngspice as emit_ngspice
from netgen.mechanics import inertial, mechanics
from netgen.model.process import etched, law_value, ratio_value, scaled
from netgen.sim.ngspice import run_ngspice
from netgen.structure import parse_structure
from tests.fixtures import shared_model as build_model
from tests.oracles.process_cases import PERFORATED_ETCHES, PERFORATED_RANGE, perforated, xyz_mass, xyz_structure
from tests.oracles.process_inertial import T_UM
from tests.oracles.process_inertial import structure as rate_structure
from tests.oracles.testbench import Bench, states, using_ngspice

RHO, T, G = 2330.0, 2e-6, 9.81
ROUND = 1e-11  # the cubic's round-off (module docstring)
RELTOL = 1e-9


def perforated_g(etch: float) -> float:
    """The hand a_in load per m/s^2 of PERFORATED at etch (module docstring)."""
    return RHO * T * ((405e-6 - 2 * etch) ** 2 - 1600 * (4e-6 + 2 * etch) ** 2)


@pytest.fixture(scope="module")
def plate():
    """The perforated mass with etch declared and the a_in port."""
    text = perforated(process=PERFORATED_RANGE).replace(
        'rigid = ["z", "tilt_x", "tilt_y"]', 'rigid = ["z", "tilt_x", "tilt_y"]\nacceleration_port = true'
    )
    return build_model(parse_structure(text, "px.toml"))


@pytest.fixture(scope="module")
def xyz():
    """accelerometer_xyz with etch declared and the rate w_z, built."""
    return build_model(xyz_structure())


@pytest.fixture(scope="module")
def tilted():
    """The crab-leg mass with tilts and rates (tests/oracles/process_inertial) with tscale and etch."""
    s = parse_structure(rate_structure(T_UM) + '[process]\nparameters = ["tscale", "etch"]\n', "gyp.toml")
    return build_model(s), s


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_a_in_load_follows_the_etched_plate(plate, etch):
    """G_z(etch) = rho t ((L - 2e)^2 - N (h + 2e)^2) on the perforated plate, G = 0 on the tilts;
    before, the load stayed at the drawn plate's (1.9e-2 / 2.1e-2 off at -0.1 / 0.1 um: the 1600
    holes grow with the etch)."""
    law = plate.process["etch"]["acceleration"]
    got = [g * ratio_value(r, etch) for g, r in zip(plate.acceleration, law["ratio"])]
    iz = [c.name for c in plate.coordinates].index("z")
    tol = ROUND + law["max_rel_error"]
    assert got[iz] == pytest.approx(perforated_g(etch), rel=tol, abs=0)
    assert [g for v, g in enumerate(got) if v != iz] == [0.0, 0.0]
    assert abs(plate.acceleration[iz] / perforated_g(etch) - 1) > 100 * tol  # the drawn load is off


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_lib_a_in_deflection_against_the_hand_load(plate, tmp_path, etch):
    """ngspice's .op of the .lib at etch: the deflection under a_in = g equals the one under the force
    port's hand load -G(etch) g (the same spring), within the two runs' reltol."""
    lib = tmp_path / "px.lib"
    lib.write_text(emit_ngspice.subcircuit(plate))
    iz = [c.name for c in plate.coordinates].index("z")
    port = -perforated_g(etch) * G / plate.coordinates[iz].port_units[3]
    x = {}
    for name, sources in (("a_in", {"a_in": f"DC {G!r}"}), ("f_z", {"f_z": f"DC {port!r}"})):
        bench = Bench(plate, lib, sources=sources | {plate.plate: "DC 0"}, options=f"reltol={RELTOL!r}")
        net = "\n".join(
            f"{ln} etch={etch!r}" if ln.startswith("X1 ") else ln for ln in bench.netlist(".op").split("\n")
        )
        with using_ngspice("39"):
            plot = run_ngspice(net, tmp_path / name)[0]
        x[name] = float(np.real(states(plot, plate)[0][0, iz]))
    assert x["a_in"] < 0
    assert x["a_in"] == pytest.approx(x["f_z"], rel=2 * RELTOL + ROUND)


@pytest.mark.parametrize("etch", [-1e-7, 4e-8, 1e-7])
def test_in_plane_inertial_terms_follow_the_etched_body(xyz, etch):
    """accelerometer_xyz at etch: the in-plane participation, the Coriolis coupling and the centrifugal
    stiffness of the translations against the hand sum of the etched plate and fingers."""
    names = [c.name for c in xyz.coordinates]
    ix, iy = names.index("x"), names.index("y")
    law = xyz.process["inertial"]["etch"]
    tol = ROUND + law["max_rel_error"]
    m = xyz_mass(etch)

    def at(kind: str, key: str, v: int, w: int | None = None) -> float:
        x = getattr(xyz.inertial, kind)[key][v]
        r = law["total"][kind][key][v]
        return float(x if w is None else x[w]) * ratio_value(r if w is None else r[w], etch)

    assert at("participation", "a_x", ix) == pytest.approx(m, rel=tol, abs=0)
    assert at("participation", "a_y", iy) == pytest.approx(m, rel=tol, abs=0)
    assert abs(at("gyroscopic", "z", ix, iy)) == pytest.approx(2 * m, rel=tol, abs=0)
    assert at("gyroscopic", "z", iy, ix) == pytest.approx(-at("gyroscopic", "z", ix, iy), rel=tol, abs=0)
    assert at("centrifugal", "zz", ix, ix) == pytest.approx(-m, rel=tol, abs=0)
    # the model's coordinate mass follows the same etched body (its own law, netgen.model.process)
    knots = tuple(xyz.process["etch"].get("knots", ()))  # the crab legs' torsion knot (netgen.model.etch_knots)
    mass = law_value(xyz.process["coordinates"][ix], "mass", 1.0, etch, knots)
    assert mass == pytest.approx(m, rel=tol + xyz.process["etch"]["max_rel_error"])


def test_every_inertial_entry_between_the_fit_points(xyz):
    """Every inertial entry of accelerometer_xyz (the rotations' too: rot_z, tilts under w_z) at an etch
    between the law's fit points (70 nm) against the terms evaluated on the structure etched there
    (netgen.mechanics.inertial.terms on netgen.model.process.etched, its mechanics re-run): the cubic
    misses an entry's quartic part (a second area moment of the etched outline, (2 etch / 400 um)^4 ~
    1e-15 relative) and the round-off (ROUND); relative to the largest entry of its table."""
    etch = 7e-8
    s = etched(xyz_structure(), etch)
    ref = inertial.terms(s, mechanics(s), ("a_x", "a_y", "w_z"))
    law = xyz.process["inertial"]["etch"]["total"]
    for kind in ("participation", "gyroscopic", "centrifugal", "centrifugal_force"):
        for key, x in getattr(xyz.inertial, kind).items():
            x, r = np.asarray(x, dtype=float), np.asarray(law[kind][key], dtype=float)
            got = x * (r @ np.array([1.0, etch * 1e6, (etch * 1e6) ** 2, (etch * 1e6) ** 3]))
            want = np.asarray(ref[kind][key], dtype=float)
            assert np.max(np.abs(got - want)) <= ROUND * np.max(np.abs(want)), (kind, key)


@pytest.mark.parametrize("tscale", (0.9, 1.1))
@pytest.mark.parametrize("etch", (-1e-7, 1e-7))
def test_rotary_and_mid_plane_parts_at_the_corners(tilted, tscale, etch):
    """With tscale and etch declared (the crab-leg mass of tests/oracles/process_inertial with tilts and
    rates), each entry is X ((1 - f) tscale R1(etch) + f tscale^3 R3(etch)), the two parts' own ratios:
    the tilts' Coriolis coupling under w_z, the plate's rotary inertia, against the closed form
    -2 rho t^3 (200 um - 2 etch)^2 / 12, and every entry against the terms on the structure scaled and
    etched at the corner, and the a_in load against rho t (200 um - 2 etch)^2; tolerance ROUND relative to the largest entry of its table (the t, t^3 laws
    are exact and the etched area quadratic)."""
    model, structure = tilted
    names = [c.name for c in model.coordinates]
    law = model.process["inertial"]
    u = np.array([1.0, etch * 1e6, (etch * 1e6) ** 2, (etch * 1e6) ** 3])

    def at(kind: str, key: str) -> np.ndarray:
        x, f = np.asarray(getattr(model.inertial, kind)[key]), np.asarray(law["t3_fraction"][kind][key])
        r1, r3 = (np.asarray(law["etch"][p][kind][key]) @ u for p in ("t", "t3"))
        return x * ((1 - f) * tscale * r1 + f * tscale**3 * r3)

    t = 5e-6 * tscale
    g = at("gyroscopic", "z")[names.index("tilt_x"), names.index("tilt_y")]
    assert abs(g) == pytest.approx(2 * RHO * t**3 * (200e-6 - 2 * etch) ** 2 / 12, rel=ROUND, abs=0)
    iz = names.index("z")  # and the a_in load, G tscale R(etch): rho t (200 um - 2 etch)^2
    load = model.acceleration[iz] * tscale * ratio_value(model.process["etch"]["acceleration"]["ratio"][iz], etch)
    assert load == pytest.approx(RHO * t * (200e-6 - 2 * etch) ** 2, rel=ROUND, abs=0)
    s = etched(scaled(structure, tscale), etch)
    ref = inertial.terms(s, mechanics(s), ("w_x", "w_y", "w_z"))
    for kind in ("gyroscopic", "centrifugal", "centrifugal_force"):
        for key in getattr(model.inertial, kind):
            want = np.asarray(ref[kind][key], dtype=float)
            assert np.max(np.abs(at(kind, key) - want)) <= ROUND * np.max(np.abs(want)), (kind, key)
