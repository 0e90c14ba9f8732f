"""Electrode kinds of the structure file: ring-sector sets facing a disk (ElectrodeSet) and
rectangles facing a suspended conductor (RectElectrode), with their [[electrodes]] parsers."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..core.names import rename_fix, reserved
from ..core.reader import Reader, check_keys, choice, identifier, integer, nonnegative, positive, quantity
from ..core.units import UnitError, parse_quantity


@dataclass(frozen=True)
class ElectrodeSet:
    """Fixed electrodes on one side of the plate: rings x sectors of annular sectors."""

    name: str
    side: str  # "above" or "below"
    gap: float  # m, undeformed plate surface to electrode
    rings: tuple[tuple[float, float], ...]
    sectors: int
    sector_start: float  # rad, start angle of the first sector's centre line boundary
    slot: float  # m, width of the straight slots between sectors
    dielectric_thickness: float = 0.0  # m, a layer on the electrodes (0: none; read_dielectric)
    dielectric_permittivity: float = 1.0  # the layer's relative permittivity

    def electrode_names(self) -> list[str]:
        return [f"{self.name}_r{r + 1}s{s + 1}" for r in range(len(self.rings)) for s in range(self.sectors)]


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
    dielectric_thickness: float = 0.0  # m, a layer on the electrode (0: none; read_dielectric)
    dielectric_permittivity: float = 1.0  # the layer's relative permittivity

    def electrode_names(self) -> list[str]:
        return [self.name]


def electrode_tables(rd: Reader, doc: dict, missing: str, fix: str, each: str) -> list[dict]:
    """The [[electrodes]] array of tables, or a clear error (missing, or not an array of tables)."""
    raw = doc.get("electrodes")
    if raw is None:
        raise rd.fail("[[electrodes]]", missing, fix)
    if not isinstance(raw, list) or not all(isinstance(e, dict) for e in raw):
        raise rd.fail("electrodes", "electrodes must be an array of tables", f"write each {each} as [[electrodes]]")
    return raw


DIELECTRIC_KEYS = ["dielectric_thickness", "dielectric_permittivity"]


def read_dielectric(rd: Reader, t: dict, where: str, gap: float) -> tuple[float, float]:
    """dielectric_thickness and dielectric_permittivity of a layer on the electrode (a nitride or
    oxide): both or neither, 0 <= thickness < gap (the mass stops on the layer), permittivity >= 1.
    Without them: (0, 1), no layer."""
    given = [k for k in DIELECTRIC_KEYS if k in t]
    if not given:
        return 0.0, 1.0
    if len(given) == 1:
        other = DIELECTRIC_KEYS[1 - DIELECTRIC_KEYS.index(given[0])]
        raise rd.fail(
            f"{where}.{other}",
            f"{given[0]} is given without {other}: a dielectric layer needs both",
            'write both, e.g. dielectric_thickness = "0.2 um" and dielectric_permittivity = 7.5 (nitride), or neither',
        )
    thickness = quantity(
        rd,
        t,
        where,
        "dielectric_thickness",
        "length",
        check=nonnegative,
        what="thickness of the layer on the electrode",
    )
    if thickness >= gap:
        raise rd.fail(
            f"{where}.dielectric_thickness",
            f"dielectric_thickness {thickness:g} m fills the gap {gap:g} m (the layer lies inside the gap)",
            f"give a thickness below the gap ({gap:g} m), or check the unit",
        )
    eps_r = quantity(
        rd,
        t,
        where,
        "dielectric_permittivity",
        "dimensionless",
        check=lambda v: None if v >= 1 else "must be >= 1 (relative permittivity: 7.5 for nitride, 3.9 for oxide)",
        what="relative permittivity of the layer",
    )
    return thickness, eps_r


def unique_name(
    rd: Reader, t: dict, where: str, seen: set[str], what: str, each: str, fix: str, forbidden: tuple[str, ...] = ()
) -> str:
    """An [[electrodes]] table's name: an identifier (not one of `forbidden`) that no emitted
    dialect reserves (netgen.core.names.reserved) and not used before, case-insensitively (`seen`
    holds the lower-case names)."""
    name = t.get("name")
    if not identifier(name) or name in forbidden:
        raise rd.fail(f"{where}.name", f"name {name!r} is not a simple identifier", fix)
    problem = reserved(name)
    if problem:
        raise rd.fail(f"{where}.name", f"{what} name {problem}", rename_fix(name))
    if name.lower() in seen:
        raise rd.fail(
            f"{where}.name",
            f"{what} name {name!r} used twice (names are compared case-insensitively: SPICE reads drv and DRV as one)",
            f"give each {each} its own name",
        )
    seen.add(name.lower())
    return name


# ---------------------------------------------------------------- ring-sector sets (disk)


def rings(rd: Reader, t: dict, where: str, radius: float) -> tuple[tuple[float, float], ...]:
    """rings = [[inner, outer], ...]: disjoint, inside-out, each starting inside the plate."""
    loc = f"{where}.rings"
    fix = 'write rings = [["20 um", "230 um"], ["240 um", "473 um"]]: [inner, outer] radius per ring'
    raw = t.get("rings")
    if raw is None:
        raise rd.fail(loc, "missing required key 'rings'", fix)
    if not isinstance(raw, list) or not raw or not all(isinstance(r, list) and len(r) == 2 for r in raw):
        raise rd.fail(loc, "rings must be a non-empty list of [inner, outer] radius pairs", fix)
    out = []
    for k, (a, b) in enumerate(raw):
        try:
            r_in, r_out = parse_quantity(a, "length"), parse_quantity(b, "length")
        except UnitError as exc:
            raise rd.fail(loc, f"ring {k + 1}: {exc}", fix) from None
        if not 0 <= r_in < r_out:
            raise rd.fail(loc, f"ring {k + 1}: need 0 <= inner < outer radius, got [{a}, {b}]", fix)
        if r_in >= radius:
            raise rd.fail(
                loc,
                f"ring {k + 1} starts at {r_in:g} m, outside the plate (radius {radius:g} m)",
                "move the ring inside the plate radius or remove it: it would sense nothing",
            )
        out.append((r_in, r_out))
    for k in range(1, len(out)):
        if out[k][0] < out[k - 1][1]:
            raise rd.fail(
                loc,
                f"ring {k + 1} overlaps ring {k} (rings must be listed inside-out, disjoint)",
                "make each ring's inner radius at least the previous ring's outer radius",
            )
    return tuple(out)


def ring_sets(rd: Reader, doc: dict, radius: float) -> tuple[ElectrodeSet, ...]:
    """[[electrodes]] of a disk: one set of rings x sectors per table."""
    raw = electrode_tables(
        rd,
        doc,
        "missing electrode sets",
        "add one [[electrodes]] table per side (see examples/levitated_disk.toml)",
        "set",
    )
    sets: list[ElectrodeSet] = []
    names: set[str] = set()
    for i, t in enumerate(raw):
        where = f"electrodes[{i}]"
        check_keys(rd, where, t, ["name", "side", "gap", "rings", "sectors", "sector_start", "slot", *DIELECTRIC_KEYS])
        name = unique_name(
            rd,
            t,
            where,
            names,
            "electrode set",
            "set",
            'use letters, digits and _ (starting with a letter), e.g. name = "top"; '
            "avoid the word 'error' (PySpice treats it as a simulator error)",
        )
        side = choice(rd, t, where, "side", ["above", "below"], default=None)
        gap = quantity(rd, t, where, "gap", "length", check=positive, what="gap between plate and electrode")
        ring_list = rings(rd, t, where, radius)
        sectors = integer(rd, t, where, "sectors", 1, 1, 64, "number of sectors per ring")
        start = quantity(
            rd, t, where, "sector_start", "angle", default=-math.pi / 4, what="angle of the first sector edge"
        )
        slot = quantity(
            rd, t, where, "slot", "length", default=0.0, check=nonnegative, what="slot width between sectors"
        )
        if sectors > 1 and slot >= 2 * ring_list[-1][1] * math.sin(math.pi / sectors):
            raise rd.fail(
                f"{where}.slot",
                f"slot {slot:g} m leaves no electrode area",
                "use a slot much narrower than the sector width",
            )
        for r_in, r_out in ring_list:
            if sectors > 1 and slot / 2 >= min(r_out, radius) * math.sin(math.pi / sectors):
                raise rd.fail(
                    f"{where}.slot",
                    f"slot {slot:g} m swallows the ring [{r_in:g}, {r_out:g}] m",
                    "narrow the slot or widen the ring",
                )
        sets.append(ElectrodeSet(name, side, gap, ring_list, sectors, start, slot, *read_dielectric(rd, t, where, gap)))
    return tuple(sets)


def check_ring_overlaps(rd: Reader, sets: tuple[ElectrodeSet, ...]) -> None:
    """Two sets on the same side must not share a radius."""
    for j, b in enumerate(sets):
        for a in sets[:j]:
            if a.side != b.side:
                continue
            for ra in a.rings:
                for rb in b.rings:
                    if ra[0] < rb[1] and rb[0] < ra[1]:
                        raise rd.fail(
                            f"electrodes[{j}].rings",
                            f"set {b.name!r} overlaps set {a.name!r} on the same side ({b.side}): rings "
                            f"[{rb[0]:g}, {rb[1]:g}] m and [{ra[0]:g}, {ra[1]:g}] m",
                            "merge the sets into one [[electrodes]] table or make their rings disjoint",
                        )


# ---------------------------------------------------------------- rectangles (suspended conductors)


def span(rd: Reader, t: dict, where: str, key: str, lo: float, hi: float) -> tuple[float, float]:
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
        raise rd.fail(f"{where}.{key}", str(exc), fix) from None
    if not a < b:
        raise rd.fail(f"{where}.{key}", f"need start < end, got {raw}", fix)
    if b <= lo or a >= hi:
        raise rd.fail(f"{where}.{key}", f"[{a:g}, {b:g}] m lies outside the conductor ([{lo:g}, {hi:g}] m)", fix)
    return a, b


def rectangles(rd: Reader, doc: dict, outline: tuple[float, float, float, float]) -> tuple[RectElectrode, ...]:
    """[[electrodes]] of a suspended conductor: one rectangle each (default: under the whole conductor)."""
    raw = electrode_tables(
        rd, doc, "missing electrodes", "add an [[electrodes]] table (see examples/cc_beam.toml)", "electrode"
    )
    x0, x1, y0, y1 = outline
    out: list[RectElectrode] = []
    names: set[str] = set()
    for i, t in enumerate(raw):
        where = f"electrodes[{i}]"
        check_keys(rd, where, t, ["name", "side", "gap", "x", "y", *DIELECTRIC_KEYS])
        name = unique_name(
            rd,
            t,
            where,
            names,
            "electrode",
            "electrode",
            'use letters, digits and _ (starting with a letter), e.g. name = "drive"; '
            "avoid 'plate' and the word 'error'",
            forbidden=("plate",),
        )
        side = choice(rd, t, where, "side", ["above", "below"], default="below")
        gap = quantity(rd, t, where, "gap", "length", check=positive, what="gap between conductor and electrode")
        a, b = span(rd, t, where, "x", x0, x1)
        c, d = span(rd, t, where, "y", y0, y1)
        for prev in out:
            if prev.side == side and a < prev.x1 and prev.x0 < b and c < prev.y1 and prev.y0 < d:
                raise rd.fail(
                    f"{where}.x",
                    f"electrode {name!r} overlaps {prev.name!r} on the same side ({side})",
                    "make the rectangles disjoint or merge them",
                )
        out.append(RectElectrode(name, side, gap, a, b, c, d, *read_dielectric(rd, t, where, gap)))
    if not out:
        raise rd.fail("[[electrodes]]", "no electrodes", "add at least one [[electrodes]] table")
    return tuple(out)


# ---------------------------------------------------------------- comb-finger arrays (proof masses)

COMB_KINDS = ("lateral_comb", "transverse_comb")
COMB_KEYS = [
    "name",
    "kind",
    "orientation",
    "fingers",
    "width",
    "gap",
    "length",
    "overlap",
    "thickness",
    "side",
    "anti_gap",
    "pitch",
    "center",
    "root",
    "substrate_gap",
]


@dataclass(frozen=True)
class CombElectrode:
    """A fixed comb interdigitated with `fingers` moving fingers of the proof mass.

    Fingers run along `orientation` ("x" or "y"); `center` is the middle of the overlap region at
    rest. The fixed comb's base lies at the `root` end ("+" or "-" along the fingers): moving toward
    it deepens the overlap (`overlap` at rest, at most `length`, the finger length). A lateral comb
    faces each moving finger on both sides at `gap` (C grows with the overlap); a transverse comb
    faces it on `side` ("+" or "-" across the fingers) at `gap`, and on the other side at `anti_gap`
    if given (0: that side belongs to another electrode, e.g. the differential partner)."""

    name: str
    kind: str
    orientation: str
    fingers: int
    width: float
    gap: float
    length: float
    overlap: float
    thickness: float
    side: str
    root: str
    anti_gap: float
    pitch: float
    center: tuple[float, float]
    substrate_gap: float

    def electrode_names(self) -> list[str]:
        return [self.name]


def sign_key(rd: Reader, t: dict, where: str, key: str, default: str | None) -> str:
    """A "+" / "-" key (accepting "+x" style with the axis letter)."""
    raw = t.get(key, default)
    value = raw[0] if isinstance(raw, str) and raw[:1] in "+-" and len(raw) <= 2 else None
    if value is None:
        raise rd.fail(
            f"{where}.{key}",
            f'{key} = {raw!r} is not "+" or "-"',
            f'write {key} = "+" (or "-"): the direction along/across the fingers',
        )
    return value


def point(rd: Reader, t: dict, where: str, key: str) -> tuple[float, float]:
    """center = [x, y] (lengths)."""
    raw = t.get(key)
    fix = f'write {key} = ["0 um", "150 um"]'
    if not isinstance(raw, list) or len(raw) != 2:
        raise rd.fail(f"{where}.{key}", f"{key} must be an [x, y] pair", fix)
    try:
        return parse_quantity(raw[0], "length"), parse_quantity(raw[1], "length")
    except UnitError as exc:
        raise rd.fail(f"{where}.{key}", str(exc), fix) from None


def comb(rd: Reader, t: dict, where: str, name: str, kind: str, thickness: float) -> CombElectrode:
    """One comb electrode's table (keys COMB_KEYS)."""
    check_keys(rd, where, t, COMB_KEYS)
    q = lambda key, what, default=None, check=positive: quantity(rd, t, where, key, "length", default, check, what)  # noqa: E731
    orientation = choice(rd, t, where, "orientation", ["x", "y"], default=None)
    fingers = integer(rd, t, where, "fingers", None, 1, 10000, "number of moving fingers in the array")
    width, gap = q("width", "finger width"), q("gap", "finger gap")
    length, overlap = q("length", "finger length"), q("overlap", "finger overlap at rest")
    if overlap >= length:
        raise rd.fail(
            f"{where}.overlap",
            f"overlap {overlap:g} m is not shorter than the finger length {length:g} m",
            "the fingers must not bottom out at rest: give overlap < length",
        )
    lateral = kind == "lateral_comb"
    anti = 0.0 if lateral else q("anti_gap", "gap on the far side of each moving finger (0: none)", 0.0, nonnegative)
    if lateral and "anti_gap" in t:
        raise rd.fail(
            f"{where}.anti_gap",
            "a lateral comb faces each finger on both sides at `gap`",
            'remove anti_gap (or use kind = "transverse_comb")',
        )
    if anti and anti <= gap:
        raise rd.fail(
            f"{where}.anti_gap",
            f"anti_gap {anti:g} m is not larger than gap {gap:g} m",
            "give the far gap larger than the sensing gap, or 0 for none",
        )
    side = "+" if lateral else sign_key(rd, t, where, "side", None)
    root = sign_key(rd, t, where, "side" if lateral else "root", "+" if not lateral else None)
    default_pitch = 2 * (width + gap) if lateral else (2 * width + gap + anti if anti else 3 * (width + gap))
    pitch = q("pitch", "finger pitch (moving finger to moving finger)", default_pitch)
    if pitch < 2 * width + gap:
        raise rd.fail(
            f"{where}.pitch",
            f"pitch {pitch:g} m leaves no room for the fixed fingers",
            f"give pitch >= 2 width + gap = {2 * width + gap:g} m",
        )
    return CombElectrode(
        name,
        kind,
        orientation,
        fingers,
        width,
        gap,
        length,
        overlap,
        q("thickness", "finger thickness", thickness),
        side,
        root,
        anti,
        pitch,
        point(rd, t, where, "center"),
        q("substrate_gap", "finger bottom to substrate", 0.0, nonnegative),
    )


