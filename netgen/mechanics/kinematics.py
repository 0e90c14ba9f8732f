"""Where the small-angle rigid-body kinematics (netgen.mechanics.base.KINEMATICS) stop being
accurate: the report every build with rotation coordinates carries.

A rotation by theta moves a point at distance r from the axis by 2 r sin(theta/2) along the chord;
the first-order model moves it by r theta along the tangent. The error vector is
r (cos theta - 1, sin theta - theta), so relative to the displacement it is
e(theta) = sqrt((1 - cos theta)^2 + (theta - sin theta)^2) / theta ~ theta / 2, which passes
0.1 % at theta = 2.0 mrad; relative to the smallest gap g it is r_max (1 - cos theta) / g ~
r_max theta^2 / (2 g), where r_max is the outline's farthest point from the axis.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

LIMIT = 1e-3  # the relative error the report flags


def relative_error(theta: np.ndarray | float) -> np.ndarray:
    """|exact - first-order displacement| / |first-order displacement| of a rotation by theta."""
    t = np.maximum(np.abs(np.asarray(theta, dtype=float)), 1e-300)
    return np.hypot(1.0 - np.cos(t), t - np.sin(t)) / t


def threshold(limit: float = LIMIT) -> float:
    """The angle (rad) beyond which relative_error exceeds `limit`."""
    return float(brentq(lambda t: relative_error(t) - limit, 1e-9, 1.0))


def small_angle_report(
    names: list[str], kinds: list[str], scales: np.ndarray, sampled: float, r_max: float, min_gap: float
) -> dict:
    """Per rotation coordinate: its sampled and touching amplitudes against the 0.1 % threshold,
    and the farthest point's second-order position error there as a fraction of the smallest gap."""
    limit_angle = threshold()
    rows = []
    for name, kind, scale in zip(names, kinds, scales):
        if kind != "rotation":
            continue
        s, touch = sampled * float(scale), float(scale)
        rows.append(
            {
                "coordinate": name,
                "sampled_rad": s,
                "touching_rad": touch,
                "error_at_sampled": float(relative_error(s)),
                "error_at_touching": float(relative_error(touch)),
                "position_error_over_gap_at_sampled": r_max * (1 - math.cos(s)) / min_gap,
                "position_error_over_gap_at_touching": r_max * (1 - math.cos(touch)) / min_gap,
                "exceeds_0p1_percent": bool(
                    relative_error(touch) > LIMIT or r_max * (1 - math.cos(touch)) / min_gap > LIMIT
                ),
            }
        )
    return {
        "model": "first order in the angles (netgen.mechanics.base.KINEMATICS)",
        "threshold_rad": limit_angle,
        "limit": LIMIT,
        "farthest_point_m": r_max,
        "smallest_gap_m": min_gap,
        "rotations": rows,
        "note": f"the displacement error of the small-angle model exceeds {LIMIT:.1%} of the displacement beyond "
        f"|angle| = {limit_angle:.4g} rad; translations are exact; two rotations together are off "
        "by their product (second order) as well",
    }
