"""Conductor kinds: one frozen dataclass per kind, each reading its own [conductor] table and the
tables whose form depends on it ([[electrodes]], [coordinates], [fem]). CONDUCTORS is the
registry the parser picks from (`kind = ...`); the mechanics stage has its own
(netgen.mechanics.KINDS). The conductor lies in the x-y plane: the disk centred at the origin,
the piston plate centred at the origin, beams from the clamp at x = 0 to x = length, centred
on y = 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from ..core.reader import Reader, check_keys, did_you_mean, flag, integer, nonnegative, positive, quantity, table
from .electrodes import check_ring_overlaps, plates_and_combs, rectangles, ring_sets
from .flexures import Flexure, read_flexure
from .holes import grid_count
from .schema import (
    ALL_RIGID,
    INERTIAL_INPUTS,
    MODE_LABEL,
    RIGID_COORDINATES,
    ConductorKind,
    Coordinates,
    FemOptions,
    mode_name,
)

MAX_PLATE_MODES = 12  # internal modes of a proof mass (the plate mesh resolves them: netgen.mechanics.rect_plate)


def acceleration_port(rd: Reader, t: dict) -> bool:
    """coordinates.acceleration_port: emit the a_in port (frame acceleration along +z)."""
    return flag(
        rd,
        t,
        "coordinates",
        "acceleration_port",
        False,
        "write acceleration_port = true (adds the port a_in: frame acceleration, 1 V = 1 m/s^2)",
    )


def inertial_inputs(rd: Reader, t: dict) -> tuple[str, ...]:
    """coordinates.inertial (frame accelerations a_x, a_y, a_z and rotation rates w_x, w_y, w_z) and
    acceleration_port = true (the a_z shorthand), in the canonical order of INERTIAL_INPUTS."""
    chosen = t.get("inertial", [])
    example = 'write inertial = ["a_x", "a_y", "a_z", "w_z"] (any of ' + ", ".join(INERTIAL_INPUTS) + ")"
    if not isinstance(chosen, list) or not all(isinstance(a, str) for a in chosen):
        raise rd.fail("coordinates.inertial", f"inertial must be a list of input names, got {chosen!r}", example)
    for a in chosen:
        if a not in INERTIAL_INPUTS:
            raise rd.fail(
                "coordinates.inertial",
                f"unknown inertial input {a!r}",
                f"{did_you_mean(a, list(INERTIAL_INPUTS))}{example}",
            )
    if len(set(chosen)) != len(chosen):
        raise rd.fail("coordinates.inertial", "an inertial input is listed twice", "list each input once")
    if acceleration_port(rd, t):
        chosen = [*chosen, "a_z"]
    return tuple(a for a in INERTIAL_INPUTS if a in chosen)


def boundary_edges(refine: int) -> int:
    """Edges on the rim of scikit-fem's MeshTri.init_circle(refine) (32 at refine 3, doubling per level)."""
    return 32 * 2 ** (refine - 3)


