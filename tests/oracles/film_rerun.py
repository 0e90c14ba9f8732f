"""The squeeze film's damping re-run at moved gaps with the gas at a temperature, and the damping of z
read from the emitted forms at a list of instance points: shared by tests/emit/
test_process_film_perforated_temp.py and tests/emit/test_process_film_temp_sides.py.

The gas: air's viscosity and mean free path at T written out here (Sutherland's mu ~ T^1.5 / (T + S),
S = 111 K: White, Viscous Fluid Flow, table 1-2; the mean free path lambda = (mu / p) sqrt(pi k T / 2 m)
at fixed pressure, 68 nm at 300 K), through netgen.mechanics.damping's own Reynolds solve."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from netgen.core import constants
from netgen.mechanics.damping import damping
from netgen.sim.ngspice import run_control

from .testbench import NGSPICE

SUTHERLAND_AIR, MEAN_FREE_PATH, VISCOSITY = 111.0, 68e-9, 1.85e-5  # K; m and Pa s at 1 atm, 300 K


def rerun(s, m, t0_k: float, moved: dict[str, float], temp_c: float) -> np.ndarray:
    """The damping of each coordinate re-run with the electrode sets' gaps + moved[set] (m) and air at
    temp_c (T0 = t0_k: the tabulated gas)."""
    t = temp_c + 273.15
    mu = (t / t0_k) ** 1.5 * (t0_k + SUTHERLAND_AIR) / (t + SUTHERLAND_AIR)
    gas = constants.Gas("air", VISCOSITY * mu, MEAN_FREE_PATH * mu * math.sqrt(t / t0_k))
    sets = tuple(dataclasses.replace(e, gap=e.gap + moved.get(e.name, 0.0)) for e in s.electrode_sets)
    with pytest.MonkeyPatch.context() as mp:
        mp.setitem(constants.GASES, "air", gas)
        return np.asarray(damping(dataclasses.replace(s, electrode_sets=sets), m)[0])


def spice_z_damping(lib: Path, pre: list[str], params: list[str], version: str, tmp_path: Path) -> list[float]:
    """b of z per instance (its parameters `params[i]`) from one .ac of the subcircuit in `lib` in
    ngspice `version` (`pre`: .control lines loading a module): a unit AC force on f_z, the other ports
    grounded, b from 1/H = k - m w^2 + i w b at 1..3 kHz."""
    head = Path(lib).read_text().split(".subckt ")[1].split("params:")[0].replace("\n+", " ").split()
    lines = []
    for i, p in enumerate(params):
        nodes = [f"fz{i}" if n == "f_z" else f"xz{i}" if n == "x_z" else f"n{i}_{n}" if n.startswith("x_") else "0"
                 for n in head[1:]]  # fmt: skip
        lines += [f"X{i} {' '.join(nodes)} {head[0]} {p}", f"Vf{i} fz{i} 0 DC 0 AC 1"]
    control = [".control", *pre, "set num_threads=1", "ac lin 3 1k 3k", "write ac.raw all", ".endc"]
    deck = "\n".join(["* film damping per instance", f".include {lib}", *lines, *control, ".end", ""])
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("NETGEN_NGSPICE", NGSPICE[version])
        ac = run_control(deck, tmp_path, "circuit", "ac.raw")
    w = 2 * np.pi * np.real(ac["frequency"])
    return [float(np.mean((1.0 / np.asarray(ac[f"v(xz{i})"])).imag / w)) for i in range(len(params))]


def fmu_z_damping(model, params: list[dict[str, float]]) -> list[float]:
    """b of z per parameter set from the FMU (model exchange): -m q'' at q = 0, q'_z = 1 m/s."""
    from netgen.sim import fmu

    c, n = model.coordinates[0], model.ncoords
    path = fmu.built(model)
    got = []
    for p in params:
        inst = fmu.Instance(path, cosim=False)
        inst.set(p)
        inst.start()
        inst.set_states(np.array([0.0] * n + [1.0] + [0.0] * (n - 1)))
        got.append(-c.mass * float(inst.get(["qdd_z"])[0]))
        inst.close()
    return got
