"""The build pipeline: structure -> mechanics -> electrostatics -> fit -> MacroModel.

Data flows one way; each stage is a function of the previous stage's output.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
from tqdm import tqdm

from . import electrostatics as es
from . import mechanics as mech
from .fit import CapacitanceFit, fit_capacitance, fit_plates, holdout_points, sampling_grid
from .model import Coordinate, Electrode, MacroModel
from .structure import Structure

EPS0 = 8.8541878128e-12


@dataclass
class Mechanics:
    """Stage output: coordinates (without scales yet) and the vertical displacement basis."""
    names: list[str]
    kinds: list[str]
    units: list[str]
    labels: list[str]
    masses: np.ndarray
    stiffnesses: np.ndarray
    frequencies: np.ndarray
    basis: Callable[[np.ndarray, np.ndarray], np.ndarray]
    report: dict


def mechanics(s: Structure) -> Mechanics:
    """Rigid-body masses and FEM eigenmodes of the conductor, as generalized coordinates."""
    if s.conductor.kind != "free_disk":                   # piston, beams (netgen.suspended)
        from . import suspended
        return suspended.mechanics(s)
    d = s.conductor
    body = mech.rigid_disk(d.radius, d.thickness, d.density)
    rigid_mass = {"z": body.mass, "tilt_x": body.inertia[0, 0], "tilt_y": body.inertia[1, 1]}
    modes = None
    if s.coordinates.modes:
        modes = mech.free_disk_modes(d.radius, d.thickness, d.youngs_modulus, d.poisson_ratio, d.density,
                                     list(s.coordinates.modes) if not isinstance(s.coordinates.modes, int)
                                     else s.coordinates.modes, refine=s.fem.refine,
                                     reference_amplitude=s.sampling.range * min(e.gap for e in s.electrode_sets))
    rigid = list(s.coordinates.rigid)
    labels = list(modes.labels) if modes else []
    names = rigid + [f"m{lab.replace(',', '_')}" for lab in labels]
    kinds = ["translation" if r == "z" else "rotation" for r in rigid] + ["mode"] * len(labels)
    units = ["m" if r == "z" else "rad" for r in rigid] + ["m"] * len(labels)
    masses = np.array([rigid_mass[r] for r in rigid] + (list(modes.modal_mass) if modes else []))
    stiff = np.array([0.0] * len(rigid) + (list(modes.modal_stiffness) if modes else []))
    freqs = np.array([0.0] * len(rigid) + (list(modes.frequencies_hz) if modes else []))

    def basis(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Vertical displacement per unit of each coordinate at points (x, y)."""
        cols = {"z": np.ones_like(x), "tilt_x": y, "tilt_y": -x}
        out = [cols[r] for r in rigid]
        if modes is not None:
            shapes = modes.shape(x, y)
            out += [shapes[:, k] for k in range(shapes.shape[1])]
        return np.stack(out, axis=-1)

    report = {"mass_kg": body.mass, "inertia_kg_m2": np.asarray(body.inertia).tolist()}
    if modes is not None:
        report.update({"fem_refine": s.fem.refine, "lambda2": [float(v) for v in modes.lambda2],
                       "side_conditions": _floats(modes.orthogonality), "rotation_mode_coupling": _floats(modes.coupling)})
    return Mechanics(names, kinds, units, [""] * len(rigid) + labels, masses, stiff, freqs, basis, report)


def _floats(d: dict) -> dict:
    return {k: (float(v) if isinstance(v, (int, float, np.floating)) else v) for k, v in d.items()}


def electrodes(s: Structure) -> tuple[list[es.Electrode], list[Electrode]]:
    """Extractor electrodes and their model descriptions, in port order."""
    if s.conductor.kind != "free_disk":
        from . import suspended
        return suspended.electrodes(s)
    out, described = [], []
    for eset in s.electrode_sets:
        names = iter(eset.electrode_names())
        for r_in, r_out in eset.rings:
            for k in range(eset.sectors):
                width = 2 * math.pi / eset.sectors
                start = eset.sector_start + k * width
                slot = eset.slot if eset.sectors > 1 else 0.0
                shape = es.AnnularSector(next(names), r_in, r_out, start, start + width, slot)
                out.append(es.Electrode(shape, eset.side, eset.gap))
    plate = plate_outline(s)
    for e in out:
        x, y, w = e.shape.quadrature(plate)
        described.append(Electrode(e.shape.name, e.shape.name.split("_")[0], e.side, e.gap, float(np.sum(w))))
    return out, described


