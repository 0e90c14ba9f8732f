"""Structure files: the TOML a user writes, validated into a Structure.

Every mistake becomes a StructureError naming the file, the line and key, the problem and the
fix. The conductor kind (netgen.structure.conductors.CONDUCTORS) reads its own table and the
tables whose form depends on it; this module reads the rest and the checks across tables.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path

from ..core.constants import GASES
from ..core.errors import StructureError
from ..core.files import read_text, toml_document
from ..core.names import duplicate, model_problem, rename_fix, reserved
from ..core.reader import (
    Reader,
    check_keys,
    choice,
    did_you_mean,
    flag,
    free_text,
    identifier,
    integer,
    nonnegative,
    positive,
    quantity,
    table,
)
from ..core.text import escape, text_problem
from . import validity
from .bem_table import read_bem
from .conductors import CONDUCTORS
from .fastcap_table import read_fastcap, refuse_bem
from .process_table import check_process, read_process
from .schema import (
    ALL_RIGID,
    DESIGN_KEYS,
    DESIGNS,
    MAX_GRID_POINTS,
    Damping,
    ElectrostaticsOptions,
    FitOptions,
    Imports,
    Sampling,
    Structure,
    default_design,
    default_points,
    smolyak_count,
)

TOP_KEYS = [
    "name",
    "description",
    "conductor",
    "electrodes",
    "coordinates",
    "sampling",
    "fit",
    "electrostatics",
    "fem",
    "damping",
    "import",
    "loop",
    "process",
]  # [loop]: the sigma-delta testbench's (loopfile)
DAMPING_KEYS = [
    "q_factor",
    "damping_ratio",
    "rayleigh",
    "squeeze_film",
    "pressure",
    "gas",
    "temperature",
    "noise",
    "fem_refine",
    "film_model",
    "film_max_frequency",
]


def parse_structure(text: str, path: str = "<string>") -> Structure:
    """Validate TOML text into a Structure; raises StructureError on any mistake."""
    problem = text_problem(path)
    if problem:
        raise StructureError(
            escape(path),
            "file name",
            f"the structure file's path {problem}; the path is copied into the netlist headers",
            "rename the file (and its folders) to printable characters",
        )
    rd = Reader(path, text)
    doc = toml_document(text, path)
    check_keys(rd, "", doc, TOP_KEYS)
    name = doc.get("name")
    if not identifier(name):
        raise rd.fail(
            "name",
            f"name {name!r} is missing or not a simple identifier",
            'add name = "levitated_disk" (letters, digits, _; it names the output files '
            "and the subcircuit; avoid the word 'error')",
        )
    description = doc.get("description", "")
    if not isinstance(description, str):
        raise rd.fail("description", "description must be a string", 'write description = "..."')
    free_text(rd, "description", description, "description")
    t = table(rd, doc, "conductor", required=True)
    kind = choice(rd, t, "conductor", "kind", list(CONDUCTORS), default="free_disk")
    conductor = CONDUCTORS[kind].read(rd, t, kind)
    model_name(rd, name)
    sets = conductor.read_electrodes(rd, doc)
    electrode_names(rd, sets)
    coords = conductor.read_coordinates(rd, doc)
    sampling, fit = read_sampling(rd, doc, coords.count, conductor.coordinate_names(coords)), read_fit(rd, doc)
    if sampling.design == "grid" and fit.degree >= sampling.levels:
        raise rd.fail(
            "fit.degree",
            f"degree {fit.degree} needs at least {fit.degree + 1} sampling levels "
            f"per coordinate (have {sampling.levels})",
            f"lower fit.degree or raise sampling.levels to {fit.degree + 1}",
        )
    fem = conductor.read_fem(rd, doc)
    conductor.check(rd, doc, sets, coords, fem)
    if sampling.design == "grid" and sampling.levels**coords.count > MAX_GRID_POINTS:
        raise rd.fail(
            "sampling.levels",
            f"{sampling.levels}^{coords.count} = {sampling.levels**coords.count} "
            f"capacitance samples exceed {MAX_GRID_POINTS}",
            'lower sampling.levels, use fewer coordinates or set design = "sparse"',
        )
    electrostatics = read_electrostatics(rd, doc)
    warnings = validity.check(rd, conductor, sets, electrostatics)
    structure = Structure(
        name=name,
        description=description,
        source=path,
        conductor=conductor,
        electrode_sets=sets,
        coordinates=coords,
        sampling=sampling,
        fit=fit,
        electrostatics=electrostatics,
        fem=fem,
        damping=read_damping(rd, doc, conductor.coordinate_names(coords), getattr(conductor, "sprung_rigid", False)),
        imports=read_imports(rd, doc),
        warnings=warnings,
        process=read_process(rd, doc),
    )
    imported = bool(structure.imports and structure.imports.modes)
    t0_c = (structure.damping.temperature if structure.damping else 300.0) - 273.15
    names = conductor.coordinate_names(coords) or list(coords.rigid)
    film = structure.damping.film_model if structure.damping else "incompressible"
    check_process(rd, structure.process, names, sets, imported, t0_c, conductor, film)
    return structure


def model_name(rd: Reader, name: str) -> None:
    """Refuse a model name an emitted dialect or a run's own files reserve (netgen.core.names)."""
    problem = model_problem(name)
    if problem:
        raise rd.fail("name", f"model name {problem}", rename_fix(name))