@dataclass(frozen=True)
class FreeDisk:
    """A free-floating thin circular plate (the paper's levitated disk) between ring-sector sets."""

    radius: float
    thickness: float
    youngs_modulus: float
    poisson_ratio: float
    density: float
    kind: str = "free_disk"
    outline_shape: ClassVar[str] = "disk"
    one_dimensional: ClassVar[bool] = False

    @property
    def mass(self) -> float:
        return math.pi * self.radius**2 * self.thickness * self.density

    @classmethod
    def read(cls, rd: Reader, t: dict, kind: str) -> FreeDisk:
        """The [conductor] table of a free disk."""
        check_keys(rd, "conductor", t, ["kind", "radius", "thickness", "youngs_modulus", "poisson_ratio", "density"])
        radius = quantity(rd, t, "conductor", "radius", "length", check=positive, what="disk radius")
        thickness = quantity(rd, t, "conductor", "thickness", "length", check=positive, what="plate thickness")
        modulus = quantity(
            rd,
            t,
            "conductor",
            "youngs_modulus",
            "modulus",
            check=positive,
            what="Young's modulus (polysilicon: 160 GPa)",
        )
        nu = quantity(
            rd,
            t,
            "conductor",
            "poisson_ratio",
            "dimensionless",
            check=lambda v: None if -1 < v < 0.5 else "must lie in (-1, 0.5)",
            what="Poisson's ratio (polysilicon: 0.22)",
        )
        density = quantity(
            rd, t, "conductor", "density", "density", check=positive, what="mass density (polysilicon: 2330 kg/m^3)"
        )
        return cls(radius, thickness, modulus, nu, density, kind)

    def read_electrodes(self, rd: Reader, doc: dict) -> tuple:
        return ring_sets(rd, doc, self.radius)

    def read_coordinates(self, rd: Reader, doc: dict) -> Coordinates:
        """Rigid z and tilts, and eigenmodes by count or (n,s) label."""
        t = table(rd, doc, "coordinates", required=True)
        check_keys(rd, "coordinates", t, ["rigid", "modes", "acceleration_port", "inertial"])
        rigid = t.get("rigid", list(RIGID_COORDINATES))
        if not isinstance(rigid, list) or not all(isinstance(r, str) for r in rigid):
            raise rd.fail(
                "coordinates.rigid", "rigid must be a list of names", f"write rigid = {list(RIGID_COORDINATES)}"
            )
        for r in rigid:
            if r not in RIGID_COORDINATES:
                raise rd.fail(
                    "coordinates.rigid",
                    f"unknown rigid coordinate {r!r}",
                    f"{did_you_mean(r, list(RIGID_COORDINATES))}use any of {list(RIGID_COORDINATES)}",
                )
        if len(set(rigid)) != len(rigid):
            raise rd.fail("coordinates.rigid", "a rigid coordinate is listed twice", "list each once")
        modes = t.get("modes", 0)
        if isinstance(modes, bool) or not isinstance(modes, (int, list)):
            raise rd.fail(
                "coordinates.modes",
                f"modes must be a count or a list of labels, got {modes!r}",
                'write modes = 4 or modes = ["2,0c", "2,0s", "3,0c", "3,0s"]',
            )
        if isinstance(modes, int):
            if not 0 <= modes <= 40:
                raise rd.fail("coordinates.modes", f"modes = {modes} is outside 0..40", "choose 0 to 40 eigenmodes")
        else:
            for m in modes:
                match = MODE_LABEL.match(m) if isinstance(m, str) else None
                if not match or (match.group(1) == "0") != (match.group(3) == ""):
                    raise rd.fail(
                        "coordinates.modes",
                        f"mode label {m!r} is not of the form 'n,s' + c|s",
                        "label a mode by nodal diameters n and nodal circles s, with c or s for the "
                        'cos/sin orientation when n > 0: e.g. "2,0c", "3,0s", "0,1"',
                    )
            if len(set(modes)) != len(modes):
                raise rd.fail("coordinates.modes", "a mode label is listed twice", "list each mode once")
            modes = tuple(modes)
        if not rigid and not modes:
            raise rd.fail("coordinates", "no generalized coordinates", "list rigid coordinates and/or modes")
        return Coordinates(tuple(rigid), modes, inertial_inputs(rd, t))

    def read_fem(self, rd: Reader, doc: dict) -> FemOptions:
        t = table(rd, doc, "fem", required=False)
        check_keys(rd, "fem", t, ["refine"])
        return FemOptions(refine=integer(rd, t, "fem", "refine", 6, 3, 8, "mesh refinement level"))

    def check(self, rd: Reader, doc: dict, electrodes: tuple, coords: Coordinates, fem: FemOptions) -> None:
        """Sets that overlap on one side; modes the FEM mesh does not resolve."""
        check_ring_overlaps(rd, electrodes)
        edges = boundary_edges(fem.refine)
        if isinstance(coords.modes, int) and coords.modes > edges // 4:
            raise rd.fail(
                "coordinates.modes",
                f"{coords.modes} modes need a finer mesh than fem.refine = {fem.refine} "
                f"(at most {edges // 4}: 8 rim edges per wavelength)",
                f"raise fem.refine or request at most {edges // 4} modes",
            )
        if not isinstance(coords.modes, int):
            for m in coords.modes:
                label = MODE_LABEL.match(m)
                assert label is not None  # read_coordinates refused labels that do not match
                n, s_ = (int(v) for v in label.groups()[:2])
                if n > edges // 8 or s_ > edges // 32:
                    raise rd.fail(
                        "coordinates.modes",
                        f"mode {m!r} is not resolved by the mesh of fem.refine = "
                        f"{fem.refine} (n <= {edges // 8}, s <= {edges // 32})",
                        "raise fem.refine or drop the mode",
                    )

    def coordinate_names(self, coords: Coordinates) -> list[str] | None:
        """Names the pipeline gives the coordinates (None while modes are only a count)."""
        if isinstance(coords.modes, int):
            return None if coords.modes else list(coords.rigid)
        return list(coords.rigid) + [mode_name(m) for m in coords.modes]


