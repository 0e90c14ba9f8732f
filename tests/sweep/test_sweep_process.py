"""`netgen sweep` over process parameters (process.tscale, process.escale; the others in
tests/sweep/test_sweep_process_points.py) of a structure with a
[process] table: by instance parameters on one shared build ([sweep] process = "parameters", the
default) against the reference that rebuilds the structure at each point (process = "rebuild"),
in real ngspice sigma-delta runs (128 periods, skip 0: the shortest runs the analysis accepts) of
examples/accelerometer_z.toml with its given spring replaced by crab legs (so that both the
thickness and the modulus move the stiffness); and bad process sweeps refused before anything runs.

Tolerances: the two paths run the same circuit up to the laws' error (stated in the model: the
crab legs' cubic in tscale, 4.5e-10; the rigid mass ~ t and the modulus law, linear in E, exact)
and ngspice's integration error. Each run's trajectory is within ngspice's tolerance of the exact
one: reltol 1e-3 (the sweep's default) of the value plus vntol 1e-6 on the scaled state xs_z
(1 = the touching amplitude L), i.e. vntol L / (1 um) volts at the x_z port. So the displacement at
every clock sample agrees within 2 (reltol max |x| + vntol L / 1 um) plus the law's error
relative; the bits agree wherever no comparator decision falls within that error of its threshold
(the bit means within 2/128: one flipped decision and the loop's compensating one), and the
gravity balance ratio (a momentum balance over the same samples, its damping and inertia terms
read from x) within 2 reltol.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from netgen.build import build_model
from netgen.cli import commands as cli
from netgen.structure import parse_structure
from tests.fixtures import ROOT
from tests.oracles.crab_legs import crab_legs

RELTOL = 1e-3  # the sweep's default reltol (netgen.testbench.sigma_delta.options)
PROCESS = '\n[process]\nparameters = ["tscale", "escale"]\n'
SWEEP = """
[sweep]
x = "process.tscale"
mode = "zip"
{head}
[fixed]
cycles = 128
skip = 0
{fixed}
[[parameters]]
name = "process.tscale"
values = [{tscale}]
[[parameters]]
name = "process.escale"
values = [0.8]
"""


CONDUCTOR = crab_legs(500.0, 20.0, 800.0)
VNTOL = 1e-6  # ngspice's default absolute voltage tolerance, on the scaled state node xs_z


def structure(tmp: Path, process: str = PROCESS) -> Path:
    """examples/accelerometer_z.toml on crab legs (2.5 N/m, 2.3 kHz: the loop holds it as the
    0.3 N/m spring), with `process` appended."""
    text = (ROOT / "examples/accelerometer_z.toml").read_text()
    a, b = text.index("[conductor]"), text.index("[[electrodes]]")
    path = tmp / "acc.toml"
    path.write_text(text[:a] + CONDUCTOR + text[b:] + process)
    return path


def sweep(tmp: Path, name: str, head: str = "", fixed: str = "", tscale: float = 1.05) -> Path:
    path = tmp / f"{name}.toml"
    path.write_text(SWEEP.format(head=head, fixed=fixed, tscale=tscale))
    return path


def rows(out: Path) -> list[dict]:
    with open(out / "results.csv", newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    """The same one-run sweep (tscale 1.05, escale 0.8) by instance parameters and by rebuild."""
    tmp = tmp_path_factory.mktemp("sweep_process")
    acc = structure(tmp)
    out = {}
    for path in ("parameters", "rebuild"):
        s = sweep(tmp, path, head=f'process = "{path}"')
        rc = cli.main(["sweep", str(acc), str(s), "-o", str(tmp / path), "--scheduler", "local:1", "-q"])
        assert rc == 0
        out[path] = tmp / path
    return acc, out


def test_instance_parameters_on_one_build(both):
    """The parameters path writes the point on the model's instance line and builds no run model;
    the rebuild path writes each run's structure (its thickness and modulus scaled, no [process])."""
    _, out = both
    run_p, run_r = out["parameters"] / "runs" / "run_0", out["rebuild"] / "runs" / "run_0"
    x1 = [line for line in (run_p / "sigma_delta.cir").read_text().splitlines() if line.startswith("X1 ")]
    assert x1 and x1[0].endswith("accelerometer_z escale=0.8 tscale=1.05"), x1
    assert not (run_p / "structure.toml").exists()
    rebuilt = parse_structure((run_r / "structure.toml").read_text(), "run.toml")
    nominal = parse_structure((out["parameters"].parent / "acc.toml").read_text(), "acc.toml")
    assert rebuilt.process is None
    assert rebuilt.conductor.thickness == pytest.approx(1.05 * nominal.conductor.thickness, rel=1e-15, abs=0)
    assert rebuilt.conductor.youngs_modulus == pytest.approx(0.8 * nominal.conductor.youngs_modulus, rel=1e-15)


