"""The compressible squeeze film's Maxwell branches under the die temperature temp (netgen.model.process:
the branches follow the viscosity ratio pv; netgen.emit.process_film.film_scaled), in the .lib (ngspice 39),
the .va through OSDI (ngspice 46) and the FMU: the small free disk of tests/mechanics/test_damping.py (rigid z,
two 3 um gaps, air at 1 atm) with the compressible film and [process] temp.

Reference: each branch is a damper r_j = c (phi, psi_j)^2 / lambda_j in series with a gas spring
r_j w_j, w_j = lambda_j g^2 p_a / (12 mu_eff) (netgen.mechanics.squeeze_film), c = 12 mu_eff / g^3:
r_j ~ mu_eff, the spring ~ p_a (fixed), so at temperature T each r_j (and the remainder damper) is R
times its value at T0 and each corner 1 / R times, R = mu_eff(T) / mu_eff(T0) from
tests/oracles/fmu_process.viscosity_ratio (Sutherland with Veijola's rarefaction, written out
independently). The model's nominal network rescaled so gives B_T(w); z held by a soft spring k
(1 kHz) through its ports, the compliance 1 / (k - M w^2 + i w B_T(w)) from 5 kHz to 300 kHz.

Tolerance: the law's stated misfit eps (relative, on R) moves each branch term r R / (1 + i w R / w_j)
by at most 2 eps relative, so H by at most 2 eps |i w B / (k - M w^2 + i w B)| (computed per point);
plus 1e-9 for ngspice's complex solve and printing. Without the law (the branches at T0) H is off by
up to the film's share of the impedance times |R - 1| (R = 0.82 / 1.19 at -40 / 125 C): asserted far
outside.

The same build declares dg too (the top ring's gap offset dg_top; netgen.model.process_film.
compressible_law): each branch is one side's (the equal gaps' merged poles split per side), its damper
~ 12 mu_eff / g^3 and its gas spring ~ p_a / g at the moved gap. Reference: the Reynolds eigen-expansion
re-run at the moved gap (netgen.mechanics.squeeze_film.pole_residues at 3 um + dg_top above, 3 um
below, mu_eff there, and at temp Sutherland's and the mean free path's ratio at that gap), the model's
kept poles (matched to the drawn solve's) its branches, static - sum of the kept residues per side its
remainder damper. The same Dirichlet eigenpairs at any gap: law and re-run differ by round-off, 1e-12
relative on each branch and the remainder (a few ulps of the scalings and of the sum of 60 residues),
and 1e-9 on H (ngspice's complex solve); with temp the viscosity polynomial's misfit as above. At
dg_top = -150 / +150 nm the drawn network is off by up to 7.7 % / 6.4 % of H there.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from netgen.core.constants import GASES, K_B
from netgen.emit import ngspice as emit_ngspice
from netgen.emit import osdi
from netgen.mechanics import mechanics
from netgen.mechanics import squeeze_film as sf
from netgen.mechanics.damping import FILM_POLES
from netgen.model.process import coordinate_values
from netgen.sim import fmu
from netgen.sim.ngspice import run_ngspice
from netgen.structure import parse_structure
from netgen.testbench.sigma_delta import ngspice as sdn
from tests.fixtures import shared_model as build_model
from tests.mechanics.test_damping import COMPRESSIBLE, SMALL
from tests.oracles.fmu_process import viscosity_ratio
from tests.oracles.spice_decks import disk_deck, disk_library
from tests.oracles.testbench import using_ngspice

GAP, T0_K = 3e-6, 300.0
TEMPS = (-40.0, 125.0)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The disk with the compressible film and temp: its .lib, _osdi.lib and .osdi."""
    return disk(tmp_path_factory.mktemp("film"), noise=False)