class Suspended:
    """What the suspended kinds share: rectangular electrodes, no plate mesh, no squeeze film."""

    outline_shape: ClassVar[str] = "rect"
    one_dimensional: ClassVar[bool] = False

    def outline(self) -> tuple[float, float, float, float]:
        """The body's rectangle (x0, x1, y0, y1), m: each suspended kind defines it."""
        raise NotImplementedError

    def read_electrodes(self, rd: Reader, doc: dict) -> tuple:
        return rectangles(rd, doc, self.outline())

    def read_fem(self, rd: Reader, doc: dict) -> FemOptions:
        if "fem" in doc:
            raise rd.fail(
                "[fem]",
                "[fem] sets the free-disk plate mesh; a suspended structure has none",
                "remove [fem] (beams: conductor.elements sets the beam mesh)",
            )
        return FemOptions()

    def check(self, rd: Reader, doc: dict, electrodes: tuple, coords: Coordinates, fem: FemOptions) -> None:
        damp = doc.get("damping")
        if isinstance(damp, dict) and damp.get("squeeze_film"):
            raise rd.fail(
                "damping.squeeze_film",
                "the squeeze-film model is solved on the free disk only",
                "remove squeeze_film and give q_factor / damping_ratio / rayleigh instead",
            )


@dataclass(frozen=True)
class Piston(Suspended):
    """A rigid rectangular plate on linear springs: vertical stiffness and (optional) tilt stiffness."""

    length: float  # m, along x
    width: float  # m, along y
    thickness: float
    density: float
    stiffness: float  # N/m, vertical spring
    tilt_stiffness: float  # N*m/rad, about x and about y (0: tilts not allowed as coordinates)
    kind: str = "piston"

    @property
    def mass(self) -> float:
        return self.length * self.width * self.thickness * self.density

    def outline(self) -> tuple[float, float, float, float]:
        """(x0, x1, y0, y1) of the plate."""
        return -self.length / 2, self.length / 2, -self.width / 2, self.width / 2

    @classmethod
    def read(cls, rd: Reader, t: dict, kind: str) -> Piston:
        check_keys(
            rd, "conductor", t, ["kind", "length", "width", "thickness", "density", "stiffness", "tilt_stiffness"]
        )
        length = quantity(rd, t, "conductor", "length", "length", check=positive, what="plate length (along x)")
        width = quantity(
            rd, t, "conductor", "width", "length", default=length, check=positive, what="plate width (along y)"
        )
        thickness = quantity(rd, t, "conductor", "thickness", "length", check=positive, what="plate thickness")
        density = quantity(
            rd, t, "conductor", "density", "density", check=positive, what="mass density (polysilicon: 2330 kg/m^3)"
        )
        k = quantity(
            rd, t, "conductor", "stiffness", "stiffness", check=positive, what="vertical spring stiffness in N/m"
        )
        kt = quantity(
            rd,
            t,
            "conductor",
            "tilt_stiffness",
            "torsional stiffness",
            default=0.0,
            check=nonnegative,
            what="tilt spring stiffness in N*m/rad",
        )
        return cls(length, width, thickness, density, k, kt)

    def read_coordinates(self, rd: Reader, doc: dict) -> Coordinates:
        """Rigid z (and the tilts, with a tilt spring)."""
        t = table(rd, doc, "coordinates", required=False)
        accel = inertial_inputs(rd, t)
        check_keys(rd, "coordinates", t, ["rigid", "acceleration_port", "inertial"])
        rigid = t.get("rigid", ["z"])
        if (
            not isinstance(rigid, list)
            or not rigid
            or not all(isinstance(r, str) for r in rigid)
            or len(set(rigid)) != len(rigid)
            or not set(rigid) <= set(RIGID_COORDINATES)
        ):
            raise rd.fail(
                "coordinates.rigid",
                f"rigid = {rigid!r} is not a list of distinct names from {list(RIGID_COORDINATES)}",
                'write rigid = ["z"] or rigid = ["z", "tilt_x", "tilt_y"]',
            )
        if any(r != "z" for r in rigid) and self.tilt_stiffness <= 0:
            raise rd.fail(
                "conductor.tilt_stiffness",
                "tilt coordinates need a tilt spring",
                'add tilt_stiffness = <N*m/rad> to [conductor] or use rigid = ["z"]',
            )
        return Coordinates(tuple(rigid), 0, accel)

    def coordinate_names(self, coords: Coordinates) -> list[str]:
        return list(coords.rigid)


