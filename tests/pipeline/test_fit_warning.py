"""Fit honesty: a capacitance fit that misses [fit] tolerance warns on stderr, in the model JSON and
in the header of every emitted format; `netgen build --strict` refuses it (exit 2, the fix, nothing
written). The case: a rigid free disk over one electrode under the whole disk, fringe off, one
plate term allowed ([fit] max_terms = 1), whose error is checked against the closed form of a
tilted disk over a plane, C = 2 pi eps0 (g - sqrt(g^2 - a^2 R^2)) / a^2 (slope a, gap g at the
centre), independent of the pipeline."""

from __future__ import annotations

import json
import math

import numpy as np
from scipy.constants import epsilon_0

from netgen.cli.commands import main
from netgen.model import MacroModel
from tests.fixtures import ROOT
from tests.structures import ONE_PLATE_GAP, ONE_PLATE_RADIUS, one_plate_disk

RADIUS, GAP = ONE_PLATE_RADIUS, ONE_PLATE_GAP
MISSES = (
    one_plate_disk("one_plate", "Rigid free disk over one electrode under the whole disk, one plate term: misses 2e-3")
    + """[sampling]
levels = 3
range = 0.2
[fit]
max_terms = 1
tolerance = 2e-3
"""
)
WARNING = "WARNING: the capacitance fit of electrode bot_r1s1 misses fit.tolerance"


def tilted_disk(model: MacroModel, x: np.ndarray) -> float:
    """Closed-form capacitance of the disk at scaled (z, tilt_x, tilt_y), small-slope parallel plate."""
    z, tx, ty = (xi * c.scale for xi, c in zip(x, model.coordinates))
    g, a = GAP + z, math.hypot(tx, ty)
    if a == 0.0:
        return epsilon_0 * math.pi * RADIUS**2 / g
    return 2 * math.pi * epsilon_0 * (g - math.sqrt(g * g - a * a * RADIUS**2)) / a**2


def test_a_missed_tolerance_warns_everywhere(tmp_path, capsys):
    """stderr, the JSON's validity entry, the headers of .lib, _xspice.lib and .va and the build
    report carry the warning with its fix; the fit really misses (closed form, 300 random points in the box)."""
    structure = tmp_path / "one_plate.toml"
    structure.write_text(MISSES)
    out = tmp_path / "out"
    assert main(["build", str(structure), "-o", str(out), "--format", "all", "--no-plots", "-q"]) == 0
    err = capsys.readouterr().err
    assert "netgen: warning:" in err and "misses fit.tolerance" in err and "max_terms" in err
    model = MacroModel.load_json(out / "one_plate.json")
    x = np.random.default_rng(0).uniform(-0.2, 0.2, (300, 3))
    closed = np.array([tilted_disk(model, p) for p in x])
    independent = float(np.abs(model.capacitance(x)[:, 0] / closed - 1).max())
    assert independent > 2e-3  # the warning is true
    validity = json.loads((out / "one_plate.json").read_text())["validity"]
    missed = validity["fit_tolerance_missed"]
    assert [m["electrode"] for m in missed] == ["bot_r1s1"] and missed[0]["tolerance"] == 2e-3
    assert missed[0]["max_rel_error"] > 2e-3
    assert abs(missed[0]["max_rel_error"] / independent - 1) < 0.2  # the held-out figure agrees with the closed form
    assert "Fix:" in validity["fit_warning"]
    for name in ("one_plate.lib", "one_plate_xspice.lib", "one_plate.va"):
        header = (out / name).read_text().split("\n.subckt" if name.endswith(".lib") else "`include")[0]
        assert WARNING in header, name
        assert "[fit] max_terms" in header.replace("\n*   ", " ").replace("\n//   ", " "), name
    page = (out / "one_plate_report.html").read_text()
    assert 'class="warning">the capacitance fit of electrode bot_r1s1 misses fit.tolerance' in page
    assert "[fit] max_terms" in page


def test_strict_refuses_a_missed_tolerance(tmp_path, capsys):
    """--strict: exit 2, one message naming the file, [fit] tolerance and the fix, no output folder."""
    structure = tmp_path / "one_plate.toml"
    structure.write_text(MISSES)
    out = tmp_path / "out"
    assert main(["build", str(structure), "-o", str(out), "--strict", "-q"]) == 2
    err = capsys.readouterr().err
    assert f"{structure}: [fit] tolerance:" in err and "fix: allow more plate terms" in err
    assert "Traceback" not in err
    assert not out.exists()


def test_a_met_tolerance_is_silent(tmp_path, capsys):
    """The piston (its fit is exact) builds under --strict without a warning anywhere."""
    out = tmp_path / "out"
    assert (
        main(
            [
                "build",
                str(ROOT / "examples" / "piston.toml"),
                "-o",
                str(out),
                "--strict",
                "--no-plots",
                "-q",
                "--format",
                "all",
            ]
        )
        == 0
    )
    assert "warning" not in capsys.readouterr().err
    assert "fit_warning" not in (out / "piston.json").read_text()
    assert all("misses fit.tolerance" not in p.read_text() for p in out.iterdir())
