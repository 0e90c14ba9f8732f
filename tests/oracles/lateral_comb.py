"""The lateral comb of the comb tests (30 fingers 2 um wide, 2 um gaps, 20 um overlap, k = 5 N/m;
tests/electrostatics/test_comb.py) and the readings of its side pull-in voltage: the circuit's (an
ngspice DC sweep), the fitted model's and the section table's (tests/electrostatics/test_comb_pull_in.py,
bench/comb_pull_in.py)."""

from __future__ import annotations

import math

import numpy as np

from netgen.electrostatics import comb_section
from netgen.emit import ngspice as emit_ngspice
from netgen.sim.ngspice import run_ngspice

from .testbench import Bench, using_ngspice

N, T, G, L0, K = 30, 2e-6, 2e-6, 20e-6, 5.0

LATERAL = f"""
name = "comb"
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
k_rot = 1e-6
[[electrodes]]
name = "drive"
kind = "lateral_comb"
orientation = "x"
fingers = {N}
width = "2 um"
gap = "2 um"
length = "40 um"
overlap = "20 um"
side = "+"
center = ["130 um", "0 um"]
[coordinates]
rigid = ["x", "y"]
[sampling]
levels = 5
[fit]
degree = 3
[electrostatics]
fringe = "none"
comb_model = "textbook"
"""


def structure(ratio: float) -> str:
    """test_comb's lateral comb, y only, fingers ratio * g thick over a substrate 2 um below, field2d."""
    return (
        LATERAL.replace('rigid = ["x", "y"]', 'rigid = ["y"]')
        .replace('comb_model = "textbook"', 'comb_model = "field2d"')
        .replace('thickness = "2 um"', f'thickness = "{ratio * G * 1e6:g} um"')
        .replace('overlap = "20 um"', 'overlap = "20 um"\nsubstrate_gap = "2 um"')
    )


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
