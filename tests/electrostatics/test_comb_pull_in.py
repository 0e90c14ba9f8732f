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

import numpy as np
import pytest

from netgen.build import build
from netgen.constants import EPS0
from netgen.electrostatics import comb_section
from netgen.emit import ngspice as emit_ngspice
from netgen.sim.ngspice import run_ngspice
from netgen.structure import parse_structure
from tests.electrostatics.test_comb import L0, LATERAL, G, K, N
from tests.fixtures import NGSPICE, Bench, using_ngspice


def structure(ratio: float) -> str:
    """test_comb's lateral comb, y only, fingers ratio * g thick over a substrate 2 um below, field2d."""
    return (
        LATERAL.replace('rigid = ["x", "y"]', 'rigid = ["y"]')
        .replace('comb_model = "textbook"', 'comb_model = "field2d"')
        .replace('thickness = "2 um"', f'thickness = "{ratio * G * 1e6:g} um"')
        .replace('overlap = "20 um"', 'overlap = "20 um"\nsubstrate_gap = "2 um"')
    )


@pytest.fixture(scope="module")
def builds(tmp_path_factory):
    """The comb built at t/g = 2 on coarse tables (kept loaded for the references)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("NETGEN_CACHE", str(tmp_path_factory.mktemp("cache")))
        mp.setattr(comb_section, "GRID", {"gaps": 5, "offsets": 4, "ends": 4})
        mp.setattr(comb_section, "SETTINGS", {"tol": 5e-3, "max_levels": 1, "mesh_scale": 1.0, "order": 2})
        mp.setattr(comb_section, "_TABLES", {})
        yield {r: build(parse_structure(structure(r), f"comb_t{r:g}.toml")) for r in (2,)}


def model_pull_in(model) -> float:
    """V at which (1/2) V^2 C''(0) of the fitted model equals k (central difference at rest)."""
    y = model.coordinates[0]
    h = 1e-3
    c = [float(model.capacitance(np.array([[s * h]]))[0, 0]) for s in (1, 0, -1)]
    return math.sqrt(2 * y.stiffness / ((c[0] - 2 * c[1] + c[2]) / (h * y.scale) ** 2))


def table_pull_in(b) -> float:
    """The same from the section table: C(y) = n L (S(g - y, 0) + S(g + y, 0)) + tips (no y)."""
    cell = next(p for _, p in b.prepared.parts if hasattr(p, "geoms")).geoms[0].cell
    h = 2e-9
    s = [float(comb_section.section(G + d, 0.0, cell)) for d in (h, 0.0, -h)]
    return math.sqrt(2 * K / (2 * N * L0 * (s[0] - 2 * s[1] + s[2]) / h**2))


def circuit_pull_in(model, tmp_path, release: str, v_max: float) -> float:
    """Where the sideways compliance y / f of a 1e-6 g static offset diverges in an ngspice DC sweep
    of the comb voltage (test_comb.test_side_instability_in_an_ngspice_dc_sweep's reading)."""
    lib = tmp_path / "comb.lib"
    lib.write_text(emit_ngspice.subcircuit(model))
    nudge = 1e-6 * G * K / 1e-6
    bench = Bench(model, lib, sources={"drive": "DC 0", "plate": "0", "f_y": f"DC {nudge!r}"})
    with using_ngspice(release):
        plot = run_ngspice(bench.netlist(f".dc Vdrive 0 {v_max!r} {v_max / 4000!r}"), tmp_path)[0]
    v, y = plot["v-sweep"], plot["x1.xs_y"]
    flips = np.flatnonzero((y[:-1] > 0) & (y[1:] < 0))
    assert len(flips), "the sideways compliance does not diverge inside the sweep"
    j = int(flips[0])
    return 0.5 * (v[j] + v[j + 1])


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
