"""A perforated mass's squeeze film under dg_<set> and temp together (netgen.model.process_film.
rarefaction_shift, netgen.emit.process_film.film_factors' pq_<set>) against the Reynolds solve re-run at the
moved gaps with the gas at temp: tests/oracles/process_cases.perforated (accelerometer_xyz's mass, 2 um
between its plates zs below and zt above, 4 um holes on a 10 um pitch), dg and temp declared, at the four
(dg, temp) corners of the valid box (both sets moved by -/+ the range, -40 / 125 degC) and its centre
(dg 0, 42.5 degC): the model's arithmetic (netgen.model.process.coordinate_values), the .lib in ngspice
39 and 46 and the .va through OSDI in ngspice 46.

Reference: netgen.mechanics.damping re-run with air's viscosity and mean free path at T written out here
(Sutherland's mu ~ T^1.5 / (T + S), S = 111 K: White, Viscous Fluid Flow, table 1-2; the mean free path
lambda = (mu / p) sqrt(pi k T / 2 m) at fixed pressure, 68 nm at 300 K). The holes' leak 12 h^4 /
(28.45 g^3 t p^2) carries no viscosity, so b(g, T) = 12 mu_eff(g, T) / g^3 R(g): the law pv(T) cubic(dg)
pq(dg, T) is the re-run's ratio times (1 + e_v)(1 + e_c), e_v the viscosity polynomial's stated misfit,
e_c the cubic's stated error (both sides at one gap: no sides' spread). Bound: e_v + e_c + e_v e_c plus
1e-12 of round-off (the model), plus the two AC fits' 2e-9 (each .ac b from 1/H = k - m w^2 + i w b by
least squares). Without pq (the product pv cubic alone) the corners are off by 2.5e-3 to 3.8e-3."""

from __future__ import annotations

import numpy as np
import pytest

from netgen import emit
from netgen.mechanics import mechanics
from netgen.model.process import coordinate_values
from netgen.structure import parse_structure
from tests.fixtures import NGSPICE
from tests.fixtures import shared_model as build_model
from tests.oracles import film_rerun
from tests.oracles.process_cases import perforated

PROCESS = '[damping]\nsqueeze_film = true\n[process]\nparameters = ["dg", "temp"]\n'
FIT = 2e-9  # two AC fits' round-off


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """(structure, model, mechanics, folder with the .lib, _osdi.lib and .osdi) of the perforated mass
    (about 15 s: the extractor, the cubics' Reynolds re-runs and openvaf-r)."""
    s = parse_structure(perforated(process=PROCESS), "px.toml")
    model = build_model(s)
    folder = tmp_path_factory.mktemp("film_perforated_temp")
    emit.write_outputs(model, folder, "ngspice,osdi")
    return s, model, mechanics(s), folder


def points(model) -> list[tuple[float, float]]:
    """(dg m of both sets, temp degC): the nominal point, the box's four corners and its centre."""
    d = min(g["max_m"] for g in model.process["gaps"])
    t0 = model.process["temperature_C"]
    return [(0.0, t0), (-d, -40.0), (-d, 125.0), (d, -40.0), (d, 125.0), (0.0, 42.5)]


def rerun(built, dg: float, temp_c: float) -> np.ndarray:
    """The damping of each coordinate re-run with both sets' gaps + dg and air at temp_c (module
    docstring; tests/oracles/film_rerun.rerun)."""
    s, model, m, _ = built
    t0 = model.process["temp"]["viscosity"]["t0_K"]
    return film_rerun.rerun(s, m, t0, {e.name: dg for e in s.electrode_sets}, temp_c)


def stated(model) -> float:
    """e_v + e_c + e_v e_c (module docstring)."""
    e_v = model.process["temp"]["viscosity"]["max_rel_error"]
    e_c = max(g["film"]["fit"]["max_rel_error"] for g in model.process["gaps"])
    return e_v + e_c + e_v * e_c


