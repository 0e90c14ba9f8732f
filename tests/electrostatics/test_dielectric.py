"""A dielectric layer on an electrode (dielectric_thickness, dielectric_permittivity): a series
capacitor in the parallel-plate extractor, and the stop on the layer's surface.

The structure is the piston example (a rigid 200 um x 200 um plate on a 2 N/m spring, 2 um over
one electrode, fringe off) with 0.2 um of nitride (eps_r = 7.5) on the electrode. The references
are closed forms independent of the pipeline: with D continuous across the layer, the plate over
a layered electrode is a parallel plate at the effective gap g_eff = g - t_d + t_d / eps_r
(1.82667 um), so C(x) = eps0 A / (g_eff - x), the pull-in voltage is sqrt(8 k g_eff^3 / (27 eps0 A))
at a travel g_eff / 3 = 0.609 um, and the plate touches the layer at a travel g - t_d = 1.8 um
(past the pull-in travel: the pull-in is the electrostatic one, not the stop).

Tolerances: with the fringe off, 1/C is exactly affine in the travel, so the fit meets its own
declared tolerance (fit.tolerance, 2e-3 by default) and the capacitance is held to it. The
pull-in voltage from the model's static balance is held to 0.5 %: V(x)^2 = 2 k x / (dC/dx) with
dC/dx within the fit tolerance (V within half of it) and the bounded maximiser converged to
1e-12 of the travel, well inside. The ngspice .op travel at 90 % of V_PI is held to 0.5 % of the
brentq stable root, as tests/emit/test_operating_point.py (Newton's tolerance is ~1e-6 relative;
the rest is the fit's force error, amplified by 1/(1 - 3 x / g_eff) ~ 2 at 90 %).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.constants import epsilon_0
from scipy.optimize import brentq, minimize_scalar

from netgen.build import build
from netgen.core.constants import EPS0
from netgen.electrostatics.parallel_plate import ParallelPlateExtractor
from netgen.emit import ngspice, report
from netgen.geometry.shapes import Electrode, Rectangle, RectPlate
from netgen.mechanics import mechanics
from netgen.mechanics.damping import damping
from netgen.sim.ngspice import run_ngspice
from netgen.structure import parse_structure
from tests.fixtures import ROOT, Bench

G, T_D, EPS_R = 2e-6, 0.2e-6, 7.5
G_EFF = G - T_D + T_D / EPS_R
K, SIDE = 2.0, 200e-6
AREA = SIDE * SIDE
LAYER = 'dielectric_thickness = "0.2 um"\ndielectric_permittivity = 7.5\n'


def layered_piston() -> str:
    """examples/piston.toml with the nitride layer on its electrode."""
    text = (ROOT / "examples" / "piston.toml").read_text()
    return text.replace('gap = "2 um"\n', 'gap = "2 um"\n' + LAYER, 1)


def pull_in(gap: float) -> float:
    return math.sqrt(8 * K * gap**3 / (27 * epsilon_0 * AREA))


@pytest.fixture(scope="module")
def piston(tmp_path_factory):
    """The layered piston's build and its emitted B-source .lib."""
    b = build(parse_structure(layered_piston(), "piston_nitride.toml"))
    folder = tmp_path_factory.mktemp("nitride")
    (folder / "piston_nitride.lib").write_text(ngspice.subcircuit(b.model))
    return b, folder


def test_structure_reads_the_layer(piston):
    b, _ = piston
    e = b.structure.electrode_sets[0]
    assert (e.dielectric_thickness, e.dielectric_permittivity) == pytest.approx((T_D, EPS_R), rel=1e-12, abs=0)


def test_extractor_series_gap_and_stop():
    """The extractor alone: C at rest and at a travel x is eps0 A / (g_eff - x) (to rounding),
    min_gap is the air gap g - t_d - x, and a plate pushed into the layer reads nan."""
    plate = RectPlate(-SIDE / 2, SIDE / 2, -SIDE / 2, SIDE / 2)
    e = Electrode(Rectangle("d", -SIDE / 2, SIDE / 2, -SIDE / 2, SIDE / 2), "below", G, "d", T_D, EPS_R)
    prepared = ParallelPlateExtractor(fringe=None).prepare([e], plate, lambda x, y: np.ones_like(x))
    x = np.array([0.0, 0.5e-6, 1.2e-6])  # travel toward the electrode below: q = -x
    c = prepared.capacitance(-x[:, None])[:, 0]
    # the package's EPS0: CODATA 2022, scipy.constants.epsilon_0 from scipy 1.15 on
    assert c == pytest.approx(EPS0 * AREA / (G_EFF - x), rel=1e-12, abs=0)
    assert prepared.min_gap(-x[:, None])[:, 0] == pytest.approx(G - T_D - x, rel=1e-12, abs=0)
    assert np.isnan(prepared.capacitance(np.array([[-(G - T_D) - 1e-9]]))[0, 0])


def test_capacitance_is_the_series_gap(piston):
    """The model's C over the sampled travel against eps0 A / (g_eff - x), within fit.tolerance."""
    b, _ = piston
    m = b.model
    scale = m.coordinates[0].scale
    xs = np.linspace(-b.structure.sampling.range, b.structure.sampling.range, 13)[:, None]
    travel = -xs[:, 0] * scale  # toward the electrode below
    c = m.capacitance(xs)[:, 0]
    assert c == pytest.approx(epsilon_0 * AREA / (G_EFF - travel), rel=b.structure.fit.tolerance, abs=0)


