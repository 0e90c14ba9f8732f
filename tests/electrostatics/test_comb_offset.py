"""Cross-axis coupling of a differential x comb on the 2-D field tables (comb_model = "field2d"):
a proof mass displaced in plane from the comb's symmetry (gaps 1.3 um and 1.7 um instead of
1.5 um on both sides), over the substrate, so the comb's out-of-plane derivative d2C/dx dz no
longer cancels between the two sides and a z acceleration moves x. ngspice's operating points
(39 and 46) against the Python MacroModel's static equilibrium, and against the 2-D section
tables' own derivatives (netgen.electrostatics.comb_section, independent of the fit); the centred
mass leaves x alone. The cell is the three-axis example's, so the converged tables the package
ships serve (seconds on a clean clone, no solve)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import fsolve

from netgen.build import build
from netgen.electrostatics import comb_section
from netgen.emit import ngspice as emit_ngspice
from netgen.sim.ngspice import run_ngspice
from netgen.structure import parse_structure
from tests.fixtures import NGSPICE, Bench, using_ngspice
from tests.structures import plate_electrode

UM = 1e-6
N, L, K, V, A = 20, 30 * UM, 2.0, 10.0, 1000.0  # fingers, overlap, N/m each axis, comb volts, m/s^2
COMB = """
[[electrodes]]
name = "{name}"
kind = "transverse_comb"
orientation = "y"
fingers = {n}
width = "2 um"
gap = "{gap} um"
length = "40 um"
overlap = "30 um"
side = "{side}"
root = "+"
pitch = "10.5 um"
substrate_gap = "2 um"
center = ["0 um", "125 um"]
"""
MASS = (
    f"""
name = "offset_comb"
[conductor]
kind = "proof_mass"
length = "200 um"
width = "200 um"
thickness = "2 um"
density = 2330
[conductor.flexure]
type = "given"
k_x = {K}
k_y = {K}
k_z = {K}
k_rot = 1e-6
"""
    + plate_electrode("zs", "below", "2 um", ("-50 um", "50 um"), ("-50 um", "50 um"))
    + """[coordinates]
rigid = ["x", "z"]
acceleration_port = true
[sampling]
levels = 7
range = 0.2
[fit]
degree = 5
"""
)


def structure(gap_p: float, gap_n: float) -> str:
    """The proof mass with its x comb: xp closing as x grows (gap_p um), xn opening (gap_n um), and
    a grounded plate below (z's stop; at the mass's potential it pulls nothing)."""
    return MASS + COMB.format(name="xp", n=N, gap=gap_p, side="+") + COMB.format(name="xn", n=N, gap=gap_n, side="-")


@pytest.fixture(scope="module")
def builds(tmp_path_factory):
    """The offset and the centred mass, built on one section table (same pitch, width, thickness
    and substrate: one cell geometry, the three-axis example's, whose converged tables the
    package ships: nothing is solved); the tables stay loaded for the references."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("NETGEN_CACHE", str(tmp_path_factory.mktemp("cache")))
        mp.setattr(comb_section, "_TABLES", {})
        mp.setattr(comb_section, "solve", lambda *a, **k: pytest.fail("solved a table the package ships"))
        yield {
            "offset": build(parse_structure(structure(1.3, 1.7), "offset.toml")),
            "centred": build(parse_structure(structure(1.5, 1.5), "centred.toml")),
        }


def operating_points(b, tmp_path, release: str) -> np.ndarray:
    """ngspice .op states (SI: x, z) at a_z = 0 and a_z = A, both combs at V."""
    model = b.model
    lib = tmp_path / "offset.lib"
    lib.write_text(emit_ngspice.subcircuit(model))
    out = []
    with using_ngspice(release):
        for a in (0.0, A):
            bench = Bench(
                model,
                lib,
                sources={"xp": f"DC {V}", "xn": f"DC {V}", "plate": "0", "a_in": f"DC {a}"},
                options="reltol=1e-9 vntol=1e-12 abstol=1e-18",
            )
            plot = run_ngspice(bench.netlist(".op"), tmp_path / f"op{a:g}")[0]
            out.append([float(plot[f"x1.xs_{c.name}"][0]) * c.scale for c in model.coordinates])
    return np.array(out)


def python_points(model) -> np.ndarray:
    """The MacroModel's static equilibria (SI) at a_z = 0 and A: accelerations(x) = 0 (scipy fsolve,
    over omega^2 so the residual reads in units of the scaled state)."""
    v = np.array([V if e.name in ("xp", "xn") else 0.0 for e in model.electrodes])
    w2 = np.array([c.stiffness / c.mass for c in model.coordinates])
    out = []
    for a in (0.0, A):
        x, _, ok, msg = fsolve(
            lambda x: model.accelerations(x, np.zeros_like(x), v, 0.0, a_frame=a) / w2,
            np.zeros(model.ncoords),
            xtol=1e-13,
            full_output=True,
        )
        assert ok == 1, msg
        out.append(x * model.scales)
    return np.array(out)


