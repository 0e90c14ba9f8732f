"""The lateral etch on plates (netgen.model.etch_geometry.etched_plate): a piston's length and width
- 2 etch, a free disk's radius - etch, an electrode edge drawn on the plate's receding with it, the
springs given as numbers kept; against closed forms and full rebuilds of the structure file rewritten
at three etches of the range (tests/oracles/plate_etch).

The piston (examples/piston.toml, fringe "none", its electrode the whole plate):
- C = eps A / (g - z) exactly, so the etch law's ratio is the area ratio (L - 2 etch)(W - 2 etch) / (L W)
  at every state, no shift and no state factor: the ratio against it within the stated capacitance
  error + 1e-12 (power_fit's round-off floor, netgen.model.process.ROUND_OFF); the mass rho t (L - 2
  etch)(W - 2 etch) the same ratio, the spring unchanged, f = sqrt(k / m) times 1 / (1 - 2 etch / L):
  within the stated mechanics error + 1e-12 (the brief's acceptance: 1e-4).
- capacitances at 100 points of the fit box: the law against the rebuild's fit, within the two fits'
  held-out errors plus the law's stated error (first order) + 1e-12.
- pull-in: V^2 = 2 k s / C'(s) maximised over s (tests/oracles/process_balance.pull_in). Against the
  closed form sqrt(8 k g^3 / (27 eps A_etched)): a fit residual |r| <= e C on the box |q| <= R has a
  relative slope error <= 4 e / R (Markov's inequality, as in tests/model/test_process_pull_in.py),
  halved by the square root: 2 (e_0 + e_c) / R + 1e-9 (the grid's parabola refinement); against the
  rebuild's the same with its fit's error added. Both below the brief's 0.05 % and 0.2 %.

The rigid free disk (z, tilts; rings to the rim; the squeeze film on a coarse Reynolds mesh):
- mass pi R'^2 t rho and the tilts' inertia m (R'^2 / 4 + t^2 / 12) against the rebuild's (the same
  closed forms): within the stated mechanics error + 1e-12. The squeeze film on the disk's mesh
  scaled to R' with the gap and so mu_eff unchanged: z's b = 3 pi mu R^4 / (2 g^3) times (R' / R)^4,
  the tilts' ~ R^6; the law's film part against the rebuild's within the stated error + 1e-12 and
  the closed-form ratios within the same (the Reynolds solve on a scaled mesh scales exactly).
- capacitances at 100 points inside 0.99 of the fit box (an under-etched rebuild's tilt scale g / R'
  is smaller, so the same angles reach 1.0017 of its box) at the same physical state: the law (ratio,
  the rim's z shift, the state factor) against the rebuild's fit within the two fits' held-out errors
  plus the law's stated error + 1e-12.
- the z force at rest, as the voltage balancing the weight (test_disk_gravity_balance): the fits'
  slope bound.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from netgen.core.constants import EPS0
from netgen.core.errors import StructureError
from netgen.model.etch_knots import edge_knots
from netgen.model.process import capacitance_at, coordinate_values, ratio_value
from netgen.structure import parse_structure
from netgen.sweep.point import at_point
from tests.fixtures import shared_model as build_model
from tests.oracles.plate_etch import (
    ETCHES,
    GAP,
    RADIUS,
    SIDE,
    STIFFNESS,
    area_ratio,
    disk_text,
    modal_disk_text,
    piston_text,
    tilted_piston_text,
)
from tests.oracles.process_balance import LawAt, balance_voltage, pull_in


@pytest.fixture(scope="module")
def piston():
    return build_model(parse_structure(piston_text(), "piston.toml"))


@pytest.fixture(scope="module")
def piston_rebuilds():
    return {e: build_model(parse_structure(piston_text(e, ""), "piston.toml")) for e in ETCHES}


@pytest.fixture(scope="module")
def disk():
    return build_model(parse_structure(disk_text(), "disk.toml"))


@pytest.fixture(scope="module")
def disk_rebuilds():
    return {e: build_model(parse_structure(disk_text(e, ""), "disk.toml")) for e in ETCHES}


def box(model) -> np.ndarray:
    """The fit box's half-widths per coordinate (scaled)."""
    rng = model.sampling.get("coordinate_range", {})
    return np.array([rng.get(c.name, model.sampling["range"]) for c in model.coordinates])


