"""Plate shapes with internal eigenmodes for suspended conductors: the conductor's outline
(`outline_shape`) -> the function giving its first N modes, each with `shape(x, y)`, modal mass
and stiffness, frequencies and labels. A new plate shape is a new module and one line here."""

from __future__ import annotations

from collections.abc import Callable

from . import rect_plate

# outline shape -> modes(conductor, count)
PLATE_MODES: dict[str, Callable] = {
    "rect": rect_plate.conductor_modes,
}