def plate_outline(s: Structure) -> es.DiskPlate | es.RectPlate:
    if s.conductor.kind != "free_disk":
        from . import suspended
        return suspended.plate_outline(s)
    return es.DiskPlate(s.conductor.radius)


def extractor(s: Structure) -> es.ParallelPlateExtractor:
    """The capacitance extractor chosen by the structure's electrostatics options."""
    o = s.electrostatics
    eps = EPS0 * o.relative_permittivity
    if o.fringe == "none":
        fringe = None
    elif o.fringe == "palmer":
        fringe = es.EdgeFringe.palmer(2 * s.conductor.radius if s.conductor.kind == "free_disk"
                                      else plate_outline(s).size)
    else:
        fringe = es.EdgeFringe(o.fringe_a, o.fringe_b, plate_outline(s).size)
    return es.ParallelPlateExtractor(eps=eps, fringe=fringe, coupling_per_length=o.coupling_per_length)


def touch_amplitudes(prepared, ncoords: int, gaps: np.ndarray) -> np.ndarray:
    """Amplitude of each coordinate alone at which the plate first touches an electrode."""
    probe = 1e-3 * float(np.min(gaps))
    amps = np.full(ncoords, np.inf)
    for v in range(ncoords):
        for sign in (1.0, -1.0):
            q = np.zeros((1, ncoords))
            q[0, v] = sign * probe
            closing = (gaps - prepared.min_gap(q)[0]) / probe     # gap closed per unit amplitude
            with np.errstate(divide="ignore"):
                reach = np.where(closing > 1e-12, gaps / closing, np.inf)
            amps[v] = min(amps[v], float(reach.min()))
    return amps


def sample(prepared, q: np.ndarray, progress: bool, desc: str, chunk: int = 256,
           executor=None, store=None) -> np.ndarray:
    """Capacitances at many coordinate points, in chunks, with a progress bar on stderr.
    With an executor (netgen.executor) the chunks run there, and with a store (a folder) each
    finished chunk is saved and a re-run reuses it; the values are the serial ones bit for bit."""
    if executor is not None or store is not None:
        from .executor import sample_chunks
        return sample_chunks(prepared, q, progress, desc, chunk, executor, store)
    out = []
    with tqdm(total=len(q), desc=desc, unit="pt", disable=not progress, file=sys.stderr, leave=False) as bar:
        for k in range(0, len(q), chunk):
            out.append(prepared.capacitance(q[k:k + chunk]))
            bar.update(min(chunk, len(q) - k))
    return np.concatenate(out, axis=0)


@dataclass
class Samples:
    """Stage output: scaled sample points and extractor capacitances, touching points removed."""
    x: np.ndarray                   # (n, ncoords) grid points kept
    c: np.ndarray                   # (n, nelectrodes) F
    excluded: int                   # grid points dropped because the plate touches an electrode


@dataclass
class Build:
    """Every stage's output of one pipeline run; `model` is what build_model returns."""
    structure: Structure
    mechanics: Mechanics
    electrodes: list[es.Electrode]
    prepared: es.PreparedExtractor
    scales: np.ndarray
    grid: Samples
    holdout: Samples
    fits: list[CapacitanceFit]
    model: MacroModel


def prepare(s: Structure, m: Mechanics) -> tuple[list[es.Electrode], list[Electrode], es.PreparedExtractor]:
    """Electrodes (extractor and model descriptions) and the extractor bound to the basis."""
    ext_electrodes, described = electrodes(s)
    return ext_electrodes, described, extractor(s).prepare(ext_electrodes, plate_outline(s), m.basis)


def coordinate_scales(prepared, m: Mechanics, ext_electrodes: list[es.Electrode]) -> np.ndarray:
    """Touching amplitude of each coordinate (the scale of its sampled state x = q / L)."""
    scales = touch_amplitudes(prepared, len(m.names), np.array([e.gap for e in ext_electrodes]))
    if not np.all(np.isfinite(scales)):
        bad = [n for n, a in zip(m.names, scales) if not math.isfinite(a)]
        raise ValueError(f"coordinates {bad} never move the plate towards an electrode; they cannot be sampled")
    return scales


