"""The [conductor.flexure] table of a proof mass: the suspension's named type and dimensions,
or given stiffnesses (netgen.mechanics.flexures turns it into k_x ... k_rot)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..core.reader import Reader, check_keys, choice, nonnegative, positive, quantity

TYPES = ("folded", "crab_leg", "clamped_guided", "given", "none")
GIVEN = ("k_x", "k_y", "k_z", "k_rot", "k_tilt_x", "k_tilt_y")
KEYS = {
    "folded": ["type", "length", "width", "thickness", "axis", "truss_width", "spacing", "k_xy"],
    "crab_leg": ["type", "length", "width", "thickness", "axis", "thigh_length", "thigh_width", "k_xy"],
    "clamped_guided": ["type", "length", "width", "thickness", "axis", "k_xy"],
    "given": ["type", *GIVEN, "k_xy"],
    "none": ["type"],
}


@dataclass(frozen=True)
class Flexure:
    """A proof mass's suspension: four units placed mirror-symmetrically about both mass axes.

    type "clamped_guided": four straight beams of `length` along `axis`, clamped at the anchor and
    guided by the mass; "folded": two trusses, each carrying two inner beams (to the mass) and two
    outer beams (to the anchors) along `axis` (Tang's folded flexure, eight beams), the beams
    `spacing` apart; "crab_leg": four legs, a shin of `length` x `width` along `axis` from the mass
    to the knee and a thigh of `thigh_length` x `thigh_width` across it to the anchor; "given":
    the stiffnesses themselves (N/m, N*m/rad); "none": a free body (no springs). `k_xy` (N/m,
    either sign) is the x-y coupling stiffness of an imperfect suspension (its principal axes turned
    by theta from x, y: k_xy = (k_1 - k_2) sin theta cos theta): the energy k_xy x y, the source of a
    gyroscope's quadrature (netgen.mechanics.proof_mass.coupling_energy)."""

    type: str
    length: float = 0.0
    width: float = 0.0
    thickness: float = 0.0
    axis: str = "y"
    truss_width: float = 0.0
    spacing: float = 0.0
    thigh_length: float = 0.0
    thigh_width: float = 0.0
    given: tuple[tuple[str, float], ...] = ()
    k_xy: float = 0.0


def read_flexure(rd: Reader, t: dict, thickness: float) -> Flexure:
    """conductor.flexure: a table with `type` and that type's keys."""
    raw = t.get("flexure", {"type": "none"})
    where = "conductor.flexure"
    if not isinstance(raw, dict):
        raise rd.fail(where, "flexure must be a table", 'write [conductor.flexure] with type = "folded" ...')
    kind = choice(rd, raw, where, "type", list(TYPES), default=None)
    check_keys(rd, where, raw, KEYS[kind])
    if kind == "none":
        return Flexure("none")
    k_xy = coupling(rd, raw, where)
    if kind == "given":
        given = tuple(
            (
                k,
                quantity(
                    rd,
                    raw,
                    where,
                    k,
                    "stiffness" if k in ("k_x", "k_y", "k_z") else "torsional stiffness",
                    0.0,
                    nonnegative,
                    f"{k} in N/m (translations) or N*m/rad (rotations)",
                ),
            )
            for k in GIVEN
            if k in raw
        )
        if not given:
            raise rd.fail(where, 'type = "given" without stiffnesses', f"give some of {', '.join(GIVEN)}")
        return Flexure("given", given=given, k_xy=k_xy)
    q = lambda key, what, default=None: quantity(rd, raw, where, key, "length", default, positive, what)  # noqa: E731
    length, width = q("length", "beam length (crab leg: shin length)"), q("width", "beam width")
    axis = choice(rd, raw, where, "axis", ["x", "y"], "y")
    out: dict[str, Any] = dict(
        type=kind, length=length, width=width, thickness=q("thickness", "beam thickness", thickness), axis=axis
    )
    if kind == "folded":
        out |= dict(
            truss_width=q("truss_width", "truss width", 4 * width), spacing=q("spacing", "beam spacing", 4 * width)
        )
    if kind == "crab_leg":
        out |= dict(thigh_length=q("thigh_length", "thigh length"), thigh_width=q("thigh_width", "thigh width", width))
    return Flexure(**out, k_xy=k_xy)


def coupling(rd: Reader, raw: dict, where: str) -> float:
    """k_xy: a stiffness of either sign (0 without the key)."""
    return quantity(rd, raw, where, "k_xy", "stiffness", 0.0, None, "x-y coupling stiffness, N/m, either sign")
