"""The loop description: a `[loop]` table in the structure file or in `--loop LOOP.toml`, read
into a LoopSpec with errors that name the file, the key, the problem and the fix (LoopError,
exit 2). Only the form is checked here; the names (channels, electrodes) and whether the
feedback can balance the input are checked against the model in loop.design().

    [loop]
    channels = ["z"]                 # any subset of the model's coordinates (default: below)
    feedback_voltage = "3 V"         # default: the DC input needs a mean bit of `density`
    sense_ratio = 0.25               # V_s / V_fb
    full_scale = 0.01                # readout: this fraction of the touch amplitude reads 1 V
    density = 0.5                    # mean bit the DC input needs when V_fb is derived
    dither = 0.2                     # comparator dither, a fraction of a_fb T_s^2
    readout = "charge_amplifier"     # the switched-capacitor charge amplifier (the only one)
    [loop.filter]                    # every channel's loop filter (FILTERS in loop.py)
    kind = "lead2"
    lead = 0.8
    [loop.timing]                    # netgen.testbench.sigma_delta.loop.Timing fields (fractions of T_s)
    cur = 0.28
    [loop.input]                     # default: gravity (a_in = g if the model has a_in, else -m g on f_z)
    acceleration = "9.81 m/s^2"      # DC frame acceleration through a_in (0 = none)
    tone = { amplitude = "2 m/s^2", frequency = "1 kHz" }            # on a_in
    # or a generalized force on a coordinate, in its f_ port unit (uN, nN*m):
    # force = { coordinate = "z", dc = 0.0, amplitude = 0.02, frequency = "2 kHz" }
    # or several, one per coordinate, at most one with a tone:
    # force = [{ coordinate = "z", dc = -0.16 }, { coordinate = "tilt_x", dc = 4e-6 }]
    [loop.channels.z]                # per channel (optional): explicit electrodes, filter
    sense = { top = 1, bottom = -1 }      # readout weight per electrode
    feedback = { top = 1, bottom = -1 }   # +1: energised when the bit is 1, -1: when it is 0
    filter = { kind = "lead2", lead = 0.8 }
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from pathlib import Path

from ...core.errors import LoopError
from ...core.files import read_text, toml_document
from ...core.options import Option, OptionError, Record
from ...core.reader import Reader, check_keys, choice
from ...core.text import escape, is_identifier, text_problem
from ...core.units import UnitError, parse_quantity
from .kinds import FILTERS
from .options import LOOP_SETTINGS, OPTIONS
from .signals import Timing, Tone

# the [loop] keys that are tables or names; the others are declared options (LoopSettings)
STRUCTURE_KEYS = ["channels", "readout", "filter", "timing", "input"]
CHANNEL_KEYS = ["sense", "feedback", "filter"]
INPUT_KEYS = ["acceleration", "tone", "force", "gravity"]
READOUTS = ["charge_amplifier"]
MAX_CHANNELS = 6  # 2^6 feedback patterns in the force table
FIX = "see the [loop] reference in docs/sigma-delta.md"


class LoopSettings(Record):
    """The top-level [loop] keys that are declared options (options.LOOP_SETTINGS: one range each,
    shared with their flags and sweep parameters), one attribute each (None: not in the file)."""

    declared = LOOP_SETTINGS


def loop_keys() -> list[str]:
    """Every key a [loop] table may hold."""
    return STRUCTURE_KEYS + list(LoopSettings.declared)


@dataclass(frozen=True)
class InputSpec:
    """The loop's mechanical input: DC values per input port (f_<q> in its port unit, a_in in
    m/s^2) and an optional tone; `default` when the file gave none (gravity, derived in design)."""

    dc: dict[str, float] = field(default_factory=dict)
    tone: object = None  # a loop.Tone (coord "a_in" for the frame acceleration)
    default: bool = True


@dataclass(frozen=True)
class ChannelSpec:
    """One channel as written: its coordinate and, optionally, explicit sense weights and
    feedback pattern per electrode and its loop filter."""

    name: str
    sense: dict[str, float] | None = None
    feedback: dict[str, int] | None = None
    filter: dict | None = None


@dataclass(frozen=True)
class LoopSpec:
    """A validated loop description (every field None = derived from the model); `settings`: the
    values of the declared [loop] options (feedback_voltage, density, ...)."""

    source: str = "<defaults>"
    channels: tuple[ChannelSpec, ...] | None = None
    settings: LoopSettings = LoopSettings()
    readout: str = "charge_amplifier"
    filter: dict | None = None
    timing: dict[str, float] = field(default_factory=dict)
    input: InputSpec = field(default_factory=InputSpec)

    def fail(self, where: str, problem: str, fix: str) -> LoopError:
        """An error against this description's file (used by the design's model checks)."""
        return LoopError(self.source, where, problem, fix)


def read_loop_file(path: str | Path) -> LoopSpec:
    """`--loop LOOP.toml`: a file with one [loop] table (the same text as in a structure file)."""
    shown = escape(str(path))
    text = read_text(path, "file", "loop description", LoopError)
    doc = toml_document(text, shown, LoopError, "fix the TOML syntax at that line (" + FIX + ")")
    rd = Reader(shown, text, LoopError)
    check_keys(rd, "", doc, ["loop"])
    if "loop" not in doc:
        raise rd.fail("[loop]", "missing table", "write the loop description as a [loop] table (" + FIX + ")")
    return read_loop(rd, doc["loop"])


def read_structure_loop(path: str | Path) -> LoopSpec:
    """The structure file's [loop] table (the defaults if it has none)."""
    shown = escape(str(path))
    text = read_text(path, "file", "structure file", LoopError)
    doc = toml_document(text, shown, LoopError)
    if "loop" not in doc:
        return LoopSpec(source=shown)
    return read_loop(Reader(shown, text, LoopError), doc["loop"])


