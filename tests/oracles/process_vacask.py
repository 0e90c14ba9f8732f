"""Corners and a Monte Carlo of process spread in VACASK's own netlist language (docs/process.md),
on the accelerometer of tests/oracles/process_mc.py (examples/accelerometer_z.toml with [process]
dg and tscale, compiled to OSDI by openvaf-r), against the same closed form.

VACASK has no random functions in its netlist or control language, so the draws are made here,
by numpy's default generator with a fixed seed (the same numbers on every machine for a given
numpy), and written into the netlist as two vectors; a sweep of the run index reads them.

VACASK sweeps a model parameter only while it is a plain value (not an expression), and a
top-level parameter not at all, so the process point is a parameter of a subcircuit `die` around
the instance: the corners sweep its `tscale` and `dg_bottom` (nested), the Monte Carlo its `run`
index into the vectors `ts` and `dg` (run = -1, the default, reads the scalars).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from netgen.core.paths import vacask_string
from netgen.sim.rawfile import Plot, read_raw
from netgen.sim.vacask import run_file

from .process_mc import FREQS, GRAVITY, SIGMA_G, SIGMA_T, Point

BIAS = 0.2  # V on the bottom electrode: the corners at the ranges' ends stay clear of pull-in (0.3 V
# with gravity pulls the plate past g/3 at tscale 1.1, dg_bottom -300 nm: no stable rest)
TSCALE = (0.9, 1.1)  # the declared tscale_range's ends (the [process] default)
DG = (-300e-9, 300e-9)  # dg_bottom's range: a quarter of the fit box (L_z / 4), the model's `gaps` max_m
# VACASK's Newton tolerances in the deck (x_z in V: 1 V = 1 um); vntol above the rounding floor of
# nodes at 0 (docs/contact.md, Newton at a stop), 2e-12 of |z| ~ 0.5 um
RELTOL, VNTOL = 1e-9, 1e-12
NAME = "process_sweep.sim"


def draws(runs: int, seed: int = 7) -> list[tuple[float, float]]:
    """(tscale, dg_bottom) of each run: normal, sigma 1 % and 10 nm (process_mc's spread)."""
    rng = np.random.default_rng(seed)
    n = rng.standard_normal((runs, 2))
    return [(1.0 + SIGMA_T * a, SIGMA_G * b) for a, b in n]


def vector(values: list[float]) -> str:
    """A VACASK vector literal of reals (repr: every double round-trips; an integer-looking value
    would make the vector an integer one, which VACASK will not multiply by a real)."""
    return "[" + ", ".join(repr(float(v)) for v in values) + "]"


def netlist(
    osdi: str | Path, points: list[tuple[float, float]], folder: Path | None = None, name: str = "accelerometer_z"
) -> str:
    """The VACASK netlist: the die subcircuit, the bias and gravity, the corner sweep (op and a
    three-point ac) and the Monte Carlo sweep over `points` (op and ac); `osdi` relative to the
    netlist's `folder` when inside it (the folder reruns wherever it is moved)."""
    ts, dg = vector([t for t, _ in points]), vector([d for _, d in points])
    runs = "[" + ", ".join(str(k) for k in range(len(points))) + "]"  # integer indices
    ac = f'ac from={FREQS[0]:g} to={FREQS[1]:g} mode="lin" points=2'  # 100, 200, 300 Hz
    corners_t, corners_g = vector(list(TSCALE)), vector(list(DG))
    return f"""process corners and Monte Carlo of {name} (tests/oracles/process_vacask.py)
ground 0
load {vacask_string(osdi, folder)}
model vsource vsource

// one die: its process point, or run `run` of the drawn vectors ts and dg
subckt die(top bottom plate fz xz a)
  parameters tscale=1.0 dg_bottom=0.0 run=-1
  parameters ts={ts}
  parameters dg={dg}
  model mems {name} tscale=run < 0 ? tscale : ts[run] dg_bottom=run < 0 ? dg_bottom : dg[run]
  x1 (top bottom plate fz xz a) mems
ends

u1 (top bottom plate fz xz a) die
v_top (top 0) vsource dc=0
v_bottom (bottom 0) vsource dc={BIAS}
v_plate (plate 0) vsource dc=0
v_a (a 0) vsource dc={GRAVITY}
v_fz (fz 0) vsource dc=0 mag=1

control
  options reltol={RELTOL} vntol={VNTOL}
  // corners: tscale and dg_bottom at their ranges' ends, nested
  sweep t instance="u1" parameter="tscale" values={corners_t}
  sweep g instance="u1" parameter="dg_bottom" values={corners_g}
    analysis corner_op op
  sweep t instance="u1" parameter="tscale" values={corners_t}
  sweep g instance="u1" parameter="dg_bottom" values={corners_g}
    analysis corner_ac {ac}
  // Monte Carlo: the drawn points, one run each
  sweep mc instance="u1" parameter="run" values={runs}
    analysis mc_op op
  sweep mc instance="u1" parameter="run" values={runs}
    analysis mc_ac {ac}
endc
"""


def points(op: Plot, ac: Plot) -> list[Point]:
    """Each sweep point's deflection (x_z, 1 V = 1 um) and, from the ac at the first and last
    frequency (1/H = k_eff - m w^2 in uN/um = N/m, no damping), k_eff and m."""
    x = np.real(op["xz"]) * 1e-6
    h = np.real(ac["xz"]).reshape(len(x), -1)
    w0, w1 = (2 * math.pi * f for f in FREQS)
    out = []
    for xi, (h0, *_, h1) in zip(x, h):
        mass = (1 / h0 - 1 / h1) / (w1**2 - w0**2)
        out.append(Point(float(xi), float(1 / h0 + mass * w0**2), float(mass)))
    return out


def corners() -> list[tuple[float, float]]:
    """The corner points in the deck's sweep order (tscale outer, dg_bottom inner)."""
    return [(t, d) for t in TSCALE for d in DG]


def run(osdi: Path, folder: Path, runs: int, seed: int = 7) -> dict[str, list[tuple[float, float, Point]]]:
    """Write the netlist into `folder`, run VACASK there; (tscale, dg, Point) of each corner and run."""
    mc = draws(runs, seed)
    sim = folder / NAME
    sim.write_text(netlist(osdi, mc, folder))
    run_file(sim, folder, "corner_op")
    out = {}
    for key, where in (("corner", corners()), ("mc", mc)):
        op, ac = (read_raw(folder / f"{key}_{a}.raw")[0] for a in ("op", "ac"))
        got = points(op, ac)
        assert len(got) == len(where), (key, len(got), len(where))
        out[key] = [(t, d, p) for (t, d), p in zip(where, got)]
    return out


def newton_bounds(p: Point, dg: float, bias: float = BIAS) -> tuple[float, float]:
    """Relative bounds on one point's z and f0 against the closed form: Newton stops within
    reltol |x| + vntol of the root (quadratic convergence: the last iterate is closer than the
    step it tests); the fit is exact to round-off (1e-12 on top). dz moves k_eff by 6 c dz / s^4
    (c = eps A V^2 / 2, s the gap), f0 by half that over k_eff; the ac is linear: 1e-9 for the
    round-off of 1/H and the difference that gives m."""
    from .process_mc import AREA, EPS0, GAP

    dz = (RELTOL * abs(p.z) * 1e6 + VNTOL) * 1e-6
    s = GAP + dg + p.z
    c = EPS0 * AREA * bias**2 / 2
    return dz / abs(p.z) + 1e-12, 0.5 * 6 * c * dz / s**4 / p.k_eff + 1e-9