def sample_points(prepared, x: np.ndarray, scales: np.ndarray, progress: bool, desc: str,
                  **parallel) -> Samples:
    """Extractor capacitances at scaled points x; points where the plate touches are dropped.
    `parallel`: executor= and store= of sample()."""
    c = sample(prepared, x * scales, progress, desc, **parallel)
    touching = np.isnan(c).any(axis=1)     # e.g. grid corners where the combined motion closes a gap
    return Samples(x[~touching], c[~touching], int(touching.sum()))


def sample_grid(s: Structure, prepared, scales: np.ndarray, progress: bool = False, **parallel) -> Samples:
    """The fit's samples: levels^ncoords tensor grid over +-range of the touching amplitudes."""
    x = sampling_grid(len(scales), s.sampling.levels, s.sampling.range)
    return sample_points(prepared, x, scales, progress, "capacitance samples", **parallel)


def sample_holdout(s: Structure, prepared, scales: np.ndarray, progress: bool = False, **parallel) -> Samples:
    """Held-out check samples: uniform random points (seeded) inside the sampled box."""
    x = holdout_points(len(scales), s.fit.holdout, s.sampling.range, s.fit.seed)
    return sample_points(prepared, x, scales, progress, "held-out samples", **parallel)


def fit_all(s: Structure, ext_electrodes: list[es.Electrode], described: list[Electrode], basis,
            scales: np.ndarray, grid: Samples, holdout: Samples, progress: bool = False) -> list[CapacitanceFit]:
    """One capacitance fit per electrode, in port order."""
    fits, start = [], {}
    for i, e in enumerate(tqdm(ext_electrodes, desc="fits", unit="el", disable=not progress, file=sys.stderr,
                               leave=False)):
        ring = described[i].name.rsplit("s", 1)[0]            # electrodes of one ring share a patch grid
        fit, start[ring] = fit_electrode(s, e, described[i].name, basis, scales, grid.x, grid.c[:, i],
                                         holdout.x, holdout.c[:, i], start.get(ring, 0))
        fits.append(fit)
    return fits


def assemble(s: Structure, m: Mechanics, ext_electrodes: list[es.Electrode], described: list[Electrode],
             scales: np.ndarray, grid: Samples, holdout: Samples, fits: list[CapacitanceFit]) -> MacroModel:
    """The MacroModel from the stage outputs (plus the constant electrode couplings)."""
    coupling = extractor(s).coupling(ext_electrodes, plate_outline(s))
    damp, damp_report = damping(s, m)
    film = damp_report.pop("branches", [()] * len(m.names))
    coords = [Coordinate(n, k, u, float(L), float(ms), float(ks), float(d), float(f), lab, br)
              for n, k, u, L, ms, ks, d, f, lab, br in zip(m.names, m.kinds, m.units, scales, m.masses,
                                                          m.stiffnesses, damp, m.frequencies, m.labels, film)]
    sampling = {"levels": s.sampling.levels, "range": s.sampling.range, "samples": int(len(grid.x)),
                "excluded_touching": grid.excluded, "holdout": int(len(holdout.x)),
                "holdout_excluded_touching": holdout.excluded, "seed": int(s.fit.seed),
                "target": s.fit.target, "degree": s.fit.degree, "tolerance": s.fit.tolerance}
    report = {"mechanics": m.report, "electrostatics": {
        "extractor": "parallel-plate over the local gap + edge fringe",
        "fringe": s.electrostatics.fringe, "permittivity_F_per_m": EPS0 * s.electrostatics.relative_permittivity}}
    if damp_report:
        report["damping"] = damp_report
    model = MacroModel(s.name, s.description, s.source, coords, described, fits, coupling,
                       sampling, report, contact=stops(s, m, ext_electrodes, scales))
    if s.coordinates.acceleration_port:
        model.acceleration = participation(s, m)
    if s.conductor.kind != "free_disk":                   # stress stiffening (netgen.suspended)
        from . import suspended
        model.nonlinear = suspended.nonlinear_stiffness(s, m, scales)
    return model


