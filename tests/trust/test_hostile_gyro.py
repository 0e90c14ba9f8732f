"""Property-based hostile input for `netgen gyro` (netgen.testbench.gyro), run in process through
the command line: the gyroscope example with one of its preconditions broken (no w_z rate port,
no drive or sense coordinate, the sense loop on another coordinate), a drive amplitude beyond the
model's sampled travel of x, a rate beyond the full scale, or an option outside its declared
range (rates, spans, points, gain, amplitude, period, cycles). The promise: exit 2 before any
simulation, the message naming the file (or, for a command-line value, the flag), the key and a
fix, no traceback, and no result set in the output folder. Seeded (derandomize, as
tests/trust/test_hostile_inputs.py): every CI run draws the same 50 cases; the counts print at the
end (tests/trust/conftest.py)."""

from __future__ import annotations

import zlib
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from netgen.cli import commands as cli
from tests.fixtures import ROOT
from tests.trust.conftest import COUNTS
from tests.trust.test_hostile_inputs import SETTINGS

EXAMPLE = ROOT / "examples" / "gyroscope_z.toml"
TEXT = EXAMPLE.read_text()
INERTIAL = 'inertial = ["a_x", "a_y", "w_z"]'
RIGID = 'rigid = ["x", "y"]'
CHANNEL = "[loop.channels.y]"
TRAVEL_UM = 6.0  # the example's [sampling] range 0.3 of the comb's 20 um overlap
FULL_SCALE_DEG_S = 2767.35  # F_fb / (2 m X_d w_d) at 4 um (docs/gyroscope.md)

# (replaced text, its replacement, the keys the refusal may name)
STRUCTURE = st.one_of(
    st.sampled_from([[], ["a_x"], ["a_y"], ["a_x", "a_y"], ["a_y", "a_x"]]).map(
        lambda ports: (INERTIAL, "inertial = [" + ", ".join(f'"{p}"' for p in ports) + "]", ("coordinates.inertial",))
    ),
    st.sampled_from(["x", "z", "w_z", "a_y"]).map(lambda c: (CHANNEL, f"[loop.channels.{c}]", ("loop.channels",))),
    st.sampled_from(['rigid = ["x"]', 'rigid = ["y"]']).map(
        lambda r: (RIGID, r, ("coordinates.rigid", "loop.channels", "conductor.flexure.k_xy"))
    ),
)
# (flag, value): each outside the option's declared range or not a number of its kind
OPTION = st.one_of(
    st.tuples(st.just("--rate-span"), st.sampled_from(["0", "-0.5", "1.5", "1e3", "nan", "inf", "half"])),
    st.tuples(st.just("--rate-points"), st.sampled_from(["1", "2", "42", "-3", "2.5", "many"])),
    st.tuples(st.just("--rate"), st.sampled_from(["2e5", "-1e6", "nan", "inf", "fast"])),
    st.tuples(st.just("--agc-gain"), st.sampled_from(["0", "-1", "1e5", "nan"])),
    st.tuples(st.just("--drive-amplitude"), st.sampled_from(["0 um", "-4 um", "1 m", "4 furlong", "4"])),
    st.tuples(st.just("--ts"), st.sampled_from(["0", "-1e-6", "nan", "1 s"])),
    st.tuples(st.just("--cycles"), st.sampled_from(["0", "-5", "1.5", "1e40"])),
    st.tuples(st.just("--simulator"), st.sampled_from(["xyce", "osdi", "spice"])),
)
CASES = st.one_of(
    STRUCTURE.map(lambda c: ("structure", c)),
    st.floats(1.01, 16.0).map(lambda f: ("drive", ("--drive-amplitude", f"{f * TRAVEL_UM:.4g} um"))),
    st.tuples(st.floats(1.01, 30.0), st.sampled_from([1, -1])).map(
        lambda c: ("rate", ("--rate", f"{c[1] * c[0] * FULL_SCALE_DEG_S:.6g}"))
    ),
    OPTION.map(lambda c: ("option", c)),
)


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    """One output folder for every case: each is refused, so only the model cache stays in it."""
    return tmp_path_factory.mktemp("gyro_hostile")


def run_case(kind: str, case: tuple, folder: Path, capsys) -> tuple[int, str, str]:
    """The command line of one case, in process: (exit code, stderr, the structure file's path)."""
    path = EXAMPLE
    args: list[str] = ["--cycles", "64"]
    if kind == "structure":
        old, new, _ = case
        assert old in TEXT
        path = folder / f"g_{zlib.crc32(new.encode())}.toml"
        path.write_text(TEXT.replace(old, new))
    else:
        # --flag=VALUE: a value starting with '-' reaches the option's own check
        args = (["--cycles", "64"] if case[0] != "--cycles" else []) + [f"{case[0]}={case[1]}"]
    try:
        code = cli.main(["gyro", str(path), "-o", str(folder / "out"), "-q", *args])
    except SystemExit as exc:  # argparse's refusal of a value
        code = int(exc.code or 0)
    return code, capsys.readouterr().err, str(path)


@settings(max_examples=50, **SETTINGS)
@given(CASES)
def test_bad_gyro_descriptions_exit_2(folder, capsys, case):
    """Exit 2 naming the file (a structure case) or the flag (a command-line value), the key and
    a fix; no traceback and no summary.json."""
    kind, c = case
    code, err, path = run_case(kind, c, folder, capsys)
    assert code == 2, (case, err)
    assert "Traceback" not in err, err
    assert not (folder / "out" / "summary.json").exists()
    if kind == "option":
        # argparse's refusal (the range and an example, or the choices), or the loop design's
        # (a value in range that the loop cannot hold: the file, its key and the fix naming the flag)
        assert c[0] in err and any(s in err for s in ("e.g.", "choose from", "fix:")), err
    else:
        keys = c[2] if kind == "structure" else (c[0],)
        assert path in err and any(k in err for k in keys) and "fix:" in err, err
    COUNTS[(f"gyro {kind}", "refused")] += 1
