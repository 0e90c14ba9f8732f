"""The `[electrostatics.fastcap]` table: the multipole extractor's settings (panel grading, mesh
levels, expansion orders, GMRES tolerance, memory budget) for `extractor = "fastcap"` and for the
FastCap calibration points of `extractor = "calibrated"` (calibration_source = "fastcap"). Each key
is one field of netgen.electrostatics.fastcap.FastcapSettings; types and ranges are checked here
(file, line, key and fix) with the BEM table's checker (netgen.structure.bem_table.number).
"""

from __future__ import annotations

from ..core.files import did_you_mean
from ..core.reader import Reader
from .bem_table import fail, number

WHERE = "electrostatics.fastcap"
# key -> (kind, low, high, what): "float" in (low, high], "int" in [low, high]
KEYS: dict[str, tuple[str, float, float, str]] = {
    "edge_to_gap": ("float", 0.0, 100.0, "panel size at free edges, in gaps"),
    "element_to_gap": ("float", 0.0, 100.0, "largest panel, in gaps"),
    "growth": ("float", 1.0, 4.0, "size ratio of neighbouring panel rows (> 1)"),
    "refinement": ("float", 1.0, 4.0, "panel size ratio between mesh levels (> 1)"),
    "levels": ("int", 2, 4, "mesh levels solved (3 or more: the convergence order is measured)"),
    "expansion_order": ("int", 1, 8, "multipole expansion order of the solves"),
    "check_order": ("int", 1, 8, "expansion order of the check solve on the coarse level"),
    "iter_tol": ("float", 0.0, 0.01, "GMRES residual tolerance (volts at 1 V)"),
    "richardson_order": ("float", 0.0, 8.0, "convergence order assumed for two levels"),
    "element_to_size": ("float", 0.0, 1.0, "largest panel, in units of the plate's size"),
    "memory_budget_gb": ("float", 0.0, 1e4, "GB for one solve of the finest level"),
}


def read_fastcap(rd: Reader, t: dict, extractor: str, source: str) -> tuple[tuple[str, float | int], ...]:
    """The table's (key, value) pairs in the order of KEYS (absent keys keep FastcapSettings'
    defaults); refused where no FastCap solve runs (`source`: the calibration source)."""
    if "fastcap" not in t:
        return ()
    table = t["fastcap"]
    if not isinstance(table, dict):
        raise fail(
            rd,
            None,
            "fastcap must be a table of solver settings",
            "write it as an [electrostatics.fastcap] section",
            WHERE,
        )
    if extractor != "fastcap" and not (extractor == "calibrated" and source == "fastcap"):
        raise fail(
            rd,
            None,
            f"FastCap settings, but extractor = {extractor!r}"
            + (f' calibrates against "{source}"' if extractor == "calibrated" else "")
            + ": no FastCap solve runs",
            'use extractor = "fastcap", or "calibrated" with calibration_source = "fastcap", or drop '
            "[electrostatics.fastcap]",
            WHERE,
        )
    out: dict[str, float | int] = {}
    for key, value in table.items():
        if key not in KEYS:
            raise fail(
                rd,
                key,
                f"unknown key '{key}'",
                f"{did_you_mean(key, list(KEYS))}allowed keys here: {', '.join(KEYS)}",
                WHERE,
            )
        v = number(rd, key, value, KEYS, WHERE)
        assert v is not None  # only the BEM table's richardson_order takes "none"
        out[key] = v
    if "check_order" in out and out["check_order"] == out.get("expansion_order", 4):
        raise fail(
            rd,
            "check_order",
            f"check_order = {out['check_order']} is the expansion order: the multipole error estimate would be 0",
            "write a check_order above expansion_order (6 for the default 4)",
            WHERE,
        )
    return tuple((k, out[k]) for k in KEYS if k in out)


def refuse_bem(rd: Reader, t: dict) -> tuple:
    """With calibration_source = "fastcap" no BEM solve runs: an [electrostatics.bem] table is refused."""
    if "bem" in t:
        raise fail(
            rd,
            None,
            'BEM settings, but calibration_source = "fastcap": no BEM solve runs',
            'put the solver settings in [electrostatics.fastcap], or write calibration_source = "bem"',
            "electrostatics.bem",
        )
    return ()
