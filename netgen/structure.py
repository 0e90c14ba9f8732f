"""Structure description: the TOML file a user writes, validated into frozen dataclasses.

Every mistake becomes a StructureError naming the file, the line and key, the problem
and the fix. The data model keeps the conductor, the electrodes and the generalized
coordinates separate so other conductor kinds (suspended beams, imported FEM matrices,
imported capacitance tables) slot in as new `kind`s without touching the rest.
"""

from __future__ import annotations

import difflib
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from .units import SI_NAME, UnitError, example, parse_quantity

RIGID_COORDINATES = ("z", "tilt_x", "tilt_y")
MODE_LABEL = re.compile(r"^(\d+),(\d+)([cs]?)$")
NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


class StructureError(Exception):
    """Invalid structure file: carries file, location, problem and fix for a one-line report."""

    def __init__(self, path: str, where: str, problem: str, fix: str, line: int | None = None):
        self.path, self.where, self.problem, self.fix, self.line = path, where, problem, fix, line
        loc = f"{path}:{line}" if line else path
        super().__init__(f"{loc}: {where}: {problem}\n  fix: {fix}")


# ---------------------------------------------------------------- dataclasses

@dataclass(frozen=True)
class FreeDisk:
    """A free-floating thin circular plate (the paper's levitated disk)."""
    radius: float
    thickness: float
    youngs_modulus: float
    poisson_ratio: float
    density: float
    kind: str = "free_disk"

    @property
    def mass(self) -> float:
        return math.pi * self.radius**2 * self.thickness * self.density


@dataclass(frozen=True)
class ElectrodeSet:
    """Fixed electrodes on one side of the plate: rings x sectors of annular sectors."""
    name: str
    side: str                      # "above" or "below"
    gap: float                     # m, undeformed plate surface to electrode
    rings: tuple[tuple[float, float], ...]
    sectors: int
    sector_start: float            # rad, start angle of the first sector's centre line boundary
    slot: float                    # m, width of the straight slots between sectors

    def electrode_names(self) -> list[str]:
        return [f"{self.name}_r{r + 1}s{s + 1}"
                for r in range(len(self.rings)) for s in range(self.sectors)]


@dataclass(frozen=True)
class Coordinates:
    """Generalized coordinates: rigid-body motions then eigenmodes (count or (n,s) labels)."""
    rigid: tuple[str, ...]
    modes: int | tuple[str, ...]
    acceleration_port: bool = False    # an a_in port: frame acceleration along +z (inertial load)


@dataclass(frozen=True)
class Sampling:
    """Capacitance sampling grid: `levels` per coordinate over +-range x touching amplitude."""
    levels: int = 3
    range: float = 0.2


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
    """Extractor settings: edge-fringe model and constant electrode-electrode coupling."""
    fringe: str = "plate_between"
    fringe_a: float = 0.42
    fringe_b: float = 0.06
    relative_permittivity: float = 1.0
    coupling_per_length: float = 0.0


@dataclass(frozen=True)
class FemOptions:
    """Eigenmode FEM settings (scikit-fem Morley plate on a refined circle mesh)."""
    refine: int = 6


@dataclass(frozen=True)
class Damping:
    """Mechanical damping: per-coordinate Q or damping ratio (a number applies to every eigenmode),
    Rayleigh D = alpha M + beta K, squeeze-film gas damping, and thermal force noise."""
    q_factor: tuple[tuple[str, float], ...] = ()         # (coordinate, Q); "*" = every eigenmode
    damping_ratio: tuple[tuple[str, float], ...] = ()    # (coordinate, zeta); "*" = every eigenmode
    rayleigh_alpha: float = 0.0                          # 1/s
    rayleigh_beta: float = 0.0                           # s
    squeeze_film: bool = False
    pressure: float = 101325.0                           # Pa
    gas: str = "air"
    temperature: float = 300.0                           # K, of the gas and of the thermal noise
    noise: bool = False                                  # emit thermal force noise sources
    fem_refine: int = 5                                  # Reynolds mesh refinement
    film_model: str = "incompressible"                   # or "compressible": Maxwell branches (pole-residue)
    film_max_frequency: float = 0.0                      # Hz the compressible network must cover (0: auto)

    def enabled(self) -> bool:
        """True when any damping contribution is requested."""
        return bool(self.q_factor or self.damping_ratio or self.rayleigh_alpha or self.rayleigh_beta
                    or self.squeeze_film)


@dataclass(frozen=True)
class Structure:
    """A validated structure description; `source` is the file it came from."""
    name: str
    description: str
    source: str
    conductor: FreeDisk
    electrode_sets: tuple[ElectrodeSet, ...]
    coordinates: Coordinates
    sampling: Sampling = field(default_factory=Sampling)
    fit: FitOptions = field(default_factory=FitOptions)
    electrostatics: ElectrostaticsOptions = field(default_factory=ElectrostaticsOptions)
    fem: FemOptions = field(default_factory=FemOptions)
    damping: Damping | None = None
    imports: "Imports | None" = None     # [import]: mechanics and/or capacitances from external tools

    def electrode_names(self) -> list[str]:
        return [n for s in self.electrode_sets for n in s.electrode_names()]


# ---------------------------------------------------------------- reading

