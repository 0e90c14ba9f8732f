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
    kind = _choice(rd, t, "conductor", "kind", ["free_disk"], default="free_disk")
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


def _electrode_sets(rd: _Reader, doc: dict, radius: float) -> tuple[ElectrodeSet, ...]:
    raw = doc.get("electrodes")
    if raw is None:
        raise rd.fail("[[electrodes]]", "missing electrode sets",
                      "add one [[electrodes]] table per side (see examples/levitated_disk.toml)")
    if not isinstance(raw, list) or not all(isinstance(e, dict) for e in raw):
        raise rd.fail("electrodes", "electrodes must be an array of tables", "write each set as [[electrodes]]")
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
    _check_keys(rd, "coordinates", t, ["rigid", "modes"])
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
    return Coordinates(tuple(rigid), modes)


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
                "noise", "fem_refine"]


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
                   _integer(rd, t, "damping", "fem_refine", 5, 2, 8, "Reynolds mesh refinement level"))


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


def parse_structure(text: str, path: str = "<string>") -> Structure:
    """Validate TOML text into a Structure; raises StructureError on any mistake."""
    rd = _Reader(path, text)
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        line = re.search(r"line (\d+)", str(exc))
        raise StructureError(path, "TOML syntax", str(exc), "correct the TOML syntax at that line "
                             "(strings need quotes, tables [name], arrays [a, b])",
                             int(line.group(1)) if line else None)
    top = ["name", "description", "conductor", "electrodes", "coordinates", "sampling", "fit",
           "electrostatics", "fem", "damping"]
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
                     damping=_damping(rd, doc, coords))


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

