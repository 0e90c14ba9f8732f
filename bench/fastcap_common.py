"""What the FastCap bench scripts share (fastcap_perforated.py, fastcap_thick_holes.py,
fastcap_perforated_piston.py, fastcap_dielectric.py): the panel-size and --json arguments, the
settings they give, the printed (and stored) JSON, and the guarded levels of a plate over the box
electrode whose face is split into a sense square and the ring around it (the guard)."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from netgen.electrostatics import fastcap
from netgen.electrostatics.bem_mesh import Sizes
from netgen.electrostatics.fastcap_mesh import Layered, Panels, layered_panels, rect_panels
from netgen.geometry.shapes import Electrode, Rectangle


def add_size_arguments(ap: argparse.ArgumentParser, edge_to_gap: float, element_to_gap: float) -> None:
    """--edge-to-gap and --element-to-gap (the panel sizes, with the script's defaults) and --json."""
    ap.add_argument("--edge-to-gap", type=float, default=edge_to_gap)
    ap.add_argument("--element-to-gap", type=float, default=element_to_gap)
    ap.add_argument("--json")


def settings(a: argparse.Namespace) -> fastcap.FastcapSettings:
    """The extractor's default settings at the panel sizes given."""
    return replace(fastcap.FastcapSettings(), edge_to_gap=a.edge_to_gap, element_to_gap=a.element_to_gap)


def report(res: dict, path: str | None) -> None:
    """Print the results as JSON, and store them in `path` if given."""
    text = json.dumps(res, indent=2)
    print(text)
    if path:
        Path(path).write_text(text)


def guarded_levels(
    cells: int, sense: int, pitch: float, gap: float, st: fastcap.FastcapSettings, plate: Callable[[Sizes], Panels]
) -> list[list]:
    """Both mesh levels: the plate (`plate` at the level's sizes) over the box electrode of the
    cells x cells square `gap` below, its face split into the sense x sense cells (the sense
    conductor) and the ring around them (the guard, with the box's back and walls)."""
    out = []
    for k in range(2):
        sz = st.sizes(gap, k)
        c, a = cells * pitch / 2, sense * pitch / 2
        box = layered_panels(Electrode(Rectangle("g", -c, c, -c, c), "below", gap, "g", 0.1 * gap, 1.0), sz, 0.0, 1.0)
        pieces = [(-c, c, -c, -a), (-c, c, a, c), (-c, -a, -a, a), (a, c, -a, a)]
        ring = Panels(np.concatenate([rect_panels(*p, sz, 0.0).corners for p in pieces]))
        empty = Panels(np.zeros((0, 4, 3)))
        out.append(
            [
                plate(sz),
                Layered(rect_panels(-a, a, -a, a, sz, 0.0), empty, empty, np.zeros((0, 3)), 1.0),
                Layered(ring, box.rest, empty, np.zeros((0, 3)), 1.0),
            ]
        )
    return out
