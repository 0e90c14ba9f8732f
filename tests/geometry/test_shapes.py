"""Shapes of netgen.geometry against independent geometry: quadrature areas and edge lengths of
slotted sectors, rings, clipped sectors and rectangles over a disk, against Green's-theorem and
circle-strip closed forms (tests/geometry/references.py)."""

from __future__ import annotations

import math

import pytest

from netgen.geometry.shapes import AnnularSector, DiskPlate, Rectangle
from tests.geometry.references import SLOT, corner_radius, disk_minus_cross, green_area, quadrants

R = 500e-6  # plate radius
PLATE = DiskPlate(R)


def test_slotted_layout_areas_match_closed_forms():
    """4 slotted quadrants + 4 slotted outer-ring sectors: quadrature areas vs circle/strip geometry."""
    r1 = 0.55 * R
    inner = quadrants(0.0, r1, tag="i")
    outer = quadrants(r1 + SLOT, R, offset=math.pi / 4, tag="o")
    wsum = lambda s: s.quadrature(PLATE)[2].sum()  # noqa: E731
    assert sum(map(wsum, inner)) == pytest.approx(disk_minus_cross(r1, SLOT), rel=1e-9)
    ring = disk_minus_cross(R, SLOT) - disk_minus_cross(r1 + SLOT, SLOT)
    assert sum(map(wsum, outer)) == pytest.approx(ring, rel=1e-9)
    rc = corner_radius(0.0, math.pi / 2, SLOT / 2)
    assert rc == pytest.approx(SLOT / math.sqrt(2), rel=1e-12)
    for s in inner:
        assert wsum(s) == pytest.approx(green_area(rc, r1, s.theta_start, s.theta_end, SLOT), rel=1e-9)
        assert s.area() == pytest.approx(green_area(rc, r1, s.theta_start, s.theta_end, SLOT), rel=1e-12)
    for s in outer:
        assert s.area() == pytest.approx(green_area(r1 + SLOT, R, s.theta_start, s.theta_end, SLOT), rel=1e-12)


def test_full_ring_and_wide_sector_areas():
    """Full ring without slot and a 3-quadrant slotted sector: quadrature vs closed forms."""
    ring = AnnularSector("ring", 0.2 * R, 0.7 * R, 0.0, 2 * math.pi)
    assert ring.quadrature(PLATE)[2].sum() == pytest.approx(math.pi * (0.49 - 0.04) * R**2, rel=1e-12)
    wide = AnnularSector("wide", 0.2 * R, 0.9 * R, 0.3, 0.3 + 1.5 * math.pi, SLOT)
    ref = green_area(0.2 * R, 0.9 * R, wide.theta_start, wide.theta_end, SLOT)
    assert wide.quadrature(PLATE)[2].sum() == pytest.approx(ref, rel=1e-9)


def test_overlap_is_clipped_at_the_plate_rim():
    """Electrode reaching beyond the disk: area and boundary are those of the clipped overlap."""
    s = AnnularSector("big", 0.6 * R, 1.3 * R, 0.1, 0.1 + math.pi / 2, SLOT)
    assert s.quadrature(PLATE)[2].sum() == pytest.approx(green_area(0.6 * R, R, 0.1, 0.1 + math.pi / 2, SLOT), rel=1e-9)
    h = SLOT / 2
    outer = R * (math.pi / 2 - 2 * math.asin(h / R))
    inner = 0.6 * R * (math.pi / 2 - 2 * math.asin(h / (0.6 * R)))
    sides = 2 * (math.sqrt(R**2 - h**2) - math.sqrt((0.6 * R) ** 2 - h**2))
    assert s.edge_points(PLATE)[2].sum() == pytest.approx(outer + inner + sides, rel=1e-12)
    rims = [p for p in s.boundary(PLATE) if p.rim]
    assert len(rims) == 1 and rims[0].radius == R
    assert AnnularSector("off", 1.1 * R, 1.5 * R, 0.0, 1.0).quadrature(PLATE)[2].size == 0


def test_quadrant_perimeter_from_corner():
    """Slotted quadrant from the slot corner: fringe line length = arc + two straight sides."""
    s = AnnularSector("q", 0.0, 0.5 * R, 0.0, math.pi / 2, SLOT)
    h = SLOT / 2
    ref = 0.5 * R * (math.pi / 2 - 2 * math.asin(h / (0.5 * R))) + 2 * (math.sqrt((0.5 * R) ** 2 - h**2) - h)
    assert s.edge_points(PLATE)[2].sum() == pytest.approx(ref, rel=1e-12)


def test_rectangle_over_disk_plate():
    """Rectangles over a disk: strip area by the circle-strip formula; covering square -> whole disk."""
    u = 0.3 * R
    band = Rectangle("band", -2 * R, 2 * R, -u, u)
    strip = 2 * (u * math.sqrt(R**2 - u**2) + R**2 * math.asin(u / R))
    assert band.quadrature(PLATE)[2].sum() == pytest.approx(strip, rel=1e-9)
    cover = Rectangle("cover", -2 * R, 2 * R, -2 * R, 2 * R)
    assert cover.quadrature(PLATE)[2].sum() == pytest.approx(math.pi * R**2, rel=1e-9)
    assert cover.edge_points(PLATE)[2].sum() == pytest.approx(2 * math.pi * R, rel=1e-12)
    corner = Rectangle("corner", 0.0, 2 * R, 0.0, 2 * R)  # quarter disk
    assert corner.quadrature(PLATE)[2].sum() == pytest.approx(math.pi * R**2 / 4, rel=1e-9)
    assert corner.edge_points(PLATE)[2].sum() == pytest.approx(2 * R + math.pi * R / 2, rel=1e-12)
