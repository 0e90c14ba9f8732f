"""A model JSON read back (MacroModel.load_json, from_dict) is an input file like any other: the
emitters and testbenches write its names into netlists and its text into their headers, so
before a MacroModel is built from it every string is printable one-line text (netgen.core.text),
every name an emitter writes outside comments is an identifier, every choice is known and every
number the headers print is a finite number. Errors are ModelError (exit 2), naming the file,
the entry (e.g. coordinates[2].label) and the fix."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any, NoReturn

from ..core.errors import ModelError
from ..core.names import GROUND, duplicate, keyword, model_problem, rename_fix, reserved
from ..core.text import escape, is_identifier, shown, text_problem

KINDS = ("translation", "rotation", "mode")
TARGETS = ("plates", "inverse", "direct")
REQUIRED = {
    "name": str,
    "description": str,
    "source": str,
    "plate": str,
    "generator": str,
    "coordinates": list,
    "electrodes": list,
    "capacitances": list,
    "coupling": list,
    "sampling": dict,
    "report": dict,
}
FIX = "rebuild the model with `netgen build STRUCTURE.toml -o DIR` rather than editing its JSON"


def leaves(value: Any, where: str = "") -> Iterator[tuple[str, Any]]:
    """(location, value) of every key and scalar of a JSON document, e.g. ('coordinates[1].label', 'x')."""
    if isinstance(value, dict):
        for k, v in value.items():
            loc = f"{where}.{k}" if where else str(k)
            yield f"{loc} (key)", k
            yield from leaves(v, loc)
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from leaves(v, f"{where}[{i}]")
    else:
        yield where, value


class Checker:
    """The checks of one document, failing with the file's path."""

    def __init__(self, path: str, units: tuple[str, ...]):
        self.path, self.units = escape(str(path)), units

    def fail(self, where: str, problem: str, fix: str = FIX) -> NoReturn:
        raise ModelError(self.path, where, problem, fix)

    def name(self, where: str, value: Any) -> None:
        """A name written outside comments (subcircuit, module, node, port)."""
        if not is_identifier(value):
            self.fail(
                where,
                f"{shown(value)} is not a netlist name",
                "use letters, digits and _ starting with a letter; " + FIX,
            )

    def choice(self, where: str, value: Any, options: tuple[str, ...]) -> None:
        if value not in options:
            self.fail(where, f"{shown(value)} is not one of {', '.join(options)}")

    def number(self, where: str, value: Any, integer: bool = False) -> float:
        """`value` itself, once it is a finite number (an integer if `integer`)."""
        ok = isinstance(value, int) if integer else isinstance(value, (int, float))
        if isinstance(value, bool) or not ok or not math.isfinite(value):
            self.fail(where, f"{shown(value)} is not a finite {'integer' if integer else 'number'}")
        return value

    def entries(self, d: dict, key: str) -> list[dict]:
        """The list d[key] of JSON objects."""
        rows = d.get(key)
        if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
            self.fail(key, f"{key} must be a list of objects")
        return rows


def check(d: Any, path: str = "<model>", units: tuple[str, ...] = ("m", "rad")) -> None:
    """Refuse a model JSON document an emitter could not write safely (see the module docstring)."""
    c = Checker(path, units)
    if not isinstance(d, dict):
        c.fail("(document)", "the model JSON is not an object")
    for key, kind in REQUIRED.items():
        if not isinstance(d.get(key), kind):
            c.fail(key, f"missing, or not a JSON {'string' if kind is str else kind.__name__}")
    for where, value in leaves(d):
        if isinstance(value, str) and text_problem(value):
            c.fail(
                where,
                f"text {text_problem(value)}",
                "write it as one line of printable text (no line breaks or other control characters); " + FIX,
            )
        if isinstance(value, float) and not math.isfinite(value):
            c.fail(where, f"{value} is not a finite number")
    check_names(c, d)
    printed = ("samples", "levels", "excluded_touching", "holdout", "corner_checks")  # in the headers as they are
    for key in printed:
        if key in d["sampling"]:
            c.number(f"sampling.{key}", d["sampling"][key], integer=True)
    if "range" in d["sampling"]:
        c.number("sampling.range", d["sampling"]["range"])
    per = d["sampling"].get("coordinate_range", {})  # printed in the headers: names and numbers only
    if not isinstance(per, dict):
        c.fail("sampling.coordinate_range", "must be an object {coordinate: half-width}")
    for name, value in per.items():
        c.name("sampling.coordinate_range", name)
        c.number(f"sampling.coordinate_range.{name}", value)