def electrode_names(rd: Reader, sets: Sequence) -> None:
    """Refuse electrode names (a set's derived <set>_r<i>s<j> too) that a dialect reserves or that
    repeat another set's case-insensitively (netgen.core.names)."""
    seen: dict[str, str] = {}
    for i, s in enumerate(sets):
        for name in s.electrode_names():
            problem = reserved(name)
            earlier = duplicate(name, seen)
            if earlier is not None:
                problem = f"{name!r} is also the name of electrode {earlier!r} (case-insensitive in SPICE)"
            if problem:
                raise rd.fail(f"electrodes[{i}].name", f"electrode name {problem}", rename_fix(s.name))


def load_structure(path: str | Path) -> Structure:
    """Read and validate a structure file; unreadable files become StructureError too."""
    path = Path(path)
    if not path.exists() and not path.is_symlink():
        raise StructureError(str(path), "file", "no such file", "check the path to the structure file")
    return parse_structure(read_text(path, "file", "a TOML structure file"), str(path))


# ---------------------------------------------------------------- sections of every kind


def read_sampling(rd: Reader, doc: dict, ncoords: int, names: list[str] | None = None) -> Sampling:
    """[sampling]: the design (default: the grid when `levels` is given or up to GRID_DEFAULT_MAX
    coordinates, else the sparse grid), its own keys (a key of another design is refused) and the
    box range (one number, or a table per coordinate: read_range)."""
    t = table(rd, doc, "sampling", required=False)
    check_keys(rd, "sampling", t, ["design", "levels", "range", "level", "points", "seed"])
    rng, ranges = read_range(rd, t, names)
    design = choice(rd, t, "sampling", "design", list(DESIGNS), "grid" if "levels" in t else default_design(ncoords))
    for key, owners in DESIGN_KEYS.items():
        if key in t and design not in owners:
            raise rd.fail(
                f"sampling.{key}",
                f"'{key}' does not apply to design = \"{design}\" (it belongs to {' / '.join(owners)})",
                f'remove {key}, or set design = "{owners[0]}"',
            )
    level = integer(rd, t, "sampling", "level", 2, 1, 6, "Smolyak level of the sparse grid")
    if design == "sparse" and smolyak_count(ncoords, level) > MAX_GRID_POINTS:
        raise rd.fail(
            "sampling.level",
            f"a level-{level} sparse grid in {ncoords} coordinates has "
            f"{smolyak_count(ncoords, level)} points, more than {MAX_GRID_POINTS}",
            "lower sampling.level or use fewer coordinates",
        )
    points = integer(
        rd,
        t,
        "sampling",
        "points",
        default_points(design, ncoords),
        8,
        MAX_GRID_POINTS,
        "sample points (lhs, sobol) or point budget (adaptive)",
    )
    if design == "sobol" and points & (points - 1):
        raise rd.fail(
            "sampling.points",
            f"points = {points} is not a power of two; a Sobol design is balanced only at powers of two",
            f"write points = {1 << (points - 1).bit_length() >> 1} or {1 << (points - 1).bit_length()}",
        )
    return Sampling(
        levels=integer(rd, t, "sampling", "levels", 3, 2, 9, "levels per coordinate"),
        range=rng,
        design=design,
        level=level,
        points=points,
        seed=integer(rd, t, "sampling", "seed", 1, 0, 2**31 - 1, "random seed of the design"),
        range_given="range" in t,
        ranges=ranges,
    )


def range_problem(v: float) -> str | None:
    """The sampling range's bounds: a fraction of the touching amplitude, below contact."""
    if 0 < v < 0.9:
        return None
    return "must lie in (0, 0.9): it is a fraction of the amplitude at which the plate touches an electrode, and 1 means contact"


