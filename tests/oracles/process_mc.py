"""Monte Carlo of process spread in ngspice's own `.control` loop (docs/process.md), and its
closed-form reference: the single-axis accelerometer (examples/accelerometer_z.toml, a rigid plate
on a given 0.3 N/m spring between two parallel plates, fringe "none") with [process] dg and
tscale, under gravity and a bias on the bottom electrode.

Closed form (z up, the bottom electrode at gap g_b = 2 um + dg_bottom below, top and plate at 0 V):
    G(z) = k z + m(t) a + c / (g_b + z)^2 = 0,   c = eps0 A V_b^2 / 2,   m(t) = m0 t
(the electrostatic pull eps0 A V^2 / (2 gap^2) towards the bottom, the inertial load -m a of the
frame acceleration a_in = a); the small-signal stiffness k_eff = k - 2 c / (g_b + z)^3 and the
resonance f = sqrt(k_eff / m) / (2 pi). The sensitivities by implicit differentiation:
dz/dt = -m0 a / k_eff, dz/dg = 2 c / ((g_b + z)^3 k_eff), dk_eff/dθ = 6 c / (g_b + z)^4 (dg/dθ + dz/dθ).
"""

from __future__ import annotations

import math
import re
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

from netgen.build import build_model
from netgen.core.constants import EPS0
from netgen.model import MacroModel
from netgen.sim.ngspice import ngspice_path
from netgen.structure import parse_structure

PROCESS = '\n[process]\nparameters = ["dg", "tscale"]\n'  # appended to examples/accelerometer_z.toml
K, GAP, SIDE, THICK, RHO = 0.3, 2e-6, 500e-6, 20e-6, 2330.0
AREA, M0 = SIDE * SIDE, 2330.0 * 500e-6 * 500e-6 * 20e-6
GRAVITY, BIAS = 9.81, 0.3  # m/s^2 on a_in; V on the bottom electrode
SIGMA_T, SIGMA_G = 0.01, 10e-9  # the spread drawn: 1 % of the thickness, 10 nm of the bottom gap
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "accelerometer_z.toml"


def model() -> MacroModel:
    """examples/accelerometer_z with PROCESS: the model the ngspice and the VACASK Monte Carlo sample."""
    return build_model(parse_structure(EXAMPLE.read_text() + PROCESS, "accelerometer_z.toml"))


FREQS = (100.0, 300.0)  # Hz: the two .ac points that give k_eff and m (1/H = k_eff - m w^2, no damping)


@dataclass(frozen=True)
class Point:
    """One process point: deflection z (m), small-signal stiffness (N/m), mass (kg), resonance (Hz)."""

    z: float
    k_eff: float
    mass: float

    @property
    def f0(self) -> float:
        return math.sqrt(self.k_eff / self.mass) / (2 * math.pi)


def closed_form(t: float = 1.0, dg: float = 0.0, bias: float = BIAS) -> Point:
    """The equilibrium and resonance of the closed form at tscale t, bottom gap offset dg and
    `bias` volts on the bottom electrode."""
    c, g, m = EPS0 * AREA * bias**2 / 2, GAP + dg, M0 * t
    z = brentq(lambda z: K * z + m * GRAVITY + c / (g + z) ** 2, -g / 3, 0.0, xtol=1e-22, rtol=1e-15)
    return Point(z, K - 2 * c / (g + z) ** 3, m)


def sensitivities(bias: float = BIAS) -> dict[str, float]:
    """d ln|z| / d t, d ln|z| / d g (1/m), d ln f / d t, d ln f / d g (1/m) at the nominal point."""
    p, c = closed_form(bias=bias), EPS0 * AREA * bias**2 / 2
    s = GAP + p.z
    dz = {"t": -M0 * GRAVITY / p.k_eff, "g": 2 * c / (s**3 * p.k_eff)}
    dk = {"t": 6 * c / s**4 * dz["t"], "g": 6 * c / s**4 * (1.0 + dz["g"])}
    dm = {"t": M0, "g": 0.0}
    out = {f"z_{v}": dz[v] / p.z for v in dz}
    out |= {f"f_{v}": 0.5 * (dk[v] / p.k_eff - dm[v] / p.mass) for v in dz}
    return out