class _Reader:
    """Knows the file text so errors can point at a line; raises StructureError."""

    def __init__(self, path: str, text: str):
        self.path, self.lines = path, text.splitlines()

    def fail(self, where: str, problem: str, fix: str) -> StructureError:
        return StructureError(self.path, where, problem, fix, self._line_of(where))

    def _line_of(self, where: str) -> int | None:
        """Best-effort line number of a dotted key such as 'electrodes[1].gap'."""
        parts = re.findall(r"[A-Za-z_][A-Za-z0-9_]*|\[\d+\]", where)
        table, index, key = None, 0, None
        if parts:
            table = parts[0]
            if len(parts) > 1 and parts[1].startswith("["):
                index = int(parts[1][1:-1])
                key = parts[2] if len(parts) > 2 else None
            else:
                key = parts[1] if len(parts) > 1 else None
        current, seen, header_line = None, -1, None
        for no, raw in enumerate(self.lines, start=1):
            line = raw.strip()
            head = re.match(r"^\[\[?\s*([A-Za-z0-9_.]+)\s*\]\]?", line)
            if head:
                current = head.group(1)
                if current == table:
                    seen += 1
                    if seen == index:
                        header_line = no
                continue
            target_key = key if current == table and seen == index else (
                table if current is None and key is None else None)
            if target_key and re.match(rf"^{re.escape(target_key)}\s*=", line):
                return no
        return header_line


def _did_you_mean(word: str, options: list[str]) -> str:
    close = difflib.get_close_matches(word, options, n=1, cutoff=0.6)
    return f"did you mean '{close[0]}'? " if close else ""


def _check_keys(rd: _Reader, where: str, table: dict, allowed: list[str]) -> None:
    for key in table:
        if key not in allowed:
            raise rd.fail(f"{where}.{key}" if where else key, f"unknown key '{key}'",
                          f"{_did_you_mean(key, allowed)}allowed keys here: {', '.join(allowed)}")


def _table(rd: _Reader, doc: dict, key: str, required: bool) -> dict:
    value = doc.get(key)
    if value is None:
        if required:
            raise rd.fail(f"[{key}]", "missing table", f"add a [{key}] table (see examples/levitated_disk.toml)")
        return {}
    if not isinstance(value, dict):
        raise rd.fail(key, f"'{key}' must be a table, got {type(value).__name__}",
                      f"write it as a [{key}] section")
    return value


def _quantity(rd: _Reader, table: dict, where: str, key: str, kind: str,
              default: float | None = None, check: Callable[[float], str | None] | None = None,
              what: str = "") -> float:
    """Read a physical quantity (SI number or unit string), apply a physical-range check."""
    loc = f"{where}.{key}"
    if key not in table:
        if default is None:
            raise rd.fail(loc, f"missing required key '{key}'",
                          f"add {key} = \"{example(kind)}\"  ({what}, SI units if no unit is given)")
        return default
    try:
        value = parse_quantity(table[key], kind)
    except UnitError as exc:
        raise rd.fail(loc, str(exc), f"write {key} = \"{example(kind)}\" or a number in {SI_NAME[kind] or 'plain units'}")
    if not math.isfinite(value):
        raise rd.fail(loc, f"{key} is not finite ({value})", f"give a finite {what or key}")
    if check:
        problem = check(value)
        if problem:
            raise rd.fail(loc, f"{key} = {table[key]!r} {problem}", f"give a physical {what or key}")
    return value


def _positive(v: float) -> str | None:
    return None if v > 0 else "must be greater than zero"


def _integer(rd: _Reader, table: dict, where: str, key: str, default: int | None,
             lo: int, hi: int, what: str) -> int:
    loc = f"{where}.{key}"
    if key not in table:
        if default is None:
            raise rd.fail(loc, f"missing required key '{key}'", f"add {key} = <integer {lo}..{hi}> ({what})")
        return default
    value = table[key]
    if isinstance(value, bool) or not isinstance(value, int):
        raise rd.fail(loc, f"{key} must be an integer, got {value!r}", f"write {key} = <integer {lo}..{hi}> ({what})")
    if not lo <= value <= hi:
        raise rd.fail(loc, f"{key} = {value} is outside {lo}..{hi}", f"choose {what} between {lo} and {hi}")
    return value


def _choice(rd: _Reader, table: dict, where: str, key: str, choices: list[str], default: str | None) -> str:
    loc = f"{where}.{key}"
    if key not in table:
        if default is None:
            raise rd.fail(loc, f"missing required key '{key}'", f"add {key} = one of {choices}")
        return default
    value = table[key]
    if value not in choices:
        hint = _did_you_mean(str(value), choices)
        raise rd.fail(loc, f"{key} = {value!r} is not one of {choices}", f"{hint}use one of {choices}")
    return value


# ---------------------------------------------------------------- sections

def _conductor(rd: _Reader, doc: dict) -> FreeDisk:
    t = _table(rd, doc, "conductor", required=True)
    kind = _choice(rd, t, "conductor", "kind", list(CONDUCTOR_KINDS), default="free_disk")
    if kind != "free_disk":
        return _suspended_conductor(rd, t, kind)
    _check_keys(rd, "conductor", t, ["kind", "radius", "thickness", "youngs_modulus", "poisson_ratio", "density"])
    radius = _quantity(rd, t, "conductor", "radius", "length", check=_positive, what="disk radius")
    thickness = _quantity(rd, t, "conductor", "thickness", "length", check=_positive, what="plate thickness")
    modulus = _quantity(rd, t, "conductor", "youngs_modulus", "modulus", check=_positive,
                        what="Young's modulus (polysilicon: 160 GPa)")
    nu = _quantity(rd, t, "conductor", "poisson_ratio", "dimensionless",
                   check=lambda v: None if -1 < v < 0.5 else "must lie in (-1, 0.5)",
                   what="Poisson's ratio (polysilicon: 0.22)")
    density = _quantity(rd, t, "conductor", "density", "density", check=_positive,
                        what="mass density (polysilicon: 2330 kg/m^3)")
    return FreeDisk(radius, thickness, modulus, nu, density, kind)


