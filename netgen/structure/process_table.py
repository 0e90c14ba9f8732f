"""The optional [process] table: which process instance parameters the emitted .lib carries
(netgen.model.process derives their laws), their valid ranges and the modulus' temperature
coefficient. Without the table no law is derived and every emitted file is what it was before."""

from __future__ import annotations

from typing import Any

from ..core.reader import Reader, check_keys, quantity, table
from ..core.units import UnitError, parse_quantity
from .schema import ALL_PROCESS_PARAMETERS, PROCESS_PARAMETERS, Process

KEYS = ["parameters", "tscale_range", "escale_range", "temp_range", "modulus_tc", "etch_range", "cavity"]
CAVITIES = ("open", "sealed")  # the film's gas under temp: fixed pressure, or a fixed amount (p ~ T)
ETCH_LIMIT = 5e-6  # m: the widest lateral etch bias per edge read (the flexure widths bound it further)
ETCH_TYPES = ("folded", "crab_leg", "clamped_guided")  # flexures with beam widths the etch narrows
BEAM_KINDS = ("cantilever", "clamped_clamped_beam")  # beam conductors: the etch narrows the beam itself
PLATE_KINDS = ("piston", "free_disk")  # plates: the etch recedes the outline (sides - 2 etch, radius - etch)
# the widest ranges the laws are offered for: thickness and modulus factors around 1, the die
# temperature between liquid nitrogen and a solder reflow (the gas laws' and the modulus' validity)
LIMITS = {"tscale": (0.5, 1.5), "escale": (0.2, 3.0), "temp": (-200.0, 300.0)}
GAP_SIDES = ("above", "below")


def read_process(rd: Reader, doc: dict) -> Process | None:
    """The [process] table as a Process; None when the file has none (no process parameters)."""
    if "process" not in doc:
        return None
    t = table(rd, doc, "process", required=False)
    check_keys(rd, "process", t, KEYS)
    params = read_parameters(rd, t)
    ranges = {name: read_range(rd, t, name, params) for name in LIMITS}
    tc = quantity(
        rd,
        t,
        "process",
        "modulus_tc",
        "dimensionless",
        Process.modulus_tc,
        lambda v: None if abs(v) < 1e-3 else "is not a modulus temperature coefficient (|tc| < 1e-3 per K)",
        "d ln E / dT in 1/K (silicon -60e-6)",
    )
    etch = read_etch_range(rd, t, params)
    return Process(params, ranges["tscale"], ranges["escale"], ranges["temp"], tc, etch, read_cavity(rd, t, params))


def read_cavity(rd: Reader, t: dict, params: tuple[str, ...]) -> str:
    """process.cavity: "open" (the film's gas at a fixed pressure as temp moves, the default) or
    "sealed" (a fixed amount of gas: p = p0 T / T0); only with temp declared."""
    where, fix = "process.cavity", 'write cavity = "open" (fixed pressure) or "sealed" (fixed gas amount, p ~ T)'
    if "cavity" not in t:
        return Process.cavity
    if "temp" not in params:
        raise rd.fail(where, "cavity is given but 'temp' is not in process.parameters", "add 'temp' or drop cavity")
    value = t["cavity"]
    if value not in CAVITIES:
        raise rd.fail(where, f"cavity must be one of {list(CAVITIES)}, got {value!r}", fix)
    return value


def read_parameters(rd: Reader, t: dict) -> tuple[str, ...]:
    """process.parameters: a non-empty list of distinct names from ALL_PROCESS_PARAMETERS (default
    PROCESS_PARAMETERS: etch only by name)."""
    fix = f"write parameters = {list(PROCESS_PARAMETERS)} or a subset of it".replace("'", '"')
    value: Any = t.get("parameters", list(PROCESS_PARAMETERS))
    if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
        raise rd.fail("process.parameters", f"parameters must be a non-empty list of names, got {value!r}", fix)
    for v in value:
        if v not in ALL_PROCESS_PARAMETERS:
            raise rd.fail("process.parameters", f"unknown process parameter {v!r}", fix)
    if len(set(value)) != len(value):
        raise rd.fail("process.parameters", "a parameter is listed twice", "list each parameter once")
    return tuple(value)


