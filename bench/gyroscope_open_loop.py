"""The open-loop gyroscope (examples/gyroscope_z.toml): the sense response to a sine drive at the x
resonance under a rate Omega_z, per simulator (ngspice 39 and 46 on the B-source .lib, VACASK on the
OpenVAF-compiled module), against the closed form Y / X = -(k_xy + 2 i m Omega w) / (k_y - m Omega^2 -
m w^2 + i w b_y) (tests/mechanics/test_gyroscope.py asserts it at Q = 20). Prints, per simulator, the
Coriolis and quadrature parts' relative errors, and the device's open-loop figures from the model:
scale factor |Y| per deg/s at a drive amplitude of 4 um, and the zero-rate output (the quadrature as
an equivalent rate k_xy / (2 m w)). At the example's Q = 2000 a run settles in 30 tau = 0.15 s
(about 2000 drive periods, 4e5 steps): minutes per simulator.

    .venv/bin/python bench/gyroscope_open_loop.py [--q 20] [--omega 10]
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
from pathlib import Path

import numpy as np
from support import NGSPICE, ROOT, Bench

from netgen.build import build_model
from netgen.emit.ngspice import subcircuit
from netgen.emit.veriloga import module
from netgen.sim import ngspice
from netgen.sim.ngspice import run_ngspice
from netgen.sim.vacask import VacaskBench, compile_va, run_vacask
from netgen.structure import parse_structure

EXAMPLE = ROOT / "examples" / "gyroscope_z.toml"
FORCE, PERIODS, DRIVE_AMPLITUDE = 0.01, 10, 4e-6  # uN, fit window (periods), m


def phasor(t: np.ndarray, y: np.ndarray, w: float) -> complex:
    """Complex amplitude at w, y ~ Re(A e^{i w t}) (least squares on cos, sin, 1)."""
    a = np.column_stack([np.cos(w * t), np.sin(w * t), np.ones_like(t)])
    (c, s, _), *_ = np.linalg.lstsq(a, y, rcond=None)
    return complex(c, -s)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--q", type=float, default=20.0)
    ap.add_argument("--omega", type=float, default=10.0, help="rate, rad/s")
    a = ap.parse_args()
    text = EXAMPLE.read_text().replace("q_factor = { x = 2000, y = 2000 }", f"q_factor = {{ x = {a.q}, y = {a.q} }}")
    model = build_model(parse_structure(text, str(EXAMPLE)))
    cx, cy = (next(c for c in model.coordinates if c.name == n) for n in "xy")
    m = 2330.0 * 10e-6 * (500e-6**2 - 50 * 50 * (4e-6) ** 2)  # rho t (L W - holes), from the file's numbers
    k_xy = 5e-3
    w = math.sqrt(cx.stiffness / cx.mass)
    period, step = 2 * math.pi / w, 2 * math.pi / w / 200
    stop = 30 * 2 * a.q / w + PERIODS * period
    d = cy.stiffness - m * a.omega**2 - m * w**2 + 1j * w * cy.damping
    print(f"drive {w / 2 / math.pi:.1f} Hz, sense {math.sqrt(cy.stiffness / cy.mass) / 2 / math.pi:.1f} Hz, Q {a.q:g}")
    sf = 2 * m * DRIVE_AMPLITUDE * w * (math.pi / 180) / abs(cy.stiffness - m * w**2 + 1j * w * cy.damping)
    print(f"open-loop scale factor at X = 4 um: {sf * 1e12:.4g} pm per deg/s")
    print(f"zero-rate output (quadrature as a rate, k_xy / (2 m w)): {k_xy / (2 * m * w) * 180 / math.pi:.4g} deg/s")
    freq = w / (2 * math.pi)
    with tempfile.TemporaryDirectory() as tmp:
        runs = {}
        lib = Path(tmp) / "g.lib"
        lib.write_text(subcircuit(model))
        for release, path in sorted(NGSPICE.items()):
            os.environ[ngspice.ENV] = path
            bench = Bench(model, lib, sources={"w_z": repr(a.omega), "f_x": f"SIN(0 {FORCE} {freq!r})"})
            plot = run_ngspice(bench.netlist(f".tran {step!r} {stop!r} 0 {step!r} uic"), Path(tmp) / release)[0]
            runs[f"ngspice {release}"] = (plot["time"], plot["v(x1.xs_x)"], plot["v(x1.xs_y)"])
        va = Path(tmp) / "g.va"
        va.write_text(module(model))
        osdi, _ = compile_va(va)
        src = {"w_z": f"dc={a.omega!r}", "f_x": f'type="sine" sinedc=0 ampl={FORCE!r} freq={freq!r}'}
        analysis = f'analysis tran1 tran step={step!r} stop={stop!r} maxstep={step!r} icmode="uic"'
        plot = run_vacask(VacaskBench(model, osdi, sources=src).netlist(analysis), Path(tmp) / "vacask")
        runs["vacask"] = (plot["time"], plot["x1:xs_x"], plot["x1:xs_y"])
        for name, (t, x, y) in runs.items():
            t = np.asarray(t)
            last = t > t[-1] - PERIODS * period
            r = phasor(t[last], np.asarray(y)[last] * cy.scale, w) / phasor(t[last], np.asarray(x)[last] * cx.scale, w)
            got = -r * d
            print(
                f"{name}: Coriolis {got.imag / (2 * m * a.omega * w) - 1:+.2e}, quadrature {got.real / k_xy - 1:+.2e} "
                f"(relative to the closed form)"
            )


if __name__ == "__main__":
    main()
