"""Each side's own viscosity law under temp (netgen.model.process_film.side_laws, netgen.emit.process.
side_factors' pw_<side>) in every form, with the gap sets' offsets: tests/oracles/process_cases.py's PROOF
mass (z, tilt_x, tilt_y) between a plate 2 um above and one 3 um below, dg and temp declared, at the
corners of the valid box (dg_top, dg_bot = -/+ the range, -40 / 125 degC) and at temp alone: the model's
arithmetic (netgen.model.process.coordinate_values), the .lib in ngspice 39 and 46, the .va through OSDI
in ngspice 46, the FMU, and (temp alone: that form has no gap offsets) the _xspice.lib in ngspice 39.

Reference: netgen.mechanics.damping re-run at the moved gaps with air's viscosity and mean free path at T
written out here (Sutherland's mu ~ T^1.5 / (T + S), S = 111 K: White, Viscous Fluid Flow, table 1-2; the
mean free path lambda = (mu / p) sqrt(pi k T / 2 m) at fixed pressure, 68 nm at 300 K). Without holes
each side's film is b = 12 mu_eff(g + dg, T) / (g + dg)^3 R (R the plate's and the shapes', not the
gap's), and the law's side factor pv pw_<side> pg_<set> is that over its value at (g, T0) times the
polynomial's (1 + e), |e| <= its stated misfit (pw and pg exact). Bound: the misfit plus 1e-12 of
round-off (the model, the FMU), plus the two AC fits' 2e-9 (each .ac b from 1/H = k - m w^2 + i w b by
least squares). With one law for both sides (pw_<side> left out) the corners are off by up to 6e-3."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from netgen import emit
from netgen.mechanics import mechanics
from netgen.model.process import coordinate_values
from netgen.structure import parse_structure
from netgen.testbench.sigma_delta import ngspice as sdn
from tests.fixtures import NGSPICE
from tests.fixtures import shared_model as build_model
from tests.oracles import film_rerun
from tests.oracles.process_cases import PROOF

FIT = 2e-9  # two AC fits' round-off
TEXT = (
    PROOF.format(t=10.0, e=160.0)
    .replace('parameters = ["dg", "tscale", "escale", "temp"]', 'parameters = ["dg", "temp"]')
    .replace('name = "bot"\nside = "below"\ngap = "2 um"', 'name = "bot"\nside = "below"\ngap = "3 um"')
)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """(structure, model, mechanics, folder with the .lib, _osdi.lib and .osdi) of the two-gap mass."""
    s = parse_structure(TEXT, "pm.toml")
    model = build_model(s)
    folder = tmp_path_factory.mktemp("film_sides")
    emit.write_outputs(model, folder, "ngspice,osdi")
    return s, model, mechanics(s), folder


def points(model, gaps: bool = True) -> list[tuple[float, float, float]]:
    """(dg_top, dg_bot m, temp degC): the nominal point, then the box's corners (gaps) or temp alone."""
    t0 = model.process["temperature_C"]
    if not gaps:
        return [(0.0, 0.0, t0), (0.0, 0.0, -40.0), (0.0, 0.0, 125.0)]
    d = min(g["max_m"] for g in model.process["gaps"])
    return [(0.0, 0.0, t0), (-d, d, -40.0), (d, -d, 125.0), (-d, -d, 125.0), (d, d, -40.0)]


def rerun(built, dg_top: float, dg_bot: float, temp_c: float) -> np.ndarray:
    """The damping of each coordinate re-run at the moved gaps with air at temp_c (module docstring)."""
    s, model, m, _ = built
    t0 = model.process["temp"]["viscosity"]["t0_K"]
    return film_rerun.rerun(s, m, t0, {"top": dg_top, "bot": dg_bot}, temp_c)


def misfit(model) -> float:
    """The viscosity polynomial's stated misfit, the law's stated error with pw_<side>."""
    visc = model.process["temp"]["viscosity"]
    assert visc["max_rel_error"] == visc["polynomial_misfit"] and visc["sides"]
    return visc["polynomial_misfit"]


def test_drawn_film_is_the_rerun(built):
    """The reference's own check: at T0 and dg 0 the re-run with the gas written out here is the model's
    damping (same Reynolds solve, air's 1.85e-5 Pa s and 68 nm: netgen.core.constants)."""
    _, model, _, _ = built
    assert rerun(built, *points(model)[0]) == pytest.approx([c.damping for c in model.coordinates], rel=1e-12)