def read_range(rd: Reader, t: dict, name: str, params: tuple[str, ...]) -> tuple[float, float]:
    """process.<name>_range: [lo, hi] within LIMITS[name], around the nominal (1, or 25 degC for temp
    is not required: the structure's temperature is checked by check_process)."""
    key, default = f"{name}_range", getattr(Process, f"{name}_range")
    where = f"process.{key}"
    if key not in t:
        return default
    if name not in params:
        raise rd.fail(where, f"{key} is given but {name!r} is not in process.parameters", f"add {name!r} or drop {key}")
    value = t[key]
    lo_lim, hi_lim = LIMITS[name]
    fix = f"write {key} = [lo, hi] with {lo_lim:g} <= lo < hi <= {hi_lim:g}" + (" (degC)" if name == "temp" else "")
    ok = isinstance(value, list) and len(value) == 2
    if not ok or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value):
        raise rd.fail(where, f"{key} must be a list of two numbers, got {value!r}", fix)
    lo, hi = float(value[0]), float(value[1])
    if not lo_lim <= lo < hi <= hi_lim:
        raise rd.fail(where, f"{key} = {value!r} is not an increasing range within {lo_lim:g}..{hi_lim:g}", fix)
    if name != "temp" and not lo < 1.0 < hi:
        raise rd.fail(where, f"{key} = {value!r} does not contain the nominal 1", f"{fix}, lo < 1 < hi")
    return lo, hi


def read_etch_range(rd: Reader, t: dict, params: tuple[str, ...]) -> tuple[float, float]:
    """process.etch_range: [lo, hi] lengths (m or with units) around the nominal 0, within +-ETCH_LIMIT."""
    where, default = "process.etch_range", Process.etch_range
    if "etch_range" not in t:
        return default
    if "etch" not in params:
        raise rd.fail(
            where, "etch_range is given but 'etch' is not in process.parameters", "add 'etch' or drop etch_range"
        )
    value = t["etch_range"]
    fix = 'write etch_range = ["-0.1 um", "0.1 um"] (over-etch per edge, lo < 0 < hi)'
    try:
        lo, hi = (parse_quantity(v, "length") for v in value) if isinstance(value, list) and len(value) == 2 else (0, 0)
    except UnitError as exc:
        raise rd.fail(where, str(exc), fix) from None
    if not -ETCH_LIMIT <= lo < 0.0 < hi <= ETCH_LIMIT:
        raise rd.fail(where, f"etch_range = {value!r} is not a range lo < 0 < hi within +-{ETCH_LIMIT:g} m", fix)
    return lo, hi


def check_etch(rd: Reader, p: Process, conductor: Any, sets: tuple) -> None:
    """etch narrows a beam conductor (check_beam_etch) or a proof mass's flexure beams (w - 2 etch) and
    comb fingers and widens its etch holes: it needs such flexures, every beam and finger keeping more
    than half its width at the range's top and holes that neither close nor merge over the range;
    a plate (piston, free disk) as check_plate_etch."""
    where = "process.parameters"
    kind = getattr(conductor, "kind", "")
    if kind in BEAM_KINDS:
        check_beam_etch(rd, p, conductor)
        return
    if kind in PLATE_KINDS:
        check_plate_etch(rd, p, conductor, sets)
        return
    flex = getattr(conductor, "flexure", None)
    if kind != "proof_mass" or flex is None or flex.type not in ETCH_TYPES:
        raise rd.fail(
            where,
            f"etch narrows beams and recedes outlines: it needs a {', '.join(BEAM_KINDS + PLATE_KINDS)} "
            f"conductor or a proof mass with a flexure of type {', '.join(ETCH_TYPES)}",
            "remove 'etch' from process.parameters",
        )
    for e in sets:
        if getattr(e, "kind", "") in ("lateral_comb", "transverse_comb") and 2 * p.etch_range[1] >= 0.5 * e.width:
            raise rd.fail(
                "process.etch_range",
                f"an over-etch of {p.etch_range[1]:g} m per edge removes half or more of comb {e.name}'s fingers "
                f"({e.width:g} m wide)",
                "narrow etch_range (its top below a quarter of the narrowest finger)",
            )
    hole, pitch = getattr(conductor, "hole", 0.0), getattr(conductor, "hole_pitch", 0.0)
    if hole and not (hole + 2 * p.etch_range[0] > 0.0 and hole + 2 * p.etch_range[1] < pitch):
        raise rd.fail(
            "process.etch_range",
            f"the etch holes (side {hole:g} m + 2 etch, pitch {pitch:g} m) close or merge within etch_range",
            "narrow etch_range (hole + 2 lo > 0 and hole + 2 hi < hole_pitch)",
        )
    widths = [w for w in (flex.width, flex.truss_width, flex.thigh_width) if w]
    if 2 * p.etch_range[1] >= 0.5 * min(widths):
        raise rd.fail(
            "process.etch_range",
            f"an over-etch of {p.etch_range[1]:g} m per edge removes half or more of the narrowest beam ({min(widths):g} m)",
            "narrow etch_range (its top below a quarter of the narrowest flexure width)",
        )


