"""Calibration of the analytic extractor against a field solution (netgen.electrostatics.calibration,
calibrated, coupling_file), with independent "field solutions":

- Palmer's two-square formula without its corner cross term IS an edge fringe with Palmer's
  per-edge coefficients (a, b) = ((1 + ln 2 pi)/(2 pi), 1/(2 pi)) at L = the side: the fit must
  recover them from a few z points, starting from the plate_between default;
- Palmer's full formula: the calibrated capacitance matches it within 1e-4 at the points and
  between them, where the default fringe is ~1 % off;
- a synthetic Maxwell matrix of a reduced disk: plate-electrode entries with a different known
  fringe per electrode, couplings of 10 % of C(0) between adjacent sectors varying +-1 % with z:
  the build (extractor = "calibrated", couplings = "maxwell.json") recovers every (a_i, b_i) to
  1e-9, the couplings' mean and spread as computed here by hand, and writes them into the .lib
  and the calibration report;
- bad Maxwell files and bad [electrostatics] keys exit 2 naming the file, the entry and the fix.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from netgen.cli.commands import main
from netgen.core.constants import EPS0
from netgen.electrostatics.calibration import calibrate, design
from netgen.electrostatics.parallel_plate import EdgeFringe, ParallelPlateExtractor
from netgen.electrostatics.sampling import coordinate_scales
from netgen.geometry.layout import electrodes, plate_outline
from netgen.geometry.shapes import Electrode, Rectangle, RectPlate
from netgen.mechanics import mechanics
from netgen.model import MacroModel
from netgen.structure import parse_structure
from tests.fixtures import ROOT
from tests.oracles.closed_forms import palmer_rectangle

MM = 1e-3
# the reduced disk of examples/calibrated_disk.toml (one ring of four sectors per side, rigid
# coordinates), without its [electrostatics] table; bench/calibrate_bem.py shares it
DISK = (ROOT / "examples" / "calibrated_disk.toml").read_text().split("[electrostatics]")[0] + "[fit]\nholdout = 50\n"
CALIBRATED = DISK + '[electrostatics]\nextractor = "calibrated"\ncouplings = "maxwell.json"\n'


def squares(g: float):
    """A 1 mm square plate under a 1 mm square electrode at gap g, moving in z."""
    return (
        [Electrode(Rectangle("top", 0, MM, 0, MM), "above", g)],
        RectPlate(0, MM, 0, MM),
        (lambda x, y: np.ones((x.size, 1))),
    )


def palmer_source(g: float, corner: bool):
    """Maxwell matrix of the two squares from Palmer's formula at gap g - z (with or without its
    second-order corner term eps A/g eps1^2, which no edge fringe has)."""

    def maxwell(q):
        gap = g - q[0]
        c = palmer_rectangle(EPS0, MM, MM, gap)
        if not corner:
            eps1 = gap / (math.pi * MM) * (1 + math.log(2 * math.pi * MM / gap))
            c -= EPS0 * MM**2 / gap * eps1**2
        return np.array([[c, -c], [-c, c]])

    return maxwell


@pytest.mark.parametrize("g", [50e-6, 20e-6, 5e-6])
def test_recovers_palmers_edge_coefficients(g):
    """Palmer without its corner term, 5 points over +-30 % of the gap: (a, b) to 1e-9."""
    els, plate, basis = squares(g)
    cal = calibrate(
        palmer_source(g, corner=False),
        els,
        plate,
        basis,
        design(5, np.array([g]), 0.3),
        ParallelPlateExtractor(fringe=EdgeFringe(length=MM)),
        "Palmer",
    )
    want = EdgeFringe.palmer(MM)
    assert cal.fringes[0].a == pytest.approx(want.a, rel=1e-9)
    assert cal.fringes[0].b == pytest.approx(want.b, rel=1e-9)
    assert np.all(cal.coupling == 0)


@pytest.mark.parametrize("g", [20e-6, 5e-6])
def test_calibrated_capacitance_matches_palmer(g):
    """Full Palmer, calibrated at 5 points: within 1e-4 at 21 points over the same +-30 %, where
    the uncalibrated plate_between fringe is 0.8-4 % low."""
    els, plate, basis = squares(g)
    base = ParallelPlateExtractor(fringe=EdgeFringe(length=MM))
    cal = calibrate(palmer_source(g, corner=True), els, plate, basis, design(5, np.array([g]), 0.3), base, "Palmer")
    z = np.linspace(-0.3, 0.3, 21) * g
    want = np.array([palmer_rectangle(EPS0, MM, MM, g - v) for v in z])
    fitted = ParallelPlateExtractor(fringes=cal.fringes).prepare(els, plate, basis).capacitance(z[:, None])[:, 0]
    default = base.prepare(els, plate, basis).capacitance(z[:, None])[:, 0]
    assert np.abs(fitted / want - 1).max() < 1e-4
    assert np.abs(default / want - 1).min() > 5e-3
    assert max(abs(e) for e in cal.comparison["top"]["calibrated_c_rel_error"]) < 1e-4


def test_design_is_centre_then_star_then_random():
    """design(): the centre, +-h per coordinate in order, then points inside the box."""
    pts = design(9, np.array([1.0, 2.0, 3.0]), 0.5)
    np.testing.assert_array_equal(pts[:3], [[0, 0, 0], [0.5, 0, 0], [-0.5, 0, 0]])
    np.testing.assert_array_equal(pts[5:7], [[0, 0, 1.5], [0, 0, -1.5]])
    assert np.all(np.abs(pts[7:]) <= [0.5, 1.0, 1.5])


# ----------------------------------------------------------------------------- the reduced disk, built


def truth(tmp_path: Path, npts: int = 7) -> dict:
    """Write tmp_path/maxwell.json: the synthetic field solution of the reduced disk, and return
    its known fringes, coupling matrix at rest and the coupling values at every point."""
    s = parse_structure(DISK, str(tmp_path / "disk.toml"))
    m, plate, els = mechanics(s), plate_outline(s), electrodes(s)
    n = len(els)
    fringes = tuple(EdgeFringe(0.40 + 0.02 * i, 0.05 + 0.004 * i, plate.size) for i in range(n))
    ext = ParallelPlateExtractor(fringes=fringes).prepare(els, plate, m.basis)
    scales = coordinate_scales(ext, m.names, np.array([e.gap for e in els]))
    q = design(npts, scales, 0.2)
    c = ext.capacitance(q)
    c0 = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1, n):
            if els[i].side == els[j].side and (j - i) % 4 in (1, 3):
                c0[i, j] = c0[j, i] = 0.1 * c[0, i]
    points, values = [], []
    for k in range(len(q)):
        cc = c0 * (1 + 0.05 * q[k, 0] / scales[0])  # +-1 % at the z points
        values.append(cc)
        mx = np.zeros((n + 1, n + 1))
        mx[0, 1:] = mx[1:, 0] = -c[k]
        mx[1:, 1:] = -cc
        np.fill_diagonal(mx, 0.0)
        np.fill_diagonal(mx, -mx.sum(axis=1) + 1e-15)  # + 1 fF to infinity each
        points.append({"q": dict(zip(m.names, q[k].tolist())), "maxwell": mx.tolist()})
    (tmp_path / "maxwell.json").write_text(
        json.dumps({"conductors": ["plate"] + [e.name for e in els], "points": points})
    )
    return {"fringes": fringes, "names": [e.name for e in els], "couplings": np.array(values), "q": q}


def build(tmp_path: Path, text: str, *extra: str) -> tuple[int, str]:
    """`netgen build` of text in tmp_path (exit code, stderr)."""
    (tmp_path / "disk.toml").write_text(text)
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.chdir(tmp_path):
        code = main(["build", "disk.toml", "-o", "out", "--format", "all", "-q", *extra])
    return code, err.getvalue()


def test_calibrated_build_recovers_fringes_and_couplings(tmp_path):
    """The pipeline with the synthetic Maxwell file: fringes to 1e-9, couplings = hand mean, spread
    = hand standard deviation; the .lib carries them and the report names each electrode."""
    t = truth(tmp_path)
    code, err = build(tmp_path, CALIBRATED)
    assert code == 0, err
    model = MacroModel.load_json(tmp_path / "out" / "calibrated_disk.json")
    for row, f in zip(model.calibration["fringe"], t["fringes"]):
        assert row["a"] == pytest.approx(f.a, rel=1e-9) and row["b"] == pytest.approx(f.b, rel=1e-9)
    mean, std = t["couplings"].mean(axis=0), t["couplings"].std(axis=0)
    np.testing.assert_allclose(model.coupling, mean, rtol=1e-12, atol=0)
    spread = {tuple(r["pair"]): r for r in model.calibration["coupling_spread"]}
    assert len(spread) == 8
    for (a, b), r in spread.items():
        i, j = t["names"].index(a), t["names"].index(b)
        assert r["std"] == pytest.approx(std[i, j], rel=1e-9, abs=0) and r["max"] == pytest.approx(
            t["couplings"][:, i, j].max(), abs=0
        )
    lib = (tmp_path / "out" / "calibrated_disk.lib").read_text()
    assert "Constant electrode-electrode couplings: 8 capacitor(s)" in lib and lib.count("\nCc_") == 8
    report = json.loads((tmp_path / "out" / "calibrated_disk_calibration.json").read_text())
    assert (
        set(report["electrodes"]) == set(t["names"]) and (tmp_path / "out" / "calibrated_disk_calibration.png").exists()
    )
    worst = max(v["calibrated_c_max_abs_rel_error"] for v in report["summary"].values())
    assert worst < 1e-9


def test_parallel_plate_takes_only_the_files_couplings(tmp_path):
    """extractor = "parallel_plate" with the file: the mean couplings, the default fringe kept."""
    t = truth(tmp_path)
    code, err = build(tmp_path, DISK + '[electrostatics]\ncouplings = "maxwell.json"\n')
    assert code == 0, err
    model = MacroModel.load_json(tmp_path / "out" / "calibrated_disk.json")
    np.testing.assert_allclose(model.coupling, t["couplings"].mean(axis=0), rtol=1e-12)
    assert "fringe" not in model.calibration


def corrupt(tmp_path: Path, change) -> None:
    """Rewrite maxwell.json through change(doc)."""
    path = tmp_path / "maxwell.json"
    doc = json.loads(path.read_text())
    change(doc)
    path.write_text(json.dumps(doc) if isinstance(doc, dict) else doc)


def _swap(doc, i, j, value):
    doc["points"][0]["maxwell"][i][j] = value


BAD_FILES = {
    "asymmetric": (lambda d: _swap(d, 1, 2, d["points"][0]["maxwell"][1][2] * 1.5), "not symmetric"),
    "positive off-diagonal": (lambda d: [_swap(d, 1, 2, 1e-14), _swap(d, 2, 1, 1e-14)], "is positive"),
    "missing electrode": (
        lambda d: [
            d["conductors"].pop(),
            [r.pop() for p in d["points"] for r in p["maxwell"]],
            [p["maxwell"].pop() for p in d["points"]],
        ],
        "no row for bot_r1s4",
    ),
    "unknown conductor": (lambda d: d["conductors"].__setitem__(1, "top_r9s1"), "neither the plate nor an electrode"),
    "pF": (
        lambda d: [p.__setitem__("maxwell", (np.array(p["maxwell"]) * 1e12).tolist()) for p in d["points"]],
        "multiply by 1e-12",
    ),
    "unknown coordinate": (lambda d: d["points"][0]["q"].__setitem__("zz", 0.0), "no coordinate 'zz'"),
    "beyond touch": (lambda d: d["points"][1]["q"].__setitem__("z", 1e-5), "beyond the touching amplitude"),
    "not square": (lambda d: d["points"][0]["maxwell"].pop(), "not a 9 x 9 matrix"),
    "NaN": (lambda d: _swap(d, 0, 0, "nan"), "not a finite number"),
    "unit": (lambda d: d.__setitem__("unit", "pF"), "must be in F"),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_maxwell_files_exit_2_naming_file_entry_and_fix(tmp_path, case):
    """Each corruption: exit 2, the file, the entry and a fix in one message, no traceback, no output."""
    truth(tmp_path)
    change, problem = BAD_FILES[case]
    corrupt(tmp_path, change)
    code, err = build(tmp_path, CALIBRATED)
    assert code == 2, err
    assert "maxwell.json" in err and "electrostatics.couplings" in err and "fix:" in err and problem in err, err
    assert "Traceback" not in err and not (tmp_path / "out" / "calibrated_disk.lib").exists()


def test_not_json_is_refused(tmp_path):
    """A truncated file: exit 2 with the JSON error's line."""
    truth(tmp_path)
    (tmp_path / "maxwell.json").write_text('{"conductors": ["plate",')
    code, err = build(tmp_path, CALIBRATED)
    assert code == 2 and "not JSON" in err and "fix:" in err, err


