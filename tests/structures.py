"""Structure-file text the tests share: the head of a silicon disk's file (name, description,
[conductor]) and its ring electrodes, which several tests put under their own coordinates,
sampling, fit and damping tables. Each test still writes the tables its assertions are about;
only the material and the table layout live here."""

from __future__ import annotations

# single-crystal silicon as every disk test uses it
SILICON = {"youngs_modulus": "160 GPa", "poisson_ratio": 0.22, "density": "2330 kg/m^3"}


def toml_value(value: object) -> str:
    """A TOML value: strings quoted, numbers as written, lists of strings as TOML arrays."""
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    return repr(value)


def table(header: str, entries: dict) -> str:
    """One TOML table (or array-of-tables entry) with its entries in the given order."""
    return "\n".join([header] + [f"{key} = {toml_value(v)}" for key, v in entries.items()]) + "\n"


def disk(name: str, description: str, radius: str, thickness: str = "5 um", kind: str | None = "free_disk") -> str:
    """The start of a disk's structure file: name, description and its silicon [conductor] table."""
    conductor = ({"kind": kind} if kind else {}) | {"radius": radius, "thickness": thickness} | SILICON
    return f'name = "{name}"\ndescription = "{description}"\n' + table("[conductor]", conductor)


def ring_electrode(name: str, side: str, gap: str, rings: list[tuple[str, str]], sectors: int = 1, **more: str) -> str:
    """One [[electrodes]] entry: `sectors` sectors over the rings (inner, outer radius), then any
    further keys (sector_start, slot, ...)."""
    return table(
        "[[electrodes]]",
        {"name": name, "side": side, "gap": gap, "rings": [list(r) for r in rings], "sectors": sectors} | more,
    )


def plate_electrode(name: str, side: str, gap: str, x: tuple[str, str], y: tuple[str, str]) -> str:
    """One rectangular `kind = "plate"` [[electrodes]] entry over x = [x0, x1], y = [y0, y1]."""
    return table(
        "[[electrodes]]", {"name": name, "kind": "plate", "side": side, "gap": gap, "x": list(x), "y": list(y)}
    )


ONE_PLATE_RADIUS, ONE_PLATE_GAP = 300e-6, 3e-6  # m: the disk of one_plate_disk and its gap


def one_plate_disk(name: str, description: str) -> str:
    """A rigid free disk (ONE_PLATE_RADIUS, 5 um thick) ONE_PLATE_GAP above one electrode "bot" under
    all of it, coordinates z, tilt_x and tilt_y, no fringe field: the parallel-plate closed forms
    hold. The test adds its own [sampling] and [fit] tables."""
    return (
        disk(name, description, "300 um")
        + ring_electrode("bot", "below", "3 um", [("0 um", "300 um")])
        + table("[coordinates]", {"rigid": ["z", "tilt_x", "tilt_y"]})
        + table("[electrostatics]", {"fringe": "none"})
    )


# a 200 um square silicon piston over one electrode of its size, 2 um below, on z and both tilts;
# the tests add their own [sampling], [fit] and [electrostatics] tables
PISTON_3 = """
name = "piston3"
[conductor]
kind = "piston"
length = "200 um"
thickness = "2 um"
density = "2330 kg/m^3"
stiffness = 2.0
tilt_stiffness = 1e-7
[[electrodes]]
name = "drive"
side = "below"
gap = "2 um"
[coordinates]
rigid = ["z", "tilt_x", "tilt_y"]
"""
