"""The build pipeline: structure -> mechanics -> electrostatics -> fit -> MacroModel.

The one place that knows the order of the stages and picks each stage's source: the conductor
kind's mechanics (netgen.mechanics.KINDS) or imported FEM data, the structure's extractor
(netgen.electrostatics.EXTRACTORS) or an imported capacitance table. Data flows one way; each
stage is a function of the previous stages' outputs.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .core.constants import EPS0
from .core.errors import StructureError
from .electrostatics import CapacitanceExtractor, PreparedExtractor, calibration_report, extractor
from .electrostatics import imported as imported_capacitance
from .electrostatics.sampling import (
    Samples,
    box_corners,
    box_factors,
    box_range,
    check_points,
    coordinate_ranges,
    coordinate_scales,
    sample_corners,
    sample_grid,
    sample_holdout,
    sample_points,
)
from .fit import cost
from .fit.adaptive import adaptive_fits
from .fit.capacitance import CapacitanceFit, at_corners, fit_all
from .fit.energy import energy_entry, fit_energy
from .geometry.layout import drawing, electrode_outlines, electrodes, overlap_area, plate_outline
from .geometry.shapes import Electrode as ShapeElectrode
from .geometry.shapes import Plate
from .mechanics import Mechanics, body_mass, inertial, mechanics, participation
from .mechanics import imported as imported_mechanics
from .mechanics.damping import damping
from .mechanics.kinematics import small_angle_report
from .model import Coordinate, Electrode, Inertial, MacroModel, contact, plots, process_loads
from .model.process import process_laws
from .model.process_loads import inertial_law
from .structure import Structure
from .structure.schema import Sampling


@dataclass
class Build:
    """Every stage's output of one pipeline run; `model` is what build_model returns."""

    structure: Structure
    mechanics: Mechanics
    electrodes: list[ShapeElectrode]
    prepared: PreparedExtractor
    scales: np.ndarray
    grid: Samples
    holdout: Samples
    fits: list[CapacitanceFit]
    model: MacroModel
    extractor: CapacitanceExtractor | None = None
    corners: Samples | None = None  # the box's corners, where the fits' stated error is checked too


@dataclass(frozen=True)
class Sampled:
    """The capacitance samples and their fits (assemble's input): the grid, the held-out set, the
    fits, the sample design's extra report and the box's corner samples the fits' stated error covers."""

    grid: Samples
    holdout: Samples
    fits: list[CapacitanceFit]
    design_extra: dict | None = None
    corners: Samples | None = None


def build(s: Structure, progress: bool = False, max_minutes: float | None = None, **parallel) -> Build:
    """Run the whole pipeline for one structure, keeping every stage's output. With `max_minutes`
    the sampling and fit cost is estimated first (netgen.fit.cost) and a design over it refused.
    `parallel`: executor= and store= for the capacitance sampling (netgen.electrostatics.sampling)."""
    imp = s.imports
    say(progress, f"{s.name}: eigenmodes and rigid-body mechanics")
    m = imported_mechanics.mechanics(s) if imp and imp.modes else mechanics(s)
    s = resolve_ranges(s, m.names)
    plate, shapes = plate_outline(s), electrodes(s)
    table = (
        imported_capacitance.table(imp.capacitance, m.names, [e.name for e in shapes])
        if imp and imp.capacitance
        else None
    )
    ext = extractor(s, plate)
    prepared = ext.prepare(shapes, plate, m.basis)
    scales = scales_of(s, prepared, m, shapes)
    if table is not None:
        grid, holdout = imported_capacitance.samples(table, scales, plate_estimates(s, shapes, plate), s.fit.degree)
        say(progress, f"{s.name}: fitting {grid.c.shape[1]} capacitances to {len(grid.x)} samples ({s.fit.target})")
        sampled = Sampled(grid, holdout, fit_all(s, shapes, m.basis, scales, grid, holdout, progress))
    else:
        s = default_range(s, prepared, scales, progress)
        sampled = sample_and_fit(s, prepared, m, shapes, scales, progress, max_minutes, **parallel)
    grid, holdout, fits = sampled.grid, sampled.holdout, sampled.fits
    model = assemble(s, m, plate, shapes, ext, prepared, scales, sampled)
    if imp:
        model.report["import"] = {k: Path(v).name for k, v in vars(imp).items() if v}
        if imp.capacitance:
            model.report["electrostatics"] = {"extractor": f"imported table {Path(imp.capacitance).name}"}
    return Build(s, m, shapes, prepared, scales, grid, holdout, fits, model, ext, sampled.corners)