def check_names(c: Checker, d: dict) -> None:
    """Names, kinds, units and fit targets of the coordinates, electrodes, fits and couplings (a stop
    point's electrode is only a label: never written outside comments, checked as text)."""
    c.name("name", d["name"])
    c.name("plate", d["plate"])
    for i, row in enumerate(c.entries(d, "coordinates")):
        c.name(f"coordinates[{i}].name", row.get("name"))
        if keyword(row["name"]):  # the coordinate names its ports and the module's variables
            c.fail(f"coordinates[{i}].name", f"coordinate name {keyword(row['name'])}", FIX)
        c.choice(f"coordinates[{i}].kind", row.get("kind"), KINDS)
        c.choice(f"coordinates[{i}].unit", row.get("unit"), c.units)
    electrodes = c.entries(d, "electrodes")
    for i, row in enumerate(electrodes):
        c.name(f"electrodes[{i}].name", row.get("name"))
    names = [e["name"] for e in electrodes]
    check_policy(c, d["name"], d["plate"], names)
    for i, row in enumerate(c.entries(d, "capacitances")):
        c.choice(f"capacitances[{i}].electrode", row.get("electrode"), tuple(names))
        c.choice(f"capacitances[{i}].target", row.get("target"), TARGETS)
    check_couplings(c, d, tuple(names))
    check_calibration(c, d.get("calibration", {}), tuple(names))
    check_inertial(c, d.get("inertial_inputs", {}), len(d["coordinates"]))
    coords = tuple(row.get("name") for row in d["coordinates"])
    check_process(c, d.get("process", {}), tuple(names), len(d["coordinates"]), coords)
    if not isinstance(d.get("contact") or {}, dict):
        c.fail("contact", "must be an object")


def check_film(c: Checker, film: Any, where: str, ncoords: int, visc: dict) -> None:
    """A gap set's squeeze-film law (netgen.model.process_film.film_law), whose numbers the emitters
    write: gap and rarefaction finite numbers, one share per coordinate; with temp's viscosity law its
    cavity and the mean free path's constants (netgen.emit.process_film.film_factors)."""
    if not isinstance(film, dict):
        c.fail(where, "must be an object")
    c.number(f"{where}.gap_m", film.get("gap_m"))
    c.number(f"{where}.rarefaction", film.get("rarefaction"))
    share = film.get("share")
    if not isinstance(share, list) or len(share) != ncoords:
        c.fail(f"{where}.share", f"must list one number per coordinate ({ncoords})")
    for k, x in enumerate(share):
        c.number(f"{where}.share[{k}]", x)
    rows = film.get("branches")
    if rows is not None and (  # the compressible film's branches of this side (process_film.compressible_law)
        not isinstance(rows, list)
        or len(rows) != ncoords
        or any(not isinstance(r, list) or any(not isinstance(j, int) or j < 0 for j in r) for r in rows)
    ):
        c.fail(f"{where}.branches", f"must list the branch indices (integers >= 0) per coordinate ({ncoords})")
    fit = film.get("fit")
    if fit is not None:  # a perforated film's cubics (netgen.model.process_film.perforated_fit)
        rows = fit.get("coeffs") if isinstance(fit, dict) else None
        if (
            not isinstance(rows, list)
            or len(rows) != ncoords
            or any(not isinstance(r, list) or len(r) != 4 for r in rows)
        ):
            c.fail(f"{where}.fit.coeffs", f"must list 4 numbers per coordinate ({ncoords})")
        for v, r in enumerate(rows):
            for k, x in enumerate(r):
                c.number(f"{where}.fit.coeffs[{v}][{k}]", x)
        c.number(f"{where}.fit.max_rel_error", fit.get("max_rel_error"))
    if visc:
        c.choice("process.temp.viscosity.cavity", visc.get("cavity"), ("open", "sealed"))
        c.number("process.temp.viscosity.sutherland_K", visc.get("sutherland_K"))
        c.number("process.temp.viscosity.t0_K", visc.get("t0_K"))


