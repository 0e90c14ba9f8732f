"""Every command-line path: argument ranges and output folders refused before any work (exit 2,
naming the argument and the fix), the one error boundary (exit 70 with a crash log, 130 for
SIGINT and SIGTERM, never a traceback), `netgen simulate` on real ngspice and VACASK runs (a
relative .include, binary and Latin-1 input, netlists ngspice rejects, a hang stopped by the
wall-clock limit, garbage raw files), and output folders as transactions (interrupted and
concurrent builds and sigma-delta runs leave the complete old or the complete new set, the
user's files untouched, no temp files, modes from the umask). bench/interrupts.py runs the full
counts; its classifier is the one used here."""

from __future__ import annotations

import fcntl
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from netgen.cli import commands as cli
from netgen.core.errors import SimulationError
from netgen.runtime.arguments import output_folder
from netgen.runtime.folders import OutputFolder, check_manifest
from netgen.runtime.interrupts import Interrupted
from netgen.sim.ngspice import run_ngspice
from netgen.sim.rawfile import read_raw
from tests.fixtures import NGSPICE, ROOT

sys.path.insert(0, str(ROOT / "bench"))
import interrupts as bench  # noqa: E402  (bench/interrupts.py: the classifier and the variants)

NETGEN = str(ROOT / ".venv/bin/netgen")
PISTON = str(ROOT / "examples/piston.toml")
DISK = str(ROOT / "examples/levitated_disk.toml")
GYRO = str(ROOT / "examples/gyroscope_z.toml")
MODEL = str(ROOT / "netlists/levitated_disk.json")


def refused(argv: list[str], capsys) -> str:
    """Run the command line in this process; it must stop in argument checking with exit 2."""
    with pytest.raises(SystemExit) as info:
        cli.main(argv)
    assert info.value.code == 2
    return capsys.readouterr().err


# ----------------------------------------------------------------------------- argument ranges

A_FILE = str(ROOT / "pyproject.toml")
RANGES = [
    (["simulate", A_FILE, "-o", "OUT", "--timeout", "0"], "--timeout", "is outside (0, 1e+07] s"),
    (["simulate", A_FILE, "-o", "OUT", "--timeout", "-1"], "--timeout", "is outside (0, 1e+07] s"),
    (["simulate", A_FILE, "-o", "OUT", "--timeout", "nan"], "--timeout", "e.g. --timeout 600"),
    (["simulate", A_FILE, "-o", "OUT", "--timeout", "1e300"], "--timeout", "outside the physical range"),
    (["simulate", "no/such.cir", "-o", "OUT"], "netlist", "check the path"),
    (["simulate", str(ROOT), "-o", "OUT"], "netlist", "give the netlist file inside it"),
    (["simulate", A_FILE, "-o", ""], "-o/--output", "give a folder"),
    (["simulate", A_FILE, "-o", A_FILE], "-o/--output", "is a file"),
    (["simulate", A_FILE, "-o", A_FILE + "/run"], "-o/--output", "which is a file"),
    (["simulate", A_FILE, "-o", "/proc/netgen-run"], "-o/--output", "choose a folder on disk"),
    (["simulate", A_FILE, "-o", "/sys/kernel/netgen-run"], "-o/--output", "choose a folder on disk"),
    (["build", PISTON, "-o", ""], "-o/--output", "give a folder"),
    (["build", PISTON, "-o", "/proc/self/netgen"], "-o/--output", "not storage"),
    (["build", PISTON, "-o", "OUT", "--sample-store", A_FILE], "--sample-store", "is a file"),
    (
        ["build", PISTON, "-o", "OUT", "--scheduler", ""],
        "--scheduler",
        "is empty; give where the capacitance samples are computed",
    ),
    (["simulate", A_FILE, "-o", "OUT", "--timeout", "-inf"], "--timeout", "--option=VALUE"),
    (["sigma-delta", DISK, "-o", "OUT", "--cycles", "10"], "--cycles", "between 64 and"),
    (["sigma-delta", DISK, "-o", "OUT", "--cycles", "1e3"], "--cycles", "whole number"),
    (["sigma-delta", DISK, "-o", "OUT", "--cycles", str(1 << 30)], "--cycles", "between 64 and"),
    (["sigma-delta", DISK, "-o", "OUT", "--ts", "0"], "--ts", "is outside [1e-09, 1] s"),
    (["sigma-delta", DISK, "-o", "OUT", "--ts", "inf"], "--ts", "e.g. --ts 1e-6"),
    (["sigma-delta", DISK, "-o", "OUT", "--segment", "3"], "--segment", "(or 0: one run)"),
    (["sigma-delta", DISK, "-o", "OUT", "--segment", "-1"], "--segment", "between 16 and"),
    (["sigma-delta", DISK, "-o", "OUT", "--lead", "nan"], "--lead", "e.g. --lead 0.8"),
    (["sigma-delta", DISK, "-o", "OUT", "--dither", "x"], "--dither", "e.g. --dither 0.2"),
    (["sigma-delta", DISK, "-o", "OUT", "--timeout", "0"], "--timeout", "is outside (0, 1e+07] s"),
    (["sigma-delta", DISK, "-o", "OUT", "--pressure", "inf"], "--pressure", "e.g. --pressure"),
    (["sigma-delta", DISK, "-o", "OUT", "--model", "no/such.json"], "--model", "check the path"),
    (["sigma-delta", DISK, "-o", ""], "-o/--output", "give a folder"),
    (["gyro", GYRO, "-o", "OUT", "--rate", "nan"], "--rate", "e.g. --rate 200"),
    (["gyro", GYRO, "-o", "OUT", "--rate-points", "2"], "--rate-points", "between 3 and 41"),
    (["gyro", GYRO, "-o", "OUT", "--drive-amplitude", "4 V"], "--drive-amplitude", "e.g. --drive-amplitude"),
    (["gyro", GYRO, "-o", "OUT", "--agc-gain", "0"], "--agc-gain", "is outside (0, 10000]"),
    (["gyro", GYRO, "-o", "OUT", "--simulator", "spectre"], "--simulator", "invalid choice"),
    (["sweep", DISK, str(ROOT / "examples/sweep_ts.toml"), "-o", ""], "-o/--output", "give a folder"),
    (["sweep", DISK, str(ROOT / "examples/sweep_ts.toml"), "-o", "/proc/x"], "-o/--output", "not storage"),
]