def sample_and_fit(
    s: Structure,
    prepared: PreparedExtractor,
    m: Mechanics,
    shapes: list[ShapeElectrode],
    scales: np.ndarray,
    progress: bool,
    max_minutes: float | None,
    **parallel,
) -> Sampled:
    """The structure's sample design (after the cost estimate, with `max_minutes`) and one fit per
    electrode; the adaptive design grows its samples while fitting (netgen.fit.adaptive). Returns
    the training and held-out samples, the fits (their stated error over the box's corners too:
    netgen.fit.capacitance.at_corners) and the design's report entries."""
    if max_minutes is not None:
        estimate = cost.estimate(s, prepared, scales, len(shapes))
        say(progress, f"{s.name}: {estimate.text()}")
        cost.check(s, estimate, max_minutes)
    grid = sample_grid(s, prepared, scales, progress, **parallel)
    holdout = sample_holdout(s, prepared, scales, progress, **parallel)
    corners = sample_corners(s, prepared, scales, progress, **parallel)
    if s.sampling.design != "adaptive":
        say(progress, f"{s.name}: fitting {grid.c.shape[1]} capacitances to {len(grid.x)} samples ({s.fit.target})")
        fits = fit_all(s, shapes, m.basis, scales, grid, holdout, progress)
        return Sampled(grid, holdout, at_corners(fits, corners), None, corners)
    say(progress, f"{s.name}: adaptive design from {len(grid.x)} samples, budget {s.sampling.points}")
    result = adaptive_fits(
        s,
        shapes,
        m.basis,
        scales,
        grid,
        lambda x: sample_points(prepared, x, scales, False, "probes", **parallel),
        holdout,
        progress,
    )
    checked = [r["validation_max_rel_error"] for r in result.rounds if "validation_max_rel_error" in r]
    return Sampled(
        result.samples,
        holdout,
        at_corners(result.fits, corners),
        {"probes": result.probes, "rounds": len(result.rounds), "converged": result.converged}
        | ({"validation_max_rel_error": checked[-1]} if checked else {}),
        corners,
    )


def resolve_ranges(s: Structure, names: list[str]) -> Structure:
    """The structure with each coordinate's share of the box (Sampling.factors) when [sampling]
    range is a table; its coordinate names are checked here when the file could not know them
    (the free disk's modes are named by the mode solve)."""
    if not s.sampling.ranges:
        return s
    unknown = [n for n, _ in s.sampling.ranges if n != "*" and n not in names]
    if unknown:
        raise StructureError(
            s.source,
            "sampling.range",
            f"unknown coordinate {unknown[0]!r}",
            f'use one of {names} (or "*" for the rest)',
        )
    r = coordinate_ranges(s.sampling, names)
    rng = float(r.max())
    factors = tuple(float(v) for v in r / rng)
    return dataclasses.replace(s, sampling=dataclasses.replace(s.sampling, range=rng, factors=factors))


def default_range(s: Structure, prepared: PreparedExtractor, scales: np.ndarray, progress: bool) -> Structure:
    """The structure with its [sampling] range narrowed when the file gives none and the default
    box's corners would reach an electrode (netgen.electrostatics.sampling.box_range); said on stderr."""
    if s.sampling.range_given:
        return s
    r = box_range(prepared, scales, s.sampling.range)
    if r == s.sampling.range:
        return s
    say(
        progress,
        f"{s.name}: [sampling] range {r:g} (not {s.sampling.range:g}: at +-{s.sampling.range:g} the "
        f"corners of the {len(scales)}-coordinate box reach an electrode; give range to choose)",
    )
    return dataclasses.replace(s, sampling=dataclasses.replace(s.sampling, range=r))


