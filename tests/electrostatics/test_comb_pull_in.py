"""Side instability of a lateral comb on the 2-D field tables (comb_model = "field2d"): the moving
fingers between two fixed fingers of one electrode, over the substrate, at t/g = 2. The ngspice
DC sweep (39 and 46) of the comb voltage against the pull-in of the Python MacroModel,
V = sqrt(2 k / C''(0)) from its fitted curvature, within 0.5 %; the model's curvature against
the section table's own, 2 n L S''(g) (independent of the fit), within 1 %; and the fringe's
shift below the closed form V = sqrt(k g^3 / (2 eps n t L)). Coarse tables in a private cache
(one mesh level: at t/g = 20 that mesh misses the curvature by 3 %, so t/g = 20 and the
converged figures are bench/comb_pull_in.py's, minutes of CPU)."""

from __future__ import annotations

import math

import pytest

from netgen.build import build
from netgen.core.constants import EPS0
from netgen.electrostatics import comb_section
from netgen.structure import parse_structure
from tests.fixtures import NGSPICE
from tests.oracles.lateral_comb import L0, G, K, N, circuit_pull_in, model_pull_in, structure, table_pull_in


@pytest.fixture(scope="module")
def builds(tmp_path_factory):
    """The comb built at t/g = 2 on coarse tables (kept loaded for the references)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("NETGEN_CACHE", str(tmp_path_factory.mktemp("cache")))
        mp.setattr(comb_section, "GRID", {"gaps": 5, "offsets": 4, "ends": 4})
        mp.setattr(comb_section, "SETTINGS", {"tol": 5e-3, "max_levels": 1, "mesh_scale": 1.0, "order": 2})
        mp.setattr(comb_section, "_TABLES", {})
        yield {r: build(parse_structure(structure(r), f"comb_t{r:g}.toml")) for r in (2,)}


@pytest.mark.parametrize("release", sorted(NGSPICE))
@pytest.mark.parametrize("ratio", [2])
def test_pull_in_on_the_2d_tables_in_an_ngspice_dc_sweep(builds, tmp_path, release, ratio):
    """Circuit against Python within 0.5 %, Python against the tables within 1 %, and the fringe
    lowering the pull-in below the closed form (0.926 of it on converged tables)."""
    b = builds[ratio]
    closed = math.sqrt(K * G**3 / (2 * EPS0 * N * ratio * G * L0))
    python, tables = model_pull_in(b.model), table_pull_in(b)
    circuit = circuit_pull_in(b.model, tmp_path, release, 1.02 * closed)
    print(
        f"t/g = {ratio}, ngspice {release}: circuit {circuit:.4f} V, Python {python:.4f} V, tables {tables:.4f} V, "
        f"closed form {closed:.4f} V; circuit / closed {circuit / closed:.4f}, circuit / Python - 1 "
        f"{circuit / python - 1:+.2e}"
    )
    assert circuit == pytest.approx(python, rel=0.005)
    assert python == pytest.approx(tables, rel=0.01)
    assert 0.90 < circuit / closed < 0.95