def participation(s: Structure, m: Mechanics, order: int = 96) -> list[float]:
    """Inertial participation G_v = rho h int phi_v dA over the plate (Gauss quadrature): the
    generalized force per unit frame acceleration. Values below 1e-6 of sqrt(M_v m) (free-plate
    modes and tilts about the centre, zero by symmetry up to round-off) are set to exactly 0."""
    plate = plate_outline(s)
    g, w = np.polynomial.legendre.leggauss(order)
    if isinstance(plate, es.DiskPlate):
        r = 0.5 * plate.radius * (g + 1)
        theta = 2 * np.pi * np.arange(2 * order) / (2 * order)
        rr, tt = np.meshgrid(r, theta, indexing="ij")
        weights = (0.5 * plate.radius * w * r)[:, None] * np.full(theta.shape, 2 * np.pi / theta.size)[None, :]
        x, y = rr * np.cos(tt), rr * np.sin(tt)
    else:                                                   # rectangle: order x 8 points (phi is at most linear in y)
        gy, wy = np.polynomial.legendre.leggauss(8)
        hx, hy = 0.5 * (plate.x1 - plate.x0), 0.5 * (plate.y1 - plate.y0)
        x, y = np.meshgrid(hx * (g + 1) + plate.x0, hy * (gy + 1) + plate.y0, indexing="ij")
        weights = (hx * w)[:, None] * (hy * wy)[None, :]
    phi = m.basis(x.ravel(), y.ravel())                                  # (points, ncoords)
    gam = s.conductor.density * s.conductor.thickness * (weights.ravel() @ phi)
    total = s.conductor.density * s.conductor.thickness * plate.area()
    return [0.0 if abs(v) < 1e-6 * math.sqrt(mv * total) else float(v) for v, mv in zip(gam, m.masses)]


def stops(s: Structure, m: Mechanics, ext_electrodes: list[es.Electrode], scales: np.ndarray) -> dict:
    """The contact model (netgen.contact): stop points from the extractor's probe points."""
    from . import contact
    ext = extractor(s).prepare(ext_electrodes, plate_outline(s), m.basis)
    probe = ext.probe
    owner = [e.shape.name for e, sl in zip(ext_electrodes, probe.slices) for _ in range(sl.stop - sl.start)]
    freqs = m.frequencies[m.frequencies > 0]
    ws = 2 * math.pi * (math.exp(float(np.mean(np.log(freqs)))) if len(freqs) else 1e6 / (2 * math.pi))
    return contact.contact_model(probe.gap, probe.phi, owner, scales, s.conductor.mass, ws)


def damping(s: Structure, m: Mechanics) -> tuple[np.ndarray, dict]:
    """Damping per coordinate (SI) and its report: Q / damping ratio (a per-coordinate entry
    overrides the eigenmode default), plus Rayleigh alpha M + beta K, plus squeeze film."""
    n = len(m.names)
    d = s.damping
    if d is None:
        return np.zeros(n), {}
    omega = 2 * np.pi * m.frequencies
    out = d.rayleigh_alpha * m.masses + d.rayleigh_beta * m.stiffnesses
    zeta = _modal_ratios(s, m.names, m.kinds)
    out = out + 2.0 * zeta * m.masses * omega
    film = squeeze_film_damping(s, m) if d.squeeze_film else {}
    if film:
        out = out + film["diagonal"]
    report = _damping_report(s, out, film)
    if film.get("branches"):
        report["branches"] = film["branches"]        # popped by assemble() into Coordinate.film
    return out, report


def _modal_ratios(s: Structure, names: list[str], kinds: list[str]) -> np.ndarray:
    """Damping ratio zeta per coordinate from q_factor / damping_ratio entries (0 if none)."""
    d = s.damping
    ratios = {k: 1 / (2 * v) for k, v in d.q_factor} | dict(d.damping_ratio)     # Q = 1 / (2 zeta)
    default = ratios.pop("*", 0.0)
    given = ratios
    unknown = sorted(set(given) - set(names))
    if unknown:
        from .structure import StructureError
        raise StructureError(s.source, "damping", f"damping given for unknown coordinate(s) {unknown}",
                             f"use the coordinate names {names} (modes = <count> names them only after the FEM)")
    return np.array([given.get(nm, default if kind == "mode" else 0.0) for nm, kind in zip(names, kinds)])


