"""`netgen sweep` over each process parameter the laws carry besides tscale and escale (process.temp,
process.etch, process.dg_<set>), by instance parameters on one [process] build ([sweep] process =
"parameters") against the reference that rebuilds the structure at the point (process = "rebuild"),
on every back end: real 128-period sigma-delta runs (skip 0) of examples/accelerometer_z.toml on crab
legs (tests/sweep/test_sweep_process.py); and bad process entries refused before anything runs.

Tolerances (as in test_sweep_process.py): the two paths run the same circuit up to the laws' stated
error and the simulator's tolerance. Each trajectory is within reltol (1e-3, the sweep's default) of
the value plus vntol (1e-6) on the scaled state xs_z (vntol L / 1 um volts at the x_z port) of the
exact one, so the displacement at every clock sample agrees within 2 (reltol max |x| + vntol L / 1 um)
plus the law's error times max |x|, up to the first comparator decision that falls within that
error of its threshold (after a flipped bit the loops run on different feedback); the gravity balance
ratio within 2 reltol plus the law's error. The bit means are not compared bit for bit: after a flip
near a threshold (another CPU's rounding can flip the first decision) they part by the two runs'
different inertial terms, and what both must still meet is the momentum balance, asserted on the ratio. The laws' errors,
as the model states them: temp moves only the modulus here (no squeeze film), e = 1 + tc (T - T0),
exact; etch: the crab legs' and the etched mass's cubic ratios in etch (process.etch.max_rel_error)
plus the a_in load's (process.etch.acceleration.max_rel_error: the load follows the etched mass,
netgen.model.process_loads), and the capacitance law's stated error eps_C
(process.etch.capacitance_max_rel_error); dg_<set>: a shift of z,
exact, and the plates without fringe (fringe = "none") give 1/C linear in z, so the shifted fit and
the rebuilt one are each the parallel-plate law within their stated fit error (fit max_rel_error,
both models' added). VACASK's own tolerances are its reltol 1e-3 and vntol 1e-6 (the bench's options),
so the same bound holds there.

The etch's capacitance error: on the same bits the two circuits' electrostatic forces differ by at
most eps_C of the largest force of the design's table F_pk, so up to the first flip x_z parts by at
most eps_C F_pk (n T_s)^2 / (2 m) more (the force error integrated twice over the n periods), and the
balance's mean force by eps_C. After a flipped decision the two loops end the window at different
points of their limit cycles, and the balance's inertial term m (v_b - v_a) / ((b - a) T_s) (v_a the
same: both start at rest) can differ by up to m (max |v| + max |v'|) / ((b - a) T_s) (each run's
central differences of x_z), relative to the balance's denominator: that, not eps_C F_fs / weight,
is what parts the two ratios at the etch point (1.3e-2 with the inertial terms -5.96e-9 / -4.61e-9 N
against 1.08e-7 N; the mean forces within 1.1e-4, eps_C). The weight each design loads the loop with
(the parameters path's a_in law G tscale R(etch) against the rebuilt body's participation: G ~ t
exactly) agrees within the etch ratio's stated residual plus round-off (1e-12); it sizes the loop's
feedback, so an a_in load that does not follow the etched mass (4e-4 at 50 nm on this plate) moved the
whole trajectory: at all five parameters at once x_z was 4.3e-5 V (_xspice.lib) and 8.8e-5 V (OSDI)
off, against 9.3e-6..9.8e-6 V with the load following the mass.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from netgen.cli import commands as cli
from netgen.model import MacroModel
from tests.fixtures import NGSPICE, ROOT
from tests.sweep.test_sweep_process import RELTOL, VNTOL, structure

CASES = {  # parameter -> ([process] parameters, its swept value)
    "temp": ('["temp"]', "125"),
    "etch": ('["etch"]', "5e-8"),
    "dg_top": ('["dg"]', "3e-8"),
}
SWEEP = """
[sweep]
process = "{path}"
[fixed]
cycles = 128
skip = 0
{fixed}
[[parameters]]
name = "process.{name}"
values = [{value}]
"""


def rows(out: Path) -> list[dict]:
    with open(out / "results.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def both_paths(tmp: Path, name: str, declared: str, value: str, fixed: str = "") -> dict[str, Path]:
    """The one-run sweep at process.<name> = value by instance parameters and by rebuild."""
    acc = structure(tmp, f"\n[process]\nparameters = {declared}\n")
    out = {}
    for path in ("parameters", "rebuild"):
        s = tmp / f"{path}.toml"
        s.write_text(SWEEP.format(path=path, name=name, value=value, fixed=fixed))
        rc = cli.main(["sweep", str(acc), str(s), "-o", str(tmp / path), "--scheduler", "serial", "-q"])
        assert rc == 0, (tmp / path / "runs" / "run_0" / "error.txt").read_text()
        out[path] = tmp / path
    return out


def capacitance_error(out: dict[str, Path], name: str) -> float:
    """The stated error of the etch's capacitance law (process.etch.capacitance_max_rel_error; 0 for
    the other parameters: they leave the capacitances or shift them exactly)."""
    model = MacroModel.load_json(out["parameters"] / "model" / "accelerometer_z.json")
    return model.process["etch"]["capacitance_max_rel_error"] if name == "etch" else 0.0


def law_error(out: dict[str, Path], name: str) -> float:
    """The stated error of the parameter's law in the shared model (module docstring)."""
    model = MacroModel.load_json(out["parameters"] / "model" / "accelerometer_z.json")
    if name == "etch":  # the mass law's and the a_in load's (the load follows the etched body)
        return model.process["etch"]["max_rel_error"] + model.process["etch"]["acceleration"]["max_rel_error"]
    if name.startswith("dg_"):
        rebuilt = MacroModel.load_json(next((out["rebuild"] / "runs" / "run_0" / "model").glob("*.json")))
        return sum(max(f.max_rel_error for f in m.capacitances) for m in (model, rebuilt))
    if name in ("tscale", "escale"):  # the crab legs' cubic in tscale; K linear in E
        return model.process[name]["max_rel_error"]
    return 0.0