def disk(folder, noise: bool):
    """(model, folder) of the disk with the compressible film, temp and dg, thermal noise per `noise`,
    its d.lib, d_osdi.lib and d.osdi written into `folder`."""
    text = SMALL.replace('modes = ["2,0c"]\n', "") + "[damping]\n" + ("noise = true\n" if noise else "") + COMPRESSIBLE
    model = build_model(parse_structure(text + '[process]\nparameters = ["temp", "dg"]\n', "damped_disk.toml"))
    (folder / "d.lib").write_text(emit_ngspice.subcircuit(model, noise=noise))
    (folder / "d_osdi.lib").write_text(osdi.subcircuit(model))
    (folder / "d.osdi").write_bytes(osdi.outputs(model)[".osdi"])
    return model, folder


def compliance(model, ratio: float, w: np.ndarray, k: float) -> tuple[np.ndarray, np.ndarray]:
    """(x / F, |i w B / Z|) with the nominal network's dampers times `ratio` and corners over it."""
    z = model.coordinates[0]
    b = ratio * z.damping + sum(ratio * r / (1.0 + 1j * w * ratio / corner) for r, corner in z.film)
    imp = k - z.mass * w**2 + 1j * w * b
    return 1.0 / imp, np.abs(1j * w * b / imp)


@pytest.mark.parametrize("form", ("lib", "osdi"))
@pytest.mark.parametrize("temp", TEMPS)
def test_film_branches_follow_the_viscosity_law(built, tmp_path, temp, form):
    """The .ac compliance of z at temp against the network rescaled by the viscosity ratio."""
    model, folder = built
    z = model.coordinates[0]
    k = z.mass * (2 * math.pi * 1e3) ** 2
    net = disk_deck(*disk_library(folder, form), f"temp={temp!r}", k, ".ac dec 5 5e3 3e5")
    with using_ngspice("39" if form == "lib" else "46"):
        plot = run_ngspice(net, tmp_path)[0]
    got = np.asarray(plot["v(xz)"])  # um per uN = m/N
    w = 2 * math.pi * np.real(plot["frequency"])
    ratio = viscosity_ratio(temp, T0_K, GAP)
    want, share = compliance(model, ratio, w, k)
    eps = model.process["temp"]["viscosity"]["max_rel_error"]
    err = np.abs(got / want - 1.0)
    assert np.all(err <= 2 * eps * share + 1e-9), (err, 2 * eps * share)
    before, _ = compliance(model, 1.0, w, k)
    assert np.max(np.abs(before / want - 1.0)) > 1e3 * np.max(2 * eps * share + 1e-9)


@pytest.mark.parametrize("temp", TEMPS)
def test_fmu_film_branches_follow_the_viscosity_law(built, temp):
    """The FMU (model exchange) at q = 0, q' = V0 and each branch force at its T0 value r_j V0: every
    branch force's derivative (w_j / R)(R r_j V0 - F_j) and the acceleration -(R D V0 + sum F_j) / M,
    against the same rescaled network; bound: the law's misfit eps on R over each term (2 eps of its
    magnitude) plus round-off 1e-12 of it."""
    model, _ = built
    z = model.coordinates[0]
    ratio = viscosity_ratio(temp, T0_K, GAP)
    eps = model.process["temp"]["viscosity"]["max_rel_error"]
    v0 = 1e-3  # m/s
    forces = np.array([r * v0 for r, _ in z.film])
    inst = fmu.Instance(fmu.built(model), cosim=False)
    inst.set({"temp": temp})
    inst.start()
    inst.set_states(np.concatenate([[0.0, v0], forces]))
    names = [f"der_film_z_{j + 1}" for j in range(len(z.film))]
    got = inst.get([*names, "qdd_z"])
    inst.close()
    for j, (r, corner) in enumerate(z.film):
        want = corner / ratio * (ratio * r * v0 - forces[j])
        scale = corner * r * v0 * (1.0 + 1.0 / ratio)
        assert abs(got[j] - want) <= (2 * eps + 1e-12) * scale, (j, got[j], want)
    want = -(ratio * z.damping * v0 + forces.sum()) / z.mass
    scale = (ratio * z.damping * v0 + forces.sum()) / z.mass
    assert abs(got[-1] - want) <= (2 * eps + 1e-12) * scale, (got[-1], want)