def test_piston_closed_form(piston):
    """The area ratio, exact: no shift, no state factor; mass times it, the spring kept, f over it."""
    law = piston.process["etch"]
    (cap,) = law["capacitance"]
    assert set(cap) == {"electrode", "ratio"} and law["plate"] == "piston"
    (c,) = piston.coordinates
    for etch in np.linspace(-0.5e-6, 1e-6, 7):
        assert ratio_value(cap["ratio"], etch) == pytest.approx(
            area_ratio(etch), rel=law["capacitance_max_rel_error"] + 1e-12
        )
        mass, k, _ = coordinate_values(piston.process, 0, etch=etch)
        assert mass / c.mass == pytest.approx(area_ratio(etch), rel=law["max_rel_error"] + 1e-12)
        assert k == pytest.approx(STIFFNESS, rel=1e-15)
        f = math.sqrt(k / mass) / (2 * math.pi)
        assert f / c.frequency_hz == pytest.approx(1 / math.sqrt(area_ratio(etch)), rel=law["max_rel_error"] + 1e-12)


@pytest.mark.parametrize("etch", ETCHES)
def test_piston_against_rebuild(piston, piston_rebuilds, etch):
    """Frequency and the capacitances at 100 points of the fit box against the rebuild (module docstring)."""
    ref, law = piston_rebuilds[etch], piston.process["etch"]
    mass, k, _ = coordinate_values(piston.process, 0, etch=etch)
    f = math.sqrt(k / mass) / (2 * math.pi)
    assert f == pytest.approx(ref.coordinates[0].frequency_hz, rel=law["max_rel_error"] + 1e-12)
    assert np.allclose(piston.scales, ref.scales, rtol=1e-15)
    x = np.random.default_rng(3).uniform(-1.0, 1.0, (100, piston.ncoords)) * box(piston)
    fits = piston.capacitances[0].max_rel_error + ref.capacitances[0].max_rel_error
    tol = fits + law["capacitance_max_rel_error"] + 1e-12
    np.testing.assert_allclose(capacitance_at(piston, x, etch), ref.capacitance(x), rtol=tol)


@pytest.mark.parametrize("etch", ETCHES)
def test_piston_pull_in(piston, piston_rebuilds, etch):
    """The law's pull-in against sqrt(8 k g^3 / (27 eps A_etched)) and the rebuild's (module docstring)."""
    ref, law = piston_rebuilds[etch], piston.process["etch"]
    k = [coordinate_values(piston.process, 0, etch=etch)[1]]
    v_law = pull_in(LawAt(piston, etch), k)
    v_closed = math.sqrt(8 * STIFFNESS * GAP**3 / (27 * EPS0 * SIDE**2 * area_ratio(etch)))
    v_ref = pull_in(ref, [ref.coordinates[0].stiffness])
    r = piston.sampling["range"]
    e0, e1 = piston.capacitances[0].max_rel_error, ref.capacitances[0].max_rel_error
    closed = 2 * (e0 + law["capacitance_max_rel_error"]) / r + 1e-9
    rebuilt = 0.5 * law["max_rel_error"] + 2 * (e0 + e1 + law["capacitance_max_rel_error"]) / r + 1e-9
    print(f"etch {etch:+.1e}: pull-in {v_law:.6f} V, closed form {v_closed:.6f} V, rebuilt {v_ref:.6f} V")
    assert closed < 5e-4 and rebuilt < 2e-3
    assert v_law == pytest.approx(v_closed, rel=closed)
    assert v_law == pytest.approx(v_ref, rel=rebuilt)


@pytest.mark.parametrize("etch", ETCHES)
def test_disk_against_rebuild(disk, disk_rebuilds, etch):
    """Masses, inertias and the squeeze film against the rebuild and (R' / R)^4, ^6; the capacitances at
    100 points against the rebuild's fit at the same physical state (module docstring)."""
    ref, law = disk_rebuilds[etch], disk.process["etch"]
    rho = (RADIUS - etch) / RADIUS
    film = {"z": rho**4, "tilt_x": rho**6, "tilt_y": rho**6}
    for v, c in enumerate(disk.coordinates):
        mass, _, damp = coordinate_values(disk.process, v, etch=etch)
        assert mass == pytest.approx(ref.coordinates[v].mass, rel=law["max_rel_error"] + 1e-12)
        assert damp == pytest.approx(ref.coordinates[v].damping, rel=law["max_rel_error"] + 1e-12)
        assert damp / c.damping == pytest.approx(film[c.name], rel=law["max_rel_error"] + 1e-12)
    x = np.random.default_rng(3).uniform(-0.99, 0.99, (100, disk.ncoords)) * box(disk)
    fits = max(f.max_rel_error for f in disk.capacitances) + max(f.max_rel_error for f in ref.capacitances)
    tol = fits + law["capacitance_max_rel_error"] + 1e-12
    got = capacitance_at(disk, x, etch)
    np.testing.assert_allclose(got, ref.capacitance(x * disk.scales / ref.scales), rtol=tol)