def _rings(rd: _Reader, t: dict, where: str, radius: float) -> tuple[tuple[float, float], ...]:
    loc = f"{where}.rings"
    fix = 'write rings = [["20 um", "230 um"], ["240 um", "473 um"]]: [inner, outer] radius per ring'
    raw = t.get("rings")
    if raw is None:
        raise rd.fail(loc, "missing required key 'rings'", fix)
    if not isinstance(raw, list) or not raw or not all(isinstance(r, list) and len(r) == 2 for r in raw):
        raise rd.fail(loc, "rings must be a non-empty list of [inner, outer] radius pairs", fix)
    rings = []
    for k, (a, b) in enumerate(raw):
        try:
            r_in, r_out = parse_quantity(a, "length"), parse_quantity(b, "length")
        except UnitError as exc:
            raise rd.fail(loc, f"ring {k + 1}: {exc}", fix)
        if not 0 <= r_in < r_out:
            raise rd.fail(loc, f"ring {k + 1}: need 0 <= inner < outer radius, got [{a}, {b}]", fix)
        if r_in >= radius:
            raise rd.fail(loc, f"ring {k + 1} starts at {r_in:g} m, outside the plate (radius {radius:g} m)",
                          "move the ring inside the plate radius or remove it: it would sense nothing")
        rings.append((r_in, r_out))
    for k in range(1, len(rings)):
        if rings[k][0] < rings[k - 1][1]:
            raise rd.fail(loc, f"ring {k + 1} overlaps ring {k} (rings must be listed inside-out, disjoint)",
                          "make each ring's inner radius at least the previous ring's outer radius")
    return tuple(rings)


def _electrode_tables(rd: _Reader, doc: dict, missing: str, fix: str, each: str) -> list[dict]:
    """The [[electrodes]] array of tables, or a clear error (missing, or not an array of tables)."""
    raw = doc.get("electrodes")
    if raw is None:
        raise rd.fail("[[electrodes]]", missing, fix)
    if not isinstance(raw, list) or not all(isinstance(e, dict) for e in raw):
        raise rd.fail("electrodes", "electrodes must be an array of tables", f"write each {each} as [[electrodes]]")
    return raw


def _electrode_sets(rd: _Reader, doc: dict, radius: float) -> tuple[ElectrodeSet, ...]:
    raw = _electrode_tables(rd, doc, "missing electrode sets",
                            "add one [[electrodes]] table per side (see examples/levitated_disk.toml)", "set")
    sets, names = [], set()
    for i, t in enumerate(raw):
        where = f"electrodes[{i}]"
        _check_keys(rd, where, t, ["name", "side", "gap", "rings", "sectors", "sector_start", "slot"])
        name = t.get("name")
        if not isinstance(name, str) or not NAME.match(name) or "error" in name.lower():
            raise rd.fail(f"{where}.name", f"name {name!r} is not a simple identifier",
                          "use letters, digits and _ (starting with a letter), e.g. name = \"top\"; "
                          "avoid the word 'error' (PySpice treats it as a simulator error)")
        if name in names:
            raise rd.fail(f"{where}.name", f"electrode set name {name!r} used twice", "give each set its own name")
        names.add(name)
        side = _choice(rd, t, where, "side", ["above", "below"], default=None)
        gap = _quantity(rd, t, where, "gap", "length", check=_positive, what="gap between plate and electrode")
        rings = _rings(rd, t, where, radius)
        sectors = _integer(rd, t, where, "sectors", 1, 1, 64, "number of sectors per ring")
        start = _quantity(rd, t, where, "sector_start", "angle", default=-math.pi / 4, what="angle of the first sector edge")
        slot = _quantity(rd, t, where, "slot", "length", default=0.0,
                         check=lambda v: None if v >= 0 else "must not be negative", what="slot width between sectors")
        if sectors > 1 and slot >= 2 * rings[-1][1] * math.sin(math.pi / sectors):
            raise rd.fail(f"{where}.slot", f"slot {slot:g} m leaves no electrode area",
                          "use a slot much narrower than the sector width")
        for r_in, r_out in rings:
            if sectors > 1 and slot / 2 >= min(r_out, radius) * math.sin(math.pi / sectors):
                raise rd.fail(f"{where}.slot", f"slot {slot:g} m swallows the ring [{r_in:g}, {r_out:g}] m",
                              "narrow the slot or widen the ring")
        sets.append(ElectrodeSet(name, side, gap, rings, sectors, start, slot))
    return tuple(sets)


def _coordinates(rd: _Reader, doc: dict) -> Coordinates:
    t = _table(rd, doc, "coordinates", required=True)
    _check_keys(rd, "coordinates", t, ["rigid", "modes", "acceleration_port"])
    rigid = t.get("rigid", list(RIGID_COORDINATES))
    if not isinstance(rigid, list) or not all(isinstance(r, str) for r in rigid):
        raise rd.fail("coordinates.rigid", "rigid must be a list of names", f'write rigid = {list(RIGID_COORDINATES)}')
    for r in rigid:
        if r not in RIGID_COORDINATES:
            raise rd.fail("coordinates.rigid", f"unknown rigid coordinate {r!r}",
                          f"{_did_you_mean(r, list(RIGID_COORDINATES))}use any of {list(RIGID_COORDINATES)}")
    if len(set(rigid)) != len(rigid):
        raise rd.fail("coordinates.rigid", "a rigid coordinate is listed twice", "list each once")
    modes = t.get("modes", 0)
    if isinstance(modes, bool) or not isinstance(modes, (int, list)):
        raise rd.fail("coordinates.modes", f"modes must be a count or a list of labels, got {modes!r}",
                      'write modes = 4 or modes = ["2,0c", "2,0s", "3,0c", "3,0s"]')
    if isinstance(modes, int):
        if not 0 <= modes <= 40:
            raise rd.fail("coordinates.modes", f"modes = {modes} is outside 0..40", "choose 0 to 40 eigenmodes")
    else:
        for m in modes:
            match = MODE_LABEL.match(m) if isinstance(m, str) else None
            if not match or (match.group(1) == "0") != (match.group(3) == ""):
                raise rd.fail("coordinates.modes", f"mode label {m!r} is not of the form 'n,s' + c|s",
                              "label a mode by nodal diameters n and nodal circles s, with c or s for the "
                              "cos/sin orientation when n > 0: e.g. \"2,0c\", \"3,0s\", \"0,1\"")
        if len(set(modes)) != len(modes):
            raise rd.fail("coordinates.modes", "a mode label is listed twice", "list each mode once")
        modes = tuple(modes)
    if not rigid and not modes:
        raise rd.fail("coordinates", "no generalized coordinates", "list rigid coordinates and/or modes")
    return Coordinates(tuple(rigid), modes, _acceleration_port(rd, t))