def check_policy(c: Checker, model: str, plate: str, electrodes: list[str]) -> None:
    """The name policy (netgen.core.names): a model name no dialect or run file reserves, a plate
    that is not ground, electrode names no dialect reserves, all distinct case-insensitively."""
    problem = model_problem(model)
    if problem:
        c.fail("name", f"model name {problem}", rename_fix(model) + "; " + FIX)
    if plate.lower() in GROUND:
        c.fail("plate", f"plate {plate!r} is ground in ngspice (0, gnd)", FIX)
    if keyword(plate):
        c.fail("plate", f"plate name {keyword(plate)}", FIX)
    seen = {plate.lower(): plate}
    for i, name in enumerate(electrodes):
        problem = reserved(name)
        earlier = duplicate(name, seen)
        if earlier is not None:
            problem = f"{name!r} is also the name of {earlier!r} (case-insensitive in SPICE)"
            if earlier == plate:
                problem = f"{name!r} is also the plate's name (the plate would be shorted to it)"
        if problem:
            c.fail(f"electrodes[{i}].name", f"electrode name {problem}", rename_fix(name) + "; " + FIX)


def check_couplings(c: Checker, d: dict, names: tuple[str, ...]) -> None:
    """Each coupling joins two different electrodes, each pair once, with a finite capacitance >= 0
    (a two-terminal capacitor; a Maxwell matrix's off-diagonal entries are its negatives)."""
    seen: dict[frozenset, int] = {}
    for i, row in enumerate(c.entries(d, "coupling")):
        pair = row.get("pair")
        if not isinstance(pair, list) or len(pair) != 2:
            c.fail(f"coupling[{i}].pair", "must be a pair of electrode names")
        for k, e in enumerate(pair):
            c.choice(f"coupling[{i}].pair[{k}]", e, names)
        if pair[0] == pair[1]:
            c.fail(
                f"coupling[{i}].pair",
                f"couples electrode {pair[0]} to itself",
                "a coupling joins two different electrodes; " + FIX,
            )
        key = frozenset(pair)
        if key in seen:
            c.fail(
                f"coupling[{i}].pair",
                f"the pair {pair[0]}-{pair[1]} is given twice (also coupling[{seen[key]}])",
                "give each pair once; " + FIX,
            )
        seen[key] = i
        value = c.number(f"coupling[{i}].capacitance", row.get("capacitance"))
        if value < 0:
            c.fail(
                f"coupling[{i}].capacitance",
                f"{value!r} F is negative",
                "give the two-terminal capacitance (the negative of the Maxwell matrix's off-diagonal entry); " + FIX,
            )


def check_calibration(c: Checker, cal: Any, names: tuple[str, ...]) -> None:
    """The optional calibration record (netgen.electrostatics.calibration): per-electrode fringe
    coefficients a, b (finite) with a positive reference length, each electrode at most once."""
    if not isinstance(cal, dict):
        c.fail("calibration", "must be an object")
    fringe = cal.get("fringe", [])
    if not isinstance(fringe, list) or not all(isinstance(r, dict) for r in fringe):
        c.fail("calibration.fringe", "must be a list of objects")
    seen: set[str] = set()
    for i, row in enumerate(fringe):
        where = f"calibration.fringe[{i}]"
        c.choice(f"{where}.electrode", row.get("electrode"), names)
        if row["electrode"] in seen:
            c.fail(f"{where}.electrode", f"electrode {row['electrode']} has two fringe entries", FIX)
        seen.add(row["electrode"])
        for key in ("a", "b", "length"):
            c.number(f"{where}.{key}", row.get(key))
        if not row["length"] > 0:
            c.fail(f"{where}.length", f"{row['length']!r} m is not a positive reference length")
    if "points" in cal:
        c.number("calibration.points", cal["points"], integer=True)


# the inertial inputs' tables (netgen.model.inertial): key -> (allowed names, rank of each entry)
INERTIAL = {
    "participation": (("a_x", "a_y"), 1),
    "gyroscopic": (("x", "y", "z"), 2),
    "centrifugal": (("xx", "yy", "zz", "xy", "xz", "yz"), 2),
    "centrifugal_force": (("xx", "yy", "zz", "xy", "xz", "yz"), 1),
}


