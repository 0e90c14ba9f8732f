"""netgen.sim.pyspice: a built macromodel in a PySpice Circuit, run through libngspice, on both
ngspice releases of the suite (39 on PATH, 46 in its private prefix).

- the documented example's transient (examples/pyspice_transient.py) equals the batch run
  (`ngspice -b`, netgen.sim.ngspice.run_ngspice) of a bench written independently
  (tests.fixtures.Bench) within 1e-6 of peak, coordinate by coordinate, in SI units;
- physics against closed forms: the piston's static deflection under a DC bias is the
  parallel-plate force balance k z = eps0 A V^2 / (2 (g - z)^2), its force response is
  1 / (k - m w^2) with m from its geometry, and its electrode admittance at zero bias is
  j w eps0 A / g;
- failures: a missing libngspice is exit 3 with the install command, one library per process,
  the word "error" in a title or node is no failure, a blown-up run names node and time,
  drive and node names are data that cannot become netlist lines.

PySpice keeps one libngspice per process, so every PySpice run is in a fresh subprocess and
this test process never loads one.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from netgen.build import build
from netgen.core.errors import InputError
from netgen.emit import ngspice as emit_ngspice
from netgen.model import MacroModel
from netgen.sim import pyspice
from netgen.sim.ngspice import run_ngspice
from netgen.structure import load_structure
from tests.fixtures import NGSPICE, ROOT, Bench, states

LIB = ROOT / "netlists" / "levitated_disk.lib"
EXAMPLE = ROOT / "examples" / "pyspice_transient.py"
EPS0 = 8.8541878188e-12  # vacuum permittivity, F/m (CODATA 2022, NIST)
VERSIONS = sorted(NGSPICE)


def env_for(version: str, **extra: str) -> dict[str, str]:
    """This process's environment with NETGEN_NGSPICE selecting one release (and no library override)."""
    env = {k: v for k, v in os.environ.items() if k not in (pyspice.ENV, "SPICE_LIB_DIR", "SPICE_SCRIPTS")}
    return env | {"NETGEN_NGSPICE": NGSPICE[version]} | extra


def python(code_or_file: str | Path, *args: str, env: dict[str, str], cwd: Path = ROOT) -> subprocess.CompletedProcess:
    """A fresh Python process (its own libngspice), a script file or inline code."""
    argv = (
        [sys.executable, str(code_or_file)] if isinstance(code_or_file, Path) else [sys.executable, "-c", code_or_file]
    )
    return subprocess.run(argv + list(args), cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def disk() -> MacroModel:
    return MacroModel.load_json(LIB.with_suffix(".json"))


# ----------------------------------------------------------------------------- the example against batch mode


@pytest.mark.parametrize("version", VERSIONS)
def test_example_transient_equals_the_batch_run(version, disk, tmp_path, monkeypatch):
    """The example in PySpice and the same bench (hand-written, tests.fixtures.Bench) in `ngspice -b`
    of the same release: every coordinate within 1e-6 of its peak, the electrode current too."""
    saved = tmp_path / "run.npz"
    proc = python(EXAMPLE, "--save", str(saved), env=env_for(version))
    assert proc.returncode == 0, proc.stderr
    assert f"ngspice-{version} through PySpice" in proc.stdout
    assert "Unsupported" not in proc.stdout + proc.stderr and "Traceback" not in proc.stderr
    got = np.load(saved)

    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE[version])
    gravity = repr(-disk.coordinates[0].mass * 9.81 / 1e-6)  # uN, 1 V = 1 uN
    sources = {
        "top_r2s1": "PULSE(0 3 0 10n 10n 0.49u 1u)",
        "top_r1s2": "PULSE(0 2 0.25u 10n 10n 0.3u 1u)",
        "bot_r1s3": "PULSE(0 2 5u 10n 10n 1 2)",
        "f_z": gravity,
        "plate": "0",
    }
    bench = Bench(disk, LIB, sources=sources, options="reltol=1e-5 chgtol=1e-18")
    plot = run_ngspice(bench.netlist(".tran 10n 20u 0 10n uic"), tmp_path / "batch")[0]
    x, xdot = states(plot, disk)
    time = plot["time"]
    for v, c in enumerate(disk.coordinates):
        q_batch = np.interp(got["time"], time, x[:, v] * c.scale)
        peak = np.abs(q_batch).max()
        assert peak > 0, c.name
        assert np.abs(got[f"q_{c.name}"] - q_batch).max() <= 1e-6 * peak, c.name
        u_batch = np.interp(got["time"], time, xdot[:, v] * c.scale)
        assert np.abs(got[f"v_{c.name}"] - u_batch).max() <= 1e-6 * np.abs(u_batch).max(), c.name
    i_batch = np.interp(got["time"], time, -plot["i(vtop_r2s1)"])
    assert np.abs(got["i_top_r2s1"] - i_batch).max() <= 1e-6 * np.abs(i_batch).max()
    assert len(got["time"]) == len(time)  # the same steps, not only close