def _acceleration_port(rd: _Reader, t: dict) -> bool:
    """coordinates.acceleration_port: emit the a_in port (frame acceleration along +z)."""
    accel = t.get("acceleration_port", False)
    if not isinstance(accel, bool):
        raise rd.fail("coordinates.acceleration_port", f"acceleration_port must be true or false, got {accel!r}",
                      "write acceleration_port = true (adds the port a_in: frame acceleration, 1 V = 1 m/s^2)")
    return accel


def _sampling(rd: _Reader, doc: dict) -> Sampling:
    t = _table(rd, doc, "sampling", required=False)
    _check_keys(rd, "sampling", t, ["levels", "range"])
    rng = _quantity(rd, t, "sampling", "range", "dimensionless", default=0.2,
                    check=lambda v: None if 0 < v < 0.9 else "must lie in (0, 0.9): it is a fraction of the "
                    "amplitude at which the plate touches an electrode, and 1 means contact",
                    what="sampling range as a fraction of the touching amplitude")
    return Sampling(levels=_integer(rd, t, "sampling", "levels", 3, 2, 9, "levels per coordinate"), range=rng)


def _fit(rd: _Reader, doc: dict) -> FitOptions:
    t = _table(rd, doc, "fit", required=False)
    _check_keys(rd, "fit", t, ["degree", "target", "holdout", "seed", "tolerance", "max_terms"])
    d = FitOptions()
    return FitOptions(degree=_integer(rd, t, "fit", "degree", d.degree, 1, 6, "polynomial total degree"),
                      target=_choice(rd, t, "fit", "target", ["plates", "inverse", "direct"], d.target),
                      tolerance=_quantity(rd, t, "fit", "tolerance", "dimensionless", d.tolerance,
                                          check=lambda v: None if 0 < v < 1 else "must lie in (0, 1)",
                                          what="held-out max relative error target"),
                      max_terms=_integer(rd, t, "fit", "max_terms", d.max_terms, 1, 25, "plate terms per electrode"),
                      holdout=_integer(rd, t, "fit", "holdout", 500, 10, 10**6, "held-out check points"),
                      seed=_integer(rd, t, "fit", "seed", 1, 0, 2**31 - 1, "random seed of the held-out points"))


def _electrostatics(rd: _Reader, doc: dict) -> ElectrostaticsOptions:
    t = _table(rd, doc, "electrostatics", required=False)
    keys = ["fringe", "fringe_a", "fringe_b", "relative_permittivity", "coupling_per_length"]
    _check_keys(rd, "electrostatics", t, keys)
    d = ElectrostaticsOptions()
    return ElectrostaticsOptions(
        fringe=_choice(rd, t, "electrostatics", "fringe", ["plate_between", "palmer", "none"], d.fringe),
        fringe_a=_quantity(rd, t, "electrostatics", "fringe_a", "dimensionless", d.fringe_a),
        fringe_b=_quantity(rd, t, "electrostatics", "fringe_b", "dimensionless", d.fringe_b),
        relative_permittivity=_quantity(rd, t, "electrostatics", "relative_permittivity", "dimensionless",
                                        d.relative_permittivity, check=lambda v: None if v >= 1 else "must be >= 1"),
        coupling_per_length=_quantity(rd, t, "electrostatics", "coupling_per_length", "dimensionless",
                                      d.coupling_per_length, check=lambda v: None if v >= 0 else "must be >= 0",
                                      what="electrode-electrode capacitance per slot length in F/m"))


def _fem(rd: _Reader, doc: dict) -> FemOptions:
    t = _table(rd, doc, "fem", required=False)
    _check_keys(rd, "fem", t, ["refine"])
    return FemOptions(refine=_integer(rd, t, "fem", "refine", 6, 3, 8, "mesh refinement level"))


DAMPING_KEYS = ["q_factor", "damping_ratio", "rayleigh", "squeeze_film", "pressure", "gas", "temperature",
                "noise", "fem_refine", "film_model", "film_max_frequency"]


def coordinate_names(c: Coordinates) -> list[str] | None:
    """Names the pipeline gives the coordinates (None while modes are only a count)."""
    if isinstance(c.modes, int):
        return None if c.modes else list(c.rigid)
    return list(c.rigid) + [f"m{m.replace(',', '_')}" for m in c.modes]


def _per_coordinate(rd: _Reader, t: dict, key: str, names: list[str] | None,
                    check: Callable[[float], str | None], what: str) -> tuple[tuple[str, float], ...]:
    """A number (every eigenmode: key '*') or a table {coordinate = number} of positive values."""
    loc = f"damping.{key}"
    if key not in t:
        return ()
    raw = t[key]
    table = raw if isinstance(raw, dict) else {"*": raw}
    out = []
    for name, value in table.items():
        if name != "*" and names is not None and name not in names:
            raise rd.fail(loc, f"unknown coordinate {name!r}", f"{_did_you_mean(name, names)}use one of {names}")
        if name in RIGID_COORDINATES:
            raise rd.fail(loc, f"{key} of the rigid coordinate {name!r} is undefined (no stiffness, no resonance)",
                          "damp rigid-body motions with squeeze_film or rayleigh alpha instead")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise rd.fail(loc, f"{key} for {name!r} must be a number, got {value!r}",
                          f"write {key} = 1e4 (all eigenmodes) or {key} = {{m2_0c = 1e4}}")
        problem = check(float(value))
        if problem:
            raise rd.fail(loc, f"{key} = {value!r} for {name!r} {problem}", f"give a physical {what}")
        out.append((name, float(value)))
    return tuple(out)