def squeeze_film_damping(s: Structure, m: Mechanics) -> dict:
    """Reynolds squeeze-film damping of both sides' gaps (the plate disk, p = 0 at its rim)."""
    from . import squeeze_film as sf
    d, radius = s.damping, s.conductor.radius
    gas = sf.GASES[d.gas]
    mesh = sf.disk_mesh(radius, d.fem_refine)
    reynolds = sf.reynolds_matrix(mesh, m.basis)                  # shared by all gaps
    gaps = {}
    for e in s.electrode_sets:
        gaps[e.side] = min(e.gap, gaps.get(e.side, math.inf))
    total, sides = np.zeros_like(reynolds), {}
    for side, gap in sorted(gaps.items()):
        mu = sf.effective_viscosity(gas, d.pressure, gap)
        total += 12.0 * mu / gap**3 * reynolds
        sigma = [sf.squeeze_number(mu, 2 * np.pi * f, radius, d.pressure, gap) for f in m.frequencies]
        sides[side] = {"gap_m": gap, "knudsen": sf.knudsen(gas, d.pressure, gap), "mu_eff_Pa_s": mu,
                       "squeeze_number_at_f0": [float(v) for v in sigma],
                       "compressible_at_f0": _compressible_at_f0(mesh, m, gap, mu, d.pressure)}
    worst = max(v for side in sides.values() for v in side["squeeze_number_at_f0"])
    if d.film_model == "compressible":
        return compressible_film(s, m, mesh, gaps, total, sides)
    note = ("incompressible model valid (squeeze number < 1 at every modal frequency)" if worst < 1 else
            f"squeeze number up to {worst:.3g} > 1: the film also stiffens and the incompressible "
            "damping overestimates the real one at those modes (compressible model not implemented)")
    return {"diagonal": np.diag(total).copy(), "off_diagonal_ratio": sf.off_diagonal_ratio(total), "sides": sides,
            "validity": note}


FILM_POLES = 60          # Dirichlet eigenpairs of the gap region behind the compressible network


def film_max_frequency(s: Structure, m: Mechanics) -> float:
    """Highest frequency (Hz) the compressible network must reproduce: the structure's
    film_max_frequency, else 1.5x the highest modal frequency (at least 100 kHz)."""
    given = s.damping.film_max_frequency
    return given if given > 0 else max(1.5 * float(np.max(m.frequencies, initial=0.0)), 1e5)


def compressible_film(s: Structure, m: Mechanics, mesh, gaps: dict, total: np.ndarray, sides: dict) -> dict:
    """Compressible squeeze film: per coordinate the exact pole-residue expansion of both gaps,
    reduced to the fewest Maxwell branches (damper in series with a gas spring) that match it
    within 1 % up to film_max_frequency; the dropped fast poles join the plain damper."""
    from . import squeeze_film as sf
    d = s.damping
    gas = sf.GASES[d.gas]
    solved = {gap: sf.pole_residues(mesh, m.basis, gap, sf.effective_viscosity(gas, d.pressure, gap), d.pressure,
                                    FILM_POLES) for gap in sorted(set(gaps.values()))}   # equal gaps: one solve
    per_side = [solved[gap] for _, gap in sorted(gaps.items())]
    omega_max = 2 * np.pi * film_max_frequency(s, m)
    remainders, branches, errors = [], [], []
    for k in range(len(m.names)):
        full = sf.combine([side[k] for side in per_side])
        reduced, err = sf.maxwell_network(full, omega_max)
        remainders.append(reduced.remainder)
        branches.append(tuple((float(r), float(w)) for r, w in zip(reduced.residues, reduced.poles)))
        errors.append(err)
    note = (f"compressible film: Maxwell branches (damper r in series with a gas spring r*omega_p) per "
            f"coordinate, within {max(errors):.2%} of the {FILM_POLES}-pole expansion up to "
            f"{omega_max / (2 * np.pi):.4g} Hz")
    return {"diagonal": np.array(remainders), "off_diagonal_ratio": sf.off_diagonal_ratio(total), "sides": sides,
            "validity": note, "branches": branches,
            "network": {"max_frequency_hz": omega_max / (2 * np.pi), "poles_solved": FILM_POLES,
                        "max_rel_error": errors,
                        "branches": [[{"damping": r, "corner_hz": w / (2 * np.pi)} for r, w in b] for b in branches]}}


