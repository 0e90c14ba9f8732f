"""The squeeze film's gap law (netgen.model.process_film.film_law) against the Reynolds solve re-run at the
moved gaps: tests/oracles/process_cases.py's PROOF mass (three coordinates z, tilt_x, tilt_y) between a
plate 2 um above and one 3 um below, so that each coordinate's film has two sides with different shares,
with dg_top and dg_bot. The model's damping at (dg_top, dg_bot) (netgen.model.process.coordinate_values,
the arithmetic the emitters render) against netgen.mechanics.damping re-run on the structure with the
gaps 2 um + dg_top and 3 um + dg_bot. Both solve the same Reynolds matrix (it depends on the plate and
the shapes, not the gap, without holes), so they differ by round-off only: the bound 1e-12 is a few
hundred ulps of the sums of the 12 mu_eff / g^3 R terms."""

from __future__ import annotations

import pytest

from netgen.build import build_model
from netgen.mechanics import mechanics
from netgen.mechanics.damping import damping
from netgen.model.process import coordinate_values
from netgen.structure import parse_structure
from tests.oracles.process_cases import PROOF

TEXT = PROOF.format(t=10.0, e=160.0).replace('parameters = ["dg", "tscale", "escale", "temp"]', 'parameters = ["dg"]')


def structure(top: float = 2.0, bot: float = 3.0):
    """PROOF with its plates top um above and bot um below."""
    text = TEXT.replace(
        'name = "top"\nside = "above"\ngap = "2 um"', f'name = "top"\nside = "above"\ngap = "{top!r} um"'
    )
    return parse_structure(
        text.replace('name = "bot"\nside = "below"\ngap = "2 um"', f'name = "bot"\nside = "below"\ngap = "{bot!r} um"'),
        "pm.toml",
    )


@pytest.fixture(scope="module")
def built():
    """The model and its mechanics (the gaps do not enter the mechanics)."""
    s = structure()
    return build_model(s), mechanics(s)


def test_two_sided_shares(built):
    """Each coordinate's film has a share on both sides, the nearer plate's larger, summing to 1."""
    model, _ = built
    films = {g["set"]: g["film"] for g in model.process["gaps"]}
    for v in range(model.ncoords):
        top, bot = films["top"]["share"][v], films["bot"]["share"][v]
        assert top + bot == pytest.approx(1.0, rel=1e-12)
        assert top > bot > 0.0


@pytest.mark.parametrize("dg_top,dg_bot", [(1.5e-7, -2e-7), (-1.5e-7, 2.5e-7), (0.0, 1e-7)])
def test_gap_law_against_rerun(built, dg_top, dg_bot):
    """The law at (dg_top, dg_bot) against the re-run at the moved gaps within 1e-12 (module docstring);
    the drawn damping is 2 % to 12 % off at these points."""
    model, m = built
    s = structure(2.0 + dg_top * 1e6, 3.0 + dg_bot * 1e6)
    rerun, _ = damping(s, m)
    for v, c in enumerate(model.coordinates):
        got = coordinate_values(model.process, v, dg={"top": dg_top, "bot": dg_bot})[2]
        print(f"{c.name}: law / re-run - 1 = {got / rerun[v] - 1:.1e} (drawn {c.damping / rerun[v] - 1:+.3f})")
        assert got == pytest.approx(rerun[v], rel=1e-12)
