"""A plain `.op` from rest finds the stable, in-range equilibrium in every emitted form, with no
`.nodeset`, and an open mechanical input is no singular matrix.

References are independent of the pipeline: the parallel-plate force balance
k x = eps0 A V^2 / (2 (g - x)^2) solved with scipy's brentq on its stable branch 0 <= x < g/3
(V_PI = sqrt(8 k g^3 / (27 eps0 A))), and symmetry (a symmetrically biased disk on springs stays at
rest). The structures are the cheapest that show the failure this guards against (the B-source
.lib converged to the pulled-in contact state from its all-zero first Newton iterate): the piston
example (fringe off, 1/C exactly affine) and a rigid free disk over one electrode, fringe off,
held by external springs through its force ports (0.3 s builds).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.constants import epsilon_0
from scipy.optimize import brentq

from netgen.build import build
from netgen.emit import ngspice, veriloga, xspice
from netgen.model import MacroModel
from netgen.sim import codemodel
from netgen.sim.ngspice import ENV, run_ngspice
from netgen.sim.vacask import VacaskBench, compile_va, run_vacask
from netgen.structure import parse_structure
from tests.fixtures import NETLISTS, NGSPICE, ROOT, Bench
from tests.structures import ONE_PLATE_GAP, ONE_PLATE_RADIUS, one_plate_disk

PISTON = ROOT / "examples" / "piston.toml"
DISK = (
    one_plate_disk(
        "spring_disk", "Rigid free disk over one electrode, held by external springs through its force ports"
    )
    + """[sampling]
levels = 5
range = 0.3
"""
)
DISK_RADIUS, DISK_GAP = ONE_PLATE_RADIUS, ONE_PLATE_GAP
SPRING_HZ = 20e3  # external springs: z at 20 kHz, the tilts twice as stiff (stable past z's fold)


def stable_root(k: float, gap: float, area: float, volts: float) -> float:
    """Travel x toward the electrode on the stable branch of the parallel-plate balance."""
    return brentq(lambda x: k * x - epsilon_0 * area * volts**2 / (2 * (gap - x) ** 2), 0.0, gap / 3, xtol=1e-18)


def pull_in(k: float, gap: float, area: float) -> float:
    return math.sqrt(8 * k * gap**3 / (27 * epsilon_0 * area))


@pytest.fixture(scope="module")
def piston(tmp_path_factory) -> tuple[MacroModel, Path, dict]:
    """The piston example's model, its three emitted files and its closed-form numbers."""
    b = build(parse_structure(PISTON.read_text(), "examples/piston.toml"))
    folder = tmp_path_factory.mktemp("piston")
    (folder / "piston.lib").write_text(ngspice.subcircuit(b.model))
    (folder / "piston_xspice.lib").write_text(xspice.subcircuit(b.model))
    (folder / "piston.va").write_text(veriloga.module(b.model))
    c = b.structure.conductor
    facts = {"k": c.stiffness, "gap": b.structure.electrode_sets[0].gap, "area": c.length * c.width}
    return b.model, folder, facts


@pytest.fixture(scope="module")
def disk(tmp_path_factory) -> tuple[MacroModel, Path]:
    b = build(parse_structure(DISK, "spring_disk.toml"))
    folder = tmp_path_factory.mktemp("disk")
    (folder / "spring_disk.lib").write_text(ngspice.subcircuit(b.model))
    (folder / "spring_disk_xspice.lib").write_text(xspice.subcircuit(b.model))
    return b.model, folder


def control(lib: Path) -> list[str]:
    """The .control lines an emitted .lib needs (the code model for the xspice form)."""
    return codemodel.control_lines(codemodel.build(progress=lambda m: None)) if "xspice" in lib.name else []


def operating_point(model: MacroModel, lib: Path, workdir: Path, sources: dict, **bench) -> np.ndarray:
    """Scaled coordinates xs of a plain .op (no .nodeset, default options)."""
    b = Bench(model, lib, sources=sources, control=control(lib), **bench)
    text = b.netlist(".op")
    assert ".nodeset" not in text and ".ic" not in text
    plot = run_ngspice(text, workdir)[0]
    return np.array([plot[f"v(x1.xs_{c.name})"][0] for c in model.coordinates])


FORMS = [("39", "piston.lib"), ("46", "piston.lib"), ("39", "piston_xspice.lib")]


@pytest.mark.parametrize("release,form", FORMS, ids=[f"{r}-{f}" for r, f in FORMS])
@pytest.mark.parametrize("fraction", [0.25, 0.5, 0.75, 0.95])
def test_piston_op_is_the_stable_root(piston, release, form, fraction, monkeypatch, tmp_path):
    """The piston at 25..95 % of V_PI: the .op travel equals brentq's stable root within 0.5 %."""
    monkeypatch.setenv(ENV, NGSPICE[release])
    model, folder, f = piston
    volts = fraction * pull_in(f["k"], f["gap"], f["area"])
    xs = operating_point(model, folder / form, tmp_path, {"drive": repr(volts), "plate": "0"})
    travel = -xs[0] * model.coordinates[0].scale
    assert travel == pytest.approx(stable_root(f["k"], f["gap"], f["area"], volts), rel=5e-3)