def _rayleigh(rd: _Reader, t: dict) -> tuple[float, float]:
    """Rayleigh coefficients (alpha in 1/s, beta in s) from rayleigh = {alpha = .., beta = ..}."""
    raw = t.get("rayleigh", {})
    if not isinstance(raw, dict):
        raise rd.fail("damping.rayleigh", f"rayleigh must be a table, got {raw!r}",
                      "write rayleigh = {alpha = 10.0, beta = 1e-9}  (D = alpha M + beta K; 1/s and s)")
    _check_keys(rd, "damping.rayleigh", raw, ["alpha", "beta"])
    nonneg = lambda v: None if v >= 0 else "must not be negative"
    return (_quantity(rd, raw, "damping.rayleigh", "alpha", "dimensionless", 0.0, nonneg, "mass-proportional 1/s"),
            _quantity(rd, raw, "damping.rayleigh", "beta", "dimensionless", 0.0, nonneg, "stiffness-proportional s"))


def _flag(rd: _Reader, t: dict, key: str, default: bool) -> bool:
    """A true/false key of the [damping] table."""
    value = t.get(key, default)
    if not isinstance(value, bool):
        raise rd.fail(f"damping.{key}", f"{key} must be true or false, got {value!r}", f"write {key} = true")
    return value


def _damping(rd: _Reader, doc: dict, coords: Coordinates) -> Damping | None:
    """The optional [damping] table."""
    if "damping" not in doc:
        return None
    t = _table(rd, doc, "damping", required=False)
    _check_keys(rd, "damping", t, DAMPING_KEYS)
    names = coordinate_names(coords)
    q = _per_coordinate(rd, t, "q_factor", names, lambda v: None if v > 0.5 else "must exceed 0.5",
                        "quality factor (> 0.5, underdamped)")
    zeta = _per_coordinate(rd, t, "damping_ratio", names, lambda v: None if 0 < v < 1 else "must lie in (0, 1)",
                           "damping ratio")
    both = sorted({n for n, _ in q} & {n for n, _ in zeta})
    if both:
        raise rd.fail("damping.damping_ratio", f"coordinate(s) {both} given both q_factor and damping_ratio",
                      "give each coordinate one of them (Q = 1 / (2 zeta))")
    alpha, beta = _rayleigh(rd, t)
    from .squeeze_film import GASES
    return Damping(q, zeta, alpha, beta, _flag(rd, t, "squeeze_film", False),
                   _quantity(rd, t, "damping", "pressure", "pressure", 101325.0, _positive, "gas pressure"),
                   _choice(rd, t, "damping", "gas", sorted(GASES), "air"),
                   _quantity(rd, t, "damping", "temperature", "temperature", 300.0, _positive, "temperature"),
                   _flag(rd, t, "noise", False),
                   _integer(rd, t, "damping", "fem_refine", 5, 2, 8, "Reynolds mesh refinement level"),
                   _choice(rd, t, "damping", "film_model", ["incompressible", "compressible"], "incompressible"),
                   _quantity(rd, t, "damping", "film_max_frequency", "frequency", 0.0,
                             lambda v: None if v >= 0 else "must not be negative",
                             "highest frequency the compressible film network must reproduce (0: auto)"))


MAX_GRID_POINTS = 2_000_000      # capacitance samples levels ** ncoords the pipeline accepts


def _boundary_edges(refine: int) -> int:
    """Edges on the rim of scikit-fem's MeshTri.init_circle(refine) (32 at refine 3, doubling per level)."""
    return 32 * 2 ** (refine - 3)


def _cross_checks(rd: _Reader, sets: tuple[ElectrodeSet, ...], coords: Coordinates,
                  sampling: Sampling, fem: FemOptions) -> None:
    """Checks that need several tables: overlapping sets, modes the mesh resolves, grid size."""
    for j, b in enumerate(sets):
        for i, a in enumerate(sets[:j]):
            if a.side != b.side:
                continue
            for ra in a.rings:
                for rb in b.rings:
                    if ra[0] < rb[1] and rb[0] < ra[1]:
                        raise rd.fail(f"electrodes[{j}].rings",
                                      f"set {b.name!r} overlaps set {a.name!r} on the same side ({b.side}): rings "
                                      f"[{rb[0]:g}, {rb[1]:g}] m and [{ra[0]:g}, {ra[1]:g}] m",
                                      "merge the sets into one [[electrodes]] table or make their rings disjoint")
    edges = _boundary_edges(fem.refine)
    if isinstance(coords.modes, int) and coords.modes > edges // 4:
        raise rd.fail("coordinates.modes", f"{coords.modes} modes need a finer mesh than fem.refine = {fem.refine} "
                      f"(at most {edges // 4}: 8 rim edges per wavelength)",
                      f"raise fem.refine or request at most {edges // 4} modes")
    if not isinstance(coords.modes, int):
        for m in coords.modes:
            n, s_ = (int(v) for v in MODE_LABEL.match(m).groups()[:2])
            if n > edges // 8 or s_ > edges // 32:
                raise rd.fail("coordinates.modes", f"mode {m!r} is not resolved by the mesh of fem.refine = "
                              f"{fem.refine} (n <= {edges // 8}, s <= {edges // 32})",
                              "raise fem.refine or drop the mode")
    ncoords = len(coords.rigid) + (coords.modes if isinstance(coords.modes, int) else len(coords.modes))
    if sampling.levels ** ncoords > MAX_GRID_POINTS:
        raise rd.fail("sampling.levels", f"{sampling.levels}^{ncoords} = {sampling.levels ** ncoords} capacitance "
                      f"samples exceed {MAX_GRID_POINTS}", "lower sampling.levels or use fewer coordinates")