def netlist(lib: Path, runs: int, seed: int) -> str:
    """The Monte Carlo deck: agauss (defined in the control language as ngspice's own examples do)
    on tscale and dg_bottom, alterparam + reset per run, .op for the deflection and a two-point .ac
    for k_eff and m; each run echoes its draws and results."""
    ac = f"ac lin 3 {FREQS[0]:g} {FREQS[1]:g}"  # the first and last of three points
    return f"""* process Monte Carlo of the accelerometer (tests/oracles/process_mc.py)
.include {lib}
.param tsc=1 dgb=0
.options reltol=1e-9 vntol=1e-12 abstol=1e-20
Vb bottom 0 DC {BIAS}
Vt top 0 0
Vp plate 0 0
Va a 0 {GRAVITY}
Vf fz 0 DC 0 AC 1
X1 top bottom plate fz xz a accelerometer_z tscale={{tsc}} dg_bottom={{dgb}}
.control
define agauss(nom, avar, sig) (nom + avar/sig * sgauss(0))
setseed {seed}
repeat {runs}
  let t = agauss(1, {3 * SIGMA_T}, 3)
  let d = agauss(0, {3 * SIGMA_G}, 3)
  echo MCP $&t $&d
  alterparam tsc = $&t
  alterparam dgb = $&d
  reset
  op
  let x = v(xz)
  echo MCX $&x
  {ac}
  let hr = real(v(xz))
  let h0 = hr[0]
  let h1 = hr[2]
  echo MCH $&h0 $&h1
  destroy all
end
.endc
.end
"""


def run(lib: Path, folder: Path, runs: int, seed: int = 7) -> list[tuple[float, float, Point]]:
    """(tscale, dg, Point) of each run of the deck in the ngspice that NETGEN_NGSPICE selects."""
    cir = folder / "mc.cir"
    cir.write_text(netlist(lib, runs, seed))
    out = subprocess.run([ngspice_path(), "-b", cir.name], cwd=folder, capture_output=True, text=True, timeout=600)
    draws = [tuple(map(float, m)) for m in re.findall(r"^MCP (\S+) (\S+)$", out.stdout, re.M)]
    xs = [float(m) for m in re.findall(r"^MCX (\S+)$", out.stdout, re.M)]
    hs = [tuple(map(float, m)) for m in re.findall(r"^MCH (\S+) (\S+)$", out.stdout, re.M)]
    results = [(x, *h) for x, h in zip(xs, hs)]
    assert len(draws) == len(xs) == len(hs) == runs, out.stdout[-2000:] + out.stderr[-2000:]
    w0, w1 = (2 * math.pi * f for f in FREQS)
    rows = []
    for (t, d), (x, h0, h1) in zip(draws, results):
        mass = (1 / h0 - 1 / h1) / (w1**2 - w0**2)  # 1/H in uN/um = N/m
        rows.append((t, d, Point(x * 1e-6, 1 / h0 + mass * w0**2, mass)))
    return rows


def regression(rows: list[tuple[float, float, Point]], points: list[Point] | None = None) -> dict[str, float]:
    """Least-squares slopes of ln|z| and ln f over (t - 1, dg) across the runs (of `points` instead
    of the runs' own results, e.g. the closed form at the same draws)."""
    pts = points or [p for _, _, p in rows]
    a = np.array([[1.0, t - 1.0, d] for t, d, _ in rows])
    out = {}
    for q, vals in (("z", [math.log(-p.z) for p in pts]), ("f", [math.log(p.f0) for p in pts])):
        coef, *_ = np.linalg.lstsq(a, np.array(vals), rcond=None)
        out[f"{q}_t"], out[f"{q}_g"] = float(coef[1]), float(coef[2])
    return out