DG_POINTS = [(-1.5e-7, None), (1.5e-7, None), (1.5e-7, 125.0)]  # (dg_top m, temp C): the range's ends


@pytest.fixture(scope="module")
def solver(built):
    """The Reynolds eigen-expansion of z on the model's film mesh (netgen.mechanics.damping's), a
    function (gap, temp) -> PoleResidue of one side, and the indices of the drawn solve's poles the
    model keeps as branches."""
    model, _ = built
    s = parse_structure(SMALL.replace('modes = ["2,0c"]\n', "") + "[damping]\n" + COMPRESSIBLE, "damped_disk.toml")
    m, d = mechanics(s), s.damping
    mesh = sf.disk_mesh(s.conductor.radius, d.fem_refine)

    @functools.cache
    def side(gap: float, temp: float | None) -> sf.PoleResidue:
        mu = sf.effective_viscosity(GASES[d.gas], d.pressure, gap) * (
            viscosity_ratio(temp, T0_K, gap) if temp is not None else 1
        )
        return sf.pole_residues(mesh, m.basis, gap, mu, d.pressure, FILM_POLES)[0]

    drawn = side(GAP, None)
    kept = sorted({int(np.argmin(np.abs(drawn.poles / w - 1))) for _, w in model.coordinates[0].film})
    return side, kept


def expected(solver, dg: float, temp: float | None) -> tuple[list[tuple[float, float]], float]:
    """The re-run network of z at dg_top and temp: (residue, pole) of every kept pole on both sides
    (sorted by pole), and the remainder damper: per side static - the kept residues (module docstring)."""
    side, kept = solver
    branches, remainder = [], 0.0
    for pr in (side(GAP + dg, temp), side(GAP, temp)):
        branches += [(float(pr.residues[i]), float(pr.poles[i])) for i in kept]
        dropped = np.setdiff1d(np.arange(len(pr.poles)), kept)
        remainder += pr.remainder + float(pr.residues[dropped].sum())
    return sorted(branches, key=lambda b: b[1]), remainder


def test_split_branches_and_remainder_law(built, solver):
    """Every branch one side's, the pairs of the equal gaps split (the same admittance); the remainder
    damper (coordinate_values, the arithmetic the emitters render) against the re-run's within 1e-12
    without temp and the viscosity law's misfit with it (module docstring)."""
    model, _ = built
    z = model.coordinates[0]
    tops, bots = ([g["film"]["branches"][0] for g in model.process["gaps"] if g["set"] == n][0] for n in ("top", "bot"))
    assert sorted(tops + bots) == list(range(len(z.film))) and len(tops) == len(bots) == len(solver[1])
    eps = model.process["temp"]["viscosity"]["max_rel_error"]
    for dg, temp in DG_POINTS:
        _, remainder = expected(solver, dg, temp)
        got = coordinate_values(model.process, 0, temp_c=temp, dg={"top": dg})[2]
        print(f"dg_top {dg * 1e9:+.0f} nm, temp {temp}: remainder law / re-run - 1 = {got / remainder - 1:.1e}")
        assert got == pytest.approx(remainder, rel=(eps if temp is not None else 0.0) + 1e-12)


def network_compliance(branches, remainder: float, mass: float, w: np.ndarray, k: float):
    """(x / F, |i w B / Z|) of z with the film network B = remainder + sum r / (1 + i w / pole)."""
    b = remainder + sum(r / (1.0 + 1j * w / p) for r, p in branches)
    imp = k - mass * w**2 + 1j * w * b
    return 1.0 / imp, np.abs(1j * w * b / imp)