def toml_document(text: str, path: str, error: type = None, fix: str = "correct the TOML syntax at that line "
                  "(strings need quotes, tables [name], arrays [a, b])") -> dict:
    """tomllib.loads, with a syntax error raised as `error` (default StructureError) naming the
    file, the line and the fix; shared by the structure and sweep files."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        line = re.search(r"line (\d+)", str(exc))
        raise (error or StructureError)(path, "TOML syntax", str(exc), fix,
                                        int(line.group(1)) if line else None) from None


def parse_structure(text: str, path: str = "<string>") -> Structure:
    """Validate TOML text into a Structure; raises StructureError on any mistake."""
    rd = _Reader(path, text)
    doc = toml_document(text, path)
    top = ["name", "description", "conductor", "electrodes", "coordinates", "sampling", "fit",
           "electrostatics", "fem", "damping", "import"]
    _check_keys(rd, "", doc, top)
    name = doc.get("name")
    if not isinstance(name, str) or not NAME.match(name) or "error" in name.lower():
        raise rd.fail("name", f"name {name!r} is missing or not a simple identifier",
                      'add name = "levitated_disk" (letters, digits, _; it names the output files '
                      "and the subcircuit; avoid the word 'error')")
    description = doc.get("description", "")
    if not isinstance(description, str):
        raise rd.fail("description", "description must be a string", 'write description = "..."')
    conductor = _conductor(rd, doc)
    if conductor.kind in SUSPENDED_KINDS:
        return _parse_suspended(rd, doc, name, description, path, conductor)
    sets = _electrode_sets(rd, doc, conductor.radius)
    coords, sampling, fit = _coordinates(rd, doc), _sampling(rd, doc), _fit(rd, doc)
    if fit.degree >= sampling.levels:
        raise rd.fail("fit.degree", f"degree {fit.degree} needs at least {fit.degree + 1} sampling levels "
                      f"per coordinate (have {sampling.levels})",
                      f"lower fit.degree or raise sampling.levels to {fit.degree + 1}")
    fem = _fem(rd, doc)
    _cross_checks(rd, sets, coords, sampling, fem)
    return Structure(name=name, description=description, source=path, conductor=conductor,
                     electrode_sets=sets, coordinates=coords, sampling=sampling,
                     fit=fit, electrostatics=_electrostatics(rd, doc), fem=fem,
                     damping=_damping(rd, doc, coords), imports=_imports(rd, doc))


def load_structure(path: str | Path) -> Structure:
    """Read and validate a structure file; unreadable files become StructureError too."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise StructureError(str(path), "file", "no such file", "check the path to the structure file")
    except (OSError, UnicodeDecodeError) as exc:
        raise StructureError(str(path), "file", f"cannot read: {exc}", "give a readable UTF-8 TOML file")
    return parse_structure(text, str(path))



# ---------------------------------------------------------------- suspended structures (issue 7)
#
# A rigid plate on linear springs ("piston") and Euler-Bernoulli beams ("clamped_clamped_beam",
# "cantilever") over rectangular electrodes. The conductor lies in the x-y plane: beams from the
# clamp at x = 0 to x = length, centred on y = 0; the piston plate centred at the origin.

SUSPENDED_KINDS = ("piston", "clamped_clamped_beam", "cantilever")
CONDUCTOR_KINDS = ("free_disk",) + SUSPENDED_KINDS


@dataclass(frozen=True)
class Piston:
    """A rigid rectangular plate on linear springs: vertical stiffness and (optional) tilt stiffness."""
    length: float                  # m, along x
    width: float                   # m, along y
    thickness: float
    density: float
    stiffness: float               # N/m, vertical spring
    tilt_stiffness: float          # N*m/rad, about x and about y (0: tilts not allowed as coordinates)
    kind: str = "piston"

    @property
    def mass(self) -> float:
        return self.length * self.width * self.thickness * self.density

    def outline(self) -> tuple[float, float, float, float]:
        """(x0, x1, y0, y1) of the plate."""
        return -self.length / 2, self.length / 2, -self.width / 2, self.width / 2


@dataclass(frozen=True)
class Beam:
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

    @property
    def mass(self) -> float:
        return self.length * self.width * self.thickness * self.density

    def outline(self) -> tuple[float, float, float, float]:
        return 0.0, self.length, -self.width / 2, self.width / 2


@dataclass(frozen=True)
class RectElectrode:
    """One fixed rectangular electrode [x0, x1] x [y0, y1] on one side of a suspended conductor."""
    name: str
    side: str
    gap: float
    x0: float
    x1: float
    y0: float
    y1: float

    def electrode_names(self) -> list[str]:
        return [self.name]


