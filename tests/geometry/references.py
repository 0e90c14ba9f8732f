"""Independent geometry of the electrode shapes: slotted-sector corners and areas by Green's
theorem, circle-strip areas; the references of the shape and extractor tests."""

from __future__ import annotations

import math

import numpy as np

from netgen.geometry.shapes import AnnularSector

SLOT = 20e-6


def side_point(theta: float, r: float, h: float, inward: float) -> np.ndarray:
    """Point at radius r on the line parallel to the ray at theta, offset h toward the sector."""
    u, n = np.array([math.cos(theta), math.sin(theta)]), np.array([-math.sin(theta), math.cos(theta)])
    return math.sqrt(r * r - h * h) * u + inward * h * n


def corner_radius(theta_start: float, theta_end: float, h: float) -> float:
    """Radius of the intersection of the two offset side lines (by solving the 2x2 system)."""
    us = np.array([math.cos(theta_start), math.sin(theta_start)])
    ue = np.array([math.cos(theta_end), math.sin(theta_end)])
    ns, ne = np.array([-us[1], us[0]]), np.array([-ue[1], ue[0]])
    t = np.linalg.solve(np.column_stack([us, -ue]), -h * ne - h * ns)
    return float(np.linalg.norm(t[0] * us + h * ns))


def green_area(r_lo: float, r_hi: float, theta_start: float, theta_end: float, slot: float) -> float:
    """Area of the slotted sector between radii r_lo and r_hi from Green's theorem on its boundary."""
    h = slot / 2
    a, b = side_point(theta_start, r_lo, h, 1), side_point(theta_start, r_hi, h, 1)
    c, d = side_point(theta_end, r_hi, h, -1), side_point(theta_end, r_lo, h, -1)
    ang = lambda p: math.atan2(p[1], p[0])  # noqa: E731
    outer = (ang(c) - ang(b)) % (2 * math.pi)
    inner = 0.0 if np.linalg.norm(d - a) < 1e-9 * r_hi else (ang(d) - ang(a)) % (2 * math.pi)
    cross = lambda p, q: p[0] * q[1] - p[1] * q[0]  # noqa: E731
    return 0.5 * (cross(a, b) + r_hi**2 * outer + cross(c, d) - r_lo**2 * inner)


def disk_minus_cross(radius: float, slot: float) -> float:
    """Area of a disk minus a centred '+' of two slots of width `slot` (circle-strip formula)."""
    u = slot / 2
    band = 2 * (u * math.sqrt(radius**2 - u**2) + radius**2 * math.asin(u / radius))
    return math.pi * radius**2 - (2 * band - slot**2)


def quadrants(r_in: float, r_out: float, offset: float = 0.0, slot: float = SLOT, tag: str = "") -> list[AnnularSector]:
    """Four slotted quadrant sectors."""
    return [
        AnnularSector(f"{tag}{k}", r_in, r_out, offset + k * math.pi / 2, offset + (k + 1) * math.pi / 2, slot)
        for k in range(4)
    ]
