"""The structure texts and re-runs of the process-parameter tests, shared with the bench scripts:
PROOF, the proof mass on folded flexures between plates (tests/model/test_process.py,
tests/emit/test_process_va.py; format with t in um and e in GPa), and the lateral etch bias's cases
(tests/model/test_process_etch.py, bench/process_etch.py): the etch values and range, the proof mass
on four clamped-guided beams (GUIDED, guided), PROOF rewritten at etched widths (proof_text) and its
mechanics re-run there (rerun)."""

from __future__ import annotations

import numpy as np

from netgen import emit
from netgen.mechanics import mechanics
from netgen.structure import parse_structure

from .crab_legs import crab_legs, plate

PROOF = """
name = "pm"
description = "proof mass on folded flexures between plates"
[conductor]
kind = "proof_mass"
length = "300 um"
width = "300 um"
thickness = "{t} um"
density = "2330 kg/m^3"
youngs_modulus = "{e} GPa"
poisson_ratio = 0.22
[conductor.flexure]
type = "folded"
axis = "x"
length = "150 um"
width = "3 um"
truss_width = "10 um"
spacing = "10 um"
[[electrodes]]
name = "top"
side = "above"
gap = "2 um"
[[electrodes]]
name = "bot"
side = "below"
gap = "2 um"
[coordinates]
rigid = ["z", "tilt_x", "tilt_y"]
[sampling]
levels = 3
range = 0.3
[fit]
degree = 2
[electrostatics]
fringe = "none"
[damping]
squeeze_film = true

[process]
parameters = ["dg", "tscale", "escale", "temp"]
"""

ETCHES = (-0.2e-6, 0.1e-6, 0.3e-6)  # m: three values across etch_range
RANGE = '\netch_range = ["-0.2 um", "0.3 um"]'

GUIDED = """
name = "cg"
description = "proof mass on four clamped-guided beams over one plate"
[conductor]
kind = "proof_mass"
length = "200 um"
width = "200 um"
thickness = "{t} um"
density = "2330 kg/m^3"
youngs_modulus = "160 GPa"
poisson_ratio = 0.22
[conductor.flexure]
type = "clamped_guided"
axis = "y"
length = "150 um"
width = "{w} um"
[[electrodes]]
name = "bot"
side = "below"
gap = "2 um"
x = ["-110 um", "110 um"]  # beyond the mass: the plate faces its whole (etched) outline
y = ["-110 um", "110 um"]
[coordinates]
rigid = ["z"]
[sampling]
levels = 3
range = 0.3
[electrostatics]
fringe = "none"
[damping]
rayleigh = {{ alpha = 2000 }}
"""


def guided(t: float = 5.0, w: float = 2.0, process: str = "", side: float = 200.0) -> str:
    """GUIDED at thickness t (um), beam width w (um) and the mass's side (um)."""
    text = GUIDED.format(t=t, w=w) + process
    return text.replace('length = "200 um"\nwidth = "200 um"', f'length = "{side!r} um"\nwidth = "{side!r} um"')


def proof_text(
    t: float = 10.0, width: float = 3.0, truss: float = 10.0, params: str = '["etch"]', side: float = 300.0
) -> str:
    """PROOF at thickness t with its beam and truss widths and the mass's side (um) rewritten, without
    damping."""
    text = PROOF.format(t=t, e=160.0).replace(
        'parameters = ["dg", "tscale", "escale", "temp"]', "parameters = " + params
    )
    text = text.replace('length = "300 um"\nwidth = "300 um"', f'length = "{side!r} um"\nwidth = "{side!r} um"')
    text = text.replace('width = "3 um"', f'width = "{width!r} um"')
    text = text.replace('truss_width = "10 um"', f'truss_width = "{truss!r} um"')
    # without the squeeze film (its Reynolds solve per re-run costs seconds; the etch leaves it alone)
    return text.replace("[damping]\nsqueeze_film = true\n", "") + (RANGE if "etch" in params else "")


def rerun(t: float, etch: float) -> list[tuple[float, float]]:
    """(mass, stiffness) per coordinate of PROOF rewritten at thickness t with the widths and the mass's
    outline etched."""
    e = 2 * etch * 1e6
    s = parse_structure(proof_text(t, 3.0 - e, 10.0 - e, '["tscale"]', 300.0 - e), "pm.toml")
    m = mechanics(s)
    return list(zip(m.masses, m.stiffnesses))


PERFORATED_ETCHES = (-0.1e-6, 0.04e-6, 0.1e-6)  # m: three values across the default etch_range
PERFORATED_RANGE = '[process]\nparameters = ["etch"]\n'  # etch_range: the default +-0.1 um