def scales_of(s: Structure, prepared: PreparedExtractor, m: Mechanics, shapes: list[ShapeElectrode]) -> np.ndarray:
    """The touching amplitudes; an imported mode that moves no electrode's gap is the modes file's fault."""
    try:
        return coordinate_scales(prepared, m.names, np.array([e.stop_gap for e in shapes]))
    except ValueError as exc:
        if not (s.imports and s.imports.modes):
            raise
        raise StructureError(
            s.imports.modes,
            "import.modes",
            str(exc),
            "export the vertical displacement of each mode at the conductor's nodes",
        ) from None


def plate_estimates(s: Structure, shapes: list[ShapeElectrode], plate: Plate) -> np.ndarray:
    """eps A / g of each electrode at rest: the scale an imported capacitance table must be near."""
    medium = s.electrostatics.relative_permittivity
    return np.array([EPS0 * medium * overlap_area(e, plate) / e.field_gap(medium) for e in shapes])


def build_key(s: Structure) -> str:
    """SHA-256 of what a build of `s` depends on: the validated structure (every value the
    pipeline reads; not the [loop] table, which the structure stage ignores), the content of the
    data files it names ([import], electrostatics.couplings) and netgen's version. A cached model
    with the same key is this build's output (netgen.testbench.sigma_delta.runner.model_for);
    file modification times play no part."""
    files = (
        [getattr(s.imports, f) for f in ("mass_matrix", "stiffness_matrix", "modes", "capacitance")]
        if s.imports
        else []
    )
    files.append(s.electrostatics.couplings)
    from . import __version__

    doc = {
        "netgen": __version__,
        "structure": repr(s),
        "files": {p: hashlib.sha256(Path(p).read_bytes()).hexdigest() for p in files if p},
    }
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def build_model(s: Structure, progress: bool = False) -> MacroModel:
    """Run the whole pipeline for one structure and return its MacroModel."""
    return build(s, progress).model


def assemble(
    s: Structure,
    m: Mechanics,
    plate: Plate,
    shapes: list[ShapeElectrode],
    ext: CapacitanceExtractor,
    prepared: PreparedExtractor,
    scales: np.ndarray,
    sampled: Sampled,
) -> MacroModel:
    """The MacroModel from the stage outputs (plus the constant electrode couplings)."""
    grid, holdout, fits, design_extra = sampled.grid, sampled.holdout, sampled.fits, sampled.design_extra
    coupling = ext.coupling(shapes, plate)
    damp, damp_report = damping(s, m)
    film = damp_report.pop("branches", [()] * len(m.names))
    coords = [
        Coordinate(n, k, u, float(L), float(ms), float(ks), float(d), float(f), lab, br)
        for n, k, u, L, ms, ks, d, f, lab, br in zip(
            m.names, m.kinds, m.units, scales, m.masses, m.stiffnesses, damp, m.frequencies, m.labels, film
        )
    ]
    described = [Electrode(e.name, e.group, e.side, e.gap, overlap_area(e, plate)) for e in shapes]
    sampling = {
        "levels": s.sampling.levels,
        "range": s.sampling.range,
        "samples": int(len(grid.x)),
        "excluded_touching": grid.excluded,
        "holdout": int(len(holdout.x)),
        "holdout_excluded_touching": holdout.excluded,
        "seed": int(s.fit.seed),
        "target": s.fit.target,
        "degree": s.fit.degree,
        "tolerance": s.fit.tolerance,
    }
    if s.sampling.design != "grid":  # the grid's JSON as before
        sampling = {k: v for k, v in sampling.items() if k != "levels"} | cost.design_report(s, design_extra or {})
    # the fits' max_rel_error covers the box's corners (netgen.fit.capacitance.at_corners)
    if sampled.corners is not None:
        sampling["corner_checks"] = int(len(sampled.corners.x))
    if s.sampling.factors:  # a range table (netgen.build.resolve_ranges): each coordinate's half-width
        sampling["coordinate_range"] = {n: s.sampling.range * f for n, f in zip(m.names, s.sampling.factors)}
    if not s.sampling.range_given and s.sampling.range < Sampling.range:  # netgen.build.default_range
        sampling["range_narrowed_from"] = Sampling.range
    report = {
        "mechanics": m.report,
        "electrostatics": {
            "extractor": ext.description,
            "fringe": s.electrostatics.fringe,
            "permittivity_F_per_m": EPS0 * s.electrostatics.relative_permittivity,
        },
    }
    layers = dielectric_layers(s)
    if layers:  # only with a layer: the JSON of a structure without one stays as it was
        report["electrostatics"]["dielectric_layers"] = layers
    if damp_report:
        report["damping"] = damp_report
    if s.warnings:  # assumptions near their limits (netgen.structure.validity), also on stderr
        report["validity_warnings"] = list(s.warnings)
    if set(m.names) & {"x", "y", "rot_z"}:  # in-plane motion: where small angles stop holding
        report["small_angle"] = small_angle_report(
            m.names, m.kinds, scales, s.sampling.range, farthest(plate, shapes), min(e.gap for e in shapes)
        )
    model = MacroModel(
        s.name,
        s.description,
        s.source,
        coords,
        described,
        fits,
        coupling,
        sampling,
        report,
        contact=stops(s, m, prepared, shapes, scales),
        layout=drawing(plate, shapes),
    )
    if hasattr(ext, "calibration"):  # calibrated fringes / given couplings (netgen.electrostatics.calibrated)
        model.calibration = ext.calibration()
    if s.coordinates.acceleration_port:
        model.acceleration = participation(s, m)
    if set(s.coordinates.inertial) - {"a_z"}:  # a_x, a_y, rates (netgen.mechanics.inertial)
        data = inertial.terms(s, m, s.coordinates.inertial)
        model.inertial = Inertial.from_dict(data)
        model.report["inertial"] = inertial.report(m.names, m.kinds, data, m.stiffnesses, s.coordinates.inertial)
    if m.strain_energy is not None:  # e.g. stress stiffening (netgen.mechanics.beam)
        poly, fit_report = fit_energy(m.strain_energy.energy, scales, degrees=m.strain_energy.degrees)
        model.nonlinear = energy_entry(poly, m.strain_energy.description, fit_report)
    scale_z = float(scales[m.names.index("z")]) if "z" in m.names else 0.0
    range_z = s.sampling.range * (box_factors(s.sampling, len(m.names))[m.names.index("z")] if "z" in m.names else 1.0)
    model.process = process_laws(s, m, mechanics, described, scale_z, float(range_z), capacitance_sampler(s, m, scales))
    if model.process and model.inertial:  # the inertial terms' tscale law (netgen.model.process_loads.inertial_law)
        model.process["inertial"] = inertial_law(s, data, lambda t: inertial.terms(t, m, s.coordinates.inertial))
    if "etch" in model.process and (model.acceleration or model.process.get("inertial")):
        etch_loads(s, m, model)
    return model