def top_slope(model, etch: float | None = None) -> float:
    """sum over the top electrodes of dC/dz (F/m) at rest: the model's fit, or with `etch` the etch law
    (tests/oracles/process_balance.LawAt: ratio, shift, state factor)."""
    reader = model if etch is None else LawAt(model, etch)
    top = [i for i, f in enumerate(model.capacitances) if f.electrode.startswith("top")]
    v = [c.name for c in model.coordinates].index("z")
    return float(reader.capacitance_gradient(np.zeros((1, model.ncoords)))[0, top, v].sum())


@pytest.mark.parametrize("etch", ETCHES)
def test_disk_gravity_balance(disk, disk_rebuilds, etch):
    """The voltage on the top electrodes holding the etched disk against gravity, V^2 = 2 M g / sum
    dC_top/dz, from the laws (mass, the capacitance law's slope) against the rebuild's: the slopes are
    read from fits, each with a relative slope error <= 4 e / R for a residual e over the box |z| <= R g
    (Markov's inequality, tests/model/test_process_pull_in.py), e the nominal's and the rebuild's
    held-out errors and the law's stated error, halved by the square root: 2 (e_0 + e_1 + e_c) / R."""
    ref, law = disk_rebuilds[etch], disk.process["etch"]
    mass = coordinate_values(disk.process, 0, etch=etch)[0]
    v_law = balance_voltage(top_slope(disk, etch), mass)
    v_ref = balance_voltage(top_slope(ref), ref.coordinates[0].mass)
    e0, e1 = (max(f.max_rel_error for f in m.capacitances) for m in (disk, ref))
    bound = 2 * (e0 + e1 + law["capacitance_max_rel_error"]) / disk.sampling["range"]
    print(
        f"etch {etch:+.1e}: balance {v_law:.6f} V, rebuilt {v_ref:.6f} V ({v_law / v_ref - 1:+.1e}, bound {bound:.1e})"
    )
    assert v_law == pytest.approx(v_ref, rel=bound)


@pytest.mark.parametrize("etch", ETCHES)
def test_tilted_piston_against_rebuild(etch):
    """The piston with its tilts (one 0.4 s build and a 0.3 s rebuild): the tilts' frequencies sqrt(k_t /
    I), I = m' (L - 2 etch)^2 / 12 (netgen.mechanics.piston; degree 4 in etch) with the spring kept, against the rebuild's within the stated
    error + 1e-12; the capacitances (a state factor: the rim strip under the tilts) at 100 points
    inside 0.99 of the box at the same physical state (the rebuild's tilt scale g / (L' / 2)) within the
    two fits' held-out errors plus the law's stated error + 1e-12."""
    model = build_model(parse_structure(tilted_piston_text(), "piston.toml"))
    ref = build_model(parse_structure(tilted_piston_text(etch, ""), "piston.toml"))
    law = model.process["etch"]
    for v, c in enumerate(ref.coordinates):
        mass, k, _ = coordinate_values(model.process, v, etch=etch)
        assert math.sqrt(k / mass) / (2 * math.pi) == pytest.approx(c.frequency_hz, rel=law["max_rel_error"] + 1e-12)
    x = np.random.default_rng(3).uniform(-0.99, 0.99, (100, model.ncoords)) * box(model)
    fits = max(f.max_rel_error for f in model.capacitances) + max(f.max_rel_error for f in ref.capacitances)
    tol = fits + law["capacitance_max_rel_error"] + 1e-12
    got = capacitance_at(model, x, etch)
    np.testing.assert_allclose(got, ref.capacitance(x * model.scales / ref.scales), rtol=tol)


@pytest.fixture(scope="module")
def modal_disk():
    return build_model(parse_structure(modal_disk_text(), "modal.toml"))


def test_modal_disk(modal_disk):
    """A free disk's (2,0) mode: the Morley modes live on the unit disk scaled to R (netgen.mechanics.
    free_disk), so f ~ 1 / R'^2 and the peak-normalised modal mass ~ R'^2 (within the stated error +
    1e-12: f is a Rayleigh quotient of the same vector); against a rebuild at the range's top (the
    largest change; one rebuild, 10 s) the frequency within the same and the capacitances at 100 points
    (the etched disk's own modes in the law's sampler, netgen.build.capacitance_sampler, as the
    rebuild's coordinates are) within the two fits' held-out errors plus the law's stated error."""
    law = modal_disk.process
    stated = law["etch"]["max_rel_error"]
    c = modal_disk.coordinates[1]
    for etch in ETCHES:
        rho = (RADIUS - etch) / RADIUS
        mass, k, _ = coordinate_values(law, 1, etch=etch)
        assert mass / c.mass == pytest.approx(rho**2, rel=stated + 1e-12)
        assert math.sqrt(k / mass) / (2 * math.pi) / c.frequency_hz == pytest.approx(rho**-2, rel=stated + 1e-12)
    etch = ETCHES[-1]
    ref = build_model(parse_structure(modal_disk_text(etch, ""), "modal.toml"))
    mass, k, _ = coordinate_values(law, 1, etch=etch)
    assert math.sqrt(k / mass) / (2 * math.pi) == pytest.approx(ref.coordinates[1].frequency_hz, rel=stated + 1e-12)
    assert np.allclose(modal_disk.scales, ref.scales, rtol=1e-15)  # z and a mode: the gap, whatever R
    x = np.random.default_rng(3).uniform(-1.0, 1.0, (100, modal_disk.ncoords)) * box(modal_disk)
    fits = max(f.max_rel_error for f in modal_disk.capacitances) + max(f.max_rel_error for f in ref.capacitances)
    tol = fits + law["etch"]["capacitance_max_rel_error"] + 1e-12
    np.testing.assert_allclose(capacitance_at(modal_disk, x, etch), ref.capacitance(x), rtol=tol)