def agree(out: dict[str, Path], name: str, others: tuple[str, ...] = ()) -> None:
    """The two runs within the module docstring's bounds; at a point of several parameters (`others`
    fixed besides the swept `name`) each declared law's stated error adds."""
    p, r = rows(out["parameters"])[0], rows(out["rebuild"])[0]
    assert p["status"] == r["status"] == "ok"
    clock_p = np.load(out["parameters"] / "runs" / "run_0" / "bitstreams.npz")
    clock_r = np.load(out["rebuild"] / "runs" / "run_0" / "bitstreams.npz")
    model = MacroModel.load_json(out["parameters"] / "model" / "accelerometer_z.json")
    names = (name, *others)
    c = model.coordinates[0]
    err, c_err = sum(law_error(out, n) for n in names), sum(capacitance_error(out, n) for n in names)
    sp, sr = (json.loads((out[k] / "runs" / "run_0" / "summary.json").read_text()) for k in ("parameters", "rebuild"))
    flips = np.nonzero(clock_p["bits_z"] != clock_r["bits_z"])[0]
    n = int(flips[0]) + 1 if flips.size else len(clock_r["x_z"])  # the same feedback up to the first flip
    x_p, x_r = clock_p["x_z"][:n], clock_r["x_z"][:n]
    scale = np.max(np.abs(x_r))
    # the capacitance law's error on the same bit pattern's force, integrated twice over the n periods
    ts, mass, x_unit = sp["ts"], sp["design"]["balance"]["mass"], sp["design"]["balance"]["x_unit_si"]
    peak = max(abs(f) for row in sp["design"]["table"] for f in row["all"])
    drift = c_err * peak * (n * ts) ** 2 / (2 * mass) / x_unit
    bound = 2 * (RELTOL * scale + VNTOL * c.scale / c.port_units[1]) + err * scale + drift
    balance = float(p["gravity_balance.ratio"]) / float(r["gravity_balance.ratio"]) - 1
    b_bound = 2 * RELTOL + err + c_err + (inertia_spread(clock_p, clock_r, sp) if flips.size else 0.0)
    print(
        f"{name}: x_z {np.max(np.abs(x_p - x_r)):.2e} V over {n} periods (bound {bound:.2e} V, largest {scale:.2e} V); "
        f"bits differ at {flips.size} of 128; balance {balance:.1e} (bound {b_bound:.1e}); law error {err:.1e}, "
        f"capacitance {c_err:.1e}; inertial terms {sp['gravity_balance']['inertial_n']:.3e} / "
        f"{sr['gravity_balance']['inertial_n']:.3e} N against need {need(sp):.3e} N"
    )
    assert np.max(np.abs(x_p - x_r)) <= bound
    assert abs(balance) <= b_bound
    # the weight each design loads the loop with: the parameters path's a_in law (G tscale R(etch), G ~ t
    # exactly) against the rebuilt body's participation, within the etch ratio's stated residual
    weight = sp["gravity_balance"]["weight_n"] / sr["gravity_balance"]["weight_n"] - 1
    load_err = model.process["etch"]["acceleration"]["max_rel_error"] if "etch" in names else 0.0
    assert abs(weight) <= load_err + 1e-12, weight