def test_parameters_agree_with_rebuild(both):
    """The two paths' runs: the displacement at every clock sample within twice ngspice's tolerance
    (plus the stiffness law's stated error), the bit means within 2/128, the gravity balance ratios
    within 2 reltol (module docstring)."""
    acc, out = both
    p, r = rows(out["parameters"])[0], rows(out["rebuild"])[0]
    assert p["status"] == r["status"] == "ok"
    clock_p = np.load(out["parameters"] / "runs" / "run_0" / "bitstreams.npz")
    clock_r = np.load(out["rebuild"] / "runs" / "run_0" / "bitstreams.npz")
    model = build_model(parse_structure(acc.read_text(), str(acc)))
    law_error = model.process["tscale"]["max_rel_error"]
    c = model.coordinates[0]
    x_p, x_r = clock_p["x_z"], clock_r["x_z"]
    scale = np.max(np.abs(x_r))
    bound = 2 * (RELTOL * scale + VNTOL * c.scale / c.port_units[1]) + law_error * scale
    print(
        f"x_z {np.max(np.abs(x_p - x_r)):.2e} V (bound {bound:.2e} V, largest {scale:.2e} V); bits differ at "
        f"{int(np.sum(clock_p['bits_z'] != clock_r['bits_z']))} of 128; balance "
        f"{float(p['gravity_balance.ratio']) / float(r['gravity_balance.ratio']) - 1:.1e}; law error {law_error:.1e}"
    )
    assert np.max(np.abs(x_p - x_r)) <= bound
    assert abs(float(p["z.bit_mean"]) - float(r["z.bit_mean"])) <= 2 / 128
    assert float(p["gravity_balance.ratio"]) == pytest.approx(float(r["gravity_balance.ratio"]), rel=2 * RELTOL)


@pytest.mark.parametrize(
    "process,head,fixed,tscale,key,words",
    [
        (PROCESS, "", "", 1.5, "parameters[0].values", "outside the structure's tscale_range"),
        ("", "", "", 1.05, "parameters[0].values", "does not declare tscale"),
        (PROCESS, 'process = "maybe"', "", 1.05, "sweep.process", "is not 'parameters' or 'rebuild'"),
    ],
)
def test_bad_process_sweeps_exit_2(tmp_path, capsys, process, head, fixed, tscale, key, words):
    """A value outside the declared range, a structure without the parameter, an unknown path: exit 2
    before anything runs, naming the sweep file, the key and a fix."""
    acc = structure(tmp_path, process)
    s = sweep(tmp_path, "bad", head=head, fixed=fixed, tscale=tscale)
    rc = cli.main(["sweep", str(acc), str(s), "-o", str(tmp_path / "out"), "--dry-run"])
    err = capsys.readouterr().err
    assert rc == 2, err
    assert str(s) in err and key in err and words in err and "fix:" in err, err
    assert not (tmp_path / "out").exists()


def test_unknown_process_name_exits_2(tmp_path, capsys):
    """A process name the laws do not carry: exit 2 naming the key and the parameters a sweep moves."""
    acc = structure(tmp_path)
    s = tmp_path / "t.toml"
    s.write_text('[fixed]\ncycles = 128\n[[parameters]]\nname = "process.pressure"\nvalues = [1, 2]\n')
    rc = cli.main(["sweep", str(acc), str(s), "-o", str(tmp_path / "out"), "--dry-run"])
    err = capsys.readouterr().err
    assert rc == 2 and "parameters[0].name" in err and "process.dg_<set>" in err and "fix:" in err, err