def read_range(rd: Reader, t: dict, names: list[str] | None) -> tuple[float, tuple[tuple[str, float], ...]]:
    """`range`: one number for every coordinate, or a table {coordinate = number, "*" = number for
    the rest} (coordinates it does not name take "*", else the default 0.2). A table lets a
    beam's higher modes, whose static reach under an electrode load is a few per cent of the first
    mode's, keep a small box while the first reaches pull-in: the corners of an even box then
    close several gaps and no fit follows them (netgen.electrostatics.sampling.box_factors).
    Returns the largest range and the per-coordinate entries."""
    what = "sampling range as a fraction of the touching amplitude"
    raw = t.get("range")
    if not isinstance(raw, dict):
        return quantity(rd, t, "sampling", "range", "dimensionless", 0.2, range_problem, what), ()
    if not raw:
        raise rd.fail(
            "sampling.range", "the range table is empty", 'write range = 0.2, or range = {"*" = 0.2, m2 = 0.05}'
        )
    entries = []
    for name, value in raw.items():
        if name != "*" and names is not None and name not in names:
            raise rd.fail(
                "sampling.range", f"unknown coordinate {name!r}", f"{did_you_mean(name, names)}use one of {names}"
            )
        entries.append(
            (name, quantity(rd, {name: value}, "sampling.range", name, "dimensionless", None, range_problem, what))
        )
    rest = dict(entries).get("*", Sampling.range)
    return max([v for _, v in entries] + ([rest] if names is None or len(entries) < len(names) else [])), tuple(entries)


def read_fit(rd: Reader, doc: dict) -> FitOptions:
    t = table(rd, doc, "fit", required=False)
    check_keys(rd, "fit", t, ["degree", "target", "holdout", "seed", "tolerance", "max_terms"])
    d = FitOptions()
    return FitOptions(
        degree=integer(rd, t, "fit", "degree", d.degree, 1, 6, "polynomial total degree"),
        target=choice(rd, t, "fit", "target", ["plates", "inverse", "direct"], d.target),
        tolerance=quantity(
            rd,
            t,
            "fit",
            "tolerance",
            "dimensionless",
            d.tolerance,
            check=lambda v: None if 0 < v < 1 else "must lie in (0, 1)",
            what="held-out max relative error target",
        ),
        max_terms=integer(rd, t, "fit", "max_terms", d.max_terms, 1, 25, "plate terms per electrode"),
        holdout=integer(rd, t, "fit", "holdout", 500, 10, 10**6, "held-out check points"),
        seed=integer(rd, t, "fit", "seed", 1, 0, 2**31 - 1, "random seed of the held-out points"),
    )


