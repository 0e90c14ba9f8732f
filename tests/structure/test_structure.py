"""Structure files: the reference example loads; every kind of mistake is named with its fix."""

import math
import subprocess
import sys

import pytest

from netgen.structure import StructureError, load_structure, parse_structure
from tests.fixtures import ROOT

EXAMPLE = ROOT / "examples" / "levitated_disk.toml"


def test_reference_example_matches_the_paper():
    s = load_structure(EXAMPLE)
    assert s.conductor.radius == pytest.approx(473e-6)
    assert s.conductor.youngs_modulus == pytest.approx(160e9)
    assert s.sampling.levels ** (len(s.coordinates.rigid) + len(s.coordinates.modes)) == 2187
    assert s.sampling.range == 0.2
    names = s.electrode_names()
    assert len(names) == 16 and len(set(names)) == 16
    assert {e.side for e in s.electrode_sets} == {"above", "below"}


def _replace(old: str, new: str) -> str:
    text = EXAMPLE.read_text()
    assert old in text, old
    return text.replace(old, new, 1)


BAD = [
    # (edit, expected words in the message, expected line or None)
    (('radius = "473 um"', 'radius = "-473 um"'), ["conductor.radius", "greater than zero"], True),
    (('thickness = "10 um"', "thickness = 0"), ["conductor.thickness", "greater than zero"], True),
    (("poisson_ratio = 0.22", "poisson_ratio = 0.7"), ["poisson_ratio", "(-1, 0.5)"], True),
    (('radius = "473 um"', 'radius = "473 uF"'), ["radius", "not a length unit"], True),
    (('radius = "473 um"', 'radus = "473 um"'), ["unknown key 'radus'", "did you mean 'radius'"], True),
    (('gap = "3 um"', 'gap = "-3 um"'), ["electrodes[0].gap", "greater than zero"], True),
    (('side = "above"', 'side = "abve"'), ["side", "did you mean 'above'"], True),
    (
        ('[["20 um", "230 um"], ["240 um", "473 um"]]', '[["20 um", "250 um"], ["240 um", "473 um"]]'),
        ["overlaps"],
        None,
    ),
    (
        ('[["20 um", "230 um"], ["240 um", "473 um"]]', '[["20 um", "230 um"], ["500 um", "600 um"]]'),
        ["outside the plate"],
        None,
    ),
    (("range = 0.2", "range = 1.0"), ["sampling.range", "touch"], None),
    (('modes = ["2,0c", "2,0s", "3,0c", "3,0s"]', 'modes = ["2,0"]'), ["mode label"], None),
    (('rigid = ["z", "tilt_x", "tilt_y"]', 'rigid = ["z", "tilt_xx"]'), ["did you mean 'tilt_x'"], None),
    (("degree = 1", 'degree = "two"'), ["fit.degree", "integer"], None),
    (('name = "levitated_disk"', 'name = "levitated disk"'), ["name", "identifier"], None),
    (("[conductor]", "[conductor"), ["TOML syntax"], None),
    (('slot = "10 um"', 'slot = "900 um"'), ["slot"], None),
    # a dielectric layer on the electrodes (netgen.structure.electrodes.read_dielectric)
    (
        ('gap = "3 um"', 'gap = "3 um"\ndielectric_thickness = "0.2 um"'),
        ["electrodes[0].dielectric_permittivity", "needs both"],
        None,
    ),
    (
        ('gap = "3 um"', 'gap = "3 um"\ndielectric_permittivity = 7.5'),
        ["electrodes[0].dielectric_thickness", "needs both"],
        None,
    ),
    (
        ('gap = "3 um"', 'gap = "3 um"\ndielectric_thickness = "3 um"\ndielectric_permittivity = 7.5'),
        ["electrodes[0].dielectric_thickness", "fills the gap", "below the gap"],
        None,
    ),
    (
        ('gap = "3 um"', 'gap = "3 um"\ndielectric_thickness = "-1 um"\ndielectric_permittivity = 7.5'),
        ["electrodes[0].dielectric_thickness", "must not be negative"],
        None,
    ),
    (
        ('gap = "3 um"', 'gap = "3 um"\ndielectric_thickness = "0.2 um"\ndielectric_permittivity = 0.5'),
        ["electrodes[0].dielectric_permittivity", ">= 1"],
        None,
    ),
]