def _suspended_conductor(rd: _Reader, t: dict, kind: str) -> Piston | Beam:
    """[conductor] of a piston or a beam."""
    pos = _positive
    if kind == "piston":
        _check_keys(rd, "conductor", t, ["kind", "length", "width", "thickness", "density", "stiffness",
                                         "tilt_stiffness"])
        length = _quantity(rd, t, "conductor", "length", "length", check=pos, what="plate length (along x)")
        width = _quantity(rd, t, "conductor", "width", "length", default=length, check=pos, what="plate width (along y)")
        thickness = _quantity(rd, t, "conductor", "thickness", "length", check=pos, what="plate thickness")
        density = _quantity(rd, t, "conductor", "density", "density", check=pos,
                            what="mass density (polysilicon: 2330 kg/m^3)")
        k = _quantity(rd, t, "conductor", "stiffness", "dimensionless", check=pos,
                      what="vertical spring stiffness in N/m")
        kt = _quantity(rd, t, "conductor", "tilt_stiffness", "dimensionless", default=0.0,
                       check=lambda v: None if v >= 0 else "must not be negative",
                       what="tilt spring stiffness in N*m/rad")
        return Piston(length, width, thickness, density, k, kt)
    _check_keys(rd, "conductor", t, ["kind", "length", "width", "thickness", "youngs_modulus", "density",
                                     "residual_stress", "stretching", "elements"])
    length = _quantity(rd, t, "conductor", "length", "length", check=pos, what="beam length (clamp to clamp/tip)")
    width = _quantity(rd, t, "conductor", "width", "length", check=pos, what="beam width")
    thickness = _quantity(rd, t, "conductor", "thickness", "length", check=pos, what="beam thickness")
    modulus = _quantity(rd, t, "conductor", "youngs_modulus", "modulus", check=pos,
                        what="Young's modulus (use E/(1-nu^2) for a wide beam)")
    density = _quantity(rd, t, "conductor", "density", "density", check=pos, what="mass density")
    stress = _quantity(rd, t, "conductor", "residual_stress", "modulus", default=0.0,
                       what="axial residual stress (tensile > 0)")
    stretching = t.get("stretching", kind == "clamped_clamped_beam")
    if not isinstance(stretching, bool):
        raise rd.fail("conductor.stretching", f"stretching must be true or false, got {stretching!r}",
                      "write stretching = true (large-deflection stress stiffening) or false")
    if kind == "cantilever" and (stress != 0.0 or stretching):
        key = "residual_stress" if stress != 0.0 else "stretching"
        raise rd.fail(f"conductor.{key}", "a cantilever has a free end: residual axial stress relaxes and the "
                      "mid-plane does not stretch", f"remove {key} (or use kind = \"clamped_clamped_beam\")")
    if stress < 0:
        # Euler buckling: sigma_cr = pi^2 E t^2 / (3 L^2) for clamped-clamped ends
        critical = math.pi**2 * modulus * thickness**2 / (3 * length**2)
        if -stress >= critical:
            raise rd.fail("conductor.residual_stress", f"compressive stress {stress:g} Pa buckles the beam "
                          f"(critical {-critical:g} Pa)", "give a smaller compressive stress")
    elements = _integer(rd, t, "conductor", "elements", 60, 8, 2000, "beam finite elements")
    return Beam(kind, length, width, thickness, modulus, density, stress, stretching, elements)


def _span(rd: _Reader, t: dict, where: str, key: str, lo: float, hi: float) -> tuple[float, float]:
    """[start, end] of a rectangular electrode along one axis (default: the conductor's extent)."""
    if key not in t:
        return lo, hi
    raw = t[key]
    fix = f'write {key} = ["{lo * 1e6:g} um", "{hi * 1e6:g} um"] (start, end within the conductor)'
    if not isinstance(raw, list) or len(raw) != 2:
        raise rd.fail(f"{where}.{key}", f"{key} must be a [start, end] pair", fix)
    try:
        a, b = parse_quantity(raw[0], "length"), parse_quantity(raw[1], "length")
    except UnitError as exc:
        raise rd.fail(f"{where}.{key}", str(exc), fix)
    if not a < b:
        raise rd.fail(f"{where}.{key}", f"need start < end, got {raw}", fix)
    if b <= lo or a >= hi:
        raise rd.fail(f"{where}.{key}", f"[{a:g}, {b:g}] m lies outside the conductor ([{lo:g}, {hi:g}] m)", fix)
    return a, b


def _rect_electrodes(rd: _Reader, doc: dict, conductor: Piston | Beam) -> tuple[RectElectrode, ...]:
    """[[electrodes]] of a suspended conductor: one rectangle each (default: under the whole conductor)."""
    raw = _electrode_tables(rd, doc, "missing electrodes", "add an [[electrodes]] table (see examples/cc_beam.toml)",
                            "electrode")
    x0, x1, y0, y1 = conductor.outline()
    out, names = [], set()
    for i, t in enumerate(raw):
        where = f"electrodes[{i}]"
        _check_keys(rd, where, t, ["name", "side", "gap", "x", "y"])
        name = t.get("name")
        if not isinstance(name, str) or not NAME.match(name) or "error" in name.lower() or name == "plate":
            raise rd.fail(f"{where}.name", f"name {name!r} is not a simple identifier",
                          "use letters, digits and _ (starting with a letter), e.g. name = \"drive\"; "
                          "avoid 'plate' and the word 'error'")
        if name in names:
            raise rd.fail(f"{where}.name", f"electrode name {name!r} used twice", "give each electrode its own name")
        names.add(name)
        side = _choice(rd, t, where, "side", ["above", "below"], default="below")
        gap = _quantity(rd, t, where, "gap", "length", check=_positive, what="gap between conductor and electrode")
        a, b = _span(rd, t, where, "x", x0, x1)
        c, d = _span(rd, t, where, "y", y0, y1)
        for prev in out:
            if prev.side == side and a < prev.x1 and prev.x0 < b and c < prev.y1 and prev.y0 < d:
                raise rd.fail(f"{where}.x", f"electrode {name!r} overlaps {prev.name!r} on the same side ({side})",
                              "make the rectangles disjoint or merge them")
        out.append(RectElectrode(name, side, gap, a, b, c, d))
    if not out:
        raise rd.fail("[[electrodes]]", "no electrodes", "add at least one [[electrodes]] table")
    return tuple(out)