@dataclass(frozen=True)
class Beam(Suspended):
    """A prismatic Euler-Bernoulli beam, clamped at x = 0 (and at x = length if clamped-clamped).

    residual_stress: axial stress (Pa, tensile > 0) of a clamped-clamped beam; it enters the
    linear stiffness (stress-stiffened modes). stretching: add the large-deflection strain energy
    of the mid-plane stretching (clamped-clamped only) as a fitted polynomial nonlinear stiffness.
    """

    kind: str
    length: float
    width: float
    thickness: float
    youngs_modulus: float
    density: float
    residual_stress: float = 0.0
    stretching: bool = True
    elements: int = 60
    one_dimensional: ClassVar[bool] = True

    @property
    def mass(self) -> float:
        return self.length * self.width * self.thickness * self.density

    def outline(self) -> tuple[float, float, float, float]:
        return 0.0, self.length, -self.width / 2, self.width / 2

    @classmethod
    def read(cls, rd: Reader, t: dict, kind: str) -> Beam:
        pos = positive
        check_keys(
            rd,
            "conductor",
            t,
            [
                "kind",
                "length",
                "width",
                "thickness",
                "youngs_modulus",
                "density",
                "residual_stress",
                "stretching",
                "elements",
            ],
        )
        length = quantity(rd, t, "conductor", "length", "length", check=pos, what="beam length (clamp to clamp/tip)")
        width = quantity(rd, t, "conductor", "width", "length", check=pos, what="beam width")
        thickness = quantity(rd, t, "conductor", "thickness", "length", check=pos, what="beam thickness")
        modulus = quantity(
            rd,
            t,
            "conductor",
            "youngs_modulus",
            "modulus",
            check=pos,
            what="Young's modulus (use E/(1-nu^2) for a wide beam)",
        )
        density = quantity(rd, t, "conductor", "density", "density", check=pos, what="mass density")
        stress = quantity(
            rd, t, "conductor", "residual_stress", "modulus", default=0.0, what="axial residual stress (tensile > 0)"
        )
        stretching = t.get("stretching", kind == "clamped_clamped_beam")
        if not isinstance(stretching, bool):
            raise rd.fail(
                "conductor.stretching",
                f"stretching must be true or false, got {stretching!r}",
                "write stretching = true (large-deflection stress stiffening) or false",
            )
        if kind == "cantilever" and (stress != 0.0 or stretching):
            key = "residual_stress" if stress != 0.0 else "stretching"
            raise rd.fail(
                f"conductor.{key}",
                "a cantilever has a free end: residual axial stress relaxes and the mid-plane does not stretch",
                f'remove {key} (or use kind = "clamped_clamped_beam")',
            )
        if stress < 0:
            # Euler buckling: sigma_cr = pi^2 E t^2 / (3 L^2) for clamped-clamped ends
            critical = math.pi**2 * modulus * thickness**2 / (3 * length**2)
            if -stress >= critical:
                raise rd.fail(
                    "conductor.residual_stress",
                    f"compressive stress {stress:g} Pa buckles the beam (critical {-critical:g} Pa)",
                    "give a smaller compressive stress",
                )
        elements = integer(rd, t, "conductor", "elements", 60, 8, 2000, "beam finite elements")
        return cls(kind, length, width, thickness, modulus, density, stress, stretching, elements)

    def read_coordinates(self, rd: Reader, doc: dict) -> Coordinates:
        """The first N bending modes (m1, m2, ...)."""
        t = table(rd, doc, "coordinates", required=False)
        accel = inertial_inputs(rd, t)
        check_keys(rd, "coordinates", t, ["modes", "acceleration_port", "inertial"])
        modes = t.get("modes", 3)
        if isinstance(modes, bool) or not isinstance(modes, int) or not 1 <= modes <= 12:
            raise rd.fail(
                "coordinates.modes",
                f"modes = {modes!r} must be a count 1..12 of bending modes",
                "write modes = 3 (the first three bending modes, named m1, m2, m3)",
            )
        if modes > self.elements // 4:
            raise rd.fail(
                "coordinates.modes",
                f"{modes} modes need more than conductor.elements = {self.elements}",
                f"raise conductor.elements to at least {4 * modes}",
            )
        return Coordinates((), modes, accel)

    def coordinate_names(self, coords: Coordinates) -> list[str]:
        assert isinstance(coords.modes, int)  # read_coordinates: a count (labelled modes are the free disk's)
        return [mode_name(str(k + 1)) for k in range(coords.modes)]