def test_dielectric_layer_is_refused_by_the_field_solvers():
    """A layer on the electrodes with extractor = "bem": refused at the layer's key (the dense BEM
    does not model it: docs/bem.md), not built as if it were absent."""
    text = (ROOT / "examples" / "piston.toml").read_text()
    text = text.replace(
        'gap = "2 um"\n', 'gap = "2 um"\ndielectric_thickness = "0.2 um"\ndielectric_permittivity = 7.5\n'
    )
    text = text.replace("[electrostatics]\n", '[electrostatics]\nextractor = "bem"\n')
    with pytest.raises(StructureError) as info:
        parse_structure(text, "bad.toml")
    message = str(info.value)
    assert message.startswith("bad.toml") and "fix:" in message
    assert "electrodes[0].dielectric_thickness" in message and "parallel_plate" in message
    assert info.value.line == text.splitlines().index('dielectric_thickness = "0.2 um"') + 1


@pytest.mark.parametrize("edit,words,line", BAD)
def test_bad_input_names_file_key_and_fix(edit, words, line):
    with pytest.raises(StructureError) as info:
        parse_structure(_replace(*edit), "bad.toml")
    message = str(info.value)
    assert message.startswith("bad.toml")
    assert "fix:" in message
    for w in words:
        assert w in message, message
    if line:  # the reported line is the one holding the edited text
        text = _replace(*edit).splitlines()
        expected = next(no for no, t in enumerate(text, 1) if edit[1].split(" =")[0] in t and edit[1] in t)
        assert info.value.line == expected, message


DOTTED = [
    # (example, edit, the line written with the bad key, expected words): each edit puts a bad key
    # inside a dotted table header
    (
        "accelerometer_xyz.toml",
        ('thigh_width = "2 um"', 'thigh_widht = "2 um"'),
        'thigh_widht = "2 um"',
        ["conductor.flexure.thigh_widht", "did you mean 'thigh_width'"],
    ),
    (
        "accelerometer_xyz.toml",
        ('width = "2 um"\nthigh', 'width = "-2 um"\nthigh'),
        'width = "-2 um"',
        ["conductor.flexure.width", "greater than zero"],
    ),
    (
        "levitated_disk.toml",
        ("[fem]", 'extractor = "bem"\n\n[electrostatics.bem]\ntolerance = 0.01\nlevels = 9\n\n[fem]'),
        "levels = 9",
        ["electrostatics.bem.levels", "2..6"],
    ),
]


@pytest.mark.parametrize("example,edit,bad,words", DOTTED)
def test_bad_key_in_a_dotted_table_is_reported_at_its_line(example, edit, bad, words):
    """A bad key under [conductor.flexure] or [electrostatics.bem] is reported at the line that
    writes it, counted here in the edited text (the same key names stand in other tables above:
    `width` under [conductor] and every [[electrodes]], `levels` under [sampling])."""
    text = (ROOT / "examples" / example).read_text()
    assert edit[0] in text, edit[0]
    text = text.replace(*edit, 1)
    expected = [no for no, t in enumerate(text.splitlines(), 1) if t.startswith(bad)]
    assert len(expected) == 1, bad
    with pytest.raises(StructureError) as info:
        parse_structure(text, "bad.toml")
    message = str(info.value)
    assert info.value.line == expected[0] and message.startswith(f"bad.toml:{expected[0]}:"), message
    for w in words:
        assert w in message, message


def test_units_are_converted_to_si():
    s = parse_structure(_replace('sector_start = "-45 deg"', 'sector_start = "-0.25 rad"'), "x.toml")
    assert s.electrode_sets[0].sector_start == pytest.approx(-0.25)
    assert load_structure(EXAMPLE).electrode_sets[0].sector_start == pytest.approx(-math.pi / 4)


def test_cli_reports_bad_file_with_exit_2_and_no_output(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(_replace('gap = "3 um"', 'gap = "0 um"'))
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "netgen.cli.commands", "build", str(bad), "-o", str(out)], capture_output=True, text=True
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert "gap" in proc.stderr and "fix:" in proc.stderr
    assert not out.exists() or not any(out.iterdir())


def test_missing_file_is_a_clear_error(tmp_path):
    with pytest.raises(StructureError, match="no such file"):
        load_structure(tmp_path / "nope.toml")