def _suspended_coordinates(rd: _Reader, doc: dict, conductor: Piston | Beam) -> Coordinates:
    """Coordinates of a piston (rigid z and tilts) or a beam (the first N bending modes)."""
    t = _table(rd, doc, "coordinates", required=False)
    accel = _acceleration_port(rd, t)
    if conductor.kind == "piston":
        _check_keys(rd, "coordinates", t, ["rigid", "acceleration_port"])
        rigid = t.get("rigid", ["z"])
        if not isinstance(rigid, list) or not rigid or not all(isinstance(r, str) for r in rigid) \
                or len(set(rigid)) != len(rigid) or not set(rigid) <= set(RIGID_COORDINATES):
            raise rd.fail("coordinates.rigid", f"rigid = {rigid!r} is not a list of distinct names from "
                          f"{list(RIGID_COORDINATES)}", 'write rigid = ["z"] or rigid = ["z", "tilt_x", "tilt_y"]')
        if any(r != "z" for r in rigid) and conductor.tilt_stiffness <= 0:
            raise rd.fail("conductor.tilt_stiffness", "tilt coordinates need a tilt spring",
                          "add tilt_stiffness = <N*m/rad> to [conductor] or use rigid = [\"z\"]")
        return Coordinates(tuple(rigid), 0, accel)
    _check_keys(rd, "coordinates", t, ["modes", "acceleration_port"])
    modes = t.get("modes", 3)
    if isinstance(modes, bool) or not isinstance(modes, int) or not 1 <= modes <= 12:
        raise rd.fail("coordinates.modes", f"modes = {modes!r} must be a count 1..12 of bending modes",
                      "write modes = 3 (the first three bending modes, named m1, m2, m3)")
    if modes > conductor.elements // 4:
        raise rd.fail("coordinates.modes", f"{modes} modes need more than conductor.elements = {conductor.elements}",
                      f"raise conductor.elements to at least {4 * modes}")
    return Coordinates((), modes, accel)


def _suspended_checks(rd: _Reader, doc: dict, conductor, coords: Coordinates, sampling: Sampling) -> None:
    """Checks across tables for suspended structures."""
    ncoords = len(coords.rigid) + coords.modes
    if sampling.levels ** ncoords > MAX_GRID_POINTS:
        raise rd.fail("sampling.levels", f"{sampling.levels}^{ncoords} = {sampling.levels ** ncoords} capacitance "
                      f"samples exceed {MAX_GRID_POINTS}", "lower sampling.levels or use fewer coordinates")
    if "fem" in doc:
        raise rd.fail("[fem]", "[fem] sets the free-disk plate mesh; a suspended structure has none",
                      "remove [fem] (beams: conductor.elements sets the beam mesh)")
    damp = doc.get("damping")
    if isinstance(damp, dict) and damp.get("squeeze_film"):
        raise rd.fail("damping.squeeze_film", "the squeeze-film model is solved on the free disk only",
                      "remove squeeze_film and give q_factor / damping_ratio / rayleigh instead")


def _parse_suspended(rd: _Reader, doc: dict, name: str, description: str, path: str,
                     conductor: Piston | Beam) -> Structure:
    """The rest of parse_structure for a suspended conductor (rectangular electrodes, no FEM mesh)."""
    sets = _rect_electrodes(rd, doc, conductor)
    coords, sampling, fit = _suspended_coordinates(rd, doc, conductor), _sampling(rd, doc), _fit(rd, doc)
    if fit.degree >= sampling.levels:
        raise rd.fail("fit.degree", f"degree {fit.degree} needs at least {fit.degree + 1} sampling levels "
                      f"per coordinate (have {sampling.levels})",
                      f"lower fit.degree or raise sampling.levels to {fit.degree + 1}")
    _suspended_checks(rd, doc, conductor, coords, sampling)
    if coords.modes:
        coords_named = Coordinates((), tuple(str(k + 1) for k in range(coords.modes)))   # names m1, m2, ...
    else:
        coords_named = coords
    return Structure(name=name, description=description, source=path, conductor=conductor,
                     electrode_sets=sets, coordinates=coords, sampling=sampling, fit=fit,
                     electrostatics=_electrostatics(rd, doc), fem=FemOptions(),
                     damping=_damping(rd, doc, coords_named) if "damping" in doc else None,
                     imports=_imports(rd, doc))


# ---------------------------------------------------------------- imported data (issue 7)

@dataclass(frozen=True)
class Imports:
    """[import]: data from an external FEM and/or field solver (netgen.importers), paths resolved
    against the structure file's folder. Mechanics needs all three of mass_matrix,
    stiffness_matrix and modes; capacitance alone replaces the extractor's samples."""
    mass_matrix: str | None = None         # Matrix Market (.mtx): M, full (with modes) or modal
    stiffness_matrix: str | None = None    # Matrix Market (.mtx): K, same size as M
    modes: str | None = None               # .npz or .csv: node coordinates + eigenvectors (vertical)
    capacitance: str | None = None         # .npz or .csv: coordinates q -> plate-electrode capacitances


def _imports(rd: _Reader, doc: dict) -> Imports | None:
    """The optional [import] table."""
    if "import" not in doc:
        return None
    t = _table(rd, doc, "import", required=False)
    keys = ["mass_matrix", "stiffness_matrix", "modes", "capacitance"]
    _check_keys(rd, "import", t, keys)
    base = Path(rd.path).parent
    out = {}
    for key, suffixes in zip(keys, [(".mtx",), (".mtx",), (".npz", ".csv"), (".npz", ".csv")]):
        if key not in t:
            continue
        value = t[key]
        if not isinstance(value, str) or not value.endswith(suffixes):
            raise rd.fail(f"import.{key}", f"{key} = {value!r} is not a {' or '.join(suffixes)} file name",
                          f'write {key} = "data/{key}{suffixes[0]}" (relative to the structure file)')
        path = base / value
        if not path.is_file():
            raise rd.fail(f"import.{key}", f"no such file: {path}", "check the path (relative to the structure file)")
        out[key] = str(path)
    mech = [k for k in keys[:3] if k in out]
    if mech and len(mech) != 3:
        missing = [k for k in keys[:3] if k not in out]
        raise rd.fail("import", f"imported mechanics needs mass_matrix, stiffness_matrix and modes (missing {missing})",
                      "give all three files, or none to use netgen's own mechanics")
    if not out:
        raise rd.fail("import", "empty [import] table", "give mass_matrix + stiffness_matrix + modes and/or capacitance")
    return Imports(**out)