def table_derivatives(b, x: float, z: float) -> tuple[float, float]:
    """E_xz and E_xx (N/m) of the two combs at (x, z) from the 2-D section table by central
    differences of comb_section.section: C_xp = N L S(g_p - x, z), C_xn = N L S(g_n + x, z)
    (rigid x and z: the gap and the offset uniform along the overlap; the tips do not see x)."""
    cell = next(p for _, p in b.prepared.parts if hasattr(p, "geoms")).geoms[0].cell
    s = lambda g, o: float(comb_section.section(g, o, cell))  # noqa: E731
    h = 2e-9
    e_xz = e_xx = 0.0
    for g0, sign in ((1.3 * UM, -1.0), (1.7 * UM, 1.0)):  # xp closes with x, xn opens
        g = g0 + sign * x
        s_go = (s(g + h, z + h) - s(g + h, z - h) - s(g - h, z + h) + s(g - h, z - h)) / (4 * h * h)
        s_gg = (s(g + h, z) - 2 * s(g, z) + s(g - h, z)) / (h * h)
        e_xz += 0.5 * V**2 * N * L * sign * s_go
        e_xx += 0.5 * V**2 * N * L * s_gg
    return e_xz, e_xx


@pytest.mark.parametrize("release", sorted(NGSPICE))
def test_offset_mass_couples_z_into_x_as_the_tables_predict(builds, tmp_path, release):
    """A z acceleration of 1000 m/s^2 moves the offset mass's x in ngspice by the Python model's
    prediction within 2 %, and the x it moves per unit z, dx/dz = E_xz / (k_x - E_xx), is the 2-D
    tables' within 2 % (E = (1/2) V^2 d2C/dq dq' of both combs at the midpoint of the two
    operating points); the term is no round-off: above 2e-3 of x's own sensitivity m / k_x."""
    b = builds["offset"]
    ng, py = operating_points(b, tmp_path, release), python_points(b.model)
    (dx_ng, dz_ng), (dx_py, dz_py) = ng[1] - ng[0], py[1] - py[0]
    own = next(c for c in b.model.coordinates if c.name == "x").mass * A / K
    print(
        f"ngspice {release}: dx {dx_ng:.4e} m, dz {dz_ng:.4e} m; Python dx {dx_py:.4e}, dz {dz_py:.4e}; "
        f"dx / (m a / k) = {dx_ng / own:.3e}; ngspice / Python - 1: dx {dx_ng / dx_py - 1:+.1e}, dz {dz_ng / dz_py - 1:+.1e}"
    )
    assert dx_ng == pytest.approx(dx_py, rel=0.02, abs=0)
    assert dz_ng == pytest.approx(dz_py, rel=0.02, abs=0)
    assert abs(dx_ng) > 2e-3 * own
    e_xz, e_xx = table_derivatives(b, *(0.5 * (ng[0] + ng[1])))
    print(
        f"dx/dz: ngspice {dx_ng / dz_ng:.5e}, tables {e_xz / (K - e_xx):.5e} (E_xz {e_xz:.4e}, E_xx {e_xx:.4e} N/m), "
        f"ngspice / tables - 1 {dx_ng / dz_ng / (e_xz / (K - e_xx)) - 1:+.2e}"
    )
    assert dx_ng / dz_ng == pytest.approx(e_xz / (K - e_xx), rel=0.02)


def test_the_model_cross_derivative_is_the_tables(builds):
    """The fitted model's d2(C_xp + C_xn)/dx dz at rest (central difference of its dC/dx over z)
    against the same from the section table, within 2 %."""
    b = builds["offset"]
    model = b.model
    zs = next(c for c in model.coordinates if c.name == "z").scale
    h = 1e-3
    grad = [model.capacitance_gradient(np.array([[0.0, s * h]]))[0, :, 0].sum() for s in (1, -1)]
    fitted = (grad[0] - grad[1]) / (2 * h * zs)
    e_xz, _ = table_derivatives(b, 0.0, 0.0)
    assert fitted == pytest.approx(e_xz / (0.5 * V**2), rel=0.02)


def test_centred_mass_leaves_x_alone(builds, tmp_path):
    """The centred mass (1.5 um on both sides): the same z acceleration moves x by less than 1e-3
    of m a / k_x (the two sides' d2C/dx dz cancel)."""
    b = builds["centred"]
    ng = operating_points(b, tmp_path, "39")
    own = next(c for c in b.model.coordinates if c.name == "x").mass * A / K
    assert abs(ng[1, 0] - ng[0, 0]) < 1e-3 * own
    assert abs(ng[1, 1] - ng[0, 1]) > 0.5 * own  # z itself moves