def etch_loads(s: Structure, m: Mechanics, model: MacroModel) -> None:
    """The inertial loads' etch laws (netgen.model.process_loads: a_in and the inertial entries follow
    the etched body), into the model's process record; the mechanics re-run once per etch point."""
    runs = process_loads.etched_runs(s, m, mechanics)
    if model.acceleration:
        model.process["etch"]["acceleration"] = process_loads.acceleration_law(s, m, mechanics, runs)
    if model.process.get("inertial"):
        law = process_loads.inertial_etch_law(s, m, mechanics, s.coordinates.inertial, runs)
        model.process["inertial"]["etch"] = law


def capacitance_sampler(s0: Structure, m: Mechanics, scales: np.ndarray):
    """(structure, n, offset) -> its electrodes' capacitances from a fresh extractor at rest and at n
    random points of s0's fit box (fixed seed: the same points for every structure), all moved by the
    displacement `offset` (SI per coordinate; None: none; `corners`: at the box's corners instead), for the process laws' re-runs of an etched
    structure (netgen.model.process.etch_record). A beam's modes are its own structure's (an etched
    cantilever's are those of its shorter length, peak 1 at its tip: the coordinates a rebuild has), so
    are a free disk's eigenmodes (an etched disk's reach its own rim); a proof mass's and a piston's rigid
    coordinates do not depend on the outline (the nominal basis)."""

    runs: dict = {}  # conductor -> its own mechanics' basis (one eigen-solve per etched conductor)

    def extract(s: Structure, n: int, offset: np.ndarray | None = None, corners: bool = False) -> np.ndarray:
        plate, shapes = plate_outline(s), electrodes(s)
        own = (getattr(s.conductor, "one_dimensional", False) or modal_disk(s)) and s.conductor != s0.conductor
        if own and s.conductor not in runs:
            runs[s.conductor] = mechanics(s).basis
        prepared = extractor(s, plate).prepare(shapes, plate, runs[s.conductor] if own else m.basis)
        q = (box_corners(s0.sampling, len(m.names)) if corners else check_points(s0.sampling, n, len(m.names))) * scales
        return np.asarray(prepared.capacitance(q + (0.0 if offset is None else offset)), dtype=float)

    return extract