def read_loop(rd: Reader, t: object) -> LoopSpec:
    """Validate a [loop] table's form into a LoopSpec."""
    if not isinstance(t, dict):
        raise rd.fail("loop", f"'loop' must be a table, got {type(t).__name__}", "write it as a [loop] section")
    check_keys(rd, "loop", t, loop_keys())
    settings = LoopSettings(
        **{k: option(rd, t, "loop", o.loop_key, k, declared=o) for k, o in LoopSettings.declared.items()}
    )
    return LoopSpec(
        source=rd.path,
        channels=read_channels(rd, t),
        settings=settings,
        readout=choice(rd, t, "loop", "readout", READOUTS, "charge_amplifier"),
        filter=read_filter(rd, t, "loop.filter") if "filter" in t else None,
        timing=read_timing(rd, t),
        input=read_input(rd, t),
    )


def subtable(rd: Reader, t: dict, where: str, key: str) -> dict:
    """t[key] as a table, or the error naming it."""
    value = t[key]
    if not isinstance(value, dict):
        raise rd.fail(
            f"{where}.{key}",
            f"'{key}' must be a table, got {type(value).__name__}",
            f"write it as [{where}.{key}] or {key} = {{ ... }} ({FIX})",
        )
    return value


def name(rd: Reader, where: str, value: object, what: str) -> str:
    """A coordinate or electrode name as written: an identifier (it is matched against the model's
    names, which are identifiers; anything else cannot be one of them)."""
    if not is_identifier(value):
        shown = text_problem(value) or f"{escape(str(value))!r} is not a name (letters, digits, _)"
        raise rd.fail(where, f"{what} {shown}", f"give the {what} as it is named in the model")
    return value


def option(
    rd: Reader, t: dict, where: str, key: str, name: str, required: bool = False, declared: Option | None = None
) -> object:
    """t[key] through its declared option's check (`declared`, else options.OPTIONS[name]: the range
    the flag and the sweep parameter share), None if absent; else the error naming the key."""
    o = declared or OPTIONS[name]
    if key not in t:
        if required:
            raise rd.fail(f"{where}.{key}", f"missing required key '{key}'", f"add {key} ({o.fix(key)})")
        return None
    try:
        return o.read(t[key], f"{where}.{key}")
    except OptionError as exc:
        raise rd.fail(f"{where}.{key}", escape(exc.problem), f"{exc.fix} ({FIX})") from None