PROCESS_EXAMPLE = ROOT / "examples" / "piston_process.toml"
PROCESS_BAD = [
    # (replacement of the example's [process] parameters line, expected key, expected words)
    ('parameters = ["dg", "tscale", "tmp"]', "process.parameters", ["unknown process parameter 'tmp'"]),
    ('parameters = ["dg", "dg"]', "process.parameters", ["listed twice"]),
    ("parameters = []", "process.parameters", ["non-empty list"]),
    ('parameters = "dg"', "process.parameters", ["non-empty list"]),
    ('parameters = ["dg", "temp"]', "process.tscale_range", ["'tscale' is not in process.parameters"]),
    ('parameters = ["dg", "tscale", "temp"]\nescale_range = [0.5, 1.5]', "process.escale_range", ["'escale'"]),
    ('parameters = ["dg", "tscale", "temp"]\nmodulus_tc = 0.5', "process.modulus_tc", ["|tc| < 1e-3"]),
    ('parameters = ["dg", "tscale", "temp"]\nprocess_corner = 1', "process.process_corner", ["unknown key"]),
]
PROCESS_RANGES = [
    ("tscale_range = [0.9, 1.1]", "tscale_range = [1.05, 1.1]", "process.tscale_range", ["nominal 1"]),
    ("tscale_range = [0.9, 1.1]", "tscale_range = [0.2, 1.1]", "process.tscale_range", ["within 0.5..1.5"]),
    ("tscale_range = [0.9, 1.1]", 'tscale_range = ["0.9", 1.1]', "process.tscale_range", ["two numbers"]),
    ("temp_range = [-40, 125]", "temp_range = [40, 125]", "process.temp_range", ["26.85 degC"]),
    ("temp_range = [-40, 125]", "temp_range = [125, -40]", "process.temp_range", ["increasing"]),
    ('rigid = ["z"]', 'rigid = ["z"]\n[process.x]', "process.x", ["unknown key"]),
]


def process_case(old: str, new: str) -> str:
    text = PROCESS_EXAMPLE.read_text()
    assert old in text, old
    return text.replace(old, new, 1)


@pytest.mark.parametrize(
    "old,new,where,words",
    [('parameters = ["dg", "tscale", "temp", "etch"]', *case) for case in PROCESS_BAD] + PROCESS_RANGES,
)
def test_bad_process_table_names_file_key_and_fix(old, new, where, words):
    """A bad [process] table (netgen.structure.process_table): exit-2 StructureError naming the
    file, the key and a fix."""
    with pytest.raises(StructureError) as info:
        parse_structure(process_case(old, new), "bad.toml")
    err = info.value
    assert err.exit_code == 2 and err.where == where and err.fix, str(err)
    assert str(err).startswith("bad.toml")
    for w in words:
        assert w in str(err), str(err)


@pytest.mark.parametrize(
    "example,params,where,words",
    [
        ("cantilever.toml", '"dg", "tscale"', "process.parameters", ["dg needs the coordinate z"]),
    ],
)
def test_process_parameters_the_structure_cannot_carry_are_refused(example, params, where, words):
    """dg without a coordinate z (a beam's modes): refused with the reason and the way out, never a
    silently wrong law."""
    text = (ROOT / "examples" / example).read_text() + f"\n[process]\nparameters = [{params}]\n"
    with pytest.raises(StructureError) as info:
        parse_structure(text, "bad.toml")
    assert info.value.where == where and info.value.fix
    for w in words:
        assert w in str(info.value), str(info.value)


def test_tscale_with_etch_on_field2d_combs_is_read():
    """tscale and etch together on field2d comb fingers parse (the model stage fits and states the cross
    factor their product needs, netgen.model.process.cross_capacitance)."""
    text = (ROOT / "examples" / "accelerometer_xyz.toml").read_text() + '\n[process]\nparameters = ["tscale", "etch"]\n'
    p = parse_structure(text, "xyz.toml").process
    assert p is not None and p.parameters == ("tscale", "etch")


def test_without_process_table_no_process_parameters():
    """No [process]: Structure.process is None (the model stage derives nothing, netgen.model.process)."""
    assert load_structure(EXAMPLE).process is None
    p = load_structure(PROCESS_EXAMPLE).process
    assert p is not None and p.parameters == ("dg", "tscale", "temp", "etch") and p.modulus_tc == -60e-6
