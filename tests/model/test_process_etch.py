"""The lateral etch bias (process parameter etch, netgen.model.process.etch_laws): the flexure laws
against closed forms and against the mechanics re-run from the structure file rewritten with the
etched widths, and the emitted .lib's etch in ngspice 39 and 46.

Tolerances:
- clamped-guided beams (Euler-Bernoulli frame elements, netgen.mechanics.flexures): k across the
  beams ~ t w^3 and k_z ~ w t^3 exactly, so the etch ratios are ((w - 2e)/w)^3 and (w - 2e)/w, and
  the etched outline's mass ((L - 2e)/L)^2; the cubic fit of a cubic is exact up to the least
  squares' round-off (Vandermonde of etch / 1 um over +-0.3 um: condition near 1e3, times the frame
  solve's 1e-13): 1e-9.
- the folded flexure's frame (trusses in series with the beams) is not a power law of w: the law is
  a cubic fit whose residual is the model's stated etch error; the modal frequencies of the law
  against the re-run at three etch values are held to the brief's 1e-4 and to half the stated
  error (f ~ sqrt(k): a relative k error e gives e / 2 in f), whichever is larger.
- with tscale as well, the law is the product of the tscale and etch laws; at the corners of the
  box its misfit is part of the stated error, so the stiffness there is held to that error.
- .ac of the .lib, the _xspice.lib and the .va through OSDI (a linear model, 1/H = k - m w^2; m of
  the etched outline, rho t (200 um - 2 etch)^2):
  ngspice's linear solve to round-off, 1e-9, against the clamped-guided closed form (exact law).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from netgen import emit
from netgen.core.constants import EPS0
from netgen.core.errors import StructureError
from netgen.emit import ngspice as emit_ngspice
from netgen.mechanics import mechanics
from netgen.model.process import capacitance_at, coordinate_values, process_laws
from netgen.sim.ngspice import run_ngspice
from netgen.structure import parse_structure
from netgen.testbench.sigma_delta import ngspice as sdn
from tests.fixtures import NGSPICE
from tests.fixtures import shared_model as build_model
from tests.oracles.process_cases import ETCHES, RANGE, guided, proof_text, rerun, xyz_text


@pytest.fixture(scope="module")
def guided_model():
    return build_model(parse_structure(guided(process='[process]\nparameters = ["etch"]' + RANGE), "cg.toml"))


@pytest.fixture(scope="module")
def guided_laws():
    """The process laws of the clamped-guided mass with x, y and z (the model stage alone: an in-plane
    coordinate has no plate to sample, so no full build), and its nominal mechanics."""
    text = guided(process='[process]\nparameters = ["etch"]' + RANGE).replace(
        'rigid = ["z"]', 'rigid = ["z", "x", "y"]'
    )
    s = parse_structure(text, "cg.toml")
    m = mechanics(s)
    return process_laws(s, m, mechanics, [], 0.0, 0.3), m


@pytest.mark.parametrize("etch", ETCHES)
def test_clamped_guided_against_closed_form(guided_laws, etch):
    """Beams along y: k_x (bending in plane) ~ w^3, k_y (axial) ~ w, k_z (out of plane) ~ w; the
    200 um square mass m = rho t (200 um - 2 etch)^2 (a quadratic: its cubic fit is exact)."""
    law, m = guided_laws
    ratio = (2.0 - 2 * etch * 1e6) / 2.0
    for name, power in (("x", 3), ("y", 1), ("z", 1)):
        v = list(m.names).index(name)
        mass, k, _ = coordinate_values(law, v, etch=etch)
        assert mass == pytest.approx(2330 * 5e-6 * (200e-6 - 2 * etch) ** 2, rel=1e-9, abs=0)
        assert k / m.stiffnesses[v] == pytest.approx(ratio**power, rel=1e-9)
    assert law["etch"]["max_rel_error"] < 1e-9


@pytest.mark.parametrize("etch", [-0.2e-6, 0.3e-6])
def test_full_rebuild_at_the_etched_widths(guided_model, etch):
    """The whole build of the file rewritten at w - 2 etch and the mass's side 200 um - 2 etch: its
    modal frequency against the law's (exact law: 1e-9 as above); its capacitances at 100 points of
    the fit box against the nominal model's times the etch ratio (netgen.model.process.capacitance_at)
    within the larger fit error plus the ratio's stated error (0 here: the plate is wider than the
    mass, so C ~ (200 um - 2 etch)^2 exactly, a quadratic), and the ratio against that closed form."""
    side = 200.0 - 2 * etch * 1e6
    model = build_model(parse_structure(guided(w=2.0 - 2 * etch * 1e6, side=side), "cg.toml"))
    c, ref = guided_model.coordinates[0], model.coordinates[0]
    m, k, _ = coordinate_values(guided_model.process, 0, etch=etch)
    assert math.sqrt(k / m) == pytest.approx(math.sqrt(ref.stiffness / ref.mass), rel=1e-9)
    law = guided_model.process["etch"]
    assert law["capacitance_max_rel_error"] == 0.0
    (ratio,) = [r["ratio"] for r in law["capacitance"]]
    assert ratio == pytest.approx([1.0, -0.02, 1e-4, 0.0], abs=1e-12)  # (1 - 2 (etch / 1 um) / 200)^2
    q = np.random.default_rng(7).uniform(-0.2, 0.2, (100, 1))
    errs = [f.max_rel_error for f in guided_model.capacitances + model.capacitances]
    assert ref.scale == c.scale  # the same touching amplitude: the same scaled points
    np.testing.assert_allclose(capacitance_at(guided_model, q, etch), model.capacitance(q), rtol=max(errs) + 1e-12)


def guided_reach(w: float = 2.0, side: float = 200.0, process: bool = True):
    """The clamped-guided mass (GUIDED) at beam width w and side (um), sampled to 0.6 of the gap on
    5 levels (its pull-in travel is g/3); with the etch parameter, or without (the full rebuild)."""
    text = guided(w=w, side=side, process=('[process]\nparameters = ["etch"]' + RANGE) if process else "")
    text = text.replace("levels = 3", "levels = 5").replace("range = 0.3", "range = 0.6")
    assert "levels = 5" in text and "range = 0.6" in text
    return build_model(parse_structure(text, "cg.toml"))


def pull_in_etched(model, k: float, etch: float) -> float:
    """max over the travel q < 0 of sqrt(2 k q / C'(q)), C at the etch bias as the emitters render it
    (capacitance_at), on a 20001-point grid refined by a parabola through the best three."""
    scale = model.coordinates[0].scale
    q = -np.linspace(1e-4, 0.55, 20001) * scale
    h = 1e-6 * scale

    def cap(x: np.ndarray) -> np.ndarray:
        return capacitance_at(model, x[:, None] / scale, etch)[:, 0]

    v2 = 2 * k * q / ((cap(q + h) - cap(q - h)) / (2 * h))
    j = int(np.argmax(v2))
    a, b, c = v2[j - 1 : j + 2]
    return math.sqrt(b + (c - a) ** 2 / (8 * (2 * b - a - c)))


@pytest.fixture(scope="module")
def guided_pull_in_model():
    return guided_reach()


@pytest.mark.parametrize("etch", ETCHES)
def test_pull_in_under_etch(guided_pull_in_model, etch):
    """The clamped-guided mass's pull-in at the etch bias (three values across etch_range) against
    sqrt(8 k g^3 / (27 eps A)) with four clamped-guided Euler-Bernoulli beams out of plane,
    k = 4 E (w - 2 etch) t^3 / L^3, and the etched outline A = (200 um - 2 etch)^2 (the plate is wider
    than the mass), and against a full rebuild at those widths. Bound: half the etch law's stated
    stiffness error (V ~ sqrt(k); under 1e-9, see test_clamped_guided_against_closed_form) plus the
    capacitance ratio's stated error (0: a quadratic), the grid's quadratic error (~1e-9) and, against
    the rebuild, the two plate fits' slope errors by Markov's inequality (4 e / R each; e round-off)."""
    nominal = guided_pull_in_model
    law = nominal.process["etch"]
    k = coordinate_values(nominal.process, 0, etch=etch)[1]
    v_model = pull_in_etched(nominal, k, etch)
    w, side = 2e-6 - 2 * etch, 200e-6 - 2 * etch
    k_closed = 4 * 160e9 * w * 5e-6**3 / 150e-6**3
    v_closed = math.sqrt(8 * k_closed * 2e-6**3 / (27 * EPS0 * side**2))
    rebuilt = guided_reach(w * 1e6, side * 1e6, process=False)
    v_rebuilt = pull_in_etched(rebuilt, rebuilt.coordinates[0].stiffness, 0.0)
    print(
        f"etch={etch:.1e}: {v_model:.10g} V, closed form {v_model / v_closed - 1:.1e}, rebuilt {v_model / v_rebuilt - 1:.1e}"
    )
    bound = 0.5 * max(law["max_rel_error"], 1e-9) + law["capacitance_max_rel_error"] + 1e-9
    assert v_model == pytest.approx(v_closed, rel=bound)
    errors = [f.max_rel_error for f in nominal.capacitances + rebuilt.capacitances]
    markov = 4 * max(errors) / nominal.sampling["range"]
    assert v_model == pytest.approx(v_rebuilt, rel=bound + 1e-9 + 2 * markov)


@pytest.fixture(scope="module")
def folded():
    return build_model(parse_structure(proof_text(params='["tscale", "etch"]'), "pm.toml"))


@pytest.mark.parametrize("etch", ETCHES)
def test_folded_frequencies_against_rerun(folded, etch):
    """The folded flexure's modal frequencies from the laws against the re-run at the etched widths."""
    err = folded.process["etch"]["max_rel_error"]
    for v, (m, k) in enumerate(rerun(10.0, etch)):
        mm, kk, _ = coordinate_values(folded.process, v, etch=etch)
        assert math.sqrt(kk / mm) / math.sqrt(k / m) == pytest.approx(1.0, abs=max(1e-4, err / 2))


def test_folded_corners_within_stated_error(folded):
    """At the (tscale, etch) box's corners the product law's stiffness within the stated error."""
    err = folded.process["etch"]["max_rel_error"]
    assert 0 < err < 0.01  # the frame's torsion is not separable in t and w: a finite, small misfit
    for tau in (0.9, 1.1):
        for etch in (-0.2e-6, 0.3e-6):
            for v, (_, k) in enumerate(rerun(10.0 * tau, etch)):
                assert coordinate_values(folded.process, v, tscale=tau, etch=etch)[1] == pytest.approx(
                    k, rel=err * 1.001
                )


@pytest.mark.parametrize("etch", ETCHES)
def test_lib_ac_with_etch(guided_model, tmp_path, ngspice_version, etch):
    """.ac of the emitted .lib from f_z to x_z at the instance's etch: k and m against the closed forms."""
    c = guided_model.coordinates[[c.name for c in guided_model.coordinates].index("z")]
    (tmp_path / "cg.lib").write_text(emit_ngspice.subcircuit(guided_model))
    net = f"""* ac
.include {tmp_path / "cg.lib"}
Vf fz 0 DC 0 AC 1
X1 0 0 fz xz cg etch={etch!r}
.ac lin 3 1k 30k
.end
"""
    plot = run_ngspice(net, tmp_path)[0]
    w = 2 * np.pi * np.real(plot["frequency"])
    inv = 1.0 / plot["v(xz)"]  # x_z in um per uN = m/N: 1/H in N/m
    (k, m), *_ = np.linalg.lstsq(np.stack([np.ones_like(w), -(w**2)], axis=1), inv.real, rcond=None)
    assert k == pytest.approx(c.stiffness * (1 - etch * 1e6), rel=1e-9)
    assert m == pytest.approx(c.mass * (1 - 2 * etch / 200e-6) ** 2, rel=1e-9, abs=0)  # the etched outline


@pytest.mark.parametrize("etch", ETCHES)
def test_osdi_ac_with_etch(guided_model, tmp_path, monkeypatch, etch):
    """The same through the .va compiled by openvaf-r (`--format osdi`) in ngspice 46."""
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    c = guided_model.coordinates[0]
    emit.write_outputs(guided_model, tmp_path, "osdi")
    net = f"""* ac osdi
.include {tmp_path / "cg_osdi.lib"}
Vf fz 0 DC 0 AC 1
X1 0 0 fz xz cg etch={etch!r}
.ac lin 3 1k 30k
.control
pre_osdi {tmp_path / "cg.osdi"}
set num_threads=1
run
write circuit.raw
.endc
.end
"""
    plot = run_ngspice(net, tmp_path / "run")[0]
    w = 2 * np.pi * np.real(plot["frequency"])
    inv = 1.0 / plot["v(xz)"]
    (k, m), *_ = np.linalg.lstsq(np.stack([np.ones_like(w), -(w**2)], axis=1), inv.real, rcond=None)
    assert k == pytest.approx(c.stiffness * (1 - etch * 1e6), rel=1e-9)
    assert m == pytest.approx(c.mass * (1 - 2 * etch / 200e-6) ** 2, rel=1e-9, abs=0)  # the etched outline


@pytest.mark.parametrize("etch", [-0.2e-6, 0.3e-6])
def test_xspice_ac_with_etch(guided_model, tmp_path, etch):
    """The same through the _xspice.lib (netgen_es code model, ngspice 39 as installed)."""
    c = guided_model.coordinates[0]
    xlib, control = sdn.xspice_library(guided_model, tmp_path, sdn.code_models(False))
    lines = "\n".join(control)
    net = f"""* ac xspice
.include {xlib.resolve()}
Vf fz 0 DC 0 AC 1
X1 0 0 fz xz cg etch={etch!r}
.ac lin 3 1k 30k
.control
{lines}
run
write ac.raw
.endc
.end
"""
    plot = run_ngspice(net, tmp_path)[0]
    w = 2 * np.pi * np.real(plot["frequency"])
    inv = 1.0 / plot["v(xz)"]
    (k, m), *_ = np.linalg.lstsq(np.stack([np.ones_like(w), -(w**2)], axis=1), inv.real, rcond=None)
    assert k == pytest.approx(c.stiffness * (1 - etch * 1e6), rel=1e-9)
    assert m == pytest.approx(c.mass * (1 - 2 * etch / 200e-6) ** 2, rel=1e-9, abs=0)  # the etched outline


@pytest.mark.parametrize(
    "process, key",
    [
        ('parameters = ["etch"]\netch_range = ["-0.2 um", "0.6 um"]', "process.etch_range"),
        ('parameters = ["etch"]\netch_range = ["0 um", "0.1 um"]', "process.etch_range"),
        ('parameters = ["tscale"]\netch_range = ["-0.1 um", "0.1 um"]', "process.etch_range"),
    ],
)
def test_bad_etch_tables(process, key):
    """An etch range eating half a beam, not around 0, or without etch declared: exit 2 naming the key."""
    with pytest.raises(StructureError) as exc:
        parse_structure(guided(process="[process]\n" + process), "cg.toml")
    assert key in str(exc.value)


def test_etch_refused_without_beams():
    """A proof mass on given springs (no flexure beams; a piston's outline etches since plates have
    their law, tests/model/test_process_etch_plates.py): exit 2 at process.parameters."""
    text = guided(process='[process]\nparameters = ["etch"]\n')
    old = 'type = "clamped_guided"\naxis = "y"\nlength = "150 um"\nwidth = "2.0 um"'
    assert old in text
    text = text.replace(old, 'type = "given"\nk_z = 2.0')
    with pytest.raises(StructureError) as exc:
        parse_structure(text, "given.toml")
    assert "process.parameters" in str(exc.value) and "or a proof mass with a flexure" in str(exc.value)


@pytest.mark.parametrize(
    ("old", "new", "reason"),
    [
        ('width = "2.0 um"\ngap = "1.5 um"', 'width = "1.0 um"\ngap = "1.5 um"', "comb xp_t's fingers"),
        ('hole = "4.0 um"', 'hole = "9.5 um"', "etch holes"),
    ],
)
def test_etch_range_eating_fingers_or_merging_holes(old, new, reason):
    """accelerometer_xyz's fingers narrowed to 1 um, or its holes widened to 9.5 um on the 9.98 um pitch,
    with etch_range up to 0.3 um: a finger loses half its width, the holes merge: exit 2 at
    process.etch_range."""
    text = xyz_text(process='[process]\nparameters = ["etch"]\netch_range = ["-0.1 um", "0.3 um"]\n')
    assert old in text
    with pytest.raises(StructureError) as exc:
        parse_structure(text.replace(old, new), "xyz.toml")
    assert "process.etch_range" in str(exc.value) and reason in str(exc.value)