@pytest.mark.parametrize(
    ("form", "dg", "temp"), [(f, dg, t) for f in ("lib", "osdi") for dg, t in DG_POINTS] + [("xspice", 1.5e-7, None)]
)
def test_film_branches_follow_the_gap(built, solver, tmp_path, form, dg, temp):
    """The .ac compliance of z at dg_top (and temp) against the re-run network (module docstring): the
    .lib in ngspice 39, OSDI in ngspice 46 and, at one point, the _xspice.lib in ngspice 39 (unbiased:
    its code model adds nothing to the small-signal matrix there)."""
    model, folder = built
    z = model.coordinates[0]
    k = z.mass * (2 * math.pi * 1e3) ** 2
    lib, control = disk_library(folder, form)
    if form == "xspice":
        lib, control = sdn.xspice_library(model, tmp_path, sdn.code_models(False))
        lib = lib.resolve()
    params = f"dg_top={dg!r}" + (f" temp={temp!r}" if temp is not None else "")
    net = disk_deck(lib, control, params, k, ".ac dec 5 5e3 3e5")
    with using_ngspice("46" if form == "osdi" else "39"):
        plot = run_ngspice(net, tmp_path)[0]
    got = np.asarray(plot["v(xz)"])
    w = 2 * math.pi * np.real(plot["frequency"])
    want, share = network_compliance(*expected(solver, dg, temp), z.mass, w, k)
    eps = model.process["temp"]["viscosity"]["max_rel_error"] if temp is not None else 0.0
    err = np.abs(got / want - 1.0)
    print(f"{form} dg_top {dg * 1e9:+.0f} nm, temp {temp}: |H / H_rerun - 1| at most {np.max(err):.1e}")
    assert np.all(err <= 2 * eps * share + 1e-9), (err, 2 * eps * share)
    if temp is None:
        drawn, _ = network_compliance(z.film, z.damping, z.mass, w, k)
        print(f"  the drawn network: {np.max(np.abs(drawn / want - 1.0)):.2e}")
        assert np.max(np.abs(drawn / want - 1.0)) > 0.01


@pytest.mark.parametrize(("dg", "temp"), DG_POINTS)
def test_fmu_film_branches_follow_the_gap(built, solver, dg, temp):
    """The FMU (model exchange) at q' = V0: each branch's derivative at F_j = 0 is its gas spring
    r_j w_j V0, at F_j = r_j V0 (the drawn damper's force) w_j (r_j - r_j0) V0; so every branch's damper
    and pole at dg_top (and temp) against the re-run's, sorted by pole: within 1e-12 without temp, the
    law's 2 eps with it (module docstring)."""
    model, _ = built
    z = model.coordinates[0]
    eps = model.process["temp"]["viscosity"]["max_rel_error"] if temp is not None else 0.0
    v0 = 1e-3
    r0 = np.array([r for r, _ in z.film])
    names = [f"der_film_z_{j + 1}" for j in range(len(z.film))]
    out = []
    for forces in (np.zeros(len(z.film)), r0 * v0):
        inst = fmu.Instance(fmu.built(model), cosim=False)
        inst.set({"dg_top": dg} | ({"temp": temp} if temp is not None else {}))
        inst.start()
        inst.set_states(np.concatenate([[0.0, v0], forces]))
        out.append(np.asarray(inst.get(names)))
        inst.close()
    spring = out[0] / v0  # r_j w_j
    pole = (out[0] - out[1]) / (r0 * v0)  # w_j
    got = sorted(zip(spring / pole, pole), key=lambda b: b[1])
    want, _ = expected(solver, dg, temp)
    dev = max(max(abs(r / r_ref - 1), abs(p / p_ref - 1)) for (r, p), (r_ref, p_ref) in zip(got, want))
    print(f"FMU dg_top {dg * 1e9:+.0f} nm, temp {temp}: branches / re-run - 1 at most {dev:.1e}")
    for (r, p), (r_ref, p_ref) in zip(got, want, strict=True):
        assert r == pytest.approx(r_ref, rel=2 * eps + 1e-12) and p == pytest.approx(p_ref, rel=2 * eps + 1e-12)


