"""A dielectric layer on an electrode in the multipole extractor (netgen.electrostatics.fastcap:
the layer's free surface is a FastCap2 dielectric interface, the electrode a box under it,
fastcap_mesh.layered_panels) against the series-capacitor closed form.

The oracle is a guarded electrode: one layered box electrode 2 c wide, 2 um under a plate of the
same width, whose face is split into a central L x L square (the sense conductor) and the ring
around it (the guard, with the box's back and walls). Both are at the same potential in the
plate's column of the Maxwell matrix, so the sense square carries exactly the charge of an
infinite parallel plate over its area, eps0 L^2 / g_eff with g_eff = g - t_d + t_d / eps_r (D
continuous across the layer), up to the fringe of the guard's outer edge, which decays as
exp(-pi W / g_eff) over the guard width W = 4 g (below 1e-5). No slot, no fringe formula.

Tolerances: the extractor's own error bar e (Richardson correction of two mesh levels plus the
change from expansion order 4 to 6) with coverage factor 2, as tests/electrostatics/test_fastcap.py
(the convergence order is assumed, not observed per solve), and the issue's 0.5 % besides. The
guarded check runs at element_to_gap 1 (panels of 1.8 um, 9 layer thicknesses): at the default 2
the conductor face and the interface 0.2 um above it, which carry nearly opposite charges (the
polarisation cancels all but 1/eps_r of the conductor's), are meshed with panels 18 layer
thicknesses wide, and the sense square came out +0.83 % with e = 1.67 %, outside the 0.5 %
(docs/fastcap.md, 'Dielectric layers'); at element_to_gap 1 it is about -0.1 % with e <= 0.8 %,
some 6 s of CPU per eps_r.
The geometry tests compare polygon areas with the exact ones within the chord deficit
(1 - sin(d)/d <= d^2/6 for chords of angle d).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("fastcap2")

from netgen.core.constants import EPS0  # noqa: E402
from netgen.core.errors import StructureError  # noqa: E402
from netgen.electrostatics import calibrated, fastcap  # noqa: E402
from netgen.electrostatics.bem_mesh import Sizes  # noqa: E402
from netgen.electrostatics.bem_sampling import key_of  # noqa: E402
from netgen.electrostatics.fastcap_mesh import layered_panels, outlines  # noqa: E402
from netgen.electrostatics.parallel_plate import ParallelPlateExtractor  # noqa: E402
from netgen.geometry.shapes import AnnularSector, Electrode, Rectangle, RectPlate  # noqa: E402
from netgen.structure import parse_structure  # noqa: E402
from tests.fixtures import ROOT  # noqa: E402
from tests.oracles.fastcap_guarded import SENSE, T_D, UM, G, guarded_levels  # noqa: E402


@pytest.mark.parametrize("eps_r", [1.0, 7.5])
def test_guarded_layer_against_series_capacitor(eps_r):
    """The sense square's charge against eps0 L^2 / g_eff within 2 e and 0.5 % (module docstring)
    at element_to_gap 1; eps_r = 1 checks that the interface itself is invisible, 7.5 (nitride) the
    series layer."""
    st = replace(fastcap.FastcapSettings(), element_to_gap=1.0)
    m = fastcap.converged(guarded_levels(eps_r, st), 1.0, st, ("plate", "sense", "guard"))
    ref = EPS0 * SENSE**2 / (G - T_D + T_D / eps_r)
    dev = abs(-m.matrix[0, 1] / ref - 1.0)
    assert dev <= 2.0 * m.error
    assert dev <= 5e-3


def shoelace(p: np.ndarray) -> float:
    """Signed area of a closed polygon (positive counter-clockwise)."""
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


@pytest.mark.parametrize(
    "shape, area",
    [
        (Rectangle("r", -3 * UM, 5 * UM, -1 * UM, 2 * UM), 8 * UM * 3 * UM),
        (AnnularSector("s", 20 * UM, 100 * UM, 0.3, 1.5, 0.0), 0.5 * 1.2 * (100**2 - 20**2) * UM**2),
        (AnnularSector("a", 20 * UM, 100 * UM, 0.0, 2 * math.pi, 0.0), math.pi * (100**2 - 20**2) * UM**2),
        (AnnularSector("d", 0.0, 100 * UM, 0.0, math.pi / 2, 0.0), math.pi / 4 * 100**2 * UM**2),
    ],
)
def test_outlines_enclose_the_shape(shape, area):
    """The outlines' signed areas add up to the shape's (the electrode to the left of every edge:
    an annulus's inner circle counts negative), within the chord deficit of arcs h_edge apart."""
    sizes = Sizes(2 * UM, 10 * UM, 1.5)
    rings = outlines(Electrode(shape, "below", G), sizes)
    total = sum(shoelace(r) for r in rings)
    d = (2 * UM) / (20 * UM)  # largest chord angle: h_edge over the smallest radius (20 um)
    assert total == pytest.approx(area, rel=d * d / 6 + 1e-12, abs=0)


def test_layered_box_panels():
    """The layered electrode: face at z, back and interface t_d away on either side, every
    interface reference point strictly inside the layer (between the face and its top)."""
    e = Electrode(AnnularSector("s", 20 * UM, 100 * UM, 0.3, 1.5, 5 * UM), "above", G, "s", T_D, 7.5)
    z = 10 * UM
    lay = layered_panels(e, Sizes(0.5 * UM, 4 * UM, 1.5), z, -1.0)
    assert np.allclose(lay.face.corners[:, :, 2], z)
    assert lay.refs.shape == (len(lay.interface), 3)
    assert np.all((lay.refs[:, 2] < z) & (lay.refs[:, 2] > z - T_D))
    top = lay.interface.corners[:, :, 2]
    assert np.isclose(top, z - T_D).all(axis=1).sum() == len(lay.face)


def layered_piston(extractor: str) -> str:
    """examples/piston.toml with 0.2 um of nitride on its electrode and the given extractor."""
    text = (ROOT / "examples" / "piston.toml").read_text()
    text = text.replace(
        'gap = "2 um"\n', 'gap = "2 um"\ndielectric_thickness = "0.2 um"\ndielectric_permittivity = 7.5\n', 1
    )
    return text.replace("[electrostatics]\n", f'[electrostatics]\nextractor = "{extractor}"\n', 1)


def test_structure_admits_a_layer_for_fastcap_only():
    """extractor = "fastcap" and a calibration on FastCap points read a layered structure; "bem"
    and a calibration on BEM points refuse it, naming the key and the reason."""
    s = parse_structure(layered_piston("fastcap"), "piston_nitride.toml")
    assert s.electrode_sets[0].dielectric_thickness == pytest.approx(T_D, abs=0)
    on_fastcap = layered_piston("calibrated").replace(
        "[electrostatics]\n", '[electrostatics]\ncalibration_points = 3\ncalibration_source = "fastcap"\n', 1
    )
    parse_structure(on_fastcap, "piston_nitride.toml")
    on_bem = on_fastcap.replace('calibration_source = "fastcap"\n', "")
    for text in (layered_piston("bem"), on_bem):
        with pytest.raises(StructureError, match="dielectric_thickness") as err:
            parse_structure(text, "piston_nitride.toml")
        assert "thinner than the layer" in str(err.value)


def test_calibrated_on_layered_fastcap_points_holds_at_held_out_points():
    """The calibrated extractor (the layer as the analytic series gap, its fringe fitted) on
    FastCap solves of a 40 um piston over 0.2 um of nitride at 3 points: at 2 points it did not
    see, within 2 e of FastCap there (e: FastCap's own error bar, coverage factor 2, as
    tests/electrostatics/test_fastcap_perforated.py); its fringe stays in the form's range 0..5."""
    field = layered_prepared(7.5)
    ex = calibrated.CalibratedExtractor(
        ParallelPlateExtractor(), ["z"], points=3, source=lambda s, e, p, b: calibrated.field_source(field)
    )
    prepared = ex.prepare(list(field.electrodes), RectPlate(-20 * UM, 20 * UM, -20 * UM, 20 * UM), rigid)
    fringe = ex.result["calibration"].fringes[0]
    assert 0.0 <= fringe.a <= 5.0 and 0.0 <= fringe.b <= 5.0
    for z in (-0.1 * (G - T_D), 0.15 * (G - T_D)):  # the design: 0 and +-0.2 of the air gap
        m = field.maxwell(np.array([z]))
        assert abs(prepared.capacitance(np.array([z]))[0] / m.plate_electrode[0] - 1.0) <= 2.0 * m.error


def rigid(x, y):
    """The piston's one coordinate: rigid z."""
    return np.ones((np.size(x), 1))


def layered_prepared(eps_r: float):
    """The multipole extractor prepared on a 40 um piston over a layered electrode (no solve)."""
    h = 20 * UM
    e = Electrode(Rectangle("d", -h, h, -h, h), "below", G, "d", T_D, eps_r)
    return fastcap.FastcapExtractor().prepare([e], RectPlate(-h, h, -h, h), rigid)


def test_stop_on_the_layer_and_store_key():
    """The plate stops on the layer's surface (min_gap is the air gap g - t_d - x, a plate pushed
    into the layer reads nan without a solve), and the sample store's key changes with the
    layer's permittivity, so a store never hands back another layer's samples."""
    p = layered_prepared(7.5)
    x = np.array([0.0, 0.5 * UM, 1.2 * UM])
    assert p.min_gap(-x[:, None])[:, 0] == pytest.approx(G - T_D - x, rel=1e-12, abs=0)
    assert np.isnan(p.capacitance(np.array([[-(G - T_D) - 1e-9]]))[0, 0])
    q = np.zeros((1, 1))
    assert key_of(p, q) != key_of(layered_prepared(3.9), q)


def test_analytic_layer_step_against_fastcap_piston():
    """The parallel-plate extractor with its edge fringe and the layer's edge step
    (parallel_plate.layer_step) on a 100 um piston 2 um over 0.2 um of nitride, against FastCap's
    layered solve: within the issue's 0.5 % plus 2 e (FastCap's own bar, coverage factor 2, as
    above). Without the step it was -0.62 % (docs/fastcap.md, 'Dielectric layers')."""
    h = 50 * UM
    e = Electrode(Rectangle("d", -h, h, -h, h), "below", G, "d", T_D, 7.5)
    plate = RectPlate(-h, h, -h, h)
    m = fastcap.FastcapExtractor().prepare([e], plate, rigid).maxwell(np.zeros(1))
    c = ParallelPlateExtractor().prepare([e], plate, rigid).capacitance(np.zeros(1))[0]
    assert abs(c / m.plate_electrode[0] - 1.0) <= 5e-3 + 2.0 * m.error