def test_law_against_reruns(built):
    """The model's damping of z, tilt_x, tilt_y at the corners against the re-runs within the misfit; the
    law with one viscosity ratio for both sides is off by more than 100 times that."""
    _, model, _, _ = built
    one_law = copy.deepcopy(model.process)
    one_law["temp"]["viscosity"]["sides"] = []
    worst = 0.0
    for top, bot, t in points(model)[1:] + points(model, False)[1:]:
        want = rerun(built, top, bot, t)
        for v, c in enumerate(model.coordinates):
            got = coordinate_values(model.process, v, temp_c=t, dg={"top": top, "bot": bot})[2]
            before = coordinate_values(one_law, v, temp_c=t, dg={"top": top, "bot": bot})[2]
            worst = max(worst, abs(before / want[v] - 1))
            print(f"{top * 1e9:+.0f}/{bot * 1e9:+.0f} nm {t:g} C {c.name}: law / re-run - 1 = {got / want[v] - 1:+.2e}")
            assert got == pytest.approx(want[v], rel=misfit(model) + 1e-12)
    print(f"one law for both sides: up to {worst:.2e}")
    assert worst > 100 * misfit(model)


def spice_b(built, tmp_path, version: str, form: str) -> list[float]:
    """b of z per point from an .ac of the .lib, the _osdi.lib with the compiled module or the
    _xspice.lib (temp alone) in ngspice `version` (tests/oracles/film_rerun.spice_z_damping)."""
    _, model, _, folder = built
    pre: list[str] = []
    lib = folder / "pm.lib"
    if form == "osdi":
        lib, pre = folder / "pm_osdi.lib", [f"pre_osdi {folder / 'pm.osdi'}"]
    elif form == "xspice":
        lib, pre = sdn.xspice_library(model, tmp_path, sdn.code_models(False))
        lib = lib.resolve()
    gaps = form != "xspice"
    params = [
        (f"dg_top={top!r} dg_bot={bot!r} " if gaps else "") + f"temp={t!r}" for top, bot, t in points(model, gaps)
    ]
    return film_rerun.spice_z_damping(lib, pre, params, version, tmp_path)


def check(built, b: list[float], label: str, gaps: bool = True) -> None:
    """Each point's b / b0 against the re-runs' ratio within the misfit plus FIT."""
    _, model, _, _ = built
    base = rerun(built, *points(model)[0])[0]
    for (top, bot, t), got in zip(points(model, gaps)[1:], b[1:]):
        want = rerun(built, top, bot, t)[0] / base
        print(f"{label} {top * 1e9:+.0f}/{bot * 1e9:+.0f} nm {t:g} C: b/b0 {got / b[0]:.9f}, re-runs {want:.9f}")
        assert got / b[0] == pytest.approx(want, rel=misfit(model) + FIT)


@pytest.mark.parametrize("version", sorted(NGSPICE))
def test_lib_against_reruns(built, tmp_path, version):
    """The .lib in ngspice 39 and 46."""
    check(built, spice_b(built, tmp_path, version, "lib"), f"ngspice {version} .lib")


def test_osdi_against_reruns(built, tmp_path):
    """The .va compiled by openvaf-r, through OSDI in ngspice 46."""
    check(built, spice_b(built, tmp_path, "46", "osdi"), "ngspice 46 OSDI")


def test_xspice_against_reruns(built, tmp_path):
    """The _xspice.lib in ngspice 39 at temp alone (unbiased: its code model adds nothing to the
    small-signal matrix there)."""
    check(built, spice_b(built, tmp_path, "39", "xspice"), "ngspice 39 _xspice.lib", gaps=False)


def test_fmu_against_reruns(built):
    """The FMU (model exchange, its runtime's pw): b = -m q'' of z at q = 0, q'_z = 1 m/s."""
    _, model, _, _ = built
    got = film_rerun.fmu_z_damping(model, [{"dg_top": top, "dg_bot": bot, "temp": t} for top, bot, t in points(model)])
    assert got[0] == pytest.approx(model.coordinates[0].damping, rel=1e-12)
    check(built, got, "FMU")


def test_header_states_the_sides_law(built):
    """The .lib's header states the misfit as the law's error and names pw_below, in comment lines only."""
    _, model, _, folder = built
    text = (folder / "pm.lib").read_text()
    header = " ".join(line[1:].strip() for line in text.splitlines() if line.startswith("*"))
    assert f"Veijola's rarefaction within {misfit(model):.1e} (fitted at gap 2e-06 m" in header
    assert "its own exact ratio pw_below at 3e-06 m" in header