def modal_disk(s: Structure) -> bool:
    """A free disk with eigenmodes among its coordinates (their shapes scale with its radius)."""
    return getattr(s.conductor, "kind", "") == "free_disk" and bool(s.coordinates.modes)


def dielectric_layers(s: Structure) -> list[dict]:
    """The electrode sets' dielectric layers (netgen.structure.electrodes.read_dielectric): each one's
    thickness, permittivity, the air gap where the plate stops and the series (effective) gap."""
    medium = s.electrostatics.relative_permittivity
    out = []
    for e in s.electrode_sets:
        t = getattr(e, "dielectric_thickness", 0.0)
        if t > 0.0:
            eps_r = e.dielectric_permittivity
            out.append(
                {
                    "set": e.name,
                    "thickness_m": t,
                    "relative_permittivity": eps_r,
                    "stop_gap_m": e.gap - t,
                    "effective_gap_m": e.gap - t + t * medium / eps_r,
                }
            )
    return out


def farthest(plate: Plate, shapes: list[ShapeElectrode]) -> float:
    """Distance from the origin of the farthest point of the conductor outline or a comb's fingers."""
    x, y, _ = plate.area_rule(4)
    corners = [getattr(plate, "radius", 0.0)] + [float(np.max(np.hypot(x, y)))]
    if hasattr(plate, "x0"):
        corners += [math.hypot(a, b) for a in (plate.x0, plate.x1) for b in (plate.y0, plate.y1)]
    return max(corners + [e.shape.extent() for e in shapes if hasattr(e.shape, "extent")])


def stops(
    s: Structure, m: Mechanics, prepared: PreparedExtractor, shapes: list[ShapeElectrode], scales: np.ndarray
) -> dict:
    """The contact model (netgen.model.contact): stop points from the extractor's probe points."""
    probe = prepared.probe_points()
    owner = [shapes[i].name for i in probe.electrode]
    freqs = m.frequencies[m.frequencies > 0]
    ws = 2 * math.pi * (math.exp(float(np.mean(np.log(freqs)))) if len(freqs) else 1e6 / (2 * math.pi))
    return contact.contact_model(probe.gap, probe.phi, owner, scales, body_mass(s), ws)


def say(progress: bool, text: str) -> None:
    """A progress line on stderr."""
    if progress:
        print(text, file=sys.stderr)


def figure_names(name: str) -> tuple[str, ...]:
    """The files write_figures and write_calibration can write for model `name`: fit errors, mode
    shapes, small-angle errors, the calibration report (JSON and PNG)."""
    return (
        f"{name}_fit_errors.png",
        f"{name}_modes.png",
        f"{name}_small_angle.png",
        f"{name}_calibration.json",
        f"{name}_calibration.png",
    )


def write_calibration(b: Build, folder: Path, figure: bool = True) -> list[Path]:
    """The calibrated extractor's report beside the netlists (netgen.electrostatics.calibration_report):
    JSON, and its PNG when `figure`; nothing for an uncalibrated build."""
    if not hasattr(b.extractor, "report"):
        return []
    names = figure_names(b.model.name)
    return calibration_report.write(b.extractor.report(), folder / names[3], folder / names[4] if figure else None)


def write_figures(b: Build, folder: Path) -> list[Path]:
    """Mode-shape and fit-error PNGs next to the netlist (from the build's stage outputs)."""
    model = b.model
    errors, modes, angles = figure_names(model.name)[:3]
    out = [plots.fit_errors(folder / errors, model)]
    if "small_angle" in model.report:
        out.append(plots.small_angle(folder / angles, model.report["small_angle"]))
    if any(c.kind == "mode" for c in model.coordinates) and b.structure.conductor.outline_shape == "disk":
        out.append(
            plots.mode_shapes(
                folder / modes, model, b.mechanics.basis, b.structure.conductor.radius, electrode_outlines(b.structure)
            )
        )
    return out