def number(rd: Reader, t: dict, where: str, key: str, lo: float, hi: float, text: str) -> float | None:
    """An optional plain number in (lo, hi] (None if absent)."""
    if key not in t:
        return None
    v = t[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not lo < v <= hi:
        raise rd.fail(
            f"{where}.{key}",
            f"{key} = {escape(repr(v))} must be a number {text}",
            f"write {key} = <number {text}> ({FIX})",
        )
    return float(v)


@dataclass(frozen=True)
class Bounds:
    """The range of a quantity key: its `kind` (units.UNITS), lo < v <= hi (signed: lo <= |v| <= hi),
    and the range as the message words it."""

    kind: str
    lo: float
    hi: float
    text: str
    signed: bool = False


def quantity(rd: Reader, t: dict, where: str, key: str, bounds: Bounds, required: bool = False) -> float | None:
    """An optional quantity (number in SI, or a string with a unit of bounds.kind) in its bounds."""
    kind, lo, hi, text, signed = bounds.kind, bounds.lo, bounds.hi, bounds.text, bounds.signed
    if key not in t:
        if required:
            raise rd.fail(f"{where}.{key}", f"missing required key '{key}'", f"add {key} = <{kind}> ({FIX})")
        return None
    raw = t[key]
    try:
        if isinstance(raw, bool):
            raise UnitError(f"a {kind} is a number or a string with a unit, not true/false")
        v = parse_quantity(raw, kind)
    except (UnitError, TypeError, ValueError) as exc:
        raise rd.fail(f"{where}.{key}", escape(str(exc)), f"write {key} = <{kind}> ({FIX})") from None
    ok = math.isfinite(v) and (lo <= abs(v) <= hi if signed else lo < v <= hi)
    if not ok:
        raise rd.fail(f"{where}.{key}", f"{key} = {escape(repr(raw))} must be {text}", f"give a {kind} {text}")
    return v


def read_channels(rd: Reader, t: dict) -> tuple[ChannelSpec, ...] | None:
    """channels = ["z", ...] (names) and/or [loop.channels.<q>] tables (explicit electrodes)."""
    if "channels" not in t:
        return None
    raw = t["channels"]
    if isinstance(raw, list):
        names = [name(rd, f"loop.channels[{i}]", v, "channel") for i, v in enumerate(raw)]
        specs = [ChannelSpec(n) for n in names]
    elif isinstance(raw, dict):
        specs = [read_channel(rd, name(rd, f"loop.channels.{escape(str(k))}", k, "channel"), v) for k, v in raw.items()]
    else:
        raise rd.fail(
            "loop.channels",
            f"channels must be a list of coordinate names or a table, got {type(raw).__name__}",
            f'write channels = ["z"] or [loop.channels.z] tables ({FIX})',
        )
    if not specs:
        raise rd.fail("loop.channels", "channels is empty", 'name at least one coordinate, e.g. channels = ["z"]')
    if len(specs) > MAX_CHANNELS:
        raise rd.fail(
            "loop.channels", f"{len(specs)} channels: at most {MAX_CHANNELS}", "close the loop on fewer coordinates"
        )
    seen = [s.name for s in specs]
    dup = next((n for n in seen if seen.count(n) > 1), None)
    if dup:
        raise rd.fail("loop.channels", f"channel {dup!r} is listed twice", "name each coordinate once")
    return tuple(specs)


def read_channel(rd: Reader, key: str, t: object) -> ChannelSpec:
    """One [loop.channels.<q>] table."""
    where = f"loop.channels.{key}"
    if not isinstance(t, dict):
        raise rd.fail(
            where,
            f"'{key}' must be a table, got {type(t).__name__}",
            f"write [loop.channels.{key}] with sense, feedback and filter ({FIX})",
        )
    check_keys(rd, where, t, CHANNEL_KEYS)
    sense = weights(rd, t, where, "sense", False) if "sense" in t else None
    feedback = weights(rd, t, where, "feedback", True) if "feedback" in t else None
    filt = read_filter(rd, t, f"{where}.filter") if "filter" in t else None
    return ChannelSpec(key, sense, feedback, filt)


def weights(rd: Reader, t: dict, where: str, key: str, pattern: bool) -> dict:
    """sense = {electrode = weight} (a non-zero number) or feedback = {electrode = +1 or -1}."""
    table = subtable(rd, t, where, key)
    if not table:
        raise rd.fail(f"{where}.{key}", f"{key} is empty", f"name at least one electrode ({FIX})")
    out = {}
    for el, w in table.items():
        loc = f"{where}.{key}.{escape(str(el))}"
        name(rd, loc, el, "electrode")
        if pattern:
            if isinstance(w, bool) or w not in (1, -1):
                raise rd.fail(
                    loc,
                    f"feedback {escape(repr(w))} is not +1 or -1",
                    "write +1 (energised when the channel's bit is 1: pushes towards +q) or -1",
                )
            out[el] = int(w)
        else:
            if isinstance(w, bool) or not isinstance(w, (int, float)) or not math.isfinite(w) or w == 0 or abs(w) > 1e3:
                raise rd.fail(
                    loc,
                    f"sense weight {escape(repr(w))} must be a non-zero number (|w| <= 1000)",
                    "write +1 or -1 (the sign of dC/dq), or another weight",
                )
            out[el] = int(w) if float(w).is_integer() else float(w)
    return out


def read_filter(rd: Reader, t: dict, where: str) -> dict:
    """A loop filter table: kind (a loop.FILTERS name) and that kind's coefficients."""
    where_parent, key = where.rsplit(".", 1)
    table = subtable(rd, t, where_parent, key)
    kind = choice(rd, table, where, "kind", list(FILTERS), "lead2")
    return FILTERS[kind].read(rd, where, table)


def read_timing(rd: Reader, t: dict) -> dict[str, float]:
    """[loop.timing]: Timing fields as fractions of T_s; their order is checked in design()."""
    if "timing" not in t:
        return {}
    table = subtable(rd, t, "loop", "timing")
    allowed = [f.name for f in fields(Timing)]
    check_keys(rd, "loop.timing", table, allowed)
    return {k: number(rd, table, "loop.timing", k, -0.5, 1.0, "between -0.5 and 1 (a fraction of T_s)") for k in table}


def read_input(rd: Reader, t: dict) -> InputSpec:
    """[loop.input]: DC acceleration and tone through a_in, or a force on a coordinate."""
    if "input" not in t:
        return InputSpec()
    table = subtable(rd, t, "loop", "input")
    check_keys(rd, "loop.input", table, INPUT_KEYS)
    if "force" in table and ("acceleration" in table or "tone" in table):
        raise rd.fail(
            "loop.input.force",
            "force and acceleration/tone are both given",
            "give either the acceleration input (acceleration, tone) or a force on a coordinate",
        )
    dc, tone = {}, None
    if "gravity" in table:
        if not isinstance(table["gravity"], bool):
            raise rd.fail(
                "loop.input.gravity",
                f"gravity must be true or false, got {escape(repr(table['gravity']))}",
                "write gravity = false for no gravity (the default is the model's gravity input)",
            )
        if table["gravity"] and len(table) > 1:
            raise rd.fail(
                "loop.input.gravity",
                "gravity = true is the default input; it does not combine with the other input keys",
                "drop gravity, or write acceleration = 9.81 with the tone",
            )
        if table["gravity"]:
            return InputSpec()
    if "acceleration" in table:
        dc["a_in"] = option(rd, table, "loop.input", "acceleration", "acceleration")
    if "tone" in table:
        tt = subtable(rd, table, "loop.input", "tone")
        check_keys(rd, "loop.input.tone", tt, ["amplitude", "frequency"])
        tone = Tone(
            "a_in",
            option(rd, tt, "loop.input.tone", "amplitude", "tone_acceleration", required=True),
            option(rd, tt, "loop.input.tone", "frequency", "tone_freq", required=True),
        )
    if "force" in table:
        dc, tone = read_forces(rd, table["force"])
    return InputSpec(dc, tone, default=False)


def read_forces(rd: Reader, value: object) -> tuple[dict[str, float], object]:
    """force = {...}, or a list of them on different coordinates (e.g. gravity's -m g on z and a
    small DC torque on a tilt); at most one of them carries a tone."""
    if not isinstance(value, list):
        return read_force(rd, subtable(rd, {"force": value}, "loop.input", "force"))
    if not value:
        raise rd.fail(
            "loop.input.force", "the force list is empty", 'give force = { coordinate = "z", dc = 0.1 } or drop the key'
        )
    dc, tones = {}, []
    for i, item in enumerate(value):
        where = f"loop.input.force[{i}]"
        if not isinstance(item, dict):
            raise rd.fail(
                where,
                f"each force must be a table, got {type(item).__name__}",
                'write force = [{ coordinate = "z", dc = 0.1 }, { coordinate = "tilt_x", dc = 1e-4 }]',
            )
        one, tone = read_force(rd, item, where)
        if set(one) & set(dc) or (tone is not None and any(t.coord == tone.coord for t in tones)):
            raise rd.fail(
                f"{where}.coordinate",
                f"a second force on {escape(str(item.get('coordinate')))}",
                "give each coordinate one force table",
            )
        dc.update(one)
        tones += [tone] if tone is not None else []
    if len(tones) > 1:
        raise rd.fail(
            "loop.input.force",
            f"{len(tones)} forces carry a tone; the loop takes one",
            "keep amplitude and frequency on one force and give the others dc only",
        )
    return dc, (tones[0] if tones else None)


def read_force(rd: Reader, t: dict, where: str = "loop.input.force") -> tuple[dict[str, float], object]:
    """force = {coordinate, dc, amplitude, frequency}: numbers in the coordinate's f_ port unit."""
    check_keys(rd, where, t, ["coordinate", "dc", "amplitude", "frequency"])
    if "coordinate" not in t:
        raise rd.fail(f"{where}.coordinate", "missing required key 'coordinate'", 'add coordinate = "z"')
    coord = name(rd, f"{where}.coordinate", t["coordinate"], "coordinate")
    dc = quantity(rd, t, where, "dc", Bounds("dimensionless", 0.0, 1e12, "a finite number (the f_ port unit)", True))
    amp = option(rd, t, where, "amplitude", "tone_amplitude")
    if amp is not None and "frequency" not in t:
        raise rd.fail(f"{where}.frequency", "an amplitude needs a frequency", 'add frequency = "2 kHz"')
    freq = option(rd, t, where, "frequency", "tone_freq")
    if freq is not None and amp is None:
        raise rd.fail(f"{where}.amplitude", "a frequency needs an amplitude", "add amplitude = 0.02 (f_ port unit)")
    tone = Tone(coord, amp, freq) if amp is not None else None
    return ({f"f_{coord}": dc} if dc is not None else {}), tone


def check_input_tone(spec: LoopSpec, ts: float) -> None:
    """The description's tone below f_s/2 at this T_s (the check --tone gets: options.tone_freq),
    else the LoopError naming its frequency key."""
    tone = spec.input.tone
    if tone is None:
        return
    where = "loop.input.tone.frequency" if tone.coord == "a_in" else "loop.input.force.frequency"
    try:
        OPTIONS["tone_freq"].read(tone.freq, where, {"ts": ts})
    except OptionError as exc:
        raise spec.fail(where, escape(exc.problem), f"{exc.fix}, or a shorter --ts") from None
