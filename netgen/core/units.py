"""Physical quantities in structure files: plain SI numbers or strings such as "473 um"."""

from __future__ import annotations

import math
import re

from .constants import G

# quantity kind -> {unit spelling: factor to SI}
UNITS: dict[str, dict[str, float]] = {
    "length": {"m": 1.0, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "nm": 1e-9},
    "modulus": {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6, "GPa": 1e9},
    "density": {"kg/m^3": 1.0, "kg/m3": 1.0, "g/cm^3": 1e3, "g/cm3": 1e3},
    "angle": {"rad": 1.0, "deg": math.pi / 180.0},
    "voltage": {"V": 1.0, "mV": 1e-3},
    "frequency": {"Hz": 1.0, "kHz": 1e3, "MHz": 1e6},
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9, "min": 60.0, "h": 3600.0},
    "pressure": {
        "Pa": 1.0,
        "kPa": 1e3,
        "mbar": 100.0,
        "bar": 1e5,
        "mTorr": 101325.0 / 760e3,
        "Torr": 101325.0 / 760,
        "atm": 101325.0,
    },
    "temperature": {"K": 1.0},
    "dimensionless": {"": 1.0},
    "acceleration": {"m/s^2": 1.0, "m/s2": 1.0, "g": G},
    "stiffness": {"N/m": 1.0, "mN/m": 1e-3, "uN/m": 1e-6, "kN/m": 1e3},
    "torsional stiffness": {"N*m/rad": 1.0, "N m/rad": 1.0, "Nm/rad": 1.0, "uN*m/rad": 1e-6, "nN*m/rad": 1e-9},
}

# the physical range of each kind (SI): a nonzero magnitude outside [low, high] is a typo or a
# unit mistake (a 1e300 m plate, a 1e-300 m gap), refused by parse_quantity before any physics
# sees it; the sign and zero are left to each key's own check (docs/structure-files.md, Limits)
RANGES: dict[str, tuple[float, float]] = {
    "length": (1e-12, 10.0),
    "modulus": (1e3, 1e13),
    "density": (1e-3, 1e5),
    "angle": (1e-12, 4 * math.pi),
    "voltage": (1e-12, 1e6),
    "frequency": (1e-6, 1e13),
    "time": (1e-18, 1e7),
    "pressure": (1e-9, 1e10),
    "temperature": (1e-3, 1e5),
    "dimensionless": (0.0, math.inf),  # each key checks its own range
    "acceleration": (1e-12, 1e9),
    "stiffness": (1e-12, 1e12),
    "torsional stiffness": (1e-24, 1e6),
}

SI_NAME = {
    "length": "m",
    "modulus": "Pa",
    "density": "kg/m^3",
    "angle": "rad",
    "voltage": "V",
    "frequency": "Hz",
    "time": "s",
    "pressure": "Pa",
    "temperature": "K",
    "dimensionless": "",
    "acceleration": "m/s^2",
    "stiffness": "N/m",
    "torsional stiffness": "N*m/rad",
}

_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(\S*(?: m/rad)?)\s*$")


class UnitError(ValueError):
    """A quantity that cannot be read as the expected kind; the message says what is accepted."""


def parse_quantity(value: object, kind: str) -> float:
    """Return `value` in SI units; numbers are taken as SI, strings carry a unit of `kind`."""
    if isinstance(value, bool):
        raise UnitError(f"expected a number or a quantity string, got {value!r}")
    if isinstance(value, (int, float)):
        return in_range(float(value), kind, repr(value))
    if not isinstance(value, str):
        raise UnitError(
            f"expected a number or a quantity string such as '{example(kind)}', got {type(value).__name__} {value!r}"
        )
    match = _QUANTITY.match(value)
    if not match:
        raise UnitError(f"cannot read {value!r} as a number with a unit (e.g. '{example(kind)}')")
    number, unit = match.groups()
    table = UNITS[kind]
    if unit not in table:
        accepted = ", ".join(u for u in table if u) or "no unit"
        raise UnitError(f"unit {unit!r} is not a {kind} unit (accepted: {accepted})")
    return in_range(float(number) * table[unit], kind, repr(value))


def in_range(value: float, kind: str, shown: str) -> float:
    """`value` (SI), refused when its nonzero magnitude lies outside RANGES[kind] (see there)."""
    low, high = RANGES[kind]
    if value != 0 and math.isfinite(value) and not low <= abs(value) <= high:
        unit = SI_NAME[kind]
        raise UnitError(
            f"{shown} = {value:g} {unit} is outside the physical range of a {kind}, "
            f"{low:g} to {high:g} {unit} in magnitude (is the unit right?)".replace("  ", " ")
        )
    return value


def example(kind: str) -> str:
    """A short example quantity string for error messages."""
    return {
        "length": "473 um",
        "modulus": "160 GPa",
        "density": "2330 kg/m^3",
        "angle": "45 deg",
        "voltage": "5 V",
        "frequency": "100 kHz",
        "time": "1 us",
        "pressure": "1 Pa",
        "temperature": "300 K",
        "dimensionless": "0.22",
        "acceleration": "9.81 m/s^2",
        "stiffness": "2 N/m",
        "torsional stiffness": "1e-7 N*m/rad",
    }[kind]
