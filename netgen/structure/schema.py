"""The validated structure description: frozen dataclasses of every table but the conductor and
its electrodes (netgen.structure.conductors, netgen.structure.electrodes)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

from ..core.reader import Reader

RIGID_COORDINATES = ("z", "tilt_x", "tilt_y")  # out of plane: every conductor kind
IN_PLANE_COORDINATES = ("x", "y", "rot_z")  # in plane: proof masses (netgen.structure.conductors.ProofMass)
ALL_RIGID = IN_PLANE_COORDINATES + RIGID_COORDINATES
# [coordinates] inertial: frame acceleration (m/s^2) and rotation rate (rad/s) per axis, as model ports
# (netgen.model.inertial; a_z is the port a_in, its name since before the other axes)
INERTIAL_INPUTS = ("a_x", "a_y", "a_z", "w_x", "w_y", "w_z")
MODE_LABEL = re.compile(r"^([0-9]+),([0-9]+)([cs]?)\Z")  # \Z: "2,0c\n" is not a label
NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*\Z")
MAX_GRID_POINTS = 2_000_000  # capacitance samples levels ** ncoords the pipeline accepts
DESIGNS = ("grid", "sparse", "lhs", "sobol", "adaptive")  # [sampling] design (netgen.electrostatics.designs)
DESIGN_KEYS = {
    "levels": ("grid",),
    "level": ("sparse",),
    "points": ("lhs", "sobol", "adaptive"),
    "seed": ("lhs", "sobol", "adaptive"),
}  # the [sampling] keys each design reads
GRID_DEFAULT_MAX = 7  # the full grid is the default design up to 7 coordinates (3^7 = 2187)


def default_design(ncoords: int) -> str:
    """The design without `[sampling] design`: the paper's grid up to GRID_DEFAULT_MAX coordinates,
    the Smolyak sparse grid above (2 n^2 + 2 n + 1 points at level 2 against the grid's 3^n)."""
    return "grid" if ncoords <= GRID_DEFAULT_MAX else "sparse"


def default_points(design: str, ncoords: int) -> int:
    """Default `points`: 32 (n + 1) for lhs (sobol: the next power of two), a budget of 64 (n + 1)
    for adaptive (the plate fit has K (n + 1) coefficients per electrode, K up to 16)."""
    if design == "adaptive":
        return 64 * (ncoords + 1)
    size = 32 * (ncoords + 1)
    return 1 << (size - 1).bit_length() if design == "sobol" else size


def smolyak_count(ncoords: int, level: int) -> int:
    """Points of the Smolyak grid of `level` on nested Clenshaw-Curtis nodes (each 1-D level i >= 2
    adds 2^(i-1) nodes, level 1 adds 2, level 0 is the centre), summed over |i| <= level."""
    sizes = [1, 2] + [2 ** (i - 1) for i in range(2, level + 1)]

    def count(n: int, budget: int) -> int:
        if n == 0:
            return 1
        return sum(sizes[i] * count(n - 1, budget - i) for i in range(budget + 1))

    return count(ncoords, level)


def mode_name(label: str) -> str:
    """The coordinate name of an eigenmode label: '2,0c' -> 'm2_0c', '1' -> 'm1'."""
    return f"m{label.replace(',', '_')}"


class Conductor(Protocol):
    """What every conductor kind (netgen.structure.conductors) offers the later stages (read-only
    properties: the kinds are frozen dataclasses)."""

    @property
    def kind(self) -> str: ...

    @property
    def thickness(self) -> float: ...

    @property
    def density(self) -> float: ...

    @property
    def outline_shape(self) -> str:
        """ "disk" (centred at the origin, `radius`) or "rect" (`outline()`)."""
        ...

    @property
    def one_dimensional(self) -> bool:
        """Mode shapes vary along x only (beams)."""
        ...

    @property
    def mass(self) -> float: ...


@dataclass(frozen=True)
class Coordinates:
    """Generalized coordinates: rigid-body motions then eigenmodes (count or (n,s) labels)."""

    rigid: tuple[str, ...]
    modes: int | tuple[str, ...]
    # inertial inputs (INERTIAL_INPUTS): frame accelerations and rotation rates as ports
    inertial: tuple[str, ...] = ()

    @property
    def acceleration_port(self) -> bool:
        """The a_in port (frame acceleration along +z: the input a_z)."""
        return "a_z" in self.inertial

    @property
    def count(self) -> int:
        """Number of generalized coordinates."""
        return len(self.rigid) + (self.modes if isinstance(self.modes, int) else len(self.modes))


@dataclass(frozen=True)
class Sampling:
    """Capacitance sample design over +-range x touching amplitude (netgen.electrostatics.designs):
    "grid" (`levels` per coordinate), "sparse" (Smolyak `level`), "lhs" / "sobol" (`points`,
    `seed`) or "adaptive" (refined until fit.tolerance or a budget of `points`, `seed`).
    `range_given` False: the file has no `range`, and the build narrows the default 0.2 where the
    box's corners would reach an electrode (netgen.electrostatics.sampling.box_range)."""

    levels: int = 3
    range: float = 0.2
    design: str = "grid"
    level: int = 2
    points: int = 0  # lhs / sobol size, adaptive budget (0 before the parser's default)
    seed: int = 1
    range_given: bool = True
    ranges: tuple[tuple[str, float], ...] = ()  # per-coordinate ranges (name or "*"); `range` is their largest
    factors: tuple[
        float, ...
    ] = ()  # each coordinate's range / `range`, in coordinate order (netgen.build.resolve_ranges)


@dataclass(frozen=True)
class FitOptions:
    """Capacitance fit form and error budget.

    target "plates": C = c_ref sum_k 1/P_k(x), K effective parallel plates (P_k of total
    `degree`), K refined until the held-out max relative error <= `tolerance` or K > max_terms;
    "inverse": one polynomial of 1/C; "direct": one polynomial of C.
    """

    degree: int = 1
    target: str = "plates"
    holdout: int = 500
    seed: int = 1
    tolerance: float = 2e-3
    max_terms: int = 16


@dataclass(frozen=True)
class ElectrostaticsOptions:
    """Extractor choice and settings: edge-fringe model and constant electrode-electrode coupling.
    `extractor` names an entry of netgen.electrostatics.EXTRACTORS (checked when the model is built)."""

    fringe: str = "plate_between"
    fringe_a: float = 0.42
    fringe_b: float = 0.06
    relative_permittivity: float = 1.0
    coupling_per_length: float = 0.0
    extractor: str = "parallel_plate"
    couplings: str | None = None  # a field solver's Maxwell matrices (netgen.electrostatics.coupling_file)
    calibration_points: int = 0  # BEM points of extractor = "calibrated" (netgen.electrostatics.calibrated)
    calibration_source: str = "bem"  # the field solver of those points: "bem" or "fastcap"
    comb_model: str = "field2d"  # netgen.electrostatics.comb.MODELS: "field2d" or "textbook"
    bem: tuple = ()  # [electrostatics.bem] (key, value) pairs: netgen.electrostatics.bem.BemSettings
    fastcap: tuple = ()  # [electrostatics.fastcap] pairs: netgen.electrostatics.fastcap.FastcapSettings


@dataclass(frozen=True)
class FemOptions:
    """Eigenmode FEM settings (scikit-fem Morley plate on a refined circle mesh)."""

    refine: int = 6


@dataclass(frozen=True)
class Damping:
    """Mechanical damping: per-coordinate Q or damping ratio (a number applies to every eigenmode),
    Rayleigh D = alpha M + beta K, squeeze-film gas damping, and thermal force noise."""

    q_factor: tuple[tuple[str, float], ...] = ()  # (coordinate, Q); "*" = every eigenmode
    damping_ratio: tuple[tuple[str, float], ...] = ()  # (coordinate, zeta); "*" = every eigenmode
    rayleigh_alpha: float = 0.0  # 1/s
    rayleigh_beta: float = 0.0  # s
    squeeze_film: bool = False
    pressure: float = 101325.0  # Pa
    gas: str = "air"
    temperature: float = 300.0  # K, of the gas and of the thermal noise
    noise: bool = False  # emit thermal force noise sources
    fem_refine: int = 5  # Reynolds mesh refinement
    film_model: str = "incompressible"  # or "compressible": Maxwell branches (pole-residue)
    film_max_frequency: float = 0.0  # Hz the compressible network must cover (0: auto)

    def enabled(self) -> bool:
        """True when any damping contribution is requested."""
        return bool(
            self.q_factor or self.damping_ratio or self.rayleigh_alpha or self.rayleigh_beta or self.squeeze_film
        )


PROCESS_PARAMETERS = ("dg", "tscale", "escale", "temp")  # [process] parameters: dg = one dg_<set> per plate set
# every parameter [process] may declare: PROCESS_PARAMETERS (the default list) and the lateral etch bias,
# which needs a proof mass's flexures and so is only declared by name
ALL_PROCESS_PARAMETERS = (*PROCESS_PARAMETERS, "etch")


@dataclass(frozen=True)
class Process:
    """[process] (opt-in): which process instance parameters the emitted .lib carries, their valid
    ranges and the modulus' temperature coefficient (netgen.model.process derives the laws)."""

    parameters: tuple[str, ...] = PROCESS_PARAMETERS  # a subset of PROCESS_PARAMETERS
    tscale_range: tuple[float, float] = (0.9, 1.1)  # device-layer thickness / nominal
    escale_range: tuple[float, float] = (0.5, 1.5)  # Young's modulus / nominal
    temp_range: tuple[float, float] = (-40.0, 125.0)  # die temperature, degC
    modulus_tc: float = -60e-6  # 1/K, d ln E / dT of the device layer (silicon about -60 ppm/K)
    etch_range: tuple[float, float] = (-1e-7, 1e-7)  # m, lateral over-etch per edge (flexure widths w - 2 etch)
    cavity: str = "open"  # the squeeze film's gas under temp: "open" (fixed pressure) or "sealed" (fixed amount, p ~ T)

    def wants(self, name: str) -> bool:
        """The parameter `name` is declared."""
        return name in self.parameters


@dataclass(frozen=True)
class Imports:
    """[import]: data from an external FEM and/or field solver (netgen.mechanics.imported,
    netgen.electrostatics.imported), paths resolved against the structure file's folder.
    Mechanics needs all three of mass_matrix, stiffness_matrix and modes; capacitance alone
    replaces the extractor's samples."""

    mass_matrix: str | None = None  # Matrix Market (.mtx): M, full (with modes) or modal
    stiffness_matrix: str | None = None  # Matrix Market (.mtx): K, same size as M
    modes: str | None = None  # .npz or .csv: node coordinates + eigenvectors (vertical)
    capacitance: str | None = None  # .npz or .csv: coordinates q -> plate-electrode capacitances


@dataclass(frozen=True)
class Structure:
    """A validated structure description; `source` is the file it came from."""

    name: str
    description: str
    source: str
    conductor: Conductor
    electrode_sets: tuple
    coordinates: Coordinates
    sampling: Sampling = field(default_factory=Sampling)
    fit: FitOptions = field(default_factory=FitOptions)
    electrostatics: ElectrostaticsOptions = field(default_factory=ElectrostaticsOptions)
    fem: FemOptions = field(default_factory=FemOptions)
    damping: Damping | None = None
    imports: Imports | None = None  # [import]: mechanics and/or capacitances from external tools
    warnings: tuple[str, ...] = ()  # model assumptions near their limits (netgen.structure.validity)
    process: Process | None = None  # [process]: the process instance parameters (None: none, main's .lib)

    def electrode_names(self) -> list[str]:
        return [n for s in self.electrode_sets for n in s.electrode_names()]


@runtime_checkable
class ConductorKind(Conductor, Protocol):
    """What a conductor kind's dataclass provides to the structure reader (netgen.structure.parse):
    itself from its [conductor] table, its electrodes, coordinates and FEM options, the checks
    across them, and its coordinates' names (None: the reader's default)."""

    @classmethod
    def read(cls, rd: Reader, t: dict, kind: str) -> ConductorKind: ...

    def read_electrodes(self, rd: Reader, doc: dict) -> tuple: ...

    def read_coordinates(self, rd: Reader, doc: dict) -> Coordinates: ...

    def read_fem(self, rd: Reader, doc: dict) -> FemOptions: ...

    def check(self, rd: Reader, doc: dict, electrodes: tuple, coords: Coordinates, fem: FemOptions) -> None: ...

    def coordinate_names(self, coords: Coordinates) -> list[str] | None: ...
