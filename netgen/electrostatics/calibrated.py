"""The calibrated extractor (`[electrostatics] extractor = "calibrated"`): the parallel-plate
extractor with per-electrode edge-fringe coefficients and the constant electrode-electrode
couplings fitted to a field solution at a few points (netgen.electrostatics.calibration).

The field solution is the BEM extractor at `calibration_points` points (netgen.electrostatics.bem,
its Maxwell matrix at given generalized coordinates; `calibration_source = "fastcap"`: the multipole
extractor, netgen.electrostatics.fastcap, with its [electrostatics.fastcap] settings), or the Maxwell matrices of a user's file
(`couplings = "file"`, netgen.electrostatics.coupling_file) at the points the file names.
`extractor = "parallel_plate"` with a `couplings` file takes the file's mean couplings only.
A perforated plate keeps its fill factor F(g) in the plate term (netgen.electrostatics.perforation)
and the fringes are fitted beside it, on FastCap points with the holes meshed (BEM points, of a
solid plate, are refused for it: netgen.structure.validity.perforation).
"""

from __future__ import annotations

import importlib.util
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from ..core.errors import StructureError
from ..geometry.shapes import Array, Basis, Electrode, Plate
from . import coupling_file
from .calibration import Calibration, MaxwellSource, calibrate, design, electrode_couplings
from .parallel_plate import ParallelPlateExtractor, PreparedParallelPlate
from .parallel_plate import from_structure as parallel_plate_from_structure
from .sampling import touch_amplitudes


def bem_source(s, electrodes: Sequence[Electrode], plate: Plate, basis: Basis) -> MaxwellSource:
    """The BEM extractor's Maxwell matrix at q (netgen.electrostatics.bem: PreparedBem.maxwell(q).matrix,
    conductors [plate, *electrodes]); each solve's estimated error is kept in `source.errors`."""
    from . import bem

    return field_source(bem.from_structure(s, plate).prepare(electrodes, plate, basis))


def fastcap_source(s, electrodes: Sequence[Electrode], plate: Plate, basis: Basis) -> MaxwellSource:
    """The multipole extractor's Maxwell matrix at q (netgen.electrostatics.fastcap, its
    [electrostatics.fastcap] settings), with each solve's error bar in `source.errors`."""
    from . import fastcap

    return field_source(fastcap.from_structure(s, plate).prepare(electrodes, plate, basis))


def field_source(prepared) -> MaxwellSource:
    """q -> a prepared field solver's Maxwell matrix (conductors [plate, *electrodes]), each
    solve's estimated error appended to `source.errors`."""
    errors: list[float] = []

    def source(q: np.ndarray) -> np.ndarray:
        m = prepared.maxwell(q)
        errors.append(float(m.error))
        return np.asarray(m.matrix, dtype=float)

    source.errors = errors  # type: ignore[attr-defined]
    return source


def bem_available() -> bool:
    """Whether the BEM extractor (netgen.electrostatics.bem and its bempp-cl) can be imported."""
    if importlib.util.find_spec("netgen.electrostatics.bem") is None:
        return False
    return importlib.util.find_spec("bempp_cl") is not None


# (structure, electrodes, plate, basis) -> the field solution's Maxwell matrix at q: the BEM
# extractor's when it is installed; empty: not available
BEM_SOURCE: list[Callable[..., MaxwellSource]] = [bem_source] if bem_available() else []


@dataclass
class CalibratedExtractor:
    """Parallel plate + per-electrode fringe + couplings, calibrated when prepared (see the module)."""

    description: ClassVar[str] = (
        "parallel-plate over the local gap + edge fringe, calibrated per electrode against a field solution"
    )
    base: ParallelPlateExtractor
    coordinates: list[str]
    points: int = 0  # BEM points (0 with a file)
    span: float = 0.2  # the design's box, a fraction of the touching amplitudes
    file: str | None = None  # a Maxwell-matrix file instead of BEM
    source: Callable[..., MaxwellSource] | None = None
    structure: object = None
    result: dict = field(default_factory=dict)  # the Calibration, once prepared

    def prepare(self, electrodes: Sequence[Electrode], plate: Plate, basis: Basis) -> PreparedParallelPlate:
        """Calibrate against the field solution, then prepare the calibrated parallel-plate extractor."""
        analytic = self.base.prepare(electrodes, plate, basis)
        scales = plate_scales(analytic, self.coordinates, electrodes)
        if self.file is not None:
            f = read_checked(self.file, self.coordinates, electrodes, analytic, scales, need_plate=True)
            cal = calibrate(
                None,
                electrodes,
                plate,
                basis,
                f.q,
                self.base,
                f"Maxwell matrices of {f.path}",
                maxwell=f.ordered([e.name for e in electrodes], plate=True),
            )
        else:
            if self.source is None:
                raise StructureError(
                    getattr(self.structure, "source", "<structure>"),
                    "electrostatics.extractor",
                    'extractor = "calibrated" needs a field solution: the BEM extractor '
                    "(netgen.electrostatics.bem) is not installed in this netgen",
                    'give the field solver\'s Maxwell matrices instead: couplings = "maxwell.json"',
                )
            maxwell = self.source(self.structure, electrodes, plate, basis)
            solver = "FastCap" if self.source is fastcap_source else "BEM"
            cal = calibrate(
                maxwell,
                electrodes,
                plate,
                basis,
                design(self.points, scales, self.span),
                self.base,
                f"{solver} at {self.points} point(s)",
            )
            self.result["field_errors"] = list(getattr(maxwell, "errors", []))
        self.result["calibration"] = cal
        self.result["names"] = [e.name for e in electrodes]
        return ParallelPlateExtractor(
            eps=self.base.eps,
            fringes=cal.fringes,
            order=self.base.order,
            edge_order=self.base.edge_order,
            perforation=self.base.perforation,
            layer_step=self.base.layer_step,
        ).prepare(electrodes, plate, basis)

    def coupling(self, electrodes: Sequence[Electrode], plate: Plate) -> Array:
        """The calibrated constant couplings (nel, nel) in F (prepare() first)."""
        if "calibration" not in self.result:
            raise RuntimeError("CalibratedExtractor.coupling before prepare()")
        return self.result["calibration"].coupling.copy()

    def calibration(self) -> dict:
        """The MacroModel's calibration entry (netgen.model.macromodel.MacroModel.calibration)."""
        cal: Calibration = self.result["calibration"]
        return cal.record(self.result["names"])

    def report(self) -> dict:
        """The calibration against its field solution (netgen.electrostatics.calibration.comparison)."""
        cal: Calibration = self.result["calibration"]
        return {
            "source": cal.source,
            "points_si": cal.points.tolist(),
            "coordinates": list(self.coordinates),
            "field_solution_rel_errors": self.result.get("field_errors", []),
            "electrodes": cal.comparison,
        } | {"calibration": self.calibration()}


