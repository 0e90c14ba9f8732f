"""A calibration through the comb composition (netgen.electrostatics.compose): a proof mass with
two substrate plates and a differential comb pair, extractor = "calibrated" with a Maxwell file
for the plates. The plates' fringes and coupling come from the file (recovered to 1e-9 from
synthetic matrices of a known fringe over the mass's perforated plate term, as in
test_calibration.py), the combs' columns are the comb
extractor's alone, and the build writes the calibration record, the coupling capacitor and the
report."""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest

from netgen.cli.commands import main
from netgen.core.constants import EPS0
from netgen.electrostatics import compose, extractor
from netgen.electrostatics.calibration import design
from netgen.electrostatics.comb import CombExtractor
from netgen.electrostatics.mixed import split
from netgen.electrostatics.parallel_plate import EdgeFringe, ParallelPlateExtractor
from netgen.electrostatics.perforation import Perforation
from netgen.electrostatics.sampling import touch_amplitudes
from netgen.geometry.layout import electrodes, plate_outline
from netgen.mechanics import mechanics
from netgen.model import MacroModel
from netgen.structure import parse_structure
from tests.fixtures import ROOT
from tests.structures import plate_electrode

EXAMPLE = (ROOT / "examples" / "accelerometer_xyz.toml").read_text()
CONDUCTOR = EXAMPLE[: EXAMPLE.index("# x: fingers")]  # the proof mass on its crab legs
# its etch holes through its 2 um: the calibrated plate term keeps their fill factor
HOLES = Perforation(4e-6, 10e-6, thickness=2e-6)
COMBS = EXAMPLE[EXAMPLE.index('[[electrodes]]\nname = "xp_t"') : EXAMPLE.index('[[electrodes]]\nname = "xp_b"')]
PLATES = "".join(
    plate_electrode(name, "below", "2 um", (f"{x0} um", f"{x1} um"), ("-150 um", "150 um"))
    for name, x0, x1 in (("zl", -150, -5), ("zr", 5, 150))
)
TEXT = (
    CONDUCTOR
    + COMBS
    + PLATES
    + """[coordinates]
rigid = ["x", "z", "tilt_y"]
[sampling]
levels = 3
range = 0.2
[fit]
holdout = 50
[electrostatics]
comb_model = "textbook"
"""
)
CALIBRATED = TEXT + 'extractor = "calibrated"\ncouplings = "maxwell.json"\n'
FRINGES = (EdgeFringe(0.47, 0.071, 400e-6), EdgeFringe(0.39, 0.052, 400e-6))
COUPLING = 2.5e-15  # F between the two plates


def write_maxwell(tmp_path) -> None:
    """maxwell.json: the plates' Maxwell matrices at the design's points from the parallel-plate
    extractor with FRINGES (one per plate), a constant coupling, 1 fF to infinity each."""
    s = parse_structure(TEXT, str(tmp_path / "acc.toml"))
    m, plate, shapes = mechanics(s), plate_outline(s), electrodes(s)
    ip, _ = split(shapes)
    plates = [shapes[i] for i in ip]
    ext = ParallelPlateExtractor(fringes=FRINGES, perforation=HOLES).prepare(plates, plate, m.basis)
    scales = touch_amplitudes(ext, len(m.names), np.array([e.gap for e in plates]))
    assert not np.isfinite(scales[0]) and np.isfinite(scales[1:]).all()  # x closes no plate gap
    q = design(1 + 2 * len(m.names), scales, 0.2)
    points = []
    for row, c in zip(q, ext.capacitance(q)):
        mx = np.zeros((3, 3))
        mx[0, 1:] = mx[1:, 0] = -c
        mx[1, 2] = mx[2, 1] = -COUPLING
        np.fill_diagonal(mx, -mx.sum(axis=1) + 1e-15)
        points.append({"q": dict(zip(m.names, row.tolist())), "maxwell": mx.tolist()})
    (tmp_path / "maxwell.json").write_text(json.dumps({"conductors": ["plate", "zl", "zr"], "points": points}))


def test_calibrated_extractor_reaches_the_combs(tmp_path):
    """The composed extractor: plate columns = the calibrated parallel plate with the file's fringes,
    comb columns = the comb extractor alone, at a few points; the hooks of the calibrated part answer."""
    write_maxwell(tmp_path)
    (tmp_path / "acc.toml").write_text(CALIBRATED)
    s = parse_structure(CALIBRATED, str(tmp_path / "acc.toml"))
    m, plate, shapes = mechanics(s), plate_outline(s), electrodes(s)
    ext = extractor(s, plate)
    assert hasattr(ext, "calibration") and hasattr(ext, "report")
    prepared = ext.prepare(shapes, plate, m.basis)
    ip, ic = split(shapes)
    q = np.array([[0.0, 0.0, 0.0], [0.2e-6, 0.1e-6, 1e-4], [-0.3e-6, -0.2e-6, -2e-4]])
    c = prepared.capacitance(q)
    want_plates = ParallelPlateExtractor(fringes=FRINGES, perforation=HOLES).prepare(
        [shapes[i] for i in ip], plate, m.basis
    )
    want_combs = CombExtractor(EPS0, "textbook").prepare([shapes[i] for i in ic], plate, m.basis)
    np.testing.assert_allclose(c[:, ip], want_plates.capacitance(q), rtol=1e-9)
    np.testing.assert_allclose(c[:, ic], want_combs.capacitance(q), rtol=1e-12)
    record = ext.calibration()
    assert [r["electrode"] for r in record["fringe"]] == ["zl", "zr"]
    for r, f in zip(record["fringe"], FRINGES):
        assert r["a"] == pytest.approx(f.a, rel=1e-9) and r["b"] == pytest.approx(f.b, rel=1e-9)
    cc = ext.coupling(shapes, plate)
    assert cc[ip[0], ip[1]] == pytest.approx(COUPLING, rel=1e-12, abs=0) and np.all(cc[np.ix_(ic, ic)] == 0)
    assert compose(ext.plates, ext.combs).calibration() == record


def test_calibrated_comb_build_writes_record_capacitor_and_report(tmp_path):
    """`netgen build`: the model's calibration entry and coupling, the .lib's coupling capacitor, the report."""
    write_maxwell(tmp_path)
    (tmp_path / "acc.toml").write_text(CALIBRATED)
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.chdir(tmp_path):
        code = main(["build", "acc.toml", "-o", "out", "-q", "--no-plots"])
    assert code == 0, err.getvalue()
    model = MacroModel.load_json(tmp_path / "out" / "accelerometer_xyz.json")
    assert [r["electrode"] for r in model.calibration["fringe"]] == ["zl", "zr"]
    lib = (tmp_path / "out" / "accelerometer_xyz.lib").read_text()
    assert "Constant electrode-electrode couplings: 1 capacitor(s)" in lib and "Cc_zl_zr" in lib
    assert (tmp_path / "out" / "accelerometer_xyz_calibration.json").exists()