@pytest.mark.parametrize("argv, argument, fix", RANGES, ids=[" ".join(a[0:1] + a[2:]) for a, _, _ in RANGES])
def test_an_argument_out_of_range_is_exit_2_naming_it_and_the_fix(argv, argument, fix, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    err = refused(argv, capsys)
    assert f"argument {argument}:" in err and fix in err, err
    assert "Traceback" not in err and not (tmp_path / "OUT").exists() and os.listdir(tmp_path) == []


@pytest.mark.parametrize(
    "argv, fix",
    [
        (["sigma-delta", DISK, "--model", MODEL, "--tone", "z:0.02:-5"], "is outside (0, 1e+12]"),
        (["sigma-delta", DISK, "--model", MODEL, "--tone", "q:0.02:1000"], "choose one of z, tilt_x"),
        (["sigma-delta", DISK, "--model", MODEL, "--tone", ""], "is not COORD:AMPLITUDE:FREQ"),
        (["sigma-delta", DISK, "--model", A_FILE], "give the .json a build wrote"),
        (["build", PISTON, "--scheduler", "processes:0"], "positive integer"),
    ],
)
def test_values_checked_after_parsing_are_exit_2_too(argv, fix, tmp_path, capsys):
    assert cli.main(argv + ["-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert fix in err and "Traceback" not in err, err
    assert not list((tmp_path).glob("out/*.json")) and not list(tmp_path.glob("out/summary*"))


def test_an_unwritable_folder_is_refused(tmp_path, capsys):
    """As root the permission bits do not stop a write; a read-only mount would. Tried, not
    guessed: a folder whose permissions refuse this process is refused, one that does not is not."""
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    probe = subprocess.run(["touch", str(locked / "x")], capture_output=True)
    if probe.returncode == 0:  # root: writable after all, so it must be accepted
        (locked / "x").unlink()
        assert output_folder(str(locked / "run")) == str(locked / "run")
        return
    err = refused(["simulate", A_FILE, "-o", str(locked / "run")], capsys)
    assert "not writable" in err and "it would be created in" in err


# ----------------------------------------------------------------------------- the error boundary


def test_an_unexpected_exception_is_one_line_exit_70_and_a_crash_log(tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"
    out.mkdir()

    def broken(path):
        return {}["no such key"]  # a bug, as netgen would have one

    monkeypatch.setattr(cli, "load_structure", broken)
    assert cli.main(["build", PISTON, "-o", str(out)]) == 70
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "internal error (KeyError" in err and str(out / "netgen-crash.log") in err
    log = (out / "netgen-crash.log").read_text()
    assert "Traceback" in log and "in broken" in log


@pytest.mark.parametrize(
    "exc, line",
    [
        (KeyboardInterrupt(), "netgen: interrupted"),
        (Interrupted(signal.SIGTERM), "netgen: interrupted (SIGTERM)"),
        # a stage that cleaned up says what is left (netgen.sweep.run.run_sweep): its line, still exit 130
        (
            Interrupted(signal.SIGTERM, "sweep stopped by SIGTERM: 1 of 2 runs finished"),
            "netgen: sweep stopped by SIGTERM: 1 of 2 runs finished",
        ),
    ],
)
def test_a_keyboard_interrupt_inside_a_command_is_exit_130(exc, line, tmp_path, capsys, monkeypatch):
    def interrupted(path):
        raise exc

    monkeypatch.setattr(cli, "load_structure", interrupted)
    assert cli.main(["build", PISTON, "-o", str(tmp_path / "out")]) == 130
    assert capsys.readouterr().err == line + "\n"


def catches(pid: int, sig: signal.Signals, argument: str = "") -> bool:
    """Has process `pid` installed a handler for `sig` (its SigCgt mask in /proc)? With `argument`:
    only once the process has exec'd a command line holding it (between fork and exec the child
    still has its parent's handlers, and a signal sent then is lost in the parent's copy)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
        if argument and argument.encode() not in Path(f"/proc/{pid}/cmdline").read_bytes():
            return False
    except OSError:
        return False
    mask = int(next(ln.split()[1] for ln in status.splitlines() if ln.startswith("SigCgt:")), 16)
    return bool(mask >> (sig - 1) & 1)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_while_the_command_starts_is_one_line_and_exit_130(sig, tmp_path):
    """Ctrl-C or SIGTERM during the imports (the ~0.6 s after netgen's first line installed its
    handlers, before the command runs): exit 130 and one line. (Before that line the interpreter
    itself is starting: Python's own reaction, measured by bench/interrupts.py.)"""
    for delay in (0.0, 0.2):
        proc = subprocess.Popen(  # a terminal's Ctrl-C: SIGINT at its default even where the suite runs with it ignored
            [NETGEN, "build", PISTON, "-o", str(tmp_path / "out")],
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        )
        deadline = time.monotonic() + 60
        while not catches(proc.pid, signal.SIGTERM, str(PISTON)) and time.monotonic() < deadline:
            time.sleep(0.002)
        time.sleep(delay)
        proc.send_signal(sig)
        err = proc.communicate(timeout=120)[1]
        assert proc.returncode == 130 and "Traceback" not in err and len(err.splitlines()) == 1, (delay, err)
        assert "while starting" in err and not (tmp_path / "out").exists()


# ----------------------------------------------------------------------------- netgen simulate


def simulate(argv: list[str], capsys) -> tuple[int, str, str]:
    code = cli.main(["simulate", *argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.mark.parametrize("version", sorted(NGSPICE))
def test_a_relative_include_resolves_against_the_netlists_own_folder(version, tmp_path, capsys, monkeypatch):
    """1 V over two 1 kOhm in parallel, one of them in sub/parallel.lib: 2 mA, run from elsewhere."""
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE[version])
    (tmp_path / "bench/sub").mkdir(parents=True)
    (tmp_path / "bench/sub/parallel.lib").write_text("R2 a 0 1k\n")
    cir = tmp_path / "bench/top.cir"
    cir.write_text("* relative include\nV1 a 0 1\nR1 a 0 1k\n.include sub/parallel.lib\n.op\n.end\n")
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    code, out, err = simulate(["../bench/top.cir", "-o", "run"], capsys)
    assert code == 0, err
    plot = read_raw(tmp_path / "elsewhere/run/top.raw")[0]
    assert plot["i(v1)"][0] == pytest.approx(-2e-3, rel=1e-9)
    assert sorted(os.listdir(tmp_path / "bench")) == ["sub", "top.cir"]  # nothing written beside it


def test_a_relative_include_resolves_in_vacask_too(tmp_path, capsys):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub/part.inc").write_text("r2 (a 0) resistor r=1k\n")
    sim = tmp_path / "top.sim"
    sim.write_text(
        'relative include\nload "resistor.osdi"\nground 0\nmodel resistor resistor\n'
        'model vsource vsource\nv1 (a 0) vsource dc=1\nr1 (a 0) resistor r=1k\ninclude "sub/part.inc"\n'
        "control\n  analysis op1 op\nendc\n"
    )
    code, _, err = simulate([str(sim), "-o", str(tmp_path / "run"), "--simulator", "vacask"], capsys)
    assert code == 0, err
    assert read_raw(tmp_path / "run/op1.raw")[0]["v1:flow(br)"][0] == pytest.approx(-2e-3, rel=1e-9)


def test_binary_input_is_refused_before_ngspice_runs(tmp_path, capsys):
    cir = tmp_path / "ls.cir"
    cir.write_bytes(Path("/bin/ls").read_bytes()[:4096])
    code, _, err = simulate([str(cir), "-o", str(tmp_path / "run")], capsys)
    assert code == 2 and str(cir) in err and "binary data" in err and "fix:" in err
    assert not (tmp_path / "run").exists()


def test_a_latin1_comment_is_text(tmp_path, capsys):
    cir = tmp_path / "latin.cir"
    cir.write_bytes("* Widerstandsteiler f\xfcr 3 V\nV1 a 0 3\nR1 a b 1k\nR2 b 0 2k\n.op\n.end\n".encode("latin-1"))
    code, _, err = simulate([str(cir), "-o", str(tmp_path / "run")], capsys)
    assert code == 0, err
    assert read_raw(tmp_path / "run/latin.raw")[0]["b"][0] == pytest.approx(2.0, rel=1e-9)


@pytest.mark.parametrize("version", sorted(NGSPICE))
@pytest.mark.parametrize(
    "body, says",
    [
        ("V1 a 0 1\nD1 a 0 nosuchmodel\n.op\n", "nosuchmodel"),
        ("V1 a 0 1\nR1 a 0 1k\n.include nothere.lib\n.op\n", "nothere.lib"),
        ("V1 a 0 1\nR1 a 0 1k\n.foo bar\n.op\n", ".foo bar"),
        ("V1 a 0 1\nB1 b 0 V=v(a)*+*\nR1 b 0 1k\n.op\n", "syntax error"),
        ("V1 a 0 1\nR1 a 0 1k\n.control\nop\nfrobnicate 3\n.endc\n", "frobnicate"),
        ("V1 a 0 1\nR1 a 0 1k\n", "no analysis"),
    ],
    ids=["unknown model", "missing include", "unknown card", "bad expression", "bad command", "no analysis"],
)
def test_a_netlist_ngspice_rejects_is_exit_1_with_its_message(body, says, version, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE[version])
    cir = tmp_path / "bad.cir"
    cir.write_text(f"* a bad netlist\n{body}.end\n")
    code, _, err = simulate([str(cir), "-o", str(tmp_path / "run")], capsys)
    assert code == 1 and says in err and "reproduce with:" in err and "Traceback" not in err, err


def test_a_hanging_ngspice_is_stopped_by_the_wall_clock_limit(tmp_path, capsys):
    """A .control loop that never ends prints nothing: the timer, not the output, stops it."""
    cir = tmp_path / "hang.cir"
    cir.write_text(
        "* never ends\nV1 a 0 1\nR1 a 0 1k\n.control\nlet i = 0\nwhile i < 1\n  let j = 1\nend\n.endc\n.end\n"
    )
    start = time.perf_counter()
    code, _, err = simulate([str(cir), "-o", str(tmp_path / "run"), "--timeout", "1.5"], capsys)
    assert code == 1 and "did not finish within 1.5 s" in err
    assert time.perf_counter() - start < 10
    assert not [p for p in Path("/proc").glob("[0-9]*/cmdline") if str(cir).encode() in safe_read(p)]


def safe_read(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError:
        return b""


@pytest.fixture(scope="module")
def real_raw(tmp_path_factory) -> bytes:
    """A binary raw file of a short transient (ngspice)."""
    out = tmp_path_factory.mktemp("raw")
    run_ngspice("* rc\nV1 a 0 PULSE(0 1 0 1u 1u 1m 2m)\nR1 a b 1k\nC1 b 0 1n\n.tran 1u 20u\n.end\n", out, "rc")
    return (out / "rc.raw").read_bytes()


def test_a_garbage_or_truncated_raw_file_is_a_simulation_error(real_raw, tmp_path):
    raw = tmp_path / "x.raw"
    raw.write_bytes(real_raw)
    assert len(read_raw(raw)[0]["time"]) > 10  # the whole file reads
    header = real_raw.index(b"Binary:\n") + len(b"Binary:\n")
    cuts = [10, header - 30, header - 1, header + 8, (header + len(real_raw)) // 2, len(real_raw) - 3]
    garbage = [
        os.urandom(5000),
        b"Title: x\nNo. Variables: 2\nNo. Points: 9\nVariables:\n",
        b"\x00" * 100,
        real_raw.replace(b"No. Points: ", b"No. Points: 9999999"),
        real_raw.replace(b"No. Variables: ", b"No. Variables: 7"),
    ]
    for k, data in enumerate([real_raw[:c] for c in cuts] + garbage):
        raw.write_bytes(data)
        try:
            plots = read_raw(raw)
        except SimulationError as exc:
            assert str(raw) in str(exc)
            continue
        assert plots == [], k  # nothing at all: the callers refuse an empty file


# ----------------------------------------------------------------------------- output folders


@pytest.fixture(scope="module")
def build_refs(tmp_path_factory):
    """The two build variants of bench/interrupts.py, each run once to the end: their file sets."""
    work = tmp_path_factory.mktemp("build_refs")
    old, new = bench.build_variants(work)
    refs = {}
    for key, argv in (("old", old), ("new", new)):
        assert cli.main(argv + ["-o", str(work / key)]) == 0
        refs[key] = bench.files(work / key)
    return work, old, new, refs


def test_the_classifier_sees_mixed_stale_and_partial_folders(build_refs, tmp_path):
    bench.selfcheck("build", tmp_path, build_refs[3])


def test_interrupted_builds_leave_the_old_or_the_new_complete_set(build_refs):
    """SIGTERM and SIGINT at random points of a build into a folder holding another build's
    set (and a user's file): each time the complete old or new set, nothing else."""
    work, old, new, refs = build_refs
    rng = random.Random(17)
    for k, sig in enumerate([signal.SIGTERM, signal.SIGTERM, signal.SIGINT, signal.SIGTERM]):
        r = bench.interrupted("build", work, old, new, refs, sig, rng.uniform(0.3, 4.0), k + 1)
        assert not any(r[key] for key in ("mixed", "stale", "partial", "traceback", "other_exit")), r


def test_two_builds_into_one_folder_at_once_leave_one_complete_set(build_refs):
    work, old, new, refs = build_refs
    r = bench.concurrent("build", work, old, new, refs, 10)
    assert not any(r[key] for key in ("mixed", "stale", "partial", "traceback", "other_exit")), r


def test_a_build_replaces_its_own_earlier_files_and_keeps_the_users(build_refs, tmp_path):
    """The old set (--format all, PNGs) then the new (--format ngspice --no-plots): the old .va,
    _xspice.lib and PNGs go, the user's own files stay, the manifest names the new set."""
    _, old, new, refs = build_refs
    out = tmp_path / "out"
    assert cli.main(old + ["-o", str(out)]) == 0
    (out / "piston_notes.txt").write_text("mine\n")
    (out / "other_model.lib").write_text("* mine too\n")
    assert cli.main(new + ["-o", str(out)]) == 0
    assert bench.files(out) == refs["new"] | {"piston_notes.txt": b"mine\n", "other_model.lib": b"* mine too\n"}
    assert check_manifest(out, "piston") == []


def test_outputs_have_the_umask_mode(tmp_path):
    old = os.umask(0o027)
    try:
        assert cli.main(["build", PISTON, "-o", str(tmp_path / "out"), "-q"]) == 0
    finally:
        os.umask(old)
    modes = {p.name: p.stat().st_mode & 0o777 for p in (tmp_path / "out").iterdir()}
    assert modes and set(modes.values()) == {0o640}, modes


def test_a_dead_runs_staging_folder_is_removed_and_a_live_ones_kept(tmp_path):
    dead, live = tmp_path / ".netgen-staging-piston-dead", tmp_path / ".netgen-staging-piston-live"
    dead.mkdir()
    (dead / "piston.lib").write_text("half")
    live.mkdir()
    fd = os.open(live, os.O_RDONLY)
    fcntl.flock(fd, fcntl.LOCK_EX)  # as the run that owns it does
    try:
        with OutputFolder(tmp_path, "piston") as out:
            (out.stage / "piston.lib").write_text("new\n")
            out.commit()
        assert not dead.exists() and live.exists()
        assert (tmp_path / "piston.lib").read_text() == "new\n"
    finally:
        os.close(fd)


# ----------------------------------------------------------------------------- sigma-delta folders


@pytest.fixture(scope="module")
def sd_refs(tmp_path_factory):
    """The two sigma-delta variants of bench/interrupts.py (64 and 128 periods of the compiled loop)."""
    work = tmp_path_factory.mktemp("sd_refs")
    old, new = bench.sigma_delta_variants(work)
    refs = {}
    for key, argv in (("old", old), ("new", new)):
        assert cli.main(argv + ["-o", str(work / key)]) == 0
        refs[key] = bench.files(work / key)
    return work, old, new, refs


@pytest.mark.slow
def test_interrupted_and_concurrent_sigma_delta_runs_leave_one_complete_set(sd_refs):
    work, old, new, refs = sd_refs
    bench.selfcheck("sigma-delta", work, refs)
    rng = random.Random(5)
    for k, sig in enumerate([signal.SIGTERM, signal.SIGINT]):
        r = bench.interrupted("sigma-delta", work, old, new, refs, sig, rng.uniform(2.0, 6.0), k + 1)
        assert not any(r[key] for key in ("mixed", "stale", "partial", "traceback", "other_exit")), r
    r = bench.concurrent("sigma-delta", work, old, new, refs, 3)
    assert not any(r[key] for key in ("mixed", "stale", "partial", "traceback", "other_exit")), r


@pytest.mark.slow
def test_a_failed_sigma_delta_run_keeps_its_files_apart_from_the_last_results(sd_refs, tmp_path, capsys):
    """ngspice stopped by the wall-clock limit: exit 1; the folder still holds the last complete
    run (its manifest agrees), the failed run's netlist and log are in sigma-delta.failed/ where
    the message points; the next good run removes that folder."""
    _, old, new, refs = sd_refs
    out, user = bench.prepared(tmp_path, refs, 1)
    assert cli.main(new + ["-o", str(out), "--timeout", "0.01"]) == 1  # ngspice needs more to start
    err = capsys.readouterr().err
    failed = out / "sigma-delta.failed"
    assert "did not finish within 0.01 s" in err and f"cd {failed}" in err and "last complete results" in err
    assert bench.classify("sigma-delta", out, refs, user) == {"mixed": False, "stale": False, "partial": False}
    assert bench.files(out) == refs["old"] and check_manifest(out, "sigma-delta") == []
    assert (failed / "sigma_delta.cir").is_file() and "did not finish" in (failed / "FAILED.txt").read_text()
    assert cli.main(new + ["-o", str(out)]) == 0
    assert not failed.exists() and check_manifest(out, "sigma-delta") == []
    assert np.load(out / "bitstreams.npz")["time"].size == 128


def test_two_runs_staging_at_once_share_a_cache_folder_and_commit_in_turn(tmp_path):
    """Interleaved by hand: run A makes the shared osdi/ and fails, run B (staging meanwhile)
    keeps using it and commits; the folder is B's set, no staging folder is left."""
    a = OutputFolder(tmp_path / "out", "sigma-delta", keep_failed=False, shared=("osdi",)).__enter__()
    b = OutputFolder(tmp_path / "out", "sigma-delta", shared=("osdi",)).__enter__()
    (a.stage / "summary.json").write_text("A\n")
    (b.stage / "osdi" / "model.osdi").write_text("compiled by B\n")
    (b.stage / "summary.json").write_text("B\n")
    a.__exit__(RuntimeError, RuntimeError("A failed"), None)
    assert (tmp_path / "out/osdi").is_dir()  # B is still staging: its cache stays
    b.commit()
    b.__exit__(None, None, None)
    assert (tmp_path / "out/summary.json").read_text() == "B\n"
    assert (tmp_path / "out/osdi/model.osdi").read_text() == "compiled by B\n"
    assert check_manifest(tmp_path / "out", "sigma-delta") == [] and bench.leftovers(tmp_path / "out") == []