def check_beam_etch(rd: Reader, p: Process, beam: Any) -> None:
    """A beam conductor's etch (netgen.model.process.etched_beam: width w - 2 etch, a cantilever's tip
    back by etch) keeps more than half its width at the range's top."""
    if 2 * p.etch_range[1] >= 0.5 * beam.width:
        raise rd.fail(
            "process.etch_range",
            f"an over-etch of {p.etch_range[1]:g} m per edge removes half or more of the beam ({beam.width:g} m wide)",
            "narrow etch_range (its top below a quarter of the beam's width)",
        )


def check_plate_etch(rd: Reader, p: Process, plate: Any, sets: tuple) -> None:
    """A plate's etch (netgen.model.etch_geometry.etched_plate: a piston's sides - 2 etch, a free disk's
    radius - etch) keeps more than half its narrower side or diameter at the range's top, and every
    electrode keeps an overlap with the etched plate over the range (an edge drawn on the plate's moves
    with it; the plate's edge must not pass an electrode's far edge)."""
    hi, where = p.etch_range[1], "process.etch_range"
    size = min(plate.length, plate.width) if plate.kind == "piston" else 2 * plate.radius
    if 2 * hi >= 0.5 * size:
        what = "narrower side" if plate.kind == "piston" else "diameter"
        raise rd.fail(
            where,
            f"an over-etch of {hi:g} m per edge removes half or more of the plate's {what} ({size:g} m)",
            f"narrow etch_range (its top below a quarter of the plate's {what})",
        )
    for e in sets:
        if plate.kind == "piston":
            reach = min(plate.length / 2 - hi - max(e.x0, -e.x1), plate.width / 2 - hi - max(e.y0, -e.y1))
        else:
            reach = plate.radius - hi - e.rings[-1][0]  # each ring is its own electrodes
        if reach <= 0.0:
            raise rd.fail(
                where,
                f"at an over-etch of {hi:g} m per edge the plate's edge passes electrode {e.name!r}'s far edge: "
                "its overlap with the plate vanishes",
                f"narrow etch_range (its top below {hi + reach:g} m) or draw {e.name!r} farther inside the plate",
            )


def check_process(
    rd: Reader,
    p: Process | None,
    names: list[str],
    sets: tuple,
    imported: bool,
    t0_c: float,
    conductor: Any = None,
    film_model: str = "incompressible",
) -> None:
    """The declared parameters against the structure: dg needs a coordinate z and a plate set
    above/below (the offset is a shift of z); tscale, escale and temp need mechanics netgen can re-run
    (tscale and etch together: netgen.model.etch_cross.cross_capacitance checks and corrects their product);
    temp's range contains the structure's own temperature (the laws' nominal point); a sealed cavity
    has the incompressible film (the compressible film's gas spring ~ p would follow T too), and so
    does a plate under etch (the compressible branches would keep the drawn outline)."""
    if p is None:
        return
    where = "process.parameters"
    if p.wants("dg") and ("z" not in names or not any(getattr(s, "side", None) in GAP_SIDES for s in sets)):
        raise rd.fail(
            where,
            "dg needs the coordinate z and an electrode set above or below the conductor (a gap offset is a shift of z)",
            "remove 'dg' from process.parameters, or add z to [coordinates] rigid",
        )
    moved = [n for n in ("tscale", "escale", "temp", "etch") if p.wants(n)]
    if imported and moved:
        raise rd.fail(
            where,
            f"{', '.join(moved)} with imported mechanics: netgen cannot re-run them at another thickness or modulus",
            "remove them from process.parameters (dg stays exact) or describe the flexures in the structure file",
        )
    if p.wants("etch"):
        check_etch(rd, p, conductor, sets)
    if p.wants("etch") and getattr(conductor, "kind", "") in PLATE_KINDS and film_model == "compressible":
        raise rd.fail(
            where,
            "etch on a plate with the compressible film: its branches (dampers ~ R^4, corner frequencies "
            "~ 1 / R^2 on a disk) would stay the drawn plate's, not modelled",
            'use [damping] film_model = "incompressible" (its damping follows the etched plate) or drop etch',
        )
    if p.cavity == "sealed" and film_model == "compressible":
        raise rd.fail(
            "process.cavity",
            "a sealed cavity with the compressible film: its branches' gas springs (~ p) would follow T, not modelled",
            'drop cavity (an open cavity) or use [damping] film_model = "incompressible"',
        )
    if p.wants("temp") and not p.temp_range[0] <= t0_c <= p.temp_range[1]:
        raise rd.fail(
            "process.temp_range",
            f"temp_range {list(p.temp_range)} degC does not contain the structure's temperature {t0_c:.6g} degC",
            "widen temp_range or set [damping] temperature inside it",
        )
