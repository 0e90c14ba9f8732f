"""The squeeze film's temperature law (netgen.model.process_film.temperature_law) with films on two sides
at different gaps: tests/oracles/process_cases.py's PROOF mass (z, tilt_x, tilt_y) between a plate 2 um
above and one 3 um below, temp declared. The viscosity polynomial is fitted at the smaller gap; the larger
gap's film is less rarefied, so its ratio mu_eff(T) / mu_eff(T0) differs (by up to 2.6 % over -40..125 degC
for 2 and 3 um of air at 1 atm): the law multiplies that side's part by pw_<side>, its own ratio over the
fitted gap's (netgen.model.process_film.side_laws; exact: both are Sutherland's mu(T) times Veijola's
(1 + A) / (1 + A pl^1.159), A the gap's rarefaction at T0, pl the mean free path's ratio). Each
coordinate's film damping is its sides' parts b_side (the model's report) each times its own gap's ratio,
written out independently (tests/oracles/fmu_process.viscosity_ratio: Sutherland, the mean free path ~
mu sqrt(T) / p, Veijola); the model's damping at temp (netgen.model.process.coordinate_values, the
arithmetic the emitters render) against it. Bound: the polynomial's stated misfit (pv pw_<side> over the
side's ratio is pv over the fitted gap's, which the misfit bounds on its 0.25 K grid, the range's ends on
it) plus round-off 1e-12; with one law for both sides (pw_<side> left out) the 3 um film is off by the
sides' spread times its share."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from netgen.model.process import coordinate_values
from netgen.structure import parse_structure
from tests.fixtures import shared_model as build_model
from tests.oracles.fmu_process import viscosity_ratio
from tests.oracles.process_cases import PROOF

TEXT = PROOF.format(t=10.0, e=160.0).replace('parameters = ["dg", "tscale", "escale", "temp"]', 'parameters = ["temp"]')
GAPS = {"above": 2e-6, "below": 3e-6}


@pytest.fixture(scope="module")
def model():
    """PROOF with its bottom plate 3 um below (the top one 2 um above), temp declared."""
    text = TEXT.replace('name = "bot"\nside = "below"\ngap = "2 um"', 'name = "bot"\nside = "below"\ngap = "3 um"')
    return build_model(parse_structure(text, "pm.toml"))


@pytest.mark.parametrize("temp", [-40.0, 125.0])
def test_two_gap_film_within_the_misfit(model, temp):
    """The law's film damping at temp against the sides' parts times their own gaps' ratios, within the
    polynomial's misfit, now the stated error; one law for both sides is off by far more."""
    visc = model.process["temp"]["viscosity"]
    sides = model.report["damping"]["squeeze_film"]["sides"]
    t0 = visc["t0_K"]
    one_law = copy.deepcopy(model.process)
    one_law["temp"]["viscosity"]["sides"] = []
    assert visc["max_rel_error"] == visc["polynomial_misfit"] < 1e-5
    for v, c in enumerate(model.coordinates):
        film = {side: sides[side]["diagonal"][v] for side in GAPS}
        rest = c.damping - sum(film.values())
        want = rest + sum(b * viscosity_ratio(temp, t0, GAPS[side]) for side, b in film.items())
        got = coordinate_values(model.process, v, temp_c=temp)[2]
        before = coordinate_values(one_law, v, temp_c=temp)[2]
        dev = abs(got / want - 1.0)
        print(f"{c.name} at {temp} degC: law / sides' ratios - 1 = {dev:.2e} (one law {before / want - 1:+.2e})")
        assert dev <= visc["polynomial_misfit"] + 1e-12
        assert abs(before / want - 1.0) > 100 * (visc["polynomial_misfit"] + 1e-12)


def test_spread_is_the_larger_gaps_ratio_deviation(model):
    """The stated spread is max over the range of |ratio(3 um) / ratio(2 um) - 1| (oracle's formula
    on a 1 K grid; the law's grid is 0.25 K, the deviation smooth: 1e-4 relative)."""
    visc = model.process["temp"]["viscosity"]
    lo, hi = model.process["temp"]["range_C"]
    t = np.arange(lo, hi + 0.5, 1.0)
    want = max(abs(viscosity_ratio(x, visc["t0_K"], 3e-6) / viscosity_ratio(x, visc["t0_K"], 2e-6) - 1) for x in t)
    assert visc["sides_spread"] == pytest.approx(want, rel=1e-4)


@pytest.fixture(scope="module")
def disk():
    """The small free disk of tests/mechanics/test_damping.py with the compressible film, its top ring
    3 um above and its bottom ring 4 um below, temp declared."""
    from tests.mechanics.test_damping import COMPRESSIBLE, SMALL

    text = SMALL.replace('modes = ["2,0c"]\n', "") + "[damping]\n" + COMPRESSIBLE
    i = text.index('gap = "3 um"', text.index('name = "bot"'))
    text = text[:i] + 'gap = "4 um"' + text[i + len('gap = "3 um"') :]
    return build_model(parse_structure(text + '[process]\nparameters = ["temp"]\n', "damped_disk.toml"))


@pytest.mark.parametrize("temp", [-40.0, 125.0])
def test_compressible_branches_follow_their_sides_law(disk, temp):
    """Each Maxwell branch is one side's film (r_j ~ mu_eff of its gap, its corner ~ 1 / mu_eff:
    netgen.model.process_film.compressible_law), so at temp its damper is times its own gap's ratio
    (the oracle's, 3 or 4 um) and its corner over it: the law's branches (netgen.model.process.film_at)
    within the polynomial's misfit, now the stated error, plus 1e-12; both sides carry branches."""
    from netgen.model.process import film_at

    visc = disk.process["temp"]["viscosity"]
    z = disk.coordinates[0]
    below = set(visc["sides"][0]["branches"][0])
    assert visc["sides"][0]["side"] == "below" and 0 < len(below) < len(z.film)
    assert visc["max_rel_error"] == visc["polynomial_misfit"]
    eps = visc["polynomial_misfit"] + 1e-12
    for j, ((r, w), (r0, w0)) in enumerate(zip(film_at(disk.process, 0, z.film, temp_c=temp), z.film)):
        ratio = viscosity_ratio(temp, visc["t0_K"], 4e-6 if j in below else 3e-6)
        print(f"branch {j} ({'below' if j in below else 'above'}) at {temp} degC: {r / r0 / ratio - 1:+.1e}")
        assert r / r0 == pytest.approx(ratio, rel=eps) and w / w0 == pytest.approx(1 / ratio, rel=eps)