def check_inertial(c: Checker, block: Any, n: int) -> None:
    """The optional inertial_inputs entry: known axis names, one number per coordinate (a vector)
    or an n x n array of numbers (a matrix) each."""
    if not isinstance(block, dict):
        c.fail("inertial_inputs", "must be an object")
    for key, (names, rank) in INERTIAL.items():
        table = block.get(key, {})
        if not isinstance(table, dict):
            c.fail(f"inertial_inputs.{key}", "must be an object")
        for axis, value in table.items():
            where = f"inertial_inputs.{key}.{axis}"
            c.choice(f"{where} (key)", axis, names)
            rows = value if rank == 2 else [value]
            if not isinstance(rows, list) or len(rows) != (n if rank == 2 else 1):
                c.fail(where, f"must be {'an n x n array' if rank == 2 else 'a list'} over the {n} coordinates")
            for r, row in enumerate(rows):
                if not isinstance(row, list) or len(row) != n:
                    c.fail(f"{where}[{r}]" if rank == 2 else where, f"must be a list of {n} numbers")
                for k, x in enumerate(row):
                    c.number(f"{where}[{r}][{k}]" if rank == 2 else f"{where}[{k}]", x)


def check_etch_law(c: Checker, law: Any, where: str, declared: bool, size: int = 4) -> None:
    """A coordinate's etch ratios (netgen.model.process.etch_laws): `size` numbers per law part (4 +
    3 per torsion knot, netgen.model.etch_knots) where etch is declared (the emitters write them),
    absent otherwise."""
    if law is None and not declared:
        return
    if not isinstance(law, dict) or not declared:
        c.fail(where, "must be an object of the etch ratios, present only when etch is a parameter")
    for key in ("mass", "a", "b", "d_rest", "d_film"):
        row = law.get(key)
        if not isinstance(row, list) or len(row) != size:
            c.fail(f"{where}.{key}", f"must be a list of {size} numbers")
        for k, x in enumerate(row):
            c.number(f"{where}.{key}[{k}]", x)


def check_ratio_laws(c: Checker, laws: Any, path: str, names: tuple[str, ...], sizes: tuple[int, ...] = (4,)) -> None:
    """A list of per-electrode capacitance ratios at `path`: each one of the model's electrode names
    and a cubic's four numbers (the etch's and the tscale's laws share this form), or `sizes` (a
    beam's etch ratio with its edge knots: 4 + 3 per knot, netgen.model.etch_knots)."""
    if not isinstance(laws, list):
        c.fail(path, "must be a list of {electrode, ratio} objects")
    for i, law in enumerate(laws):
        where = f"{path}[{i}]"
        if not isinstance(law, dict) or not isinstance(law.get("ratio"), list) or len(law["ratio"]) not in sizes:
            c.fail(
                where, f"must be an object with an electrode name and a ratio of {' or '.join(map(str, sizes))} numbers"
            )
        c.choice(f"{where}.electrode", law.get("electrode"), names)
        for k, x in enumerate(law["ratio"]):
            c.number(f"{where}.ratio[{k}]", x)


def check_thickness_laws(c: Checker, tscale: dict, names: tuple[str, ...], ncoords: int) -> None:
    """The tscale capacitance laws (netgen.model.process.thickness_capacitance), where there are:
    per electrode one of the model's electrode names and four numbers, a comb's optional state
    factor, and their stated errors."""
    laws = tscale.get("capacitance_laws")
    if laws is None:
        return
    check_ratio_laws(c, laws, "process.tscale.capacitance_laws", names)
    c.number("process.tscale.capacitance_max_rel_error", tscale.get("capacitance_max_rel_error"))
    if "capacitance_stateless_max_rel_error" in tscale:  # stated in the header (netgen.emit.process)
        c.number("process.tscale.capacitance_stateless_max_rel_error", tscale["capacitance_stateless_max_rel_error"])
    for i, law in enumerate(laws):
        if "state" in law:
            check_state_law(c, law["state"], f"process.tscale.capacitance_laws[{i}].state", ncoords)