def perforated(etch: float = 0.0, process: str = "") -> str:
    """accelerometer_xyz's perforated mass on crab legs between its z plates, without the combs (the
    etch refuses comb fingers), drawn at etch 0 (with `process`) or rewritten at the etched sizes: side
    405 - 2 etch, hole 4 + 2 etch, beam and thigh widths 3 - 2 etch (um). 405 um: the fitted hole count,
    40 on the 10 um pitch, is the same at every etched side, as the drawn grid the etch keeps; beams
    3 um, not the example's 2 um: at w = t the frame's torsion constant
    (netgen.mechanics.frame.torsion_constant, Roark's fit with A = max(w, t)) has a kink, which the
    knotted law follows (netgen.model.etch_knots, tests/model/test_process_etch_knots.py); at 3 um the
    knot lies outside the range: the plain cubic."""
    e = 2 * etch * 1e6
    return (
        'name = "px"\ndescription = "perforated proof mass on crab legs between plates"\n'
        + crab_legs(405.0 - e, 2.0, 100.0, width=3.0 - e, hole=4.0 + e)
        + plate("zs", "below")
        + plate("zt", "above")
        + '[coordinates]\nrigid = ["z", "tilt_x", "tilt_y"]\n[sampling]\nlevels = 3\nrange = 0.2\n[fit]\ndegree = 2\n'
        + process
    )


# the [process] table that declares the etch a model parameter (its default range)
ETCH_PROCESS = '[process]\nparameters = ["etch"]\n'


def xyz_etch_text() -> str:
    """The drawn xyz accelerometer with the etch as a parameter: one text, so the session's shared
    build (tests.fixtures.shared_model) serves every module and bench/stop_newton.py."""
    return xyz_text(process=ETCH_PROCESS)


def xyz_text(etch: float = 0.0, process: str = "") -> str:
    """examples/accelerometer_xyz.toml with the textbook comb form (eps t / g per face: the etch's gap
    and overlap shifts are exact for it) and hole_pitch 9.98 um (40 holes at every etched side: the
    drawn grid the etch keeps; at 10 um the file's fitted count drops to 39 at 399.8 um), drawn
    (with `process`) or rewritten at the etched sizes: mass side 400 - 2 etch, hole 4 + 2 etch, legs
    and fingers 2 - 2 etch, finger gaps 1.5 + 2 etch, overlap 30 - 2 etch (um)."""
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "examples" / "accelerometer_xyz.toml").read_text()
    text = text.split("[loop]")[0].replace('comb_model = "field2d"', 'comb_model = "textbook"')
    text = text.replace('hole_pitch = "10 um"', 'hole_pitch = "9.98 um"')
    e = 2 * etch * 1e6
    for old, new in (
        ('length = "400 um"', f'length = "{400.0 - e!r} um"'),
        ('width = "400 um"', f'width = "{400.0 - e!r} um"'),
        ('hole = "4 um"', f'hole = "{4.0 + e!r} um"'),
        ('width = "2 um"', f'width = "{2.0 - e!r} um"'),
        ('gap = "1.5 um"', f'gap = "{1.5 + e!r} um"'),
        ('overlap = "30 um"', f'overlap = "{30.0 - e!r} um"'),
    ):
        text = text.replace(old, new)
    return text + process


TSCALES = (0.9, 1.0, 1.1)  # thickness / nominal: the default tscale_range's ends and the nominal


def xyz_thick(tscale: float = 1.0, process: str = "") -> str:
    """xyz_text (textbook combs) drawn (with `process`) or rewritten at tscale times the 2 um device
    layer: conductor, flexures and comb fingers (both default to the conductor's thickness)."""
    text = xyz_text(process=process)
    assert text.count('thickness = "2 um"') == 1
    return text.replace('thickness = "2 um"', f'thickness = "{2.0 * tscale!r} um"')


def xyz_structure():
    """accelerometer_xyz (xyz_text) with etch declared and the rate w_z (tests/model/test_process_loads.py,
    tests/emit/test_fmu_process.py)."""
    text = xyz_text(process='\n[process]\nparameters = ["etch"]\n')
    text = text.replace('inertial = ["a_x", "a_y", "a_z"]', 'inertial = ["a_x", "a_y", "a_z", "w_z"]')
    return parse_structure(text, "xyz.toml")


def xyz_mass(etch: float) -> float:
    """The hand moving mass of accelerometer_xyz (xyz_text) at etch: the plate 400 um - 2 etch, 40 x 40 holes
    4 um + 2 etch, 80 fingers 2 um - 2 etch wide 40 um beyond the edge, all 2 um thick (rho 2330 kg/m^3)."""
    return 2330.0 * 2e-6 * ((400e-6 - 2 * etch) ** 2 - 1600 * (4e-6 + 2 * etch) ** 2 + 80 * (2e-6 - 2 * etch) * 40e-6)


def control_block(lines: list[str], raw: str) -> str:
    """An ngspice .control block: `lines` (the code model's or the OSDI module's loading), one thread,
    run, and the results written to `raw`."""
    return "\n".join([".control", *lines, "set num_threads=1", "run", f"write {raw}", ".endc"])


def osdi_form(model, folder) -> tuple[str, list[str]]:
    """The model's OSDI form written into `folder` (netgen.emit.write_outputs, openvaf-r): the
    _osdi.lib to include and the control lines that load its module."""
    emit.write_outputs(model, folder, "osdi")
    return str(folder / f"{model.name}_osdi.lib"), [f"pre_osdi {folder / (model.name + '.osdi')}"]