def read_electrostatics(rd: Reader, doc: dict) -> ElectrostaticsOptions:
    t = table(rd, doc, "electrostatics", required=False)
    keys = [
        "extractor",
        "fringe",
        "fringe_a",
        "fringe_b",
        "relative_permittivity",
        "coupling_per_length",
        "couplings",
        "calibration_points",
        "comb_model",
        "bem",
        "calibration_source",
        "fastcap",
    ]
    check_keys(rd, "electrostatics", t, keys)
    d = ElectrostaticsOptions()
    extractor = t.get("extractor", d.extractor)
    if not identifier(extractor):
        raise rd.fail(
            "electrostatics.extractor", f"extractor = {extractor!r} is not a name", 'write extractor = "parallel_plate"'
        )
    couplings = data_file(rd, t, "electrostatics", "couplings", (".json", ".csv"))
    points = integer(rd, t, "electrostatics", "calibration_points", 0, 0, 1000, "BEM calibration points")
    if couplings and extractor not in ("parallel_plate", "calibrated"):
        raise rd.fail(
            "electrostatics.couplings",
            f"extractor = {extractor!r} takes no couplings file (its own field solution gives the couplings)",
            'drop couplings, or use extractor = "calibrated" or "parallel_plate"',
        )
    if couplings and t.get("coupling_per_length"):
        raise rd.fail(
            "electrostatics.coupling_per_length",
            "coupling_per_length and a couplings file both set the electrode-electrode couplings",
            "keep one of them",
        )
    if extractor == "calibrated" and not couplings and not points:
        raise rd.fail(
            "electrostatics.extractor",
            'extractor = "calibrated" needs a field solution to calibrate against',
            'add calibration_points = 9 (BEM solves) or couplings = "maxwell.json" (a field solver\'s matrices)',
        )
    if points and extractor != "calibrated":
        raise rd.fail(
            "electrostatics.calibration_points",
            f"calibration_points with extractor = {extractor!r}",
            'write extractor = "calibrated", or drop calibration_points',
        )
    if points and couplings:
        raise rd.fail(
            "electrostatics.calibration_points",
            "calibration_points (BEM) and a couplings file are two calibration sources",
            "keep one: the file's points, or BEM at calibration_points",
        )
    source = choice(rd, t, "electrostatics", "calibration_source", ["bem", "fastcap"], "bem")
    if "calibration_source" in t and not points:
        raise rd.fail(
            "electrostatics.calibration_source",
            "calibration_source without calibration_points: no field solve runs for a calibration",
            'write extractor = "calibrated" with calibration_points = 9, or drop calibration_source',
        )
    return ElectrostaticsOptions(
        couplings=couplings,
        calibration_points=points,
        calibration_source=source,
        bem=read_bem(rd, t, extractor, couplings) if source == "bem" else refuse_bem(rd, t),
        fastcap=read_fastcap(rd, t, extractor, source),
        fringe=choice(rd, t, "electrostatics", "fringe", ["plate_between", "palmer", "none"], d.fringe),
        fringe_a=quantity(rd, t, "electrostatics", "fringe_a", "dimensionless", d.fringe_a),
        fringe_b=quantity(rd, t, "electrostatics", "fringe_b", "dimensionless", d.fringe_b),
        relative_permittivity=quantity(
            rd,
            t,
            "electrostatics",
            "relative_permittivity",
            "dimensionless",
            d.relative_permittivity,
            check=lambda v: None if v >= 1 else "must be >= 1",
        ),
        coupling_per_length=quantity(
            rd,
            t,
            "electrostatics",
            "coupling_per_length",
            "dimensionless",
            d.coupling_per_length,
            check=lambda v: None if v >= 0 else "must be >= 0",
            what="electrode-electrode capacitance per slot length in F/m",
        ),
        extractor=extractor,
        comb_model=choice(rd, t, "electrostatics", "comb_model", ["field2d", "textbook"], d.comb_model),
    )


def data_file(rd: Reader, t: dict, section: str, key: str, suffixes: tuple[str, ...]) -> str | None:
    """An optional data file named relative to the structure file, with one of `suffixes`; None if absent."""
    if key not in t:
        return None
    value = t[key]
    if isinstance(value, str):
        free_text(rd, f"{section}.{key}", value, key)
    if not isinstance(value, str) or not value.endswith(suffixes):
        raise rd.fail(
            f"{section}.{key}",
            f"{key} = {value!r} is not a {' or '.join(suffixes)} file name",
            f'write {key} = "data/{key}{suffixes[0]}" (relative to the structure file)',
        )
    path = Path(rd.path).parent / value
    if not path.is_file():
        raise rd.fail(f"{section}.{key}", f"no such file: {path}", "check the path (relative to the structure file)")
    return str(path)


# ---------------------------------------------------------------- [damping]


def per_coordinate(
    rd: Reader,
    t: dict,
    key: str,
    names: list[str] | None,
    check: Callable[[float], str | None],
    what: str,
    sprung: bool = False,
) -> tuple[tuple[str, float], ...]:
    """A number (every eigenmode: key '*') or a table {coordinate = number} of positive values."""
    loc = f"damping.{key}"
    if key not in t:
        return ()
    raw = t[key]
    entries = raw if isinstance(raw, dict) else {"*": raw}
    out = []
    for name, value in entries.items():
        if name != "*" and names is not None and name not in names:
            raise rd.fail(loc, f"unknown coordinate {name!r}", f"{did_you_mean(name, names)}use one of {names}")
        if name in ALL_RIGID and not sprung:
            raise rd.fail(
                loc,
                f"{key} of the rigid coordinate {name!r} is undefined (no stiffness, no resonance)",
                "damp rigid-body motions with squeeze_film or rayleigh alpha instead",
            )
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise rd.fail(
                loc,
                f"{key} for {name!r} must be a number, got {value!r}",
                f"write {key} = 1e4 (all eigenmodes) or {key} = {{m2_0c = 1e4}}",
            )
        problem = check(float(value))
        if problem:
            raise rd.fail(loc, f"{key} = {value!r} for {name!r} {problem}", f"give a physical {what}")
        out.append((name, float(value)))
    return tuple(out)


