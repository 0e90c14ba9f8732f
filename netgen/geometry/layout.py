"""The layout of a structure: its plate outline and its electrodes as shapes, in port order.

The conductor says its outline form (`outline_shape`: a disk centred at the origin, or the
rectangle `outline()`); each electrode kind of the structure file maps to shapes through
SHAPES, one line per kind.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..structure import CombElectrode, ElectrodeSet, RectElectrode, Structure
from .combs import CombShape
from .shapes import AnnularSector, DiskPlate, Electrode, Plate, Rectangle, RectPlate


def plate_outline(s: Structure) -> Plate:
    """The conductor outline the extractor integrates over."""
    c = s.conductor
    return DiskPlate(c.radius) if c.outline_shape == "disk" else RectPlate(*c.outline())


def ring_sectors(eset: ElectrodeSet) -> list[Electrode]:
    """A set of rings x sectors as annular-sector electrodes (names from the set)."""
    out, names = [], iter(eset.electrode_names())
    for r_in, r_out in eset.rings:
        for k in range(eset.sectors):
            width = 2 * math.pi / eset.sectors
            start = eset.sector_start + k * width
            slot = eset.slot if eset.sectors > 1 else 0.0
            out.append(
                Electrode(
                    AnnularSector(next(names), r_in, r_out, start, start + width, slot),
                    eset.side,
                    eset.gap,
                    eset.name,
                    eset.dielectric_thickness,
                    eset.dielectric_permittivity,
                )
            )
    return out


def rectangle(e: RectElectrode) -> list[Electrode]:
    """A rectangular electrode (its own group)."""
    return [
        Electrode(
            Rectangle(e.name, e.x0, e.x1, e.y0, e.y1),
            e.side,
            e.gap,
            e.name,
            e.dielectric_thickness,
            e.dielectric_permittivity,
        )
    ]


def comb(e: CombElectrode) -> list[Electrode]:
    """A comb-finger array: one electrode whose gaps close in the plane."""
    return [Electrode(CombShape.of(e), "in_plane", e.gap, e.name)]


# electrode kind of the structure file -> its shapes
SHAPES: dict[type, Callable[..., list[Electrode]]] = {
    ElectrodeSet: ring_sectors,
    RectElectrode: rectangle,
    CombElectrode: comb,
}


def electrodes(s: Structure) -> list[Electrode]:
    """Every electrode of the structure as a shape on its side and gap, in port order."""
    return [e for entry in s.electrode_sets for e in SHAPES[type(entry)](entry)]


def overlap_area(e: Electrode, plate: Plate) -> float:
    """Area of an electrode over the plate (its quadrature weights)."""
    _, _, w = e.shape.quadrature(plate)
    return float(np.sum(w))


def electrode_outlines(s: Structure, points: int = 40) -> list[tuple[np.ndarray, np.ndarray]]:
    """Closed outline (x, y) of every ring-sector electrode, clipped to the plate, for plots."""
    out = []
    for eset in s.electrode_sets:
        if not isinstance(eset, ElectrodeSet):
            continue
        width = 2 * math.pi / eset.sectors
        for r_in, r_out in eset.rings:
            r_out = min(r_out, s.conductor.radius)
            for k in range(eset.sectors):
                t0 = eset.sector_start + k * width

                def half(r: float, eset=eset) -> float:
                    return math.asin(min(1.0, eset.slot / (2 * r))) if eset.sectors > 1 and r > 0 else 0.0

                lo_o, hi_o = t0 + half(r_out), t0 + width - half(r_out)
                r_lo = max(r_in, eset.slot / 2 + 1e-12) if eset.sectors > 1 else r_in
                lo_i, hi_i = t0 + half(r_lo), t0 + width - half(r_lo)
                ta, tb = np.linspace(lo_o, hi_o, points), np.linspace(hi_i, lo_i, points)
                x = np.concatenate([r_out * np.cos(ta), r_lo * np.cos(tb), [r_out * math.cos(lo_o)]])
                y = np.concatenate([r_out * np.sin(ta), r_lo * np.sin(tb), [r_out * math.sin(lo_o)]])
                out.append((x, y))
    return out


def drawing(plate: Plate, shapes: list[Electrode], points: int = 12) -> dict:
    """The layout as plain polylines for a drawing to scale (the build report, netgen.emit.report):
    the conductor's outline and, per electrode in port order, the pieces of its overlap with the
    conductor's outline (a comb: the overlap of each facing sidewall), in m, rounded to 1 pm."""

    def line(x, y) -> list[list[float]]:
        return [[round(float(v), 12) for v in x], [round(float(v), 12) for v in y]]

    if isinstance(plate, DiskPlate):
        t = np.linspace(0, 2 * math.pi, 4 * points + 1)
        conductor = line(plate.radius * np.cos(t), plate.radius * np.sin(t))
    else:
        conductor = line(
            [plate.x0, plate.x1, plate.x1, plate.x0, plate.x0], [plate.y0, plate.y0, plate.y1, plate.y1, plate.y0]
        )
    out = []
    for e in shapes:
        if isinstance(e.shape, CombShape):
            back = e.shape.engage * e.shape.overlap
            ends = [(np.asarray(f.tip), np.asarray(f.tip) - back) for f in e.shape.faces()]
            pieces = [line([a[0], b[0]], [a[1], b[1]]) for a, b in ends]
        else:
            pieces = []
            for p in e.shape.boundary(plate):
                if hasattr(p, "p0"):
                    pieces.append(line([p.p0[0], p.p1[0]], [p.p0[1], p.p1[1]]))
                else:
                    t = np.linspace(p.phi0, p.phi1, points + 1)
                    pieces.append(line(p.radius * np.cos(t), p.radius * np.sin(t)))
        out.append({"name": e.name, "side": e.side, "pieces": pieces})
    return {"unit": "m", "conductor": conductor, "electrodes": out}