def test_csv_matrix_gives_the_couplings(tmp_path):
    """A CSV Maxwell matrix at rest (conductor,<names> header): the couplings are its entries."""
    t = truth(tmp_path)
    mx = np.array(json.loads((tmp_path / "maxwell.json").read_text())["points"][0]["maxwell"])
    names = ["plate"] + t["names"]
    rows = ["conductor," + ",".join(names)] + [f"{n}," + ",".join(repr(float(v)) for v in r) for n, r in zip(names, mx)]
    (tmp_path / "maxwell.csv").write_text("\n".join(rows) + "\n")
    code, err = build(tmp_path, DISK + '[electrostatics]\ncouplings = "maxwell.csv"\n')
    assert code == 0, err
    model = MacroModel.load_json(tmp_path / "out" / "calibrated_disk.json")
    np.testing.assert_allclose(model.coupling, t["couplings"][0], rtol=1e-12)


@pytest.mark.parametrize(
    "section, problem",
    [
        ('extractor = "calibrated"\n', "needs a field solution"),
        ("calibration_points = 5\n", "calibration_points with extractor = 'parallel_plate'"),
        ('extractor = "calibrated"\ncalibration_points = 5\ncouplings = "maxwell.json"\n', "two calibration sources"),
        ('couplings = "maxwell.json"\ncoupling_per_length = 1e-9\n', "both set"),
        ('couplings = "nothere.json"\n', "no such file"),
        ('couplings = "maxwell.txt"\n', "is not a .json or .csv file name"),
        ('extractor = "bem_typo"\n', "unknown extractor"),
        ('extractor = "bem"\ncouplings = "maxwell.json"\n', "takes no couplings file"),
    ],
)
def test_bad_electrostatics_keys_exit_2(tmp_path, section, problem):
    """Bad [electrostatics] calibration keys: exit 2 naming the key and the fix."""
    truth(tmp_path)
    code, err = build(tmp_path, DISK + "[electrostatics]\n" + section)
    assert code == 2 and problem in err and "fix:" in err and "electrostatics." in err, err


def test_calibrated_without_bem_says_what_to_do(tmp_path):
    """extractor = "calibrated" with BEM points on a netgen whose bempp-cl cannot be imported (a
    fresh interpreter with the import blocked): exit 2, the fix names the file alternative."""
    (tmp_path / "disk.toml").write_text(DISK + '[electrostatics]\nextractor = "calibrated"\ncalibration_points = 3\n')
    code = (
        "import sys; sys.modules['bempp_cl'] = None\n"
        "from netgen.cli.commands import main\n"
        "sys.exit(main(['build', 'disk.toml', '-o', 'out', '-q']))"
    )
    run = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    err = run.stderr
    assert run.returncode == 2 and "not installed" in err and "couplings" in err, err
    assert "Traceback" not in err and not (tmp_path / "out").exists()