def rectangle_table(
    rd: Reader, t: dict, where: str, name: str, outline: tuple[float, float, float, float], out: list
) -> RectElectrode:
    """One rectangular plate electrode's table, refused if it overlaps an earlier one on its side."""
    x0, x1, y0, y1 = outline
    check_keys(rd, where, t, ["name", "kind", "side", "gap", "x", "y", *DIELECTRIC_KEYS])
    side = choice(rd, t, where, "side", ["above", "below"], default="below")
    gap = quantity(rd, t, where, "gap", "length", check=positive, what="gap between conductor and electrode")
    a, b = span(rd, t, where, "x", x0, x1)
    c, d = span(rd, t, where, "y", y0, y1)
    for prev in out:
        if (
            isinstance(prev, RectElectrode)
            and prev.side == side
            and a < prev.x1
            and prev.x0 < b
            and c < prev.y1
            and prev.y0 < d
        ):
            raise rd.fail(
                f"{where}.x",
                f"electrode {name!r} overlaps {prev.name!r} on the same side ({side})",
                "make the rectangles disjoint or merge them",
            )
    return RectElectrode(name, side, gap, a, b, c, d, *read_dielectric(rd, t, where, gap))


def plates_and_combs(rd: Reader, doc: dict, outline: tuple[float, float, float, float], thickness: float) -> tuple:
    """[[electrodes]] of a proof mass: plates over the substrate (kind = "plate", the default) and
    comb arrays (kind = "lateral_comb" / "transverse_comb")."""
    raw = electrode_tables(
        rd, doc, "missing electrodes", "add [[electrodes]] tables (see examples/accelerometer_xyz.toml)", "electrode"
    )
    out: list[RectElectrode | CombElectrode] = []
    names: set[str] = set()
    for i, t in enumerate(raw):
        where = f"electrodes[{i}]"
        name = unique_name(
            rd,
            t,
            where,
            names,
            "electrode",
            "electrode",
            'use letters, digits and _ (starting with a letter), e.g. name = "xp"; '
            "avoid 'plate' and the word 'error'",
            forbidden=("plate",),
        )
        kind = choice(rd, t, where, "kind", ["plate", *COMB_KINDS], default="plate")
        out.append(
            rectangle_table(rd, t, where, name, outline, out)
            if kind == "plate"
            else comb(rd, t, where, name, kind, thickness)
        )
    if not out:
        raise rd.fail("[[electrodes]]", "no electrodes", "add at least one [[electrodes]] table")
    return tuple(out)