@dataclass(frozen=True)
class FileCoupledExtractor:
    """The parallel-plate extractor with the constant couplings of a Maxwell-matrix file (the mean
    over its points); the plate-electrode capacitances stay analytic."""

    description: ClassVar[str] = "parallel-plate over the local gap + edge fringe; couplings from a field-solver file"
    base: ParallelPlateExtractor
    coordinates: list[str]
    file: str
    result: dict = field(default_factory=dict)

    def prepare(self, electrodes: Sequence[Electrode], plate: Plate, basis: Basis) -> PreparedParallelPlate:
        """Read and check the file against the electrodes, then prepare the analytic extractor."""
        prepared = self.base.prepare(electrodes, plate, basis)
        scales = plate_scales(prepared, self.coordinates, electrodes)
        f = read_checked(self.file, self.coordinates, electrodes, prepared, scales, need_plate=False)
        cc = pad_plate(f.ordered([e.name for e in electrodes], plate=False))
        self.result.update(
            coupling=cc.mean(axis=0),
            spread=cc.std(axis=0),
            points=len(f.q),
            path=f.path,
            names=[e.name for e in electrodes],
        )
        return prepared

    def coupling(self, electrodes: Sequence[Electrode], plate: Plate) -> Array:
        """The file's mean couplings (nel, nel) in F (prepare() first)."""
        return self.result["coupling"].copy()

    def calibration(self) -> dict:
        """The MacroModel's calibration entry: the file and the couplings' spread over its points."""
        names, c, s = self.result["names"], self.result["coupling"], self.result["spread"]
        spread = [
            {"pair": [names[i], names[j]], "mean": float(c[i, j]), "std": float(s[i, j])}
            for i in range(len(names))
            for j in range(i + 1, len(names))
            if c[i, j]
        ]
        return {
            "source": f"couplings from {self.result['path']}",
            "points": int(self.result["points"]),
            "coupling_spread": spread,
        }


def plate_scales(analytic, coordinates: list[str], electrodes: Sequence[Electrode]) -> np.ndarray:
    """Touching amplitude of each coordinate for these (plate) electrodes; infinite for one that
    moves none of them (in-plane beside combs: netgen.electrostatics.compose), which the
    calibration leaves at 0."""
    return touch_amplitudes(analytic, len(coordinates), np.array([e.stop_gap for e in electrodes]))


def pad_plate(m: np.ndarray) -> np.ndarray:
    """Electrode-only Maxwell matrices (npts, nel, nel) -> their two-terminal couplings (zero diagonal)."""
    padded = np.zeros((m.shape[0], m.shape[1] + 1, m.shape[2] + 1))
    padded[:, 1:, 1:] = m
    return electrode_couplings(padded)


def read_checked(
    path: str, coordinates: list[str], electrodes: Sequence[Electrode], analytic, scales: np.ndarray, need_plate: bool
) -> coupling_file.MaxwellFile:
    """A Maxwell-matrix file read and checked against the electrodes, eps A / g at rest and the scales."""
    f = coupling_file.read(path, coordinates)
    estimates = np.asarray(analytic.capacitance(np.zeros(len(coordinates))), dtype=float)
    coupling_file.check(f, [e.name for e in electrodes], need_plate, estimates, scales)
    return f


def from_structure(s, plate: Plate) -> CalibratedExtractor:
    """`extractor = "calibrated"`: the structure's analytic extractor, its calibration source and count."""
    o = s.electrostatics
    names = list(s.conductor.coordinate_names(s.coordinates))
    base = parallel_plate_from_structure(s, plate)
    if o.couplings is None and o.calibration_points < 1:
        raise StructureError(
            s.source,
            "electrostatics.calibration_points",
            'extractor = "calibrated" needs calibration points or a couplings file',
            'write calibration_points = 9 (BEM solves), or couplings = "maxwell.json"',
        )
    if getattr(o, "calibration_source", "bem") == "fastcap":
        source: Callable[..., MaxwellSource] | None = fastcap_source
    else:
        source = BEM_SOURCE[0] if BEM_SOURCE else None
    return CalibratedExtractor(base, names, o.calibration_points, s.sampling.range, o.couplings, source, s)


def with_file_couplings(s, base: ParallelPlateExtractor) -> FileCoupledExtractor:
    """`couplings = "file"` beside the parallel-plate extractor: its couplings from the file."""
    return FileCoupledExtractor(base, list(s.conductor.coordinate_names(s.coordinates)), s.electrostatics.couplings)