def rayleigh(rd: Reader, t: dict) -> tuple[float, float]:
    """Rayleigh coefficients (alpha in 1/s, beta in s) from rayleigh = {alpha = .., beta = ..}."""
    raw = t.get("rayleigh", {})
    if not isinstance(raw, dict):
        raise rd.fail(
            "damping.rayleigh",
            f"rayleigh must be a table, got {raw!r}",
            "write rayleigh = {alpha = 10.0, beta = 1e-9}  (D = alpha M + beta K; 1/s and s)",
        )
    check_keys(rd, "damping.rayleigh", raw, ["alpha", "beta"])
    return (
        quantity(rd, raw, "damping.rayleigh", "alpha", "dimensionless", 0.0, nonnegative, "mass-proportional 1/s"),
        quantity(rd, raw, "damping.rayleigh", "beta", "dimensionless", 0.0, nonnegative, "stiffness-proportional s"),
    )


def read_damping(rd: Reader, doc: dict, names: list[str] | None, sprung: bool = False) -> Damping | None:
    """The optional [damping] table; `names`: the coordinate names (None while unknown); `sprung`:
    the rigid-body motions have springs (a proof mass on flexures), so Q and zeta apply to them too."""
    if "damping" not in doc:
        return None
    t = table(rd, doc, "damping", required=False)
    check_keys(rd, "damping", t, DAMPING_KEYS)
    q = per_coordinate(
        rd,
        t,
        "q_factor",
        names,
        lambda v: None if v > 0.5 else "must exceed 0.5",
        "quality factor (> 0.5, underdamped)",
        sprung,
    )
    zeta = per_coordinate(
        rd, t, "damping_ratio", names, lambda v: None if 0 < v < 1 else "must lie in (0, 1)", "damping ratio", sprung
    )
    both = sorted({n for n, _ in q} & {n for n, _ in zeta})
    if both:
        raise rd.fail(
            "damping.damping_ratio",
            f"coordinate(s) {both} given both q_factor and damping_ratio",
            "give each coordinate one of them (Q = 1 / (2 zeta))",
        )
    alpha, beta = rayleigh(rd, t)
    return Damping(
        q,
        zeta,
        alpha,
        beta,
        flag(rd, t, "damping", "squeeze_film", False),
        quantity(rd, t, "damping", "pressure", "pressure", 101325.0, positive, "gas pressure"),
        choice(rd, t, "damping", "gas", sorted(GASES), "air"),
        quantity(rd, t, "damping", "temperature", "temperature", 300.0, positive, "temperature"),
        flag(rd, t, "damping", "noise", False),
        integer(rd, t, "damping", "fem_refine", 5, 2, 8, "Reynolds mesh refinement level"),
        choice(rd, t, "damping", "film_model", ["incompressible", "compressible"], "incompressible"),
        quantity(
            rd,
            t,
            "damping",
            "film_max_frequency",
            "frequency",
            0.0,
            nonnegative,
            "highest frequency the compressible film network must reproduce (0: auto)",
        ),
    )


# ---------------------------------------------------------------- [import]

IMPORT_KEYS = ["mass_matrix", "stiffness_matrix", "modes", "capacitance"]
IMPORT_SUFFIXES = [(".mtx",), (".mtx",), (".npz", ".csv"), (".npz", ".csv")]


def read_imports(rd: Reader, doc: dict) -> Imports | None:
    """The optional [import] table: files relative to the structure file's folder."""
    if "import" not in doc:
        return None
    t = table(rd, doc, "import", required=False)
    check_keys(rd, "import", t, IMPORT_KEYS)
    base = Path(rd.path).parent
    out = {}
    for key, suffixes in zip(IMPORT_KEYS, IMPORT_SUFFIXES):
        if key not in t:
            continue
        value = t[key]
        if isinstance(value, str):
            free_text(rd, f"import.{key}", value, key)
        if not isinstance(value, str) or not value.endswith(suffixes):
            raise rd.fail(
                f"import.{key}",
                f"{key} = {value!r} is not a {' or '.join(suffixes)} file name",
                f'write {key} = "data/{key}{suffixes[0]}" (relative to the structure file)',
            )
        path = base / value
        if not path.is_file():
            raise rd.fail(f"import.{key}", f"no such file: {path}", "check the path (relative to the structure file)")
        out[key] = str(path)
    mech = [k for k in IMPORT_KEYS[:3] if k in out]
    if mech and len(mech) != 3:
        missing = [k for k in IMPORT_KEYS[:3] if k not in out]
        raise rd.fail(
            "import",
            f"imported mechanics needs mass_matrix, stiffness_matrix and modes (missing {missing})",
            "give all three files, or none to use netgen's own mechanics",
        )
    if not out:
        raise rd.fail(
            "import", "empty [import] table", "give mass_matrix + stiffness_matrix + modes and/or capacitance"
        )
    return Imports(**out)