def test_contact_stop_on_the_layer(piston):
    """The plate's travel scale and every stop point's gap are the air gap g - t_d."""
    b, _ = piston
    m = b.model
    assert m.coordinates[0].scale == pytest.approx(G - T_D, rel=1e-9, abs=0)
    assert m.contact["points"]
    assert all(p["gap"] == pytest.approx(G - T_D, rel=1e-9, abs=0) for p in m.contact["points"])


def test_pull_in_from_the_model(piston):
    """V_PI = max over the stable travel of sqrt(2 k x / (dC/dx)) from the MacroModel's own
    capacitance gradient, against sqrt(8 k g_eff^3 / (27 eps0 A)) within 0.5 %; its travel g_eff/3
    lies before the stop at g - t_d."""
    b, _ = piston
    m = b.model
    scale = m.coordinates[0].scale

    def minus_v2(x: float) -> float:
        grad = m.capacitance_gradient(np.array([[-x / scale]]))[0, 0, 0]  # dC/dz, z = -x
        return -2 * K * x / -grad

    res = minimize_scalar(minus_v2, bounds=(0.05 * G_EFF, 0.9 * (G - T_D)), method="bounded", options={"xatol": 1e-18})
    assert math.sqrt(-res.fun) == pytest.approx(pull_in(G_EFF), rel=5e-3)
    assert res.x == pytest.approx(G_EFF / 3, rel=0.02)
    assert G_EFF / 3 < G - T_D


def test_ngspice_op_at_90_percent(piston, tmp_path):
    """ngspice .op of the emitted .lib at 0.9 V_PI: the travel is the series-gap balance's stable
    root k x = eps0 A V^2 / (2 (g_eff - x)^2) within 0.5 %."""
    b, folder = piston
    m = b.model
    volts = 0.9 * pull_in(G_EFF)
    bench = Bench(m, folder / "piston_nitride.lib", sources={"drive": repr(volts), "plate": "0"})
    plot = run_ngspice(bench.netlist(".op"), tmp_path)[0]
    travel = -float(plot["v(x1.xs_z)"][0]) * m.coordinates[0].scale
    root = brentq(lambda x: K * x - epsilon_0 * AREA * volts**2 / (2 * (G_EFF - x) ** 2), 0.0, G_EFF / 3, xtol=1e-18)
    assert travel == pytest.approx(root, rel=5e-3)


def test_header_and_report_state_the_layer(piston):
    b, folder = piston
    layers = b.model.report["electrostatics"]["dielectric_layers"]
    assert layers[0]["effective_gap_m"] == pytest.approx(G_EFF, rel=1e-12, abs=0)
    assert layers[0]["stop_gap_m"] == pytest.approx(G - T_D, rel=1e-12, abs=0)
    text = (folder / "piston_nitride.lib").read_text()
    assert "Dielectric layers" in text and "eps_r 7.5" in text
    html = report.page(b.model, [], {})
    assert 'id="dielectric_layers"' in html and f'data-value="{G - T_D!r}"' in html


def test_squeeze_film_sees_the_air_gap():
    """The gas film ends at the layer's surface: a disk 3 um from its electrodes under 0.3 um
    layers has the damping of the same disk 2.7 um from bare electrodes (Reynolds' equation knows
    only the air gap; the same mesh and modes: equal to rounding, 1e-12)."""
    from tests.mechanics.test_damping import SMALL

    layer = '\ndielectric_thickness = "0.3 um"\ndielectric_permittivity = 3.9\n'
    coarse = SMALL.replace("refine = 5", "refine = 3")  # an equality on one mesh: its fineness is not tested here
    assert coarse != SMALL
    layered = coarse.replace('gap = "3 um"', 'gap = "3 um"' + layer)
    assert layered.count("dielectric_thickness") == 2
    bare = coarse.replace('gap = "3 um"', 'gap = "2.7 um"')
    structures = [parse_structure(text + "[damping]\nsqueeze_film = true\n", "film.toml") for text in (layered, bare)]
    a, b = (damping(s, mechanics(s))[0] for s in structures)  # the build's damping stage, without the fits
    assert a == pytest.approx(b, rel=1e-12, abs=0)
    assert (a > 0).all()


def test_layer_step_force_is_the_derivative():
    """With the edge fringe on, dC/dx (the force term, with parallel_plate.layer_step_slope) against
    the central difference of C at a step of 1e-4 g_eff: truncation (h / g)^2 C''' / 6 C' ~ 1e-8 and
    rounding 1e-16 C / (h C') ~ 1e-12 of C', held to 1e-6."""
    h = SIDE / 2
    e = Electrode(Rectangle("d", -h, h, -h, h), "below", G, "d", T_D, EPS_R)
    p = ParallelPlateExtractor().prepare([e], RectPlate(-h, h, -h, h), lambda x, y: np.ones_like(x))
    dx = 1e-4 * G_EFF
    x = np.array([[0.3 * G_EFF]])
    fd = (p.capacitance(x + dx)[0, 0] - p.capacitance(x - dx)[0, 0]) / (2 * dx)
    assert p.gradient(x)[0, 0, 0] == pytest.approx(fd, rel=1e-6)