def test_plate_knots():
    """Where the etched piston's edges (+-(L - 2 etch) / 2) meet an electrode's edge drawn off the
    plate's: x1 0.2 um inside (at etch 0.2 um), y1 0.3 um past (at -0.3 um); none where drawn on it."""
    lo, hi = -0.5e-6, 1e-6
    assert edge_knots(parse_structure(piston_text(), "p.toml"), lo, hi) == ()
    text = piston_text().replace(
        'gap = "2 um"\n', 'gap = "2 um"\nx = ["-100 um", "99.8 um"]\ny = ["-100 um", "100.3 um"]\n', 1
    )
    assert edge_knots(parse_structure(text, "p.toml"), lo, hi) == pytest.approx((-0.3, 0.2))


def test_knotted_piston_area():
    """The electrode's x1 drawn 0.2 um inside the plate's edge (its other edges on the plate's): the
    facing area is (min(x1, L / 2 - etch) + L / 2 - etch)(W - 2 etch), a kink at etch 0.2 um. With
    fringe "none" C ~ that area, and the knotted ratio (a cubic on each side, joined there) carries it
    at rest within the stated capacitance error + 1e-12, in the law and in a sweep's model at the point
    (netgen.sweep.point.at_point)."""
    text = piston_text().replace('gap = "2 um"\n', 'gap = "2 um"\nx = ["-100 um", "99.8 um"]\n', 1)
    model = build_model(parse_structure(text, "piston.toml"))
    law = model.process["etch"]
    assert law["knots"] == pytest.approx([0.2])
    rest = np.zeros((1, 1))
    c0 = model.capacitance(rest)[0, 0]
    half, x1 = SIDE / 2, 99.8e-6
    for etch in np.linspace(-0.5e-6, 1e-6, 7):
        area = (min(x1, half - etch) + half - etch) * (SIDE - 2 * etch) / ((x1 + half) * SIDE)
        tol = law["capacitance_max_rel_error"] + 1e-12
        assert capacitance_at(model, rest, etch)[0, 0] / c0 == pytest.approx(area, rel=tol)
        assert at_point(model, {"etch": etch}).capacitance(rest)[0, 0] / c0 == pytest.approx(area, rel=tol)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (
            [('length = "200 um"', 'length = "20 um"'), ('"1 um"]', '"5 um"]')],
            "half or more of the plate's narrower side",
        ),
        ([('gap = "2 um"\n', 'gap = "2 um"\nx = ["99.5 um", "100 um"]\n')], "overlap with the plate vanishes"),
    ],
)
def test_piston_refused(edit, message):
    """A range whose top removes half the plate's narrower side (5 um a side of 20 um), or passes an
    electrode's far edge: exit 2 at process.etch_range, naming the fix."""
    text = piston_text()
    for old, new in edit:
        assert old in text
        text = text.replace(old, new, 1)
    with pytest.raises(StructureError) as exc:
        parse_structure(text, "piston.toml")
    assert (
        "process.etch_range" in str(exc.value) and message in str(exc.value) and "narrow etch_range" in str(exc.value)
    )


def test_disk_refused():
    """A ring starting 0.5 um inside the rim with the range's top at 1 um: its overlap vanishes."""
    text = disk_text().replace('["20 um", "300.0 um"]', '["299.5 um", "300.0 um"]')
    with pytest.raises(StructureError) as exc:
        parse_structure(text, "disk.toml")
    assert "process.etch_range" in str(exc.value) and "'top'" in str(exc.value)


def test_disk_compressible_film_refused():
    """The compressible film's branches would keep the drawn disk's outline: exit 2 at
    process.parameters, naming the incompressible film as the fix."""
    text = disk_text().replace("squeeze_film = true\n", 'squeeze_film = true\nfilm_model = "compressible"\n')
    with pytest.raises(StructureError) as exc:
        parse_structure(text, "disk.toml")
    assert "process.parameters" in str(exc.value) and 'film_model = "incompressible"' in str(exc.value)
