"""The benchmark scripts run: each in its smallest setting, printing the figure lines its
documentation quotes (the long settings are docs/performance.md's). They call the package's
public API, so a change of it that a script missed fails here, not in the next measurement."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

from netgen.structure import parse_structure
from tests.fixtures import ROOT, shared_model
from tests.oracles.process_cases import xyz_etch_text

RUNS = {
    "build_scaling": (
        ["bench/build_scaling.py", "-o", "{tmp}", "--n", "3", "--designs", "grid,sparse"],
        ["sparse      3   0.2       25", "wrote "],
    ),
    "sigma_delta_designs": (
        [
            "bench/sigma_delta_designs.py",
            "examples/levitated_disk.toml",
            "netlists/levitated_disk.json",
            "-o",
            "{tmp}",
            "--eps=0",
            "--cycles",
            "512",
        ],
        ["mean median", "0_netlists               z"],
    ),
    "build": (
        ["bench/build.py", "--repeat", "1"],
        ["median of 1 build(s)", "fits (16 electrodes, plates)", "budget 60 s"],
    ),
    "fit_corners": (["bench/fit_corners.py", "examples/cc_beam.toml"], ["cc_beam          drive       3"]),
    "sigma_delta": (
        [
            "bench/sigma_delta.py",
            "--cycles",
            "64",
            "--repeat",
            "1",
            "--naive-cycles",
            "1",
            "--variants",
            "xspice,fast,nodes,naive,floor,linear",
            "--loops",
            "xspice,analog",
        ],
        ["ratio xspice/floor", "ratio nodes/fast", "ratio naive/fast", "analog loop"],
    ),
    "sigma_delta_vacask": (
        ["bench/sigma_delta_vacask.py", "--cycles", "64", "--ngspice-cycles", "64", "--repeat", "1"],
        ["ngspice / vacask", "vacask "],
    ),
    "callgrind": (["bench/callgrind.py", "--cycles", "1", "--variants", "floor"], ["floor"]),
    "loop_scaling": (
        [
            "bench/loop_scaling.py",
            "-o",
            "{tmp}",
            "--modes",
            "0",
            "--layouts",
            "",
            "--cycles",
            "1",
            "--paths",
            "xspice,vacask",
        ],
        ["disk_m0_r2s4       3    16", "instructions per iteration ~", "vacask: instructions per period ~", "wrote "],
    ),
    "fastcap_love": (["bench/fastcap_love.py", "--kappa", "0.05"], [" 0.050 ", "inside"]),
    "import_ulp_sensitivity": (
        ["bench/import_ulp_sensitivity.py", "--trials", "2"],
        ["rows twice", "1 BLAS thread", "of the test's 1e-06 bound"],
    ),
    "fastcap_dask": (
        ["bench/fastcap_dask.py", "--points", "2"],
        ["serial: ", "2 Dask workers: ", "equal bit for bit: True"],
    ),
    "ideal_loop": (["bench/sigma_delta_ideal_loop.py", "--cycles", "2048"], ["dB/decade"]),
    "stop_newton": (
        ["bench/stop_newton.py", "--variants", "1", "--etches", "1e-7", "--timeout", "5", "--model", "{xyz_etch}"],
        ["osdi ngspice 46, vntol 1e-12", "vacask, default", "iterations"],
    ),
    "stop_newton_sensitivity": (
        ["bench/stop_newton.py", "--sensitivity", "--etches", "1e-7", "--model", "{xyz_etch}"],
        ["B-source sum", "etch +1e-07"],
    ),
    "sigma_delta_accelerometer": (
        [
            "bench/sigma_delta_accelerometer.py",
            "-o",
            "out/test_bench_accelerometer",
            "--cycles",
            "256",
            "--long",
            "0",
            "--points",
            "3",
            "--amplitudes",
            "0.5",
            "--jobs",
            "1",
        ],
        ["DC sweep: scale factor", "maximum stable tone amplitude"],
    ),
}


@pytest.fixture(scope="module")
def xyz_etch(tmp_path_factory) -> str:
    """The JSON of bench/stop_newton.py's structure, built once in the session (tests.fixtures.
    shared_model: tests/emit/test_process_etch_forms.py builds the same), for its two runs."""
    text = xyz_etch_text()
    model = shared_model(parse_structure(text, "xyz.toml"))
    path = tmp_path_factory.mktemp("xyz_etch") / "xyz.json"
    path.write_text(model.json_text())
    return str(path)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(RUNS))
def test_bench_script_runs(name, tmp_path, request):
    argv, expect = RUNS[name]
    if "{xyz_etch}" in argv:
        argv = [request.getfixturevalue("xyz_etch") if a == "{xyz_etch}" else a for a in argv]
    proc = subprocess.run(
        [sys.executable, *[a.replace("{tmp}", str(tmp_path)) for a in argv]],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    for text in expect:
        assert text in proc.stdout, f"{name}: no {text!r} in\n{proc.stdout[-2000:]}"


@pytest.fixture(scope="module")
def tone_run(tmp_path_factory):
    """A short compiled sigma-delta run with a tone on z (the input of the two analysis scripts)."""
    out = tmp_path_factory.mktemp("tone")
    subprocess.run(
        [
            str(ROOT / ".venv/bin/netgen"),
            "sigma-delta",
            "examples/levitated_disk.toml",
            "--model",
            "netlists/levitated_disk.json",
            "--simulator",
            "ngspice-xspice",
            "--cycles",
            "512",
            "--tone",
            "z:0.02:20000",
            "-o",
            str(out),
            "-q",
            "--no-plots",
        ],
        cwd=ROOT,
        check=True,
        timeout=300,
    )
    return out


def test_compare_simulators_and_tone_coupling_read_a_run(tone_run):
    """compare_simulators.py on one run against itself: the same floors and notches (0 dB, 0 %);
    tone_coupling.py finds the tone's line in the z bitstream; couplings_sigma_delta.py on the run against
    itself finds no differing bit and no line change."""
    same = subprocess.run(
        [sys.executable, "bench/compare_simulators.py", str(tone_run), str(tone_run)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert same.returncode == 0, same.stderr[-3000:]
    for channel in ("z", "tilt_x", "tilt_y"):  # floor, floor, difference 0.0 dB
        assert re.search(rf"^{channel}\s+-?[\d.]+\s+-?[\d.]+\s+0\.0\s", same.stdout, re.M), same.stdout
    tone = subprocess.run(
        [sys.executable, "bench/tone_coupling.py", str(tone_run), "--nperseg", "256"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert tone.returncode == 0, tone.stderr[-3000:]
    assert "tilt_x" in tone.stdout and "dB" in tone.stdout, tone.stdout
    pair = subprocess.run(
        [sys.executable, "bench/couplings_sigma_delta.py", str(tone_run), str(tone_run), "--nperseg", "256"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert pair.returncode == 0, pair.stderr[-3000:]
    for channel in ("z", "tilt_x", "tilt_y"):  # a run against itself: no bit differs, no line moves
        assert f"{channel:8s} differing bits: 0 of 512; line change +0.00 dB" in pair.stdout, pair.stdout


def test_fit_derivatives_extractor_rows_meet_the_parallel_plate_limits():
    """bench/fit_derivatives.py's extractor rows (its second derivatives are finite differences):
    a gap electrode's dC/dz / C and d2C/dz2 / C, in units of the gap, are those of a parallel plate,
    1 and 2, lowered a little by the edge fringe (it grows only as ln(1/g) when the gap closes);
    the committed grid model follows within its fit tolerance in C."""
    proc = subprocess.run(
        [
            sys.executable,
            "bench/fit_derivatives.py",
            "examples/levitated_disk.toml",
            "netlists/levitated_disk.json",
            "--rows",
            "z",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = proc.stdout.splitlines()
    rows = [k for k, line in enumerate(lines) if re.match(r"^(top|bot)_r\ds\d\s+extractor", line)]
    assert len(rows) == 16, proc.stdout[-2000:]
    for k in rows:
        c, dz, dzz = (float(v) for v in lines[k].split()[2:5])
        assert c == 1.0 and 0.9 < abs(dz) < 1.0 and 1.8 < dzz < 2.0, lines[k]
        model_c_error = float(lines[k + 1].split()[1])
        assert abs(model_c_error) <= 2e-3, lines[k + 1]  # [fit] tolerance of the example
    assert "stiffness row z" in proc.stdout