def test_drawn_film_is_the_rerun(built):
    """The reference's own check: at T0 and dg 0 the re-run with the gas written out here is the model's
    damping (same Reynolds solve, viscosity 1.85e-5 Pa s and 68 nm: air's in netgen.core.constants)."""
    _, model, _, _ = built
    assert rerun(built, 0.0, model.process["temperature_C"]) == pytest.approx(
        [c.damping for c in model.coordinates], rel=1e-12
    )


def test_law_against_reruns(built):
    """The model's damping of z, tilt_x, tilt_y at the corners and the centre against the re-runs within
    the stated error (module docstring)."""
    _, model, _, _ = built
    for dg, t in points(model)[1:]:
        want = rerun(built, dg, t)
        for v, c in enumerate(model.coordinates):
            got = coordinate_values(model.process, v, temp_c=t, dg={"zs": dg, "zt": dg})[2]
            print(f"dg={dg * 1e9:+.0f} nm T={t:g} C {c.name}: law / re-run - 1 = {got / want[v] - 1:+.2e}")
            assert got == pytest.approx(want[v], rel=stated(model) + 1e-12)


def spice_b(built, tmp_path, version: str, form: str) -> list[float]:
    """b of z per point from an .ac of the .lib (or the _osdi.lib with the compiled module) in ngspice
    `version` (tests/oracles/film_rerun.spice_z_damping)."""
    _, model, _, folder = built
    lib, pre = (
        (folder / "px.lib", []) if form == "lib" else (folder / "px_osdi.lib", [f"pre_osdi {folder / 'px.osdi'}"])
    )
    params = [f"dg_zs={dg!r} dg_zt={dg!r} temp={t!r}" for dg, t in points(model)]
    return film_rerun.spice_z_damping(lib, pre, params, version, tmp_path)


def check(built, b: list[float], label: str) -> None:
    """Each point's b / b0 against the re-runs' ratio within the stated error plus FIT."""
    _, model, _, _ = built
    base = rerun(built, *points(model)[0])[0]
    for (dg, t), got in zip(points(model)[1:], b[1:]):
        want = rerun(built, dg, t)[0] / base
        print(f"{label} dg={dg * 1e9:+.0f} nm T={t:g} C: b/b0 {got / b[0]:.9f}, re-runs {want:.9f}")
        assert got / b[0] == pytest.approx(want, rel=stated(model) + FIT)


@pytest.mark.parametrize("version", sorted(NGSPICE))
def test_lib_against_reruns(built, tmp_path, version):
    """The .lib in ngspice 39 and 46."""
    check(built, spice_b(built, tmp_path, version, "lib"), f"ngspice {version} .lib")


def test_osdi_against_reruns(built, tmp_path):
    """The .va compiled by openvaf-r, through OSDI in ngspice 46."""
    check(built, spice_b(built, tmp_path, "46", "osdi"), "ngspice 46 OSDI")


def test_fmu_against_reruns(built):
    """The FMU (model exchange, its runtime's pq): b = -m q'' of z at q = 0, q'_z = 1 m/s."""
    _, model, _, _ = built
    got = film_rerun.fmu_z_damping(model, [{"dg_zs": dg, "dg_zt": dg, "temp": t} for dg, t in points(model)])
    assert got[0] == pytest.approx(model.coordinates[0].damping, rel=1e-12)
    check(built, got, "FMU")


def test_header_states_the_joint_error(built):
    """The .lib's header states pq_<set> and the joint law's error e_v + e_c + e_v e_c (module docstring)
    for each set, in comment lines only."""
    _, model, _, folder = built
    text = (folder / "px.lib").read_text()
    header = " ".join(line[1:].strip() for line in text.splitlines() if line.startswith("*"))
    for g in ("zs", "zt"):
        assert f"under temp also times pq_{g} =" in header
    assert header.count(f"with pv within {stated(model):.1e}") == 2
