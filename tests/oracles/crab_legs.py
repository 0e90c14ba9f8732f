"""A square silicon proof mass on crab legs along y, as structure-file text: its [conductor] and
[conductor.flexure] tables (crab_legs) and the 100 um square plate under or over its centre (plate),
which the process, inertial and sweep tests and benches put under their own electrodes, coordinates,
sampling and damping (tests/oracles/process_cases.perforated, tests/oracles/process_inertial.structure,
tests/mechanics/test_frame_inputs.py, tests/sweep/test_sweep_process.py, bench/process_sweep.py)."""

from __future__ import annotations


def crab_legs(
    side: float,
    thickness: float,
    length: float,
    thigh_length: float | None = None,
    width: float = 2.0,
    hole: float | None = None,
    hole_pitch: float = 10.0,
) -> str:
    """[conductor] and [conductor.flexure] of a silicon mass `side` x `side` x `thickness` on crab legs
    of leg and thigh lengths `length` and `thigh_length` (default: `length`), both `width` wide (all in
    um); a perforated mass with `hole` given: square holes of that side on the `hole_pitch` grid (um)."""
    perforation = "" if hole is None else f'hole = "{hole!r} um"\nhole_pitch = "{hole_pitch!r} um"\n'
    return f"""[conductor]
kind = "proof_mass"
length = "{side!r} um"
width = "{side!r} um"
thickness = "{thickness!r} um"
density = "2330 kg/m^3"
youngs_modulus = "160 GPa"
poisson_ratio = 0.22
{perforation}
[conductor.flexure]
type = "crab_leg"
axis = "y"
length = "{length!r} um"
width = "{width!r} um"
thigh_length = "{length if thigh_length is None else thigh_length!r} um"
thigh_width = "{width!r} um"

"""


def plate(name: str, side: str) -> str:
    """An [[electrodes]] plate 100 um square centred under (side "below") or over ("above") the mass, 2 um away."""
    return f"""[[electrodes]]
name = "{name}"
kind = "plate"
side = "{side}"
gap = "2 um"
x = ["-50 um", "50 um"]
y = ["-50 um", "50 um"]
"""