# ----------------------------------------------------------------------------- physics: the piston

PISTON_RUN = """
import json, sys
from netgen.model import MacroModel
from netgen.sim.pyspice import ModelCircuit
lib, volts = sys.argv[1], float(sys.argv[2])
model = MacroModel.load_json(lib.replace(".lib", ".json"))              # emitted afresh into a temporary folder
op = ModelCircuit.build(lib, drive={"drive": volts}).operating_point()
force = ModelCircuit.build(lib, drive={"f_z": "DC 0 AC 1"}).ac(1e3, 1e5, 5)
admittance = ModelCircuit.build(model, drive={"drive": "DC 0 AC 1"}).ac(1e3, 1e5, 5)
print(json.dumps({"z": float(op.q["z"][0]), "i_dc": float(op.current["drive"][0]),
                  "f": force.axis.tolist(), "x_re": force.q["z"].real.tolist(), "x_im": force.q["z"].imag.tolist(),
                  "i_re": admittance.current["drive"].real.tolist(),
                  "i_im": admittance.current["drive"].imag.tolist(), "release": op.release}))
"""


@pytest.fixture(scope="module")
def piston(tmp_path_factory):
    """The piston example built, its .lib and .json side by side (as `netgen build` writes them)."""
    folder = tmp_path_factory.mktemp("piston")
    b = build(load_structure(ROOT / "examples" / "piston.toml"))
    (folder / "piston.lib").write_text(emit_ngspice.subcircuit(b.model))
    b.model.save_json(folder / "piston.json")
    return b, folder / "piston.lib"


@pytest.mark.parametrize("version", VERSIONS)
def test_piston_statics_and_ac_against_parallel_plate(version, piston):
    """Pure parallel plate on a 2 N/m spring, 3 V (82 % of V_PI): the .op deflection solves
    k z = eps0 A V^2 / (2 (g - z)^2) within the error Newton's convergence test allows plus
    gmin's: ngspice stops when the last update of xs_z = z / L is <= reltol |xs_z| + vntol
    (1e-3, 1e-6), and the next error of Newton on f(z) = k z - F(z) is |f'' / (2 f')| times
    that update squared: 1.0e-7 of z here; gmin (1e-12 S on every node) shifts it linearly,
    1.0e-11 (1.5e-14 at gmin 1e-15), taken at 10x. The capacitance fit is exact to rounding
    (max_rel_error 5.6e-16). Measured 1.0e-11 in both releases, the same at reltol 1e-2..1e-5
    (Newton converges quadratically past the test); the 1.8e-7 measured before was brentq's
    default absolute xtol 2e-12 m, now 1e-22. 1 uN on z moves it
    1e-6 / (k - m w^2) m with m = rho L W t, and at 0 V bias 1 V AC on the electrode draws
    j w eps0 A / g (measured 1e-13, 6e-16: linear elements)."""
    b, lib = piston
    c, gap = b.structure.conductor, b.structure.electrode_sets[0].gap
    area, volts = c.length * c.width, 3.0
    proc = python(PISTON_RUN, str(lib), repr(volts), env=env_for(version))
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout.splitlines()[-1])
    assert got["release"] == f"ngspice-{version}"

    travel = brentq(
        lambda z: c.stiffness * z - EPS0 * area * volts**2 / (2 * (gap - z) ** 2), 0, gap / 3, xtol=1e-22, rtol=1e-15
    )
    force = EPS0 * area * volts**2 / (2 * (gap - travel) ** 2)
    f1, f2 = c.stiffness - 2 * force / (gap - travel), -6 * force / (gap - travel) ** 2  # f', f'' of k z - F(z)
    newton = abs(f2 / (2 * f1)) * (1e-3 * travel + 1e-6 * b.model.coordinates[0].scale) ** 2 / travel
    assert -got["z"] == pytest.approx(travel, rel=newton + 1e-10, abs=0)
    assert travel > 0.1 * gap  # a real deflection, not a linear one
    assert abs(got["i_dc"]) < 1e-15  # no DC through a capacitor

    w = 2 * np.pi * np.array(got["f"])
    mass = c.length * c.width * c.thickness * c.density
    x = np.array(got["x_re"]) + 1j * np.array(got["x_im"])
    assert x == pytest.approx(1e-6 / (c.stiffness - mass * w**2), rel=1e-8, abs=0)
    assert math.sqrt(c.stiffness / mass) / (2 * np.pi) < got["f"][-1]  # the sweep crosses resonance
    i = np.array(got["i_re"]) + 1j * np.array(got["i_im"])
    assert i == pytest.approx(1j * w * EPS0 * area / gap, rel=1e-8, abs=0)


