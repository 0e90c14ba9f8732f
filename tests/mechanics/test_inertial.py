"""The inertial-load port a_in (coordinates.acceleration_port): frame acceleration along +z.

Each coordinate feels -G_v a_in with the participation G_v = rho h int phi_v dA. Checks
against closed forms, in ngspice (and the Verilog-A module in VACASK):
- piston on a spring: static deflection -m a / k;
- cantilever under its own uniform inertial load: tip deflection -rho b t a L^4 / (8 E I)
  (Euler-Bernoulli), from three modes within 1 %;
- free disk: the plate falls freely relative to the frame, z(t) = -a t^2 / 2, while the tilts
  and eigenmodes stay at rest (their G is zero by symmetry).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from netgen.build import build_model
from netgen.emit.ngspice import subcircuit
from netgen.emit.veriloga import module
from netgen.sim.ngspice import run_ngspice
from netgen.sim.vacask import VacaskBench, compile_va, run_vacask
from netgen.structure import StructureError, load_structure, parse_structure
from tests.fixtures import ROOT, Bench

ACCEL = 100.0  # m/s^2 (about 10 g)


def with_port(name: str) -> str:
    """An example structure file's text with acceleration_port = true in [coordinates]."""
    text = (ROOT / "examples" / name).read_text()
    return text.replace("[coordinates]\n", "[coordinates]\nacceleration_port = true\n", 1)


def op_positions(model, tmp_path: Path, accel: float) -> dict[str, float]:
    """ngspice .op of the model with every electrode and the plate grounded and a_in = accel:
    the coordinates in SI units."""
    lib = tmp_path / f"{model.name}.lib"
    lib.write_text(subcircuit(model))
    bench = Bench(model, lib, sources={"plate": "0", "a_in": repr(accel)})
    plot = run_ngspice(bench.netlist(".op"), tmp_path)[0]
    return {c.name: float(np.ravel(plot[f"v(x1.xs_{c.name})"])[0]) * c.scale for c in model.coordinates}


def test_piston_static_deflection_is_m_a_over_k(tmp_path):
    model = build_model(parse_structure(with_port("piston.toml"), "piston.toml"))
    s = load_structure(ROOT / "examples" / "piston.toml")
    mass, k = s.conductor.mass, s.conductor.stiffness
    assert model.acceleration == pytest.approx([mass], rel=1e-9, abs=0)
    z = op_positions(model, tmp_path, ACCEL)["z"]
    assert z == pytest.approx(-mass * ACCEL / k, rel=1e-6, abs=0)


def test_cantilever_tip_deflection_under_uniform_inertial_load(tmp_path):
    s = load_structure(ROOT / "examples" / "cantilever.toml")
    c = s.conductor
    model = build_model(parse_structure(with_port("cantilever.toml"), "cantilever.toml"))
    q = op_positions(model, tmp_path, ACCEL)
    tip = sum(q.values())  # modes normalised to a tip (peak) deflection of 1
    inertia = c.width * c.thickness**3 / 12
    expected = -c.density * c.width * c.thickness * ACCEL * c.length**4 / (8 * c.youngs_modulus * inertia)
    assert tip == pytest.approx(expected, rel=0.01, abs=0)


def test_piston_in_vacask_matches_the_closed_form(tmp_path):
    """The Verilog-A module (openvaf-r, warnings denied) in a VACASK transient with the spring
    critically damped (Rayleigh alpha = 2 w0) and settled: the same static deflection -m a / k."""
    text = with_port("piston.toml") + "\n[damping]\nrayleigh = {alpha = 2e5}\n"
    model = build_model(parse_structure(text, "piston.toml"))
    va = tmp_path / "piston.va"
    va.write_text(module(model))
    osdi, _ = compile_va(va)
    bench = VacaskBench(model, osdi, sources={"plate": "dc=0", "a_in": f"dc={ACCEL!r}"})
    plot = run_vacask(bench.netlist('analysis tran1 tran step=1u stop=400u maxstep=1u icmode="uic"'), tmp_path)
    z = plot["x1:xs_z"][-1] * model.coordinates[0].scale
    mass, k = model.coordinates[0].mass, model.coordinates[0].stiffness
    assert z == pytest.approx(-mass * ACCEL / k, rel=1e-3, abs=0)


def test_free_disk_falls_freely_and_modes_stay_at_rest(tmp_path):
    text = (ROOT / "examples" / "levitated_disk.toml").read_text()
    text = text.replace("[coordinates]\n", "[coordinates]\nacceleration_port = true\n", 1)
    model = build_model(parse_structure(text, "levitated_disk.toml"))
    z = model.coordinates[0]
    assert model.acceleration[0] == pytest.approx(z.mass, rel=1e-6, abs=0)
    assert all(g == 0.0 for g in model.acceleration[1:])
    lib = tmp_path / "disk.lib"
    lib.write_text(subcircuit(model))
    bench = Bench(model, lib, sources={"plate": "0", "a_in": repr(ACCEL)})
    stop = 20e-6
    plot = run_ngspice(bench.netlist(f".tran 0.1u {stop} 0 0.1u uic"), tmp_path)[0]
    t = plot["time"]
    assert plot["v(x1.xs_z)"] * z.scale == pytest.approx(-0.5 * ACCEL * t**2, abs=1e-4 * 0.5 * ACCEL * stop**2)
    for c in model.coordinates[1:]:
        assert np.abs(plot[f"v(x1.xs_{c.name})"]).max() < 1e-9


def test_acceleration_port_must_be_a_flag():
    text = with_port("piston.toml").replace("acceleration_port = true", "acceleration_port = 1")
    with pytest.raises(StructureError, match="acceleration_port must be true or false"):
        parse_structure(text, "piston.toml")


def test_reference_model_has_no_acceleration_port():
    """Off by default: the committed reference netlists keep their port list."""
    from netgen.model import MacroModel

    model = MacroModel.load_json(ROOT / "netlists" / "levitated_disk.json")
    assert not model.acceleration and "a_in" not in [p["name"] for p in model.ports()]