def need(summary: dict) -> float:
    """The balance's denominator (netgen.testbench.sigma_delta.analysis.gravity_balance)."""
    g = summary["gravity_balance"]
    return g["weight_n"] + g["inertial_n"] + g["damping_n"]


def inertia_spread(clock_p: dict, clock_r: dict, sp: dict) -> float:
    """After a flipped decision the two loops end the window at different points of their limit cycles:
    the balance's inertial term m (v_b - v_a) / ((b - a) ts) (v_a the same: both start at rest) can then
    differ by m (|v_b| + |v_b'|) / ((b - a) ts) <= m (max |v| + max |v'|) / ((b - a) ts), with v each
    run's central differences of x_z; relative to the balance's denominator."""
    ts, mass = sp["ts"], sp["design"]["balance"]["mass"]
    a, b = sp["gravity_balance"]["window"]
    unit = sp["design"]["balance"]["x_unit_si"]
    vmax = [np.max(np.abs(x[2:] - x[:-2])) * unit / (2 * ts) for x in (clock_p["x_z"], clock_r["x_z"])]
    return mass * sum(vmax) / ((b - a) * ts) / abs(need(sp))


@pytest.mark.parametrize("name", list(CASES))
def test_parameter_against_rebuild(tmp_path, name):
    """Each of temp, etch and dg_top on the .lib (ngspice): the instance parameter on the model's
    line, the rebuild's structure at the point, the runs within the derived bounds (module docstring)."""
    declared, value = CASES[name]
    out = both_paths(tmp_path, name, declared, value)
    x1 = [x for x in (out["parameters"] / "runs/run_0/sigma_delta.cir").read_text().splitlines() if x.startswith("X1 ")]
    assert x1 and x1[0].endswith(f"accelerometer_z {name}={float(value)!r}"), x1
    assert "[process]" not in (out["rebuild"] / "runs/run_0/structure.toml").read_text()
    agree(out, name)


FILM = '\n[damping]\nsqueeze_film = true\npressure = "100 Pa"\n'
BAD = [  # (appended to the structure, [sweep] process, parameter, value, key, words)
    ('["temp"]', "parameters", "temp", "200", "parameters[0].values", "outside the structure's temp_range"),
    ('["temp"]', "parameters", "etch", "5e-8", "parameters[0].values", "does not declare etch"),
    ('["dg"]', "parameters", "dg_side", "1e-8", "parameters[0].values", "is not an electrode set above or below"),
    ('["dg"]', "parameters", "dg_top", '"1 um"', "parameters[0].values", "outside the gap offsets' valid range"),
    ('["dg"]', "parameters", "dg_top", '"2 furlongs"', "parameters[0].values", "process.dg_top"),
    ('["temp"]', "parameters", "temp", '"hot"', "parameters[0].values", "is not a temperature in degC"),
    ('["temp"]' + FILM, "rebuild", "temp", "85", "parameters[0].values", "cannot move the squeeze film's gas"),
]


@pytest.mark.parametrize("declared,path,name,value,key,words", BAD)
def test_bad_process_entries_exit_2(tmp_path, capsys, declared, path, name, value, key, words):
    """An undeclared parameter, a value outside its valid range (temp_range; |dg| <= range x gap / 4),
    a set that has no gap offset, a value in the wrong unit, and a rebuild that would be a wrong
    reference (the film's viscosity at temp): exit 2 before anything runs, naming the sweep file, the
    key and a fix; no output folder."""
    acc = structure(tmp_path, f"\n[process]\nparameters = {declared}\n")
    s = tmp_path / "bad.toml"
    s.write_text(SWEEP.format(path=path, name=name, value=value, fixed=""))
    rc = cli.main(["sweep", str(acc), str(s), "-o", str(tmp_path / "out"), "--dry-run"])
    err = capsys.readouterr().err
    assert rc == 2, err
    assert str(s) in err and key in err and words in err and "fix:" in err, err
    assert not (tmp_path / "out").exists()


