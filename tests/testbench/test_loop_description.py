"""The loop description (netgen.testbench.sigma_delta.loopfile, loop.design): every structure
example runs `netgen sigma-delta` or exits 2 with its reason, and bad loop files (wrong types,
unknown keys, unknown channels and electrodes, impossible feedback, out-of-range values, hostile
strings) exit 2 with a message naming the file and the key, never a traceback and never output."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from netgen.cli import commands as cli
from netgen.testbench.sigma_delta import loopfile
from tests.fixtures import ROOT

EXAMPLES = sorted((ROOT / "examples").glob("*.toml"))
# what each example does under `netgen sigma-delta` (hand-written: the devices' electrodes)
EXPECTED = {
    "levitated_disk": (0, None),
    "accelerometer_z": (0, None),
    "cantilever_fb": (0, None),
    # one electrode below: the feedback only pulls towards -z / -m1
    "piston": (2, "one-sided"),
    "cantilever": (2, "one-sided"),
    "cc_beam": (2, "one-sided"),
    # x, y on combs and z on plates above and below, each channel on its own electrodes ([loop])
    "accelerometer_xyz": (0, None),
    "sweep_ts": (2, "conductor"),  # a sweep file, not a structure
    "calibrated_disk": (0, None),  # the disk with calibrated couplings
}


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_every_structure_example_runs_the_loop_or_says_why_not(path, tmp_path, capsys):
    """64 periods in the compiled loop; a device whose electrodes cannot close the loop exits 2
    naming the reason before any output."""
    out = tmp_path / "sd"
    code = cli.main(["sigma-delta", str(path), "--simulator", "ngspice-xspice", "--cycles", "64", "-o", str(out), "-q"])
    err = capsys.readouterr().err
    want, reason = EXPECTED.get(path.stem, (None, "fix:"))  # an example added since: runs, or says why not
    assert "Traceback" not in err
    assert code == want if want is not None else code in (0, 2), err
    if code == 0:
        s = json.loads((out / "summary.json").read_text())
        assert s["levitation"]["held"] and s["channels"]
    else:
        assert reason in err and path.name in err and "fix:" in err
        assert not (out / "summary.json").exists()


@pytest.fixture(scope="module")
def accelerometer(tmp_path_factory) -> Path:
    """The accelerometer's model JSON (built once; the bad files are checked against it)."""
    out = tmp_path_factory.mktemp("acc_model")
    assert cli.main(["build", str(ROOT / "examples" / "accelerometer_z.toml"), "-o", str(out), "-q"]) == 0
    return out / "accelerometer_z.json"