@pytest.mark.parametrize("release,form", FORMS, ids=[f"{r}-{f}" for r, f in FORMS])
def test_open_force_port_runs(piston, release, form, monkeypatch, tmp_path):
    """f_z left unconnected (no source on it): the .op runs without a singular-matrix warning and
    reads zero external force (the stable root at half V_PI)."""
    monkeypatch.setenv(ENV, NGSPICE[release])
    model, folder, f = piston
    volts = 0.5 * pull_in(f["k"], f["gap"], f["area"])
    xs = operating_point(model, folder / form, tmp_path, {"drive": repr(volts), "plate": "0"}, driven_elsewhere={"f_z"})
    assert "singular" not in (tmp_path / "circuit.log").read_text().lower()
    travel = -xs[0] * model.coordinates[0].scale
    assert travel == pytest.approx(stable_root(f["k"], f["gap"], f["area"], volts), rel=5e-3)


@pytest.mark.parametrize("open_port", [False, True])
def test_piston_op_in_vacask(piston, open_port, tmp_path):
    """The Verilog-A module in VACASK `op` at 95 % of V_PI, with f_z driven and left open."""
    model, folder, f = piston
    osdi, _ = compile_va(folder / "piston.va", tmp_path / "piston.osdi")
    volts = 0.95 * pull_in(f["k"], f["gap"], f["area"])
    text = VacaskBench(model, osdi, sources={"drive": f"dc={volts!r}", "plate": "dc=0"}).netlist("analysis op1 op")
    if open_port:
        text = "\n".join(line for line in text.splitlines() if not line.startswith("v_f_z ")) + "\n"
    plot = run_vacask(text, tmp_path, analysis="op1")
    travel = -float(plot["x1:xs_z"][0]) * model.coordinates[0].scale
    assert travel == pytest.approx(stable_root(f["k"], f["gap"], f["area"], volts), rel=5e-3)


def springs(model: MacroModel) -> tuple[list[str], set[str], float]:
    """Testbench springs on every coordinate through its force port (z at SPRING_HZ, the tilts twice
    as stiff), and k_z in N/m."""
    lines, held = [], set()
    for c in model.coordinates:
        k = c.mass * (2 * math.pi * SPRING_HZ) ** 2 * (1.0 if c.name == "z" else 2.0)
        _, xf, _, ff = c.port_units
        lines.append(f"Bsp_{c.name} f_{c.name} 0 V={float(-k * xf / ff)!r}*v(x_{c.name})")
        held.add(f"f_{c.name}")
    return lines, held, model.coordinates[0].mass * (2 * math.pi * SPRING_HZ) ** 2


DISK_FORMS = [("39", "spring_disk.lib"), ("46", "spring_disk.lib"), ("39", "spring_disk_xspice.lib")]


@pytest.mark.parametrize("release,form", DISK_FORMS, ids=[f"{r}-{f}" for r, f in DISK_FORMS])
@pytest.mark.parametrize("fraction", [0.5, 0.9])
def test_disk_on_springs_op_is_the_stable_root(disk, release, form, fraction, monkeypatch, tmp_path):
    """The free disk held by port springs, biased at 50 and 90 % of its V_PI: z equals brentq's
    stable root within 0.5 % (the fit's own error, 8.6e-4 in C, is most of what is left) and the
    tilts stay at rest (symmetry)."""
    monkeypatch.setenv(ENV, NGSPICE[release])
    model, folder = disk
    lines, held, k = springs(model)
    area = math.pi * DISK_RADIUS**2
    volts = fraction * pull_in(k, DISK_GAP, area)
    xs = operating_point(
        model, folder / form, tmp_path, {"bot_r1s1": repr(volts), "plate": "0"}, extra=lines, driven_elsewhere=held
    )
    assert -xs[0] * model.coordinates[0].scale == pytest.approx(stable_root(k, DISK_GAP, area, volts), rel=5e-3)
    assert np.abs(xs[1:]).max() < 1e-3


@pytest.mark.parametrize(
    "release,form", [("39", "levitated_disk.lib"), ("46", "levitated_disk.lib"), ("39", "levitated_disk_xspice.lib")]
)
def test_reference_disk_on_springs_stays_at_rest(release, form, monkeypatch, tmp_path):
    """The committed reference model, 15 V on all 16 electrodes, rigid coordinates on 20 kHz port
    springs (the modes on their own): by symmetry the stable state is the plate at rest; a plain
    .op finds it (every |xs| < 1e-3, the fit's asymmetry) instead of a tilted contact state."""
    monkeypatch.setenv(ENV, NGSPICE[release])
    model = MacroModel.load_json(NETLISTS / "levitated_disk.json")
    lines, held = [], set()
    for c in model.coordinates[:3]:
        _, xf, _, ff = c.port_units
        lines.append(
            f"Bsp_{c.name} f_{c.name} 0 V={float(-c.mass * (2 * math.pi * SPRING_HZ) ** 2 * xf / ff)!r}*v(x_{c.name})"
        )
        held.add(f"f_{c.name}")
    sources = {e.name: "15" for e in model.electrodes} | {"plate": "0"}
    xs = operating_point(model, NETLISTS / form, tmp_path, sources, extra=lines, driven_elsewhere=held)
    assert np.abs(xs).max() < 1e-3
