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


def plate_outline(s: Structure) -> es.DiskPlate:
    return es.DiskPlate(s.conductor.radius)


def extractor(s: Structure) -> es.ParallelPlateExtractor:
    """The capacitance extractor chosen by the structure's electrostatics options."""
    o = s.electrostatics
    eps = EPS0 * o.relative_permittivity
    if o.fringe == "none":
        fringe = None
    elif o.fringe == "palmer":
        fringe = es.EdgeFringe.palmer(2 * s.conductor.radius)
    else:
        fringe = es.EdgeFringe(o.fringe_a, o.fringe_b, s.conductor.radius)
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


def sample(prepared, q: np.ndarray, progress: bool, desc: str, chunk: int = 256) -> np.ndarray:
    """Capacitances at many coordinate points, in chunks, with a progress bar on stderr."""
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


def sample_points(prepared, x: np.ndarray, scales: np.ndarray, progress: bool, desc: str) -> Samples:
    """Extractor capacitances at scaled points x; points where the plate touches are dropped."""
    c = sample(prepared, x * scales, progress, desc)
    touching = np.isnan(c).any(axis=1)     # e.g. grid corners where the combined motion closes a gap
    return Samples(x[~touching], c[~touching], int(touching.sum()))


def sample_grid(s: Structure, prepared, scales: np.ndarray, progress: bool = False) -> Samples:
    """The fit's samples: levels^ncoords tensor grid over +-range of the touching amplitudes."""
    x = sampling_grid(len(scales), s.sampling.levels, s.sampling.range)
    return sample_points(prepared, x, scales, progress, "capacitance samples")


def sample_holdout(s: Structure, prepared, scales: np.ndarray, progress: bool = False) -> Samples:
    """Held-out check samples: uniform random points (seeded) inside the sampled box."""
    x = holdout_points(len(scales), s.fit.holdout, s.sampling.range, s.fit.seed)
    return sample_points(prepared, x, scales, progress, "held-out samples")


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
    coords = [Coordinate(n, k, u, float(L), float(ms), float(ks), 0.0, float(f), lab)
              for n, k, u, L, ms, ks, f, lab in zip(m.names, m.kinds, m.units, scales, m.masses,
                                                   m.stiffnesses, m.frequencies, m.labels)]
    sampling = {"levels": s.sampling.levels, "range": s.sampling.range, "samples": int(len(grid.x)),
                "excluded_touching": grid.excluded, "holdout": int(len(holdout.x)),
                "holdout_excluded_touching": holdout.excluded, "seed": int(s.fit.seed),
                "target": s.fit.target, "degree": s.fit.degree, "tolerance": s.fit.tolerance}
    report = {"mechanics": m.report, "electrostatics": {
        "extractor": "parallel-plate over the local gap + edge fringe",
        "fringe": s.electrostatics.fringe, "permittivity_F_per_m": EPS0 * s.electrostatics.relative_permittivity}}
    return MacroModel(s.name, s.description, s.source, coords, described, fits, coupling,
                      sampling, report)


def build(s: Structure, progress: bool = False) -> Build:
    """Run the whole pipeline for one structure, keeping every stage's output."""
    _say(progress, f"{s.name}: eigenmodes and rigid-body mechanics")
    m = mechanics(s)
    ext_electrodes, described, prepared = prepare(s, m)
    scales = coordinate_scales(prepared, m, ext_electrodes)
    grid = sample_grid(s, prepared, scales, progress)
    holdout = sample_holdout(s, prepared, scales, progress)
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
        if grid[0] * grid[1] > o.max_terms:
            break
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
    if any(c.kind == "mode" for c in model.coordinates):
        out.append(plots.mode_shapes(folder / f"{model.name}_modes.png", model, b.mechanics.basis,
                                     b.structure.conductor.radius, electrode_outlines(b.structure)))
    return out