def check_capacitance_laws(
    c: Checker, laws: Any, names: tuple[str, ...], coords: tuple[str, ...], nknots: int = 0
) -> None:
    """The etch's capacitance laws (netgen.model.process.capacitance_laws): per electrode one of the
    model's electrode names (the emitters name the parameter pc_<electrode>), four numbers, an
    optional shift {coordinate: number} over the model's x and y (z with fill) and a comb's optional
    stop_shift over the same coordinates; with `nknots` knots a ratio may have 4 + 3 nknots numbers."""
    check_ratio_laws(c, laws, "process.etch.capacitance", names, (4, 4 + 3 * nknots))
    for i, law in enumerate(laws):
        where = f"process.etch.capacitance[{i}]"
        shift = law.get("shift", {})
        if not isinstance(shift, dict):
            c.fail(f"{where}.shift", "must be an object {coordinate: shift per metre of etch}")
        fill = law.get("fill", False)  # a plate's fill shift along z (netgen.model.etch_fill)
        if not isinstance(fill, bool):
            c.fail(f"{where}.fill", "must be true or false")
        for q, x in shift.items():
            c.choice(f"{where}.shift", q, tuple(n for n in coords if n in (("z",) if fill else ("x", "y"))))
            c.number(f"{where}.shift.{q}", x)
        stops = law.get("stop_shift", {})  # a comb's geometric shift beside a fitted one (netgen.model.etch_combs)
        if not isinstance(stops, dict) or (stops and (fill or set(stops) != set(shift))):
            c.fail(f"{where}.stop_shift", "must be an object over the shift's coordinates (not with fill)")
        for q, x in stops.items():
            c.number(f"{where}.stop_shift.{q}", x)
        if "state" in law:
            check_state_law(c, law["state"], f"{where}.state", len(coords))
        if "cross" in law:  # tscale with etch: 1 + (tscale - 1) (u Q1 + u^2 Q2), Q1, Q2 with their constants
            check_state_law(c, law["cross"], f"{where}.cross", len(coords), constant=True)


def check_state_law(c: Checker, law: Any, where: str, ncoords: int, constant: bool = False) -> None:
    """A comb's state factor 1 + u P1(xs) + u^2 P2(xs) (netgen.model.etch_state), which every form
    renders as monomials: exponents a list of rows of ncoords integers >= 0, none all zero (the ratio
    pc holds the constant; a cross factor's, `constant`, may have one), and coeffs two lists of
    numbers, one per row."""
    exps: Any = law.get("exponents") if isinstance(law, dict) else None
    ok = isinstance(exps, list) and all(
        isinstance(r, list)
        and len(r) == ncoords
        and all(isinstance(k, int) and k >= 0 for k in r)
        and (constant or sum(r) > 0)
        for r in exps
    )
    if not ok:
        none = "" if constant else ", none all zero"
        c.fail(f"{where}.exponents", f"must be a list of rows of {ncoords} integers >= 0{none}")
    coeffs: Any = law.get("coeffs")
    if (
        not isinstance(coeffs, list)
        or len(coeffs) != 2
        or any(not isinstance(r, list) or len(r) != len(exps) for r in coeffs)
    ):
        c.fail(f"{where}.coeffs", f"must be two lists of {len(exps)} numbers (P1's and P2's)")
    for j, row in enumerate(coeffs):
        for k, x in enumerate(row):
            c.number(f"{where}.coeffs[{j}][{k}]", x)
    if "below" in law:  # a cantilever's overhanging tip: the factor in (k - u)+ (netgen.model.etch_state)
        c.number(f"{where}.below", law["below"])