# (the [loop] table's text, the key the message must name); each is also given inside [loop.x] etc.
BAD = [
    ('[loop]\nchannels = "z"', "loop.channels"),
    ("[loop]\nchannels = []", "loop.channels"),
    ("[loop]\nchannels = [1]", "loop.channels[0]"),
    ('[loop]\nchannels = ["z", "z"]', "loop.channels"),
    ('[loop]\nchannels = ["tilt_x"]', "loop.channels[0]"),
    ('[loop]\nchannels = ["zz"]', "loop.channels[0]"),
    ('[loop]\nchannels = ["a", "b", "c", "d", "e", "f", "g"]', "loop.channels"),
    ('[loop]\nchannels = ["z\\u202e"]', "loop.channels[0]"),
    ('[loop]\nchannels = ["z; rm -rf"]', "loop.channels[0]"),
    ('[loop]\nchannels = ["z\\n.include /etc/passwd"]', "loop.channels[0]"),
    ('[loop]\nchanels = ["z"]', "loop.chanels"),
    ('[loop]\nfeedback_voltage = "5 A"', "loop.feedback_voltage"),
    ("[loop]\nfeedback_voltage = -3", "loop.feedback_voltage"),
    ("[loop]\nfeedback_voltage = 0", "loop.feedback_voltage"),
    ("[loop]\nfeedback_voltage = true", "loop.feedback_voltage"),
    ('[loop]\nfeedback_voltage = "nan V"', "loop.feedback_voltage"),
    ("[loop]\nfeedback_voltage = 1e9", "loop.feedback_voltage"),
    ('[loop]\nfeedback_voltage = "0.05 V"', "loop.feedback_voltage"),  # cannot carry gravity
    ("[loop]\nsense_ratio = 0", "loop.sense_ratio"),
    ('[loop]\nsense_ratio = "a"', "loop.sense_ratio"),
    ("[loop]\nfull_scale = 2", "loop.full_scale"),
    ("[loop]\ndensity = 1.5", "loop.density"),
    ("[loop]\ndensity = 0", "loop.density"),
    ("[loop]\ndither = -0.1", "loop.dither"),
    ("[loop]\ndither = [0.1]", "loop.dither"),
    ("[loop]\nreltol = 0.5", "loop.reltol"),
    ('[loop]\nreadout = "opamp"', "loop.readout"),
    ("[loop]\nfilter = 3", "loop.filter"),
    ('[loop.filter]\nkind = "cifb9"', "loop.filter.kind"),
    ('[loop.filter]\nkind = "lead2"\nlead = "x"', "loop.filter.lead"),
    ("[loop.filter]\nlead = 11", "loop.filter.lead"),
    ("[loop.filter]\nlead = 0.8\nzero = 1", "loop.filter.zero"),
    ("[loop.timing]\ncur = 0.1", "loop.timing.cur"),
    ("[loop.timing]\nfb_off = 1.2", "loop.timing.fb_off"),
    ("[loop.timing]\nedge = 0.5", "loop.timing.edge"),
    ("[loop.timing]\nlatch = 0.3", "loop.timing.latch"),
    ('[loop.timing]\nclk = "0.4"', "loop.timing.clk"),
    ('[loop]\ntiming = "fast"', "loop.timing"),
    ('[loop.input]\nacceleration = "9.81 N"', "loop.input.acceleration"),
    ('[loop.input]\nacceleration = "1e9 m/s^2"', "loop.input.acceleration"),
    (
        "[loop]\nfeedback_voltage = 1.381\n[loop.input]\nacceleration = 300",
        "loop.feedback_voltage",
    ),  # beyond full scale
    ("[loop]\nfeedback_voltage = 1.381\n[loop.input]\nacceleration = -300", "loop.feedback_voltage"),
    ('[loop.input]\ntone = { amplitude = "2 m/s^2" }', "loop.input.tone.frequency"),
    ('[loop.input]\ntone = { frequency = "1 kHz" }', "loop.input.tone.amplitude"),
    ('[loop.input]\ntone = { amplitude = 1, frequency = "600 kHz" }', "loop.input.tone.frequency"),  # > f_s/2
    ('[loop.input]\nforce = { coordinate = "z", amplitude = 0.02, frequency = 5e5 }', "loop.input.force.frequency"),
    ("[loop.input]\ntone = { amplitude = -2, frequency = 1000 }", "loop.input.tone.amplitude"),
    ("[loop.input]\ntone = { amplitude = 2, frequency = 1000, phase = 1 }", "loop.input.tone.phase"),
    ("[loop.input]\nacceleration = 9.81\ntone = { amplitude = 15, frequency = 1000 }", "loop.input"),  # DC + tone > FS
    ('[loop.input]\ngravity = "yes"', "loop.input.gravity"),
    ("[loop.input]\ngravity = true\nacceleration = 1", "loop.input.gravity"),
    ('[loop.input]\nforce = { coordinate = "q", dc = 0.1 }', "loop.input.force.coordinate"),
    ("[loop.input]\nforce = { dc = 0.1 }", "loop.input.force.coordinate"),
    ('[loop.input]\nforce = { coordinate = "z", amplitude = 0.1 }', "loop.input.force.frequency"),
    ('[loop.input]\nforce = { coordinate = "z", dc = 0.1 }\nacceleration = 1', "loop.input.force"),
    ('[loop.input]\nforce = { coordinate = "z", dc = 1e6 }', "loop.input"),
    ("[loop.input]\nforce = []", "loop.input.force"),
    ("[loop.input]\nforce = [1]", "loop.input.force[0]"),
    (
        '[loop.input]\nforce = [{ coordinate = "z", dc = 0.1 }, { coordinate = "z", dc = 0.2 }]',
        "loop.input.force[1].coordinate",
    ),
    (
        '[loop.input]\nforce = [{ coordinate = "z", dc = 0.1 }, { coordinate = "q", dc = 0.1 }]',
        "loop.input.force.coordinate",
    ),
    ('[loop.input]\nforce = [{ coordinate = "z", dc = 0.1 }, { dc = 0.1 }]', "loop.input.force[1].coordinate"),
    ("[loop.input]\nwind = 1", "loop.input.wind"),
    ("[loop]\ninput = 9.81", "loop.input"),
    ("[loop.channels.z]\nsense = { top = 1, middle = -1 }", "loop.channels.z.sense.middle"),
    ("[loop.channels.z]\nfeedback = { top = 2, bottom = -1 }", "loop.channels.z.feedback.top"),
    ("[loop.channels.z]\nfeedback = { top = true }", "loop.channels.z.feedback.top"),
    ("[loop.channels.z]\nsense = { top = 0 }", "loop.channels.z.sense.top"),
    ("[loop.channels.z]\nsense = { top = -1, bottom = 1 }", "loop.channels.z.sense"),  # reads -z
    ("[loop.channels.z]\nfeedback = { top = -1, bottom = 1 }", "loop.channels.z.feedback"),  # pushes -z on 1
    ("[loop.channels.z]\nsense = {}", "loop.channels.z.sense"),
    ("[loop.channels.z]\ngain = 2", "loop.channels.z.gain"),
    ('[loop.channels.z]\nfilter = { kind = "lead2", lead = [1] }', "loop.channels.z.filter.lead"),
    ("[loop.channels.tilt_y]\nsense = { top = 1 }", "loop.channels.tilt_y"),
    ("[loop]\nchannels = { z = 1 }", "loop.channels.z"),
    ("loop = 5", "loop"),
    ('[loop]\n"top\\u0007" = 1', "loop.top"),
    ('[loop]\nchannels = ["z"\n', "TOML syntax"),
    ("[other]\nx = 1", "other"),
]