PUSH_PARTS = ("push", "k_x", "k_rot_z", "offset", "stop")  # what pushed_rest's `scale` may perturb


def pushed_rest(model, etch: float, push: float, scale: dict[str, float] | None = None) -> tuple[float, float]:
    """x (um) and rot_z (mrad) of accelerometer_xyz (xyz_text) pushed by `push` (N) along x onto comb
    xp_t's sidewall stop, from the model: K(etch) q = F - k gap^2 (p - delta/2) a / L (netgen.model.contact
    past its ramp), p = a . q / L - 1 - 2 etch / gap (the stop at the widened gap), K from the etch's laws
    (netgen.model.process_values). `scale`: relative factors on PUSH_PARTS (the rest's sensitivities)."""
    from netgen.model.process_values import coordinate_values

    f = {k: 1.0 for k in PUSH_PARTS} | (scale or {})
    names = [c.name for c in model.coordinates]
    vx, vr = names.index("x"), names.index("rot_z")
    pt = next(p for p in model.contact["points"] if p["electrode"] == "xp_t" and p["a"][vx] != 0.0)
    a = np.array([pt["a"][vx] / model.coordinates[vx].scale, pt["a"][vr] / model.coordinates[vr].scale])
    spring = np.diag(
        [coordinate_values(model.process, v, etch=etch)[1] * f[k] for v, k in ((vx, "k_x"), (vr, "k_rot_z"))]
    )
    gain = f["stop"] * model.contact["stiffness"] * pt["gap"] ** 2 * a
    shift = 1 + f["offset"] * 2 * etch / pt["gap"] + model.contact["smoothing"] / 2
    q = np.linalg.solve(spring + np.outer(gain, a), np.array([f["push"] * push, 0.0]) + gain * shift)
    return float(q[0] * 1e6), float(q[1] * 1e3)


def fresh_extractor(s0, scales: np.ndarray):
    """(structure, xs) -> a fresh extractor's capacitances of `structure` at the scaled states xs (rows)
    on the drawn structure s0's mechanics basis (as netgen.build.capacitance_sampler, whose points are
    the laws' own fixed-seed check points): the field solution at points of the caller's choosing."""
    from netgen.electrostatics import extractor
    from netgen.geometry.layout import electrodes, plate_outline

    basis, prepared = mechanics(s0).basis, {}

    def extract(s, xs: np.ndarray) -> np.ndarray:
        if id(s) not in prepared:
            plate = plate_outline(s)
            prepared[id(s)] = (s, extractor(s, plate).prepare(electrodes(s), plate, basis))
        return np.asarray(prepared[id(s)][1].capacitance(np.atleast_2d(xs) * scales), dtype=float)

    return extract


class Drawn:
    """A MacroModel with its capacitance fits replaced by the drawn structure's extractor: its process
    laws (netgen.model.process.capacitance_at) then read the field solution itself, so a comparison
    with the extractor of the etched or scaled structure is the laws' error alone (no fit error)."""

    def __init__(self, model, s0, extract):
        self.process, self.coordinates, self.capacitances = model.process, model.coordinates, model.capacitances
        self.s0, self.extract = s0, extract

    def capacitance(self, x: np.ndarray) -> np.ndarray:
        return self.extract(self.s0, x)


def fresh_points(sampling, n: int, ncoords: int, seed: int) -> np.ndarray:
    """n uniform random scaled states of the fit box from `seed` (not the laws' seed-0 check points,
    netgen.electrostatics.sampling.check_points)."""
    half = sampling.range * (np.array(sampling.factors, dtype=float) if sampling.factors else np.ones(ncoords))
    return np.random.default_rng(seed).uniform(-1.0, 1.0, (n, ncoords)) * half


# the (tscale, etch) cross factor's cases (tests/model/test_process_cross_field2d.py, the shipped comb
# tables' list in tests/electrostatics/test_comb_tables.py, bench/comb_tables.py cross_cells)
CROSS_PROCESS = '[process]\nparameters = ["tscale", "etch"]\n'
CROSS_CORNERS = ((0.9, -1e-7), (0.9, 1e-7), (1.1, -1e-7), (1.1, 1e-7))  # the default ranges' corners
CROSS_INSIDE = ((0.95, 0.04e-6), (1.05, -0.05e-6))  # inside the box, held out of the cross fit
CROSS_REBUILDS = ((0.9, -1e-7), (1.05, -0.05e-6))  # the points rebuilt whole


def field2d_text(tscale: float = 1.0, etch: float = 0.0, process: str = "") -> str:
    """accelerometer_xyz (xyz_text) with its field2d combs, drawn (with `process`) or rewritten at the
    device layer tscale times 2 um and the etched sizes."""
    body = xyz_text(etch, process).replace('comb_model = "textbook"', 'comb_model = "field2d"')
    assert body.count('thickness = "2 um"') == 1
    return body.replace('thickness = "2 um"', f'thickness = "{2.0 * tscale!r} um"')