@pytest.mark.parametrize(("dg", "temp"), DG_POINTS)
def test_sweep_point_moves_the_branches(built, solver, dg, temp):
    """netgen sweep's model at the process point (netgen.sweep.point.at_point, which designs and
    analyses a run) carries the same film: every branch and the remainder against the re-run's, 1e-12
    without temp and the law's 2 eps with it (module docstring)."""
    from netgen.sweep.point import at_point

    model, _ = built
    z = at_point(model, {"dg_top": dg} | ({"temp": temp} if temp is not None else {})).coordinates[0]
    eps = model.process["temp"]["viscosity"]["max_rel_error"] if temp is not None else 0.0
    want, remainder = expected(solver, dg, temp)
    assert z.damping == pytest.approx(remainder, rel=eps + 1e-12)
    for (r, p), (r_ref, p_ref) in zip(sorted(z.film, key=lambda b: b[1]), want, strict=True):
        assert r == pytest.approx(r_ref, rel=2 * eps + 1e-12) and p == pytest.approx(p_ref, rel=2 * eps + 1e-12)


@pytest.fixture(scope="module")
def noisy(tmp_path_factory):
    """The same disk with thermal noise on ([damping] noise): its .lib, _osdi.lib and .osdi."""
    return disk(tmp_path_factory.mktemp("film_noise"), noise=True)


@pytest.mark.parametrize(("form", "dg"), [(f, dg) for f in ("lib39", "lib46", "osdi") for dg in (-1.5e-7, 1.5e-7)])
def test_branch_noise_follows_the_gap(noisy, solver, tmp_path, form, dg):
    """.noise of x_z at dg_top against fluctuation-dissipation with the re-run film (module docstring):
    S_x = 4 k_B T Re{B(w)} |H|^2, B = remainder + sum r_j / (1 + i w / w_j) the re-run network at 3 um
    + dg_top above and 3 um below, H = 1 / (k - M w^2 + i w B), T the model's 300 K (temp's default).
    Each branch's damper carries its own thermal force, filtered by its gas spring into 4 k_B T Re of its
    admittance, so the sum is exact; the law's network is the re-run's within 1e-12 per branch
    (test_fmu_film_branches_follow_the_gap), ngspice's .noise a linear solve per frequency: 1e-9. The
    .lib in ngspice 39 and 46 (its noise resistors at the model's temperature under any .temp,
    netgen.emit.ngspice.noise_resistor), the .va's white_noise through OSDI in 46. The
    drawn network's noise is off by more than 1 % there."""
    model, folder = noisy
    z = model.coordinates[0]
    kelvin = model.process["temperature_C"] + 273.15
    k = z.mass * (2 * math.pi * 1e3) ** 2
    lib, control = disk_library(folder, "osdi" if form == "osdi" else "lib")
    net = disk_deck(lib, control, f"dg_top={dg!r}", k, ".noise v(xz) Vac dec 5 5e3 3e5")
    with using_ngspice("39" if form == "lib39" else "46"):
        spec = next(p for p in run_ngspice(net, tmp_path) if "onoise_spectrum" in p.vectors)
    w = 2 * math.pi * np.real(spec["frequency"])
    got = np.real(spec["onoise_spectrum"]) ** 2 * z.port_units[1] ** 2  # V^2/Hz at x_z -> m^2/Hz

    def psd(branches, remainder: float) -> np.ndarray:
        b = remainder + sum(r / (1.0 + 1j * w / p) for r, p in branches)
        return 4 * K_B * kelvin * b.real / np.abs(k - z.mass * w**2 + 1j * w * b) ** 2

    want = psd(*expected(solver, dg, None))
    dev = np.max(np.abs(got / want - 1.0))
    drawn = np.max(np.abs(psd(z.film, z.damping) / want - 1.0))
    print(f"{form} dg_top {dg * 1e9:+.0f} nm: .noise / 4 k_B T Re B |H|^2 - 1 at most {dev:.1e} (drawn {drawn:.1e})")
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=0)
    assert drawn > 0.01