@pytest.mark.parametrize("text,key", BAD, ids=[f"{k}-{i}" for i, (_, k) in enumerate(BAD)])
def test_a_bad_loop_file_exits_2_naming_the_file_and_the_key(text, key, accelerometer, tmp_path, capsys):
    """--loop BAD.toml against the accelerometer's model: exit 2 before any output, the message
    names the loop file and the key (and a fix), no traceback."""
    bad = tmp_path / "bad_loop.toml"
    bad.write_text(text + "\n", encoding="utf-8")
    out = tmp_path / "sd"
    code = cli.main(
        [
            "sigma-delta",
            str(ROOT / "examples" / "accelerometer_z.toml"),
            "--model",
            str(accelerometer),
            "--loop",
            str(bad),
            "--cycles",
            "64",
            "-o",
            str(out),
            "-q",
        ]
    )
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err and str(bad) in err and key in err and "fix:" in err, err
    assert not out.exists() or not any(out.iterdir())


def test_there_are_at_least_50_bad_loop_files():
    assert len(BAD) >= 50


def test_a_loop_file_parses_into_its_spec(tmp_path):
    """The documented keys land in the LoopSpec as SI numbers (units read, defaults None)."""
    p = tmp_path / "loop.toml"
    p.write_text(
        '[loop]\nchannels = ["z"]\nfeedback_voltage = "1500 mV"\ndensity = 0.4\n'
        '[loop.filter]\nkind = "lead2"\nlead = 0.75\n[loop.timing]\ncur = 0.27\n'
        '[loop.input]\nacceleration = "0.5 g"\ntone = { amplitude = "2 m/s^2", frequency = "1 kHz" }\n'
    )
    spec = loopfile.read_loop_file(p)
    assert [c.name for c in spec.channels] == ["z"] and spec.settings.feedback_voltage == pytest.approx(1.5)
    assert (
        spec.settings.density == 0.4
        and spec.settings.sense_ratio is None
        and spec.filter == {"kind": "lead2", "lead": 0.75}
    )
    assert spec.timing == {"cur": 0.27} and spec.input.dc == {"a_in": pytest.approx(0.5 * 9.81)}
    assert (spec.input.tone.coord, spec.input.tone.amplitude, spec.input.tone.freq) == ("a_in", 2.0, 1000.0)


