"""The build with the sample designs: refusals (terms the design cannot determine, a cost over
--max-minutes) with file, key and fix and no output, and the design recorded in the model."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from netgen.build import build
from netgen.structure import StructureError, parse_structure
from tests.fixtures import ROOT

PISTON = (ROOT / "examples/piston.toml").read_text()


def _piston(sampling: str, fit: str = "") -> str:
    text = PISTON.replace('rigid = ["z"]', 'rigid = ["z", "tilt_x", "tilt_y"]')
    text = text.replace("# tilt_stiffness = 1e-7", "tilt_stiffness = 1e-7")
    text = text.replace("levels = 5\nrange = 0.6", sampling + "\nrange = 0.3")
    return text + (f"\n[fit]\n{fit}\n" if fit else "")


def test_a_degree_the_sparse_grid_cannot_determine_is_refused():
    """A level-1 sparse grid (centre and axis points) has no x_i x_j information: a degree-2
    polynomial of 1/C is refused, naming fit.degree and the fix; level 2 determines it."""
    s = parse_structure(_piston('design = "sparse"\nlevel = 1', 'target = "inverse"\ndegree = 2'), "p.toml")
    with pytest.raises(StructureError) as info:
        build(s)
    text = str(info.value)
    assert "p.toml" in text and "fit.degree" in text and "determine only 7 of the 10 terms" in text, text
    assert "level-L sparse grid determines total degree L" in text
    ok = build(parse_structure(_piston('design = "sparse"\nlevel = 2', 'target = "inverse"\ndegree = 2'), "p.toml"))
    assert ok.model.sampling["design"] == "sparse" and ok.model.sampling["samples"] == 25


def test_a_design_over_max_minutes_is_refused_with_the_fix(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text(_piston("levels = 9"))
    out = tmp_path / "out"
    run = subprocess.run(
        [sys.executable, "-m", "netgen.cli.commands", "build", str(path), "-o", str(out), "--max-minutes", "1e-6"],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert run.returncode == 2, run.stderr
    assert "[sampling] design" in run.stderr and "729 samples" in run.stderr and 'design = "sparse"' in run.stderr
    assert "over --max-minutes 1e-06" in run.stderr and "Traceback" not in run.stderr
    assert not out.exists()


def test_the_estimate_is_printed_and_the_design_recorded(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text(_piston('design = "lhs"\npoints = 64\nseed = 5'))
    run = subprocess.run(
        [sys.executable, "-m", "netgen.cli.commands", "build", str(path), "-o", str(tmp_path / "o"), "--no-plots"],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert run.returncode == 0, run.stderr
    # check points: the 500 held-out ones and the 2^3 corners of the 3-coordinate box
    assert "lhs design: 64 samples + 508 check points; estimated extractor" in run.stderr
    sampling = json.loads((tmp_path / "o" / "piston.json").read_text())["sampling"]
    assert sampling["design"] == "lhs" and sampling["points"] == 64 and sampling["design_seed"] == 5
    assert sampling["samples"] + sampling["excluded_touching"] == 64 and "levels" not in sampling
    assert "(lhs design," in (tmp_path / "o" / "piston.lib").read_text()
