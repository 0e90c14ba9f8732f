"""Bad sweep files are refused before anything runs: every generated bad file (tests/sweep/
bad_sweeps.py, by class) exits 2 with no traceback, names the file and the key, and gives a fix;
nothing is written. The references are the hand-written keys of each case and the good file it
was derived from, which is accepted. Sizes are refused from the spec alone (a 1e9-run grid in
well under a second, no MemoryError), with the run count and a time estimate."""

from __future__ import annotations

import collections
import time

import pytest

from netgen.cli import commands as cli
from netgen.sweep import parse_sweep
from netgen.sweep.size import RUN_SECONDS, SECONDS_PER_PERIOD, estimate, run_count
from tests.fixtures import ROOT
from tests.sweep.bad_sweeps import FIXED, GOOD, PARAM, cases

STRUCTURE = ROOT / "examples" / "levitated_disk.toml"


def _sweep(tmp_path, data: bytes, *extra: str) -> tuple[int, str]:
    """`netgen sweep --dry-run` on the file content; (exit code, stderr)."""
    f = tmp_path / "s.toml"
    f.write_bytes(data)
    return cli.main(["sweep", str(STRUCTURE), str(f), "-o", str(tmp_path / "out"), "--dry-run", *extra]), str(f)


def test_the_good_file_is_accepted(tmp_path, capsys):
    rc, _ = _sweep(tmp_path, GOOD.encode())
    err = capsys.readouterr().out
    # 2 runs of 128 periods at the stated rough figure for a rigid model
    assert rc == 0 and "2 run(s)" in err and f"{SECONDS_PER_PERIOD['rigid'] * 128 + RUN_SECONDS:.3g} s each" in err, err
    assert not (tmp_path / "out").exists()  # a dry run writes nothing


def test_every_generated_bad_file_is_refused_with_file_key_and_fix(tmp_path, capsys):
    all_cases = cases()
    per_class = collections.Counter(c for c, _, _ in all_cases)
    assert len(all_cases) >= 169 and len(per_class) >= 10, per_class
    failures = []
    for k, (cls, data, key) in enumerate(all_cases):
        case = tmp_path / f"case_{k}"
        case.mkdir()
        rc, path = _sweep(case, data)
        out, err = capsys.readouterr()
        ok = rc == 2 and "Traceback" not in err + out and path in err and key in err and "\n  fix: " in err
        if not ok or (case / "out").exists():
            failures.append((k, cls, key, rc, err[-300:]))
    assert not failures, f"{len(failures)} of {len(all_cases)} bad files not refused properly: {failures[:5]}"


def test_a_billion_run_grid_is_refused_from_the_spec_alone(tmp_path, capsys):
    text = "[fixed]\ncycles = 128\n" + "".join(
        f'[[parameters]]\nname = "{n}"\nstart = {a}\nstop = {b}\nnum = 1000\n'
        for n, a, b in [("ts", 1e-6, 2e-6), ("lead", 0.1, 0.9), ("density", 0.3, 0.7)]
    )
    start = time.perf_counter()
    assert run_count(parse_sweep(text, "big.toml")) == 1000**3  # counted, never listed
    rc, _ = _sweep(tmp_path, text.encode())
    err = capsys.readouterr().err
    assert rc == 2 and "1000000000 runs" in err and "--max-runs 10000" in err and "fix:" in err
    assert time.perf_counter() - start < 5


def test_the_estimate_uses_runs_measured_in_the_folder(tmp_path):
    sweep = parse_sweep(GOOD, "s.toml")
    run = tmp_path / "runs" / "run_0"
    run.mkdir(parents=True)
    (run / "summary.json").write_text('{"wall_s": 64.0, "requested_cycles": 128}')
    est = estimate(sweep, workers=1, out=tmp_path)
    per_run = 0.5 * 128 + RUN_SECONDS  # the measured 0.5 s per period, 128 periods
    assert est.per_run_s == pytest.approx(per_run) and est.wall_s == pytest.approx(2 * per_run)  # 2 runs, 1 worker
    assert "measured" in est.basis


def test_max_runs_refuses_a_sweep_one_over_it(tmp_path, capsys):
    rc, _ = _sweep(tmp_path, GOOD.encode(), "--max-runs", "1")
    err = capsys.readouterr().err
    assert rc == 2 and "2 runs" in err and "--max-runs 1" in err
    assert _sweep(tmp_path, GOOD.encode(), "--max-runs", "2")[0] == 0


def test_a_dry_run_refuses_what_every_run_would_refuse(tmp_path, capsys):
    """A tone amplitude beyond the declared range, and a simulator the installed ngspice cannot
    run (ngspice-osdi needs OSDI 0.5: ngspice 44 and later), are refused by the dry run with the
    key and the fix, so no run fails on them."""
    from netgen.testbench.sigma_delta import simulator_problem

    rc, path = _sweep(tmp_path, GOOD.replace(FIXED, FIXED + 'tone = "z:0.02:2000"\ntone_amplitude = 1e30\n').encode())
    err = capsys.readouterr().err
    assert rc == 2 and "tone_amplitude = 1e+30 is outside (0, 1e+12]" in err and "fix:" in err, err
    rc, _ = _sweep(tmp_path, GOOD.replace(FIXED, FIXED + 'simulator = "ngspice-osdi"\n').encode())
    err = capsys.readouterr().err
    if simulator_problem("ngspice-osdi"):  # ngspice 39-43 (the PATH's ngspice here)
        assert rc == 2 and "fixed.simulator" in err and "OSDI 0.5" in err and "fix:" in err, err
    else:
        assert rc == 0, err


def test_a_timeout_in_hours_and_any_device_with_a_loop(tmp_path, capsys):
    """timeout = "2 h" is 7200 s; the z accelerometer (no tilts) is swept like the disk."""
    assert parse_sweep(GOOD, "s.toml").timeout is None
    sweep = parse_sweep('[sweep]\ntimeout = "2 h"\n' + FIXED + PARAM, "s.toml")
    assert sweep.timeout == 7200.0
    f = tmp_path / "s.toml"
    f.write_text(FIXED + PARAM)
    acc = ROOT / "examples" / "accelerometer_z.toml"
    rc = cli.main(["sweep", str(acc), str(f), "-o", str(tmp_path / "out"), "--dry-run"])
    out, err = capsys.readouterr()
    assert rc == 0 and "2 run(s)" in out, err