def test_a_force_list_gives_each_coordinate_its_dc_and_one_tone(tmp_path):
    """force = [...]: one DC force per coordinate in its port unit (gravity's weight on z beside a
    small torque on a tilt), the tone on the one that has it; two tones are refused."""
    p = tmp_path / "loop.toml"
    p.write_text(
        '[loop.input]\nforce = [{ coordinate = "z", dc = -0.16 }, '
        '{ coordinate = "tilt_x", dc = 1e-4, amplitude = 2e-3, frequency = "2 kHz" }]\n'
    )
    spec = loopfile.read_loop_file(p)
    assert spec.input.dc == {"f_z": -0.16, "f_tilt_x": 1e-4} and not spec.input.default
    assert (spec.input.tone.coord, spec.input.tone.amplitude, spec.input.tone.freq) == ("tilt_x", 2e-3, 2000.0)
    p.write_text(
        '[loop.input]\nforce = [{ coordinate = "z", amplitude = 1, frequency = 1e3 }, '
        '{ coordinate = "tilt_x", amplitude = 1, frequency = 2e3 }]\n'
    )
    with pytest.raises(Exception) as err:
        loopfile.read_loop_file(p)
    assert "loop.input.force" in str(err.value) and "one" in str(err.value)


# (structure example, extra arguments, the flag the message names, the text of its fix)
HOSTILE = [
    ("accelerometer_z", ["--pressure", "100 Pa"], "--pressure", "drop --pressure"),
    ("cantilever_fb", ["--pressure", "100 Pa"], "--pressure", "drop --pressure"),
    ("accelerometer_xyz", ["--pressure", "100 Pa", "--film", "compressible"], "--film", "drop --film"),
    ("accelerometer_z", ["--film", "incompressible"], "--film", "drop --film"),
    ("levitated_disk", ["--ts", "1e-300"], "--ts", "e.g. --ts 1e-6"),
    ("levitated_disk", ["--tone", "z:1_0:1000"], "--tone", "e.g. --tone z:0.02:1000"),
    ("levitated_disk", ["--tone", "z:inf:1000"], "--tone", "e.g. --tone z:0.02:1000"),
    ("levitated_disk", ["--tone", "z:1e30:1000"], "--tone", "(0, 1e+12]"),
    ("levitated_disk", ["--tone", "z:0.02:5e5"], "--tone", "f_s/2"),
    ("levitated_disk", ["--cycles", "1_000"], "--cycles", "e.g. --cycles 4096"),
]


@pytest.mark.parametrize("example, extra, flag, fix", HOSTILE, ids=[f"{e} {' '.join(x)}" for e, x, _, _ in HOSTILE])
def test_a_flag_gets_the_check_of_its_file_key(example, extra, flag, fix, tmp_path, capsys):
    """The structure file refuses squeeze_film on a suspended device and the compressible film on a
    proof mass: --pressure / --film on them are refused alike (exit 2, before any model is built),
    as are the values the file keys refuse (a period below 1 ns, tone numbers with underscores,
    non-finite or out of range, a tone at f_s/2)."""
    out = tmp_path / "sd"
    argv = ["sigma-delta", str(ROOT / "examples" / f"{example}.toml"), "-o", str(out), "--cycles", "64", *extra]
    try:
        code = cli.main(argv)
    except SystemExit as exc:  # argparse's own exit 2
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and flag in err and fix in err and "Traceback" not in err, err
    assert not out.exists()
