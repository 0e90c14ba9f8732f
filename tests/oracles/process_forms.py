"""The piston of examples/piston_process.toml with the gap offset dg_drive in its emitted forms, shared by
tests/emit/test_process_stops.py, tests/emit/test_process_xspice.py and bench/process_dg_forms.py:
the static balance on the contact stop moved by dg (resting), the .op pushed onto the stop through the
force port in the .lib or through OSDI (op), and one ngspice run of the B-source .lib or the
_xspice.lib (libs, run). The test modules' docstrings give the references and tolerances."""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from netgen.emit import ngspice as emit_ngspice
from netgen.sim.ngspice import run_ngspice
from netgen.testbench.sigma_delta import ngspice as sdn

SPRING, GAP = 2.0, 2e-6  # N/m, m: examples/piston_process.toml
FORCE = -10e-6  # N through f_z (1 V = 1 uN), downwards onto the electrode


def resting(model, dg: float) -> float:
    """z (m) where spring, force and the stop's penalty balance, the stop at -(GAP + dg)."""
    c = model.contact
    k_c, delta = c["stiffness"], c["smoothing"]

    def pen(p: float) -> float:
        r = min(max(p, 0.0), delta)
        return r * r / (2 * delta) + max(p - delta, 0.0)

    def balance(z: float) -> float:
        return -SPRING * z + FORCE + k_c * GAP * pen((-z - GAP - dg) / GAP)

    return brentq(balance, -(GAP + dg) * 1.5, -(GAP + dg) * 0.9, xtol=1e-22, rtol=1e-15)


def op(folder, form: str, dg: float, workdir) -> float:
    """x_z (m) of the .op with FORCE on f_z and no voltage, in `form` (lib or osdi)."""
    lib = folder / ("piston_process.lib" if form == "lib" else "piston_process_osdi.lib")
    control = ""
    if form == "osdi":
        control = f".control\npre_osdi {folder / 'piston_process.osdi'}\nset num_threads=1\nrun\nwrite op.raw\n.endc"
    net = f"""* stop with dg, {form}
.include {lib}
X1 0 0 fz xz piston_process dg_drive={dg!r}
Vf fz 0 DC {FORCE * 1e6!r}
.options reltol=1e-6 vntol=1e-12
.op
{control}
.end
"""
    plot = run_ngspice(net, workdir / form)[0]
    return float(plot["v(xz)"].real[0]) * 1e-6


def libs(model, folder) -> dict[str, tuple[str, str]]:
    """form -> (.include path, .control lines) for the B-source .lib and the _xspice.lib."""
    (folder / "piston_process.lib").write_text(emit_ngspice.subcircuit(model))
    xlib, control = sdn.xspice_library(model, folder, sdn.code_models(False))
    return {"lib": (str(folder / "piston_process.lib"), ""), "xspice": (str(xlib.resolve()), "\n".join(control))}


def run(include: tuple[str, str], dg: float, drive: str, analysis: str, folder):
    """One ngspice run of the piston with dg_drive = dg in the given form."""
    path, control = include
    ctl = f".control\n{control}\nrun\nwrite out.raw\n.endc" if control else ""
    net = f"""* dg
.include {path}
X1 drive 0 fz xz piston_process dg_drive={dg!r}
Vd drive 0 DC {drive}
Vf fz 0 {analysis}
.options reltol=1e-6 vntol=1e-12
{ctl}
.end
"""
    return run_ngspice(net, folder)[0]


def ac_fit(plot) -> tuple[float, float, float]:
    """k, m, b from 1/H = k - m w^2 + i w b (H in um/uN = m/N) of an .ac plot's v(xz)."""
    w = 2 * np.pi * np.real(plot["frequency"])
    inv = 1.0 / plot["v(xz)"]
    a = np.stack([np.ones_like(w), -(w**2)], axis=1)
    (k, m), *_ = np.linalg.lstsq(a, inv.real, rcond=None)
    return float(k), float(m), float(np.mean(inv.imag / w))
