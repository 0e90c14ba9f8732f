"""The `[electrostatics.bem]` table: the boundary-element solver's settings (mesh levels,
quadrature, memory budget) for `extractor = "bem"` and for the BEM calibration points of
`extractor = "calibrated"`. Each key is one field of netgen.electrostatics.bem.BemSettings; this
module checks types and ranges (file, line, key and fix); the limits that depend on the solver's
quadrature rules are checked by netgen.electrostatics.bem.from_structure.
"""

from __future__ import annotations

import math

from ..core.errors import InputError
from ..core.files import did_you_mean
from ..core.reader import Reader

WHERE = "electrostatics.bem"
# key -> (kind, low, high, what): "float" in (low, high], "int" in [low, high]
KEYS: dict[str, tuple[str, float, float, str]] = {
    "element_to_gap": ("float", 0.0, 100.0, "largest element, in gaps (sets the quadrature order)"),
    "edge_to_gap": ("float", 0.0, 100.0, "element size at free edges, in gaps"),
    "growth": ("float", 1.0, 4.0, "size ratio of neighbouring elements (> 1)"),
    "refinement": ("float", 1.0, 4.0, "element size ratio between mesh levels (> 1)"),
    "levels": ("int", 2, 6, "mesh levels always solved (2 give the Richardson error estimate)"),
    "max_levels": ("int", 2, 6, "mesh levels at most"),
    "tolerance": ("float", 0.0, 1.0, "relative error estimate to reach"),
    "richardson_order": ("float", 0.0, 8.0, "convergence order assumed for the extrapolation"),
    "memory_budget_gb": ("float", 0.0, 1e4, "GB for the dense matrix of the finest level"),
    "quadrature_order": ("int", 1, 20, "regular quadrature order (default: from element_to_gap)"),
    "singular_order": ("int", 1, 20, "quadrature order of touching element pairs"),
    "element_to_size": ("float", 0.0, 1.0, "largest element, in units of the plate's size"),
}


def fail(rd: Reader, key: str | None, problem: str, fix: str, where: str = WHERE) -> InputError:
    """A StructureError at `where`[.key] (electrostatics.bem), at the key's line (else the table's header)."""
    return rd.fail(f"{where}.{key}" if key else where, problem, fix)


def read_bem(rd: Reader, t: dict, extractor: str, couplings: str | None) -> tuple[tuple[str, float | int | None], ...]:
    """The table's (key, value) pairs in the order of KEYS (absent keys keep BemSettings' defaults);
    `richardson_order = "none"` gives None; refused where no BEM solve runs."""
    if "bem" not in t:
        return ()
    table = t["bem"]
    if not isinstance(table, dict):
        raise fail(rd, None, "bem must be a table of solver settings", "write it as an [electrostatics.bem] section")
    if extractor not in ("bem", "calibrated") or couplings is not None:
        raise fail(
            rd,
            None,
            f"BEM settings, but extractor = {extractor!r}"
            + (" calibrates against a couplings file" if couplings is not None else "")
            + ": no BEM solve runs",
            'use extractor = "bem", or "calibrated" with calibration_points, or drop [electrostatics.bem]',
        )
    out: dict[str, float | int | None] = {}
    for key, value in table.items():
        if key not in KEYS:
            raise fail(
                rd, key, f"unknown key '{key}'", f"{did_you_mean(key, list(KEYS))}allowed keys here: {', '.join(KEYS)}"
            )
        out[key] = number(rd, key, value)
    levels, max_levels = out.get("levels", 2), out.get("max_levels", 3)
    assert isinstance(levels, int) and isinstance(max_levels, int)  # "int" keys in KEYS: number() gives int
    if max_levels < levels:
        raise fail(
            rd,
            "max_levels",
            f"max_levels = {max_levels} is below levels = {levels}",
            "make max_levels at least levels",
        )
    return tuple((k, out[k]) for k in KEYS if k in out)


def number(rd: Reader, key: str, value, keys=None, where: str = WHERE) -> float | int | None:
    """One key's value checked against its kind and range in `keys` (KEYS; the FastCap table
    passes its own, netgen.structure.fastcap_table)."""
    kind, lo, hi, what = (keys or KEYS)[key]
    bem_none = key == "richardson_order" and keys is None  # the BEM alone can report its finest level
    if bem_none and value == "none":
        return None
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            raise fail(
                rd,
                key,
                f"{key} = {value!r} is not an integer in {lo:g}..{hi:g}",
                f"write {key} = <integer {lo:g}..{hi:g}> ({what})",
                where,
            )
        return int(value)
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not math.isfinite(value)
        or not lo < value <= hi
    ):
        extra = ', or "none" (report the finest level)' if bem_none else ""
        raise fail(
            rd,
            key,
            f"{key} = {value!r} is not a number in ({lo:g}, {hi:g}]",
            f"write {key} = <number above {lo:g}, at most {hi:g}>{extra} ({what})",
            where,
        )
    return float(value)