@dataclass(frozen=True)
class ProofMass(Suspended):
    """A rigid rectangular proof mass (length along x, width along y, centred at the origin) with
    an optional square etch-hole grid (`hole` side on a `hole_pitch` grid), suspended by a named
    flexure (netgen.structure.flexures), between plate electrodes and comb-finger arrays; its
    coordinates are any of the six rigid-body motions and, if requested, its first internal plate
    modes (netgen.mechanics.proof_mass)."""

    length: float
    width: float
    thickness: float
    density: float
    youngs_modulus: float
    poisson_ratio: float
    flexure: Flexure
    hole: float = 0.0
    hole_pitch: float = 0.0
    kind: str = "proof_mass"
    # the hole count fixed by the layout: an etched copy (netgen.model.process.etched) keeps the
    # drawn grid although its outline shrank; None: the grid that fits (holes)
    hole_grid: tuple[int, int] | None = None

    def holes(self) -> tuple[int, int]:
        """Number of etch holes along x and y (a centred grid that fits inside the mass)."""
        if not self.hole:
            return 0, 0
        if self.hole_grid is not None:
            return self.hole_grid
        return grid_count(self.length, self.hole_pitch), grid_count(self.width, self.hole_pitch)

    @property
    def mass(self) -> float:
        nx, ny = self.holes()
        return (self.length * self.width - nx * ny * self.hole**2) * self.thickness * self.density

    @property
    def fill_factor(self) -> float:
        """Solid fraction of the rectangle (1 without holes): the areal density's factor."""
        nx, ny = self.holes()
        return 1.0 - nx * ny * self.hole**2 / (self.length * self.width)

    def outline(self) -> tuple[float, float, float, float]:
        return -self.length / 2, self.length / 2, -self.width / 2, self.width / 2

    @classmethod
    def read(cls, rd: Reader, t: dict, kind: str) -> ProofMass:
        """The [conductor] table of a proof mass (with its [conductor.flexure])."""
        check_keys(
            rd,
            "conductor",
            t,
            [
                "kind",
                "length",
                "width",
                "thickness",
                "density",
                "youngs_modulus",
                "poisson_ratio",
                "hole",
                "hole_pitch",
                "flexure",
            ],
        )
        length = quantity(rd, t, "conductor", "length", "length", check=positive, what="mass length (along x)")
        width = quantity(
            rd, t, "conductor", "width", "length", default=length, check=positive, what="mass width (along y)"
        )
        thickness = quantity(rd, t, "conductor", "thickness", "length", check=positive, what="mass thickness")
        density = quantity(
            rd, t, "conductor", "density", "density", check=positive, what="mass density (polysilicon: 2330 kg/m^3)"
        )
        modulus = quantity(
            rd,
            t,
            "conductor",
            "youngs_modulus",
            "modulus",
            default=160e9,
            check=positive,
            what="Young's modulus of the flexures (polysilicon: 160 GPa)",
        )
        nu = quantity(
            rd,
            t,
            "conductor",
            "poisson_ratio",
            "dimensionless",
            default=0.22,
            check=lambda v: None if -1 < v < 0.5 else "must lie in (-1, 0.5)",
            what="Poisson's ratio",
        )
        hole = quantity(rd, t, "conductor", "hole", "length", default=0.0, check=nonnegative, what="etch-hole side")
        pitch = quantity(
            rd, t, "conductor", "hole_pitch", "length", default=0.0, check=nonnegative, what="etch-hole pitch"
        )
        if bool(hole) != bool(pitch) or (hole and hole >= pitch):
            raise rd.fail(
                "conductor.hole_pitch",
                f"hole = {hole:g} m with hole_pitch = {pitch:g} m is not a hole grid",
                'give both, with hole < hole_pitch (e.g. hole = "4 um", hole_pitch = "10 um"), or neither',
            )
        return cls(length, width, thickness, density, modulus, nu, read_flexure(rd, t, thickness), hole, pitch)

    def read_electrodes(self, rd: Reader, doc: dict) -> tuple:
        return plates_and_combs(rd, doc, self.outline(), self.thickness)

    def read_coordinates(self, rd: Reader, doc: dict) -> Coordinates:
        """Any of the six rigid-body motions (default x, y, z) and, if requested, the first
        `modes` internal plate modes m1, m2, ... (netgen.mechanics.rect_plate)."""
        t = table(rd, doc, "coordinates", required=False)
        accel = inertial_inputs(rd, t)
        check_keys(rd, "coordinates", t, ["rigid", "modes", "acceleration_port", "inertial"])
        rigid = t.get("rigid", ["x", "y", "z"])
        if (
            not isinstance(rigid, list)
            or not all(isinstance(r, str) for r in rigid)
            or len(set(rigid)) != len(rigid)
            or not set(rigid) <= set(ALL_RIGID)
        ):
            raise rd.fail(
                "coordinates.rigid",
                f"rigid = {rigid!r} is not a list of distinct names from {list(ALL_RIGID)}",
                'write rigid = ["x", "y", "z"] (any of the six rigid-body motions)',
            )
        modes = t.get("modes", 0)
        if isinstance(modes, bool) or not isinstance(modes, int) or not 0 <= modes <= MAX_PLATE_MODES:
            raise rd.fail(
                "coordinates.modes",
                f"modes = {modes!r} must be a count 0..{MAX_PLATE_MODES} of internal plate modes",
                "write modes = 2 (the first two internal modes of the mass, named m1, m2)",
            )
        if not rigid and not modes:
            raise rd.fail(
                "coordinates.rigid",
                "no generalized coordinates",
                'list rigid coordinates (e.g. rigid = ["x", "y", "z"]) and/or modes = N',
            )
        return Coordinates(tuple(r for r in ALL_RIGID if r in rigid), modes, accel)

    def check(self, rd: Reader, doc: dict, electrodes: tuple, coords: Coordinates, fem: FemOptions) -> None:
        """The squeeze film under the mass is the incompressible one (with its etch holes); a
        flexure's k_xy couples x and y, so both must be coordinates."""
        if self.flexure.k_xy and not {"x", "y"} <= set(coords.rigid):
            raise rd.fail(
                "conductor.flexure.k_xy",
                f"k_xy couples x and y but the coordinates are {list(coords.rigid)}",
                'list both in [coordinates] rigid (e.g. rigid = ["x", "y"]) or remove k_xy',
            )
        damp = doc.get("damping")
        if isinstance(damp, dict) and damp.get("film_model") == "compressible":
            raise rd.fail(
                "damping.film_model",
                "the compressible film is solved on the free disk only",
                "remove film_model (a proof mass has the incompressible film with its etch holes)",
            )

    @property
    def sprung_rigid(self) -> bool:
        """The rigid-body motions have springs (so a Q or damping ratio of them is defined)."""
        return self.flexure.type != "none"

    def coordinate_names(self, coords: Coordinates) -> list[str]:
        assert isinstance(coords.modes, int)  # read_coordinates: a count (labelled modes are the free disk's)
        return list(coords.rigid) + [mode_name(str(k + 1)) for k in range(coords.modes)]


# kind -> conductor class; a new kind is a dataclass satisfying ConductorKind, one line here, and
# its mechanics (netgen.mechanics.KINDS)
CONDUCTORS: dict[str, type[ConductorKind]] = {
    "free_disk": FreeDisk,
    "piston": Piston,
    "clamped_clamped_beam": Beam,
    "cantilever": Beam,
    "proof_mass": ProofMass,
}