def _compressible_at_f0(mesh, m: Mechanics, gap: float, mu: float, pressure: float) -> dict:
    """Compressible-film damping b and gas-spring stiffness k of each mode at its own frequency
    (complex Reynolds solve; informational, the model keeps the incompressible b)."""
    from . import squeeze_film as sf
    b, k = [], []
    for v, f in enumerate(m.frequencies):
        y = sf.compressible_admittance(mesh, m.basis, v, gap, mu, pressure, 2 * np.pi * f) if f > 0 else None
        b.append(float(y.real) if y is not None else None)
        k.append(float(-2 * np.pi * f * y.imag) if y is not None else None)
    return {"damping_N_s_per_m": b, "spring_N_per_m": k}


def _damping_report(s: Structure, out: np.ndarray, film: dict) -> dict:
    """What the damping stage did, for the JSON report and the emitters (noise switch)."""
    d = s.damping
    rep = {"temperature_K": d.temperature, "noise": d.noise, "per_coordinate": [float(v) for v in out]}
    if film:
        rep["squeeze_film"] = {"gas": d.gas, "pressure_Pa": d.pressure, "fem_refine": d.fem_refine,
                               "diagonal": [float(v) for v in film["diagonal"]],
                               "off_diagonal_ratio": film["off_diagonal_ratio"], "sides": film["sides"],
                               "validity": film["validity"], **({"network": film["network"]} if "network" in film else {}),
                               "model": "incompressible linearised Reynolds, Veijola mu_eff, p = 0 at the plate rim"}
    return rep


def build(s: Structure, progress: bool = False, **parallel) -> Build:
    """Run the whole pipeline for one structure, keeping every stage's output.
    `parallel`: executor= and store= for the capacitance sampling (see sample())."""
    if getattr(s, "imports", None) is not None:          # [import]: external FEM / field-solver data
        from . import importers
        return importers.build(s, progress, **parallel)
    _say(progress, f"{s.name}: eigenmodes and rigid-body mechanics")
    m = mechanics(s)
    ext_electrodes, described, prepared = prepare(s, m)
    scales = coordinate_scales(prepared, m, ext_electrodes)
    grid = sample_grid(s, prepared, scales, progress, **parallel)
    holdout = sample_holdout(s, prepared, scales, progress, **parallel)
    _say(progress, f"{s.name}: fitting {grid.c.shape[1]} capacitances to {len(grid.x)} samples ({s.fit.target})")
    fits = fit_all(s, ext_electrodes, described, m.basis, scales, grid, holdout, progress)
    model = assemble(s, m, ext_electrodes, described, scales, grid, holdout, fits)
    return Build(s, m, ext_electrodes, prepared, scales, grid, holdout, fits, model)


def build_model(s: Structure, progress: bool = False) -> MacroModel:
    """Run the whole pipeline for one structure and return its MacroModel."""
    return build(s, progress).model


PATCH_GRIDS = [(1, 1), (1, 2), (2, 2), (2, 3), (3, 3), (3, 4), (4, 4), (4, 5), (5, 5)]


def fit_electrode(s: Structure, e: es.Electrode, name: str, basis, scales: np.ndarray, x: np.ndarray,
                  c: np.ndarray, x_check: np.ndarray, c_check: np.ndarray,
                  first: int = 0) -> tuple[CapacitanceFit, int]:
    """Fit one electrode's capacitance in the chosen form; 'plates' refines its patch count,
    starting at PATCH_GRIDS[first], until the held-out error meets the tolerance (or the
    term limit is reached). Returns the fit and the index of the grid used."""
    o = s.fit
    if o.target != "plates":
        return fit_capacitance(name, x, c, o.degree, o.target, x_check, c_check), 0
    best, used = None, first
    for k in range(first, len(PATCH_GRIDS)):
        grid = PATCH_GRIDS[k]
        if grid[0] * grid[1] > o.max_terms or grid[0] * grid[1] * math.comb(x.shape[1] + o.degree, o.degree) > len(x):
            break                              # more plate terms than the samples determine
        init = patch_guess(s, e, basis, scales, grid, float(c[np.argmin(np.sum(x * x, axis=1))]))
        fit = fit_plates(name, x, c, init, o.degree, x_check, c_check)
        if best is None or fit.max_rel_error < best.max_rel_error:
            best, used = fit, k
        if fit.max_rel_error <= o.tolerance:
            break
    return best, used