# ----------------------------------------------------------------------------- failures and their messages


def cli(args: list[str], env: dict[str, str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "netgen.cli.commands", *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_missing_library_is_exit_3_with_the_install_command(tmp_path):
    """An ngspice whose prefix has no libngspice, and a NETGEN_LIBNGSPICE that is not there."""
    fake = tmp_path / "prefix" / "bin" / "ngspice"
    fake.parent.mkdir(parents=True)
    fake.write_text("#!/bin/sh\necho ngspice-46\n")
    fake.chmod(0o755)
    cir = tmp_path / "r.cir"
    cir.write_text("* divider\nV1 a 0 1\nR1 a 0 1k\n.op\n.end\n")
    proc = cli(
        ["simulate", str(cir), "-o", str(tmp_path / "run"), "--simulator", "pyspice"],
        env_for("39", NETGEN_NGSPICE=str(fake)),
        tmp_path,
    )
    assert proc.returncode == 3, proc.stderr
    assert "libngspice" in proc.stderr and "apt-get install -y libngspice0" in proc.stderr
    assert str(tmp_path / "prefix" / "lib") in proc.stderr and "Traceback" not in proc.stderr
    code = (
        "from netgen.sim import pyspice\ntry:\n    pyspice.shared()\nexcept pyspice.SimulatorNotFound as e:\n"
        "    print(e.exit_code, e)"
    )
    proc = python(code, env=env_for("39", NETGEN_LIBNGSPICE=str(tmp_path / "nosuch.so")))
    assert proc.stdout.startswith(f"3 NETGEN_LIBNGSPICE={str(tmp_path / 'nosuch.so')!r} is not a file"), proc.stderr


BLOW_UP = "* finite-time blow-up\nC1 n 0 1\nB1 0 n I=v(n)*v(n)\n.ic v(n)=1\n.tran 1m 2 uic\n.end\n"
ERROR_WORD = (
    "error budget: the word error in the title and a node name\n"
    "V1 in 0 1\nR1 in error_node 1k\nR2 error_node 0 3k\n.op\n.end\n"
)


RUNS = """
import json, sys
from netgen.core.errors import SimulationError
from netgen.sim import SIMULATORS
for name in sys.argv[2:]:
    try:
        plot = SIMULATORS["pyspice"].run(open(name + ".cir").read(), sys.argv[1], name, 0.5)[-1]
        print(name, "ok", plot.name, json.dumps({k: float(v[-1].real) for k, v in plot.vectors.items()}))
    except SimulationError as e:
        print(name, "failed", e)
"""
SLOW = "* the disk, 200 us (several seconds)\n.include {lib}\nX1 {ports} levitated_disk\n{sources}\n.tran 10n 200u 0 10n uic\n.end\n"


@pytest.mark.parametrize("version", VERSIONS)
def test_runner_reports_failures_and_keeps_its_files(version, disk, tmp_path):
    """The `--simulator pyspice` runner: the word "error" in a title and a node is no failure (the
    divider's 0.75 V); a .control block runs; a blow-up names node and time (the analytic blow-up
    is at t = 1 s) with the saved netlist and log; an unknown subcircuit is named; a run past its
    wall-clock limit is halted and the next run works; nothing of PySpice's log is printed."""
    ports = [p["name"] for p in disk.ports()]
    sources = "\n".join(f"V{p} {p} 0 0" for p in ports if not p.startswith("x_"))
    cases = {
        "w": ERROR_WORD,
        "ctl": "* control\nV1 a 0 2\nR1 a 0 1k\n.control\nop\n.endc\n.end\n",
        "blow": BLOW_UP,
        "bad": "* bad\nV1 a 0 1\nX1 a 0 nosuch\n.op\n.end\n",
        "slow": SLOW.format(lib=LIB, ports=" ".join(ports), sources=sources),
    }
    for name, text in cases.items():
        (tmp_path / f"{name}.cir").write_text(text)
    proc = python(RUNS, "run", "w", "ctl", "blow", "bad", "slow", "w", env=env_for(version), cwd=tmp_path)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    word, ctl, blow, bad, slow, again = proc.stdout.splitlines()
    assert word.startswith("w ok op1 ") and json.loads(word.split(" ", 3)[3]) == pytest.approx(
        {"v(in)": 1.0, "v(error_node)": 0.75, "i(v1)": -1 / 4000}, rel=1e-12, abs=0
    )
    assert ctl.startswith("ctl ok op1 ") and json.loads(ctl.split(" ", 3)[3]) == pytest.approx(
        {"v(a)": 2.0, "i(v1)": -2 / 1000}, rel=1e-12, abs=0
    )
    assert "timestep too small" in blow and "node n" in blow
    assert 0.99 < float(blow.split("at t = ")[1].split()[0]) < 1.0
    assert "reproduce with: ngspice -b run/blow.cir" in blow and "log run/blow.log" in blow
    assert "Timestep too small" in (tmp_path / "run" / "blow.log").read_text()
    assert (tmp_path / "run" / "blow.cir").read_text() == BLOW_UP
    assert (
        "failed" in bad and "unknown subckt" in bad and "unknown subckt" in (tmp_path / "run" / "bad.log").read_text()
    )
    assert "failed" in slow and "did not finish within 0 s" in slow
    assert again == word


def test_simulate_cli_exit_code_of_a_failed_run(tmp_path):
    """`netgen simulate --simulator pyspice` of the blow-up: exit 1, the one-line message."""
    (tmp_path / "blow.cir").write_text(BLOW_UP)
    proc = cli(["simulate", "blow.cir", "-o", "run", "--simulator", "pyspice"], env_for("39"), tmp_path)
    assert proc.returncode == 1 and proc.stderr.startswith("netgen: ngspice (libngspice via PySpice) failed: ")
    assert proc.stderr.count("\n") == 1 and "timestep too small" in proc.stderr


def test_one_library_per_process(tmp_path):
    """After 39 is loaded, asking for 46 in the same process is a clear refusal, not a crash."""
    code = (
        "import os; from netgen.sim import pyspice; from netgen.core.errors import SimulatorNotFound\n"
        f"print(pyspice.release()); os.environ['NETGEN_NGSPICE'] = {NGSPICE['46']!r}\n"
        "try:\n    pyspice.shared()\nexcept SimulatorNotFound as e:\n    print(e)\n"
    )
    proc = python(code, env=env_for("39"))
    assert proc.returncode == 0, proc.stderr
    first, message = proc.stdout.splitlines()[:2]
    assert first == "ngspice-39" and "one libngspice per process" in message and "ngspice-46" in message


def test_library_beside_each_ngspice():
    """The libngspice, code models and spinit found from each release's binary, and from a library
    named by NETGEN_LIBNGSPICE (46's, with 39 selected as the binary): no loading, no release check."""
    prefix46 = str(Path(NGSPICE["46"]).parent.parent / "usr/lib/x86_64-linux-gnu")
    code = "from netgen.sim import pyspice; l = pyspice.library(); print(l.path, l.lib_dir, l.scripts, l.binary)"
    for env, folder in (
        (env_for("39"), "/usr/lib/x86_64-linux-gnu"),
        (env_for("46"), prefix46),
        (env_for("39", NETGEN_LIBNGSPICE=f"{prefix46}/libngspice.so.0"), prefix46),
    ):
        path, lib_dir, scripts, binary = python(code, env=env).stdout.split()
        assert path == f"{folder}/libngspice.so.0" and lib_dir == f"{folder}/ngspice"
        assert Path(scripts, "spinit").is_file() and scripts == str(
            Path(folder).parent.parent / "share/ngspice/scripts"
        )
        assert (binary == "None") == (pyspice.ENV in env)


def test_drive_and_node_names_are_data(disk):
    """A source text that would add a netlist line, an unknown port, a node name PySpice would take
    for a failure: InputErrors naming the entry and the fix, before anything runs."""
    with pytest.raises(InputError, match=r"drive\['top_r1s1'\].*bad part: '\.include'"):
        pyspice.ModelCircuit.build(LIB, drive={"top_r1s1": "0\n.include /etc/passwd"})
    with pytest.raises(InputError, match="fix: give a number"):
        pyspice.ModelCircuit.build(LIB, drive={"top_r1s1": "0\n1"})
    with pytest.raises(InputError, match=r"(?s)not an input port.*fix: use one of"):
        pyspice.ModelCircuit.build(LIB, drive={"x_z": 1.0})
    with pytest.raises(InputError, match=r"(?s)nodes\[.x_z.\].*.error."):
        pyspice.ModelCircuit.build(LIB, nodes={"x_z": "z_error"})
    with pytest.raises(InputError, match=r"(?s)_xspice.lib form.*fix: give the B-source levitated_disk.lib"):
        pyspice.ModelCircuit.build(ROOT / "netlists" / "levitated_disk_xspice.lib")
    bench = pyspice.ModelCircuit.build(LIB, drive={"f_z": -1.6e-7, "top_r2s1": "SIN(0 1 50k)"}, nodes={"plate": "0"})
    deck = str(bench.simulation())
    assert "Vf_z f_z 0 -0.16" in deck and "Vtop_r2s1 top_r2s1 0 SIN(0 1 50k)" in deck  # N -> uN port volts
    assert "Vplate" not in deck and " plate " not in deck.split("\n")[2]