def test_etch_rebuild_of_a_plate(tmp_path, capsys):
    """A rebuild at an etch bias of a piston on a given spring: its outline etches (netgen.model.
    etch_geometry.etched_plate; it was refused as having no flexure beams), so the dry run plans it."""
    acc = tmp_path / "acc.toml"
    acc.write_text((ROOT / "examples/accelerometer_z.toml").read_text())
    s = tmp_path / "plate.toml"
    s.write_text(SWEEP.format(path="rebuild", name="etch", value="5e-8", fixed=""))
    rc = cli.main(["sweep", str(acc), str(s), "-o", str(tmp_path / "out"), "--dry-run"])
    err = capsys.readouterr().err
    assert rc == 0 and "no flexure beams" not in err, err


BACKEND_POINT = '"process.temp" = 85\n"process.escale" = 0.9\nsimulator = "{simulator}"\n'


@pytest.mark.parametrize("simulator", ["ngspice-xspice", "ngspice-osdi", "vacask"])
def test_backends_take_the_point(tmp_path, monkeypatch, simulator):
    """temp, escale and dg_top at once on the other back ends, each in its own form (the _xspice.lib's
    and the _osdi.lib's .subckt params:, VACASK's model card), against the rebuild on the same back
    end, within the module docstring's bounds (OSDI on ngspice 46; the code model on the PATH's 39)."""
    if simulator == "ngspice-osdi":
        monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    fixed = BACKEND_POINT.format(simulator=simulator)
    out = both_paths(tmp_path, "dg_top", '["dg", "temp", "escale"]', "3e-8", fixed)
    run = out["parameters"] / "runs" / "run_0"
    if simulator == "vacask":
        card = [x for x in (run / "sigma_delta.sim").read_text().splitlines() if x.startswith("model mems ")]
        assert card == ["model mems accelerometer_z dg_top=3e-08 escale=0.9 temp=85.0"], card
    else:
        x1 = [x for x in (run / "sigma_delta.cir").read_text().splitlines() if x.startswith("X1 ")]
        assert x1 and x1[0].endswith("accelerometer_z dg_top=3e-08 escale=0.9 temp=85.0"), x1
    agree(out, "dg_top")


FIVE_POINT = (
    '"process.temp" = 85\n"process.escale" = 0.9\n"process.tscale" = 1.05\n"process.etch" = 5e-8\n'
    'simulator = "{simulator}"\n'
)


@pytest.mark.parametrize("simulator", ["ngspice-xspice", "ngspice-osdi", "vacask"])
def test_all_five_at_once(tmp_path, monkeypatch, simulator):
    """tscale, escale, temp, etch and dg_top at one point on each back end against its rebuild, within
    the module docstring's bounds with every declared law's stated error added."""
    if simulator == "ngspice-osdi":
        monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    declared = '["dg", "temp", "escale", "tscale", "etch"]'
    out = both_paths(tmp_path, "dg_top", declared, "3e-8", FIVE_POINT.format(simulator=simulator))
    agree(out, "dg_top", ("temp", "escale", "tscale", "etch"))


def test_monte_carlo_draw_outside_the_range_exits_2(tmp_path, capsys):
    """A seeded normal draw of dg_top beyond the gap offsets' range (std 200 nm against |dg| <= 300 nm):
    exit 2 naming the distribution's entry and the fix, before anything runs."""
    acc = structure(tmp_path, '\n[process]\nparameters = ["dg"]\n')
    s = tmp_path / "mc.toml"
    s.write_text(
        '[sweep]\nsamples = 20\nseed = 3\n[fixed]\ncycles = 128\n[[parameters]]\nname = "process.dg_top"\n'
        'distribution = "normal"\nmean = "0 nm"\nstd = "200 nm"\n'
    )
    rc = cli.main(["sweep", str(acc), str(s), "-o", str(tmp_path / "out"), "--dry-run"])
    err = capsys.readouterr().err
    assert rc == 2 and "parameters[0]:" in err and "narrow the distribution" in err, err
    assert not (tmp_path / "out").exists()