def patch_guess(s: Structure, e: es.Electrode, basis, scales: np.ndarray, grid: tuple[int, int],
                c_ref: float) -> np.ndarray:
    """Affine first guesses P_k(x) for K = nr x nt patches of the electrode (equal-area bins in
    r and theta): each patch a parallel plate at its mean local displacement."""
    px, py, w = e.shape.quadrature(plate_outline(s))
    r, theta = np.hypot(px, py), np.unwrap(np.arctan2(py, px))
    phi = basis(px, py) * scales[None, :] * e.sign          # gap closed per unit x
    ids = _bins(r, w, grid[0]) * grid[1] + _bins(theta, w, grid[1])
    if s.conductor.kind in ("clamped_clamped_beam", "cantilever"):
        ids = _bins(px, w, grid[0] * grid[1])              # beams: all patches along the beam axis
    eps = EPS0 * s.electrostatics.relative_permittivity
    rows, caps = [], []
    for k in range(grid[0] * grid[1]):
        sel = ids == k
        area = float(np.sum(w[sel]))
        if area <= 0:
            continue
        mean_phi = np.sum(w[sel, None] * phi[sel], axis=0) / area
        rows.append(np.concatenate([[e.gap], -mean_phi]) / (eps * area))
        caps.append(eps * area / e.gap)
    lam = c_ref / sum(caps)                                  # absorbs the edge fringe
    return np.array(rows) * c_ref / lam


def _bins(values: np.ndarray, weights: np.ndarray, n: int) -> np.ndarray:
    """Bin index of each point so that the n bins hold equal total weight."""
    order = np.argsort(values, kind="stable")
    cum = np.cumsum(weights[order]) / np.sum(weights)
    ids = np.empty(len(values), dtype=int)
    ids[order] = np.minimum((cum * n - 1e-12).astype(int), n - 1)
    return ids


def _say(progress: bool, text: str) -> None:
    if progress:
        print(text, file=sys.stderr)


def electrode_outlines(s: Structure, points: int = 40) -> list[tuple[np.ndarray, np.ndarray]]:
    """Closed outline (x, y) of every electrode, clipped to the plate, for plots."""
    out = []
    for eset in s.electrode_sets:
        width = 2 * math.pi / eset.sectors
        for r_in, r_out in eset.rings:
            r_out = min(r_out, s.conductor.radius)
            for k in range(eset.sectors):
                t0 = eset.sector_start + k * width
                half = (lambda r: math.asin(min(1.0, eset.slot / (2 * r))) if eset.sectors > 1 and r > 0 else 0.0)
                lo_o, hi_o = t0 + half(r_out), t0 + width - half(r_out)
                r_lo = max(r_in, eset.slot / 2 + 1e-12) if eset.sectors > 1 else r_in
                lo_i, hi_i = t0 + half(r_lo), t0 + width - half(r_lo)
                ta, tb = np.linspace(lo_o, hi_o, points), np.linspace(hi_i, lo_i, points)
                x = np.concatenate([r_out * np.cos(ta), r_lo * np.cos(tb), [r_out * math.cos(lo_o)]])
                y = np.concatenate([r_out * np.sin(ta), r_lo * np.sin(tb), [r_out * math.sin(lo_o)]])
                out.append((x, y))
    return out


def write_figures(b: Build, folder: Path) -> list[Path]:
    """Mode-shape and fit-error PNGs next to the netlist (from the build's stage outputs)."""
    from . import plots
    model = b.model
    out = [plots.fit_errors(folder / f"{model.name}_fit_errors.png", model)]
    if any(c.kind == "mode" for c in model.coordinates) and b.structure.conductor.kind == "free_disk":
        out.append(plots.mode_shapes(folder / f"{model.name}_modes.png", model, b.mechanics.basis,
                                     b.structure.conductor.radius, electrode_outlines(b.structure)))
    return out