def check_process(
    c: Checker, process: Any, names: tuple[str, ...], ncoords: int = 0, coords: tuple[str, ...] = ()
) -> None:
    """The optional process record (netgen.model.process), whose numbers and names the emitters write
    into the netlist (netgen.emit.process): its parameters are known names, its laws finite numbers
    (four per law and coordinate), its gap sets identifiers (they become instance parameter names
    dg_<set>) naming the model's electrodes, with a sign of +-1."""
    if not isinstance(process, dict):
        c.fail("process", "must be an object")
    if not process:
        return
    params = process.get("parameters")
    if not isinstance(params, list) or not params:
        c.fail("process.parameters", "must be a non-empty list")
    for i, p in enumerate(params):
        c.choice(f"process.parameters[{i}]", p, ("dg", "tscale", "escale", "temp", "etch"))
    c.number("process.temperature_C", process.get("temperature_C"))
    c.number("process.modulus_tc_per_K", process.get("modulus_tc_per_K"))
    knots = (process.get("etch") or {}).get("knots", []) if "etch" in params else []
    if not isinstance(knots, list):
        c.fail("process.etch.knots", "must be a list of numbers (the torsion knots, etch / 1 um)")
    for k, x in enumerate(knots):
        c.number(f"process.etch.knots[{k}]", x)
    laws = process.get("coordinates")
    if not isinstance(laws, list) or len(laws) != ncoords:
        c.fail("process.coordinates", f"must list one law per coordinate ({ncoords})")
    for v, law in enumerate(laws):
        for key in ("mass", "a", "b", "d_rest", "d_film"):
            row = law.get(key) if isinstance(law, dict) else None
            if not isinstance(row, list) or len(row) != 4:
                c.fail(f"process.coordinates[{v}].{key}", "must be a list of 4 numbers")
            for k, x in enumerate(row):
                c.number(f"process.coordinates[{v}].{key}[{k}]", x)
            size = 4 + 3 * len(knots)
            check_etch_law(c, law.get("etch"), f"process.coordinates[{v}].etch", "etch" in params, size)
    for where in ("tscale.range", "escale.range", "temp.range_C"):
        outer, inner = where.split(".")
        rng = (process.get(outer) or {}).get(inner)
        if not isinstance(rng, list) or len(rng) != 2:
            c.fail(f"process.{where}", "must be a list of 2 numbers")
        for k, x in enumerate(rng):
            c.number(f"process.{where}[{k}]", x)
    c.number("process.tscale.max_rel_error", process["tscale"].get("max_rel_error"))
    check_thickness_laws(c, process["tscale"], names, ncoords)
    if "etch" in params:
        etch = process.get("etch")
        if not isinstance(etch, dict) or not isinstance(etch.get("range_m"), list) or len(etch["range_m"]) != 2:
            c.fail("process.etch.range_m", "must be a list of 2 numbers")
        for k, x in enumerate(etch["range_m"]):
            c.number(f"process.etch.range_m[{k}]", x)
        c.number("process.etch.max_rel_error", etch.get("max_rel_error"))
        for key in (
            "area_rel",
            "capacitance_max_rel_error",
            "capacitance_stateless_max_rel_error",
            "capacitance_cross_max_rel_error",
            "capacitance_product_max_rel_error",
        ):  # stated in the header (netgen.emit.process)
            if key in etch:
                c.number(f"process.etch.{key}", etch[key])
        check_capacitance_laws(c, etch.get("capacitance", []), names, coords, len(knots))
    visc = (process.get("temp") or {}).get("viscosity") or {}
    if visc:
        c.number("process.temp.viscosity.max_rel_error", visc.get("max_rel_error"))
    for k, x in enumerate(visc.get("coeffs", []) if isinstance(visc, dict) else [None]):
        c.number(f"process.temp.viscosity.coeffs[{k}]", x)
    for i, row in enumerate(visc.get("sides") or [] if isinstance(visc, dict) else []):
        # a side's own viscosity law (netgen.model.process_film.side_laws): the emitters' pw_<side>
        where = f"process.temp.viscosity.sides[{i}]"
        c.choice(f"{where}.side", row.get("side") if isinstance(row, dict) else None, ("above", "below"))
        c.number("process.temp.viscosity.rarefaction", visc.get("rarefaction"))
        check_film(c, row, where, ncoords, visc)
    for i, g in enumerate(process.get("gaps", [])):
        if not isinstance(g, dict):
            c.fail(f"process.gaps[{i}]", "must be an object")
        c.name(f"process.gaps[{i}].set", g.get("set"))
        if g.get("sign") not in (1.0, -1.0):
            c.fail(f"process.gaps[{i}].sign", "must be 1 or -1")
        c.number(f"process.gaps[{i}].max_m", g.get("max_m"))
        if "film" in g:
            check_film(c, g["film"], f"process.gaps[{i}].film", ncoords, visc if "temp" in params else {})
        for e in g.get("electrodes", []):
            if e not in names:
                c.fail(f"process.gaps[{i}].electrodes", f"{e!r} is not an electrode of the model")
