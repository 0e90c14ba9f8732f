"""Comb-finger cross-section capacitances from the 2-D field solver (netgen.electrostatics.field2d).

Two 2-D problems per comb geometry (`cell`: any object with width, thickness, pitch,
substrate_gap, eps -- netgen.electrostatics.comb's CombCell):

* the finger cross-section: a periodic cell (period 2 pitch) of one moving finger and one fixed
  finger of width w and thickness t over a grounded substrate; the fixed fingers' bottoms at
  substrate_gap, the moving finger's at substrate_gap + offset. A face at local gap g sits in
  the cell [moving | g | fixed | 2 (pitch - w) - g] (a rigid lateral shift at fixed pitch).
  "Per side" is the mutual charge on the half of the moving finger facing that gap (the residual
  charges of its dofs split at the finger's centre line, Solution.charge), so
  side(g0 - x) + side(g0 + x) is the cell's whole moving-to-fixed C' and one solve at g gives
  both side(g) and side(2 g0 - g). The moving finger's capacitance to the substrate is its row
  sum. No substrate (substrate_gap None or inf): open below as above.
* the finger-end cross-section (along the finger): the moving finger's tip facing the opposite
  comb's base across the end gap e, both `reach` = 5 t long, over the substrate; C' per unit
  finger width times the width is the tip capacitance of one finger end.

Each is solved on a small (gap, offset) grid, interpolated by bicubic splines (smooth first
derivatives for the fit and the forces), and the grid values are cached on disk keyed by the
SHA-256 of the geometry, the grid and the solver settings (NETGEN_CACHE, else
$XDG_CACHE_HOME/netgen, folder comb_sections), so a build does not re-solve. The package ships
the tables of the examples' combs under the same names (SHIPPED, netgen/electrostatics/comb_tables),
so a fresh install builds them without solving; `bench/comb_tables.py` re-solves and writes them
there (after a change of the cell, the grid or the settings renames every table).
"""

from __future__ import annotations

import hashlib
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import RectBivariateSpline

from ..core.files import cache_root, write_bytes_atomic
from .field2d import Conductor, Problem, solve
from .mesh2d import Rect

Array = np.ndarray
VERSION = 3  # bump when the solver, the cell or the grids change what a table holds (3: the middle gap's mean)
GAP_RANGE = (0.1, 1.9)  # x nominal gap (pitch - width)
OFFSET_RANGE = (-1.0, 1.0)  # x thickness (down at most 0.8 substrate gaps): fingers apart at +-1
END_RANGE = (0.2, 20.0)  # x nominal gap, log-spaced
SETTINGS = {"tol": 2e-3, "max_levels": 3, "mesh_scale": 1.5, "order": 2}
GRID = {"gaps": 13, "offsets": 9, "ends": 6}
SHIPPED = Path(__file__).with_name("comb_tables")  # converged tables of the examples' combs, read before a solve


@dataclass(frozen=True)
class Geometry:
    """The numbers of a comb cell that enter the 2-D solves (m, F/m); substrate_gap inf: none."""

    width: float
    thickness: float
    pitch: float
    substrate_gap: float
    eps: float

    @classmethod
    def of(cls, cell) -> Geometry:
        """The geometry of any object with width, thickness, pitch, substrate_gap, eps."""
        sg = getattr(cell, "substrate_gap", None)
        g = cls(
            float(cell.width),
            float(cell.thickness),
            float(cell.pitch),
            math.inf if sg is None else float(sg),
            float(cell.eps),
        )
        if not (g.width > 0 and g.thickness > 0 and g.pitch > g.width and g.substrate_gap > 0 and g.eps > 0):
            raise ValueError(f"comb_section: need width, thickness, substrate_gap, eps > 0 and pitch > width, got {g}")
        return g

    @property
    def gap(self) -> float:
        """The nominal finger gap pitch - width."""
        return self.pitch - self.width

    def key(self, kind: str) -> str:
        """The content hash naming a table of this geometry (kind, grid and settings included)."""
        text = json.dumps(
            {
                "kind": kind,
                "geometry": [self.width, self.thickness, self.pitch, self.substrate_gap, self.eps],
                "grid": GRID,
                "settings": SETTINGS,
                "version": VERSION,
                "ranges": [GAP_RANGE, OFFSET_RANGE, END_RANGE],
            },
            sort_keys=True,
        )
        return hashlib.sha256(text.encode()).hexdigest()[:32]


def cache_dir() -> Path:
    """Where the tables live: NETGEN_CACHE, else $XDG_CACHE_HOME/netgen (~/.cache/netgen), comb_sections/."""
    return cache_root() / "comb_sections"


def sides(g: Geometry) -> dict[str, str]:
    """Side conditions of a cross-section: grounded bottom (substrate) or open."""
    bottom = "open" if math.isinf(g.substrate_gap) else "ground"
    return {"bottom": bottom, "top": "open", "left": "open", "right": "open"}


def floor_y(g: Geometry, reach: float) -> float:
    """The box's bottom: the substrate (y = 0) or `reach` below the fingers."""
    return 0.0 if not math.isinf(g.substrate_gap) else -reach


def finger_y(g: Geometry) -> float:
    """The fixed fingers' bottom y (the substrate at 0; without one, fingers at y = 0)."""
    return 0.0 if math.isinf(g.substrate_gap) else g.substrate_gap


def cell_problem(g: Geometry, gap: float, offset: float) -> Problem:
    """The periodic finger cell with the moving finger's right face at `gap` from the fixed finger."""
    w, t, y0 = g.width, g.thickness, finger_y(g)
    other = 2.0 * g.gap - gap
    moving = Rect(-w / 2, y0 + offset, w / 2, y0 + offset + t)
    fixed = Rect(w / 2 + gap, y0, w / 2 + gap + w, y0 + t)
    x0 = -w / 2 - other / 2
    far = 3.0 * 2.0 * g.pitch + t
    box = (x0, floor_y(g, far + abs(offset)), x0 + 2.0 * g.pitch, y0 + t + abs(offset) + far)
    return Problem((Conductor("moving", (moving,)), Conductor("fixed", (fixed,))), box, sides(g), True, g.eps)


def end_problem(g: Geometry, end_gap: float, offset: float) -> Problem:
    """The finger-end cross-section: the moving finger's tip at s = 0 facing the base at s = end_gap."""
    t, y0 = g.thickness, finger_y(g)
    reach = 5.0 * t
    tip = Rect(-reach, y0 + offset, 0.0, y0 + offset + t)
    base = Rect(end_gap, y0, end_gap + reach, y0 + t)
    far = 40.0 * (reach + end_gap)
    box = (-reach - far, floor_y(g, far), end_gap + reach + far, y0 + t + abs(offset) + far)
    return Problem((Conductor("moving", (tip,)), Conductor("fixed", (base,))), box, sides(g), False, g.eps)


def solve_cell(g: Geometry, gap: float, offset: float) -> tuple[float, float, float]:
    """(side at gap, side at the other gap, moving finger to substrate) in F/m per unit overlap."""
    sol = solve(cell_problem(g, gap, offset), **SETTINGS)
    right = -sol.charge("moving", "fixed", lambda x, y: np.where(x > 0, 1.0, np.where(x < 0, 0.0, 0.5)))
    left = sol.mutual("moving", "fixed") - right
    return right, left, sol.to_ground("moving") if not math.isinf(g.substrate_gap) else 0.0


def grids(g: Geometry) -> tuple[Array, Array, Array]:
    """The (gap, offset, end gap) grids of a geometry's tables (at least 4 points each: bicubic)."""
    if min(GRID.values()) < 4:
        raise ValueError(f"comb_section.GRID needs at least 4 points per axis, got {GRID}")
    gaps = g.gap * np.linspace(*GAP_RANGE, GRID["gaps"])
    low = max(OFFSET_RANGE[0] * g.thickness, -0.8 * g.substrate_gap)  # the finger stays off the substrate
    offsets = offset_grid(low, OFFSET_RANGE[1] * g.thickness, GRID["offsets"])
    ends = g.gap * np.geomspace(*END_RANGE, GRID["ends"])
    return gaps, offsets, ends


def offset_grid(low: float, high: float, n: int) -> Array:
    """n offsets from low < 0 to high > 0 with 0 a node (the fingers level: a y-only or in-plane
    motion reads the table on that row exactly), the points shared in proportion to each side's
    length, at least one interval per side."""
    below = min(max(round((n - 1) * -low / (high - low)), 1), n - 2)
    return np.concatenate([np.linspace(low, 0.0, below + 1), np.linspace(0.0, high, n - below)[1:]])


def section_values(g: Geometry) -> dict[str, Array]:
    """The side and substrate C' on the (gap, offset) grid: half the gaps solved, the mirror gap
    read from the same solve. The middle gap (an odd grid's nominal gap, its own mirror) holds the
    mean of its solve's two halves, half the cell's mutual C' (so side(g0) + side(g0) is the cell's
    whole C' as at every other pair of mirror nodes): the halves differ by the discretisation's
    left-right asymmetry (2.8e-6 of the value on the three-axis example, under the solve's tol),
    and before VERSION 3 the left half overwrote the right one there."""
    gaps, offsets, _ = grids(g)
    side = np.empty((gaps.size, offsets.size))
    sub = np.empty_like(side)
    n = gaps.size
    for j, dz in enumerate(offsets):
        for i in range((n + 1) // 2):
            right, left, ground = solve_cell(g, float(gaps[i]), float(dz))
            side[i, j], side[n - 1 - i, j] = (right, left) if i != n - 1 - i else ((right + left) / 2,) * 2
            sub[i, j] = sub[n - 1 - i, j] = ground
    return {"gaps": gaps, "offsets": offsets, "side": side, "substrate": sub}


def end_values(g: Geometry) -> dict[str, Array]:
    """The tip C' per unit finger width on the (end gap, offset) grid."""
    _, offsets, ends = grids(g)
    tip = np.array(
        [
            [solve(end_problem(g, float(e), float(dz)), **SETTINGS).mutual("moving", "fixed") for dz in offsets]
            for e in ends
        ]
    )
    return {"ends": ends, "offsets": offsets, "tip": tip}


def cached(g: Geometry, kind: str) -> dict[str, Array]:
    """A table from the disk cache or the shipped tables, computed and stored (atomically) in the
    cache if in neither."""
    name = f"{kind}-{g.key(kind)}.npz"
    path = cache_dir() / name
    for found in (path, SHIPPED / name):
        if found.exists():
            with np.load(found) as z:
                return {k: z[k] for k in z.files}
    values = section_values(g) if kind == "section" else end_values(g)
    buf = io.BytesIO()
    np.savez(buf, **values)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_bytes_atomic(path, buf.getvalue())
    return values


class OutsideTable(ValueError):
    """A gap or offset outside a section table's span (netgen.electrostatics.comb turns it into
    a StructureError naming the electrode)."""


@dataclass(frozen=True)
class Table:
    """A bicubic spline over (u, offset) of gap * C (`scaled`, for the side: smooth where C ~ 1/gap),
    C (the substrate) or, `log`, gap * C over u = log(end gap) (the tip)."""

    spline: RectBivariateSpline
    u: Array
    offsets: Array
    what: str
    log: bool = False
    scaled: bool = False

    def ev(self, gap: ArrayLike, offset: ArrayLike, dgap: int = 0, doff: int = 0) -> Array:
        """The value (or a first derivative) at arrays of gaps and offsets; ValueError outside the grid."""
        gap, offset = np.broadcast_arrays(np.asarray(gap, float), np.asarray(offset, float))
        u = np.log(gap) if self.log else gap
        lo, hi = self.u[0], self.u[-1]
        if np.any(~((u >= lo - 1e-12 * abs(lo)) & (u <= hi + 1e-12 * abs(hi)))) or np.any(
            (offset < self.offsets[0] - 1e-15) | (offset > self.offsets[-1] + 1e-15)
        ):
            span = np.exp([lo, hi]) if self.log else np.array([lo, hi])
            raise OutsideTable(
                f"comb_section: {self.what} asked outside its table: gap in [{span[0]:.4g}, "
                f"{span[1]:.4g}] m, offset in [{self.offsets[0]:.4g}, {self.offsets[-1]:.4g}] m"
            )
        v = self.spline.ev(u, offset, dx=dgap, dy=doff)
        if self.log:  # spline of gap * C over log(gap)
            return (v if not dgap else v - self.spline.ev(u, offset)) / gap ** (1 + dgap)
        if self.scaled:  # spline of gap * C over gap
            return (v if not dgap else v - self.spline.ev(u, offset) / gap) / gap
        return v


_TABLES: dict[tuple[Geometry, str], Table] = {}


def table(cell, what: str) -> Table:
    """The spline of `what` ("side", "substrate" or "tip") for a cell, from memory, disk or a solve."""
    g = Geometry.of(cell)
    if (g, what) not in _TABLES:
        kind = "end" if what == "tip" else "section"
        v = cached(g, kind)
        u = np.log(v["ends"]) if kind == "end" else v["gaps"]
        gap = np.exp(u) if kind == "end" else v["gaps"]
        scaled = what != "substrate"
        z = v[what] * gap[:, None] if scaled else v[what]
        _TABLES[g, what] = Table(
            RectBivariateSpline(u, v["offsets"], z, kx=3, ky=3),
            u,
            v["offsets"],
            what,
            kind == "end",
            scaled and kind != "end",
        )
    return _TABLES[g, what]


def section(gap: ArrayLike, offset: ArrayLike, cell) -> Array:
    """C' (F/m per unit overlap) of one finger SIDE: the moving finger's face at local `gap` to
    the fixed finger it faces, the moving finger `offset` above the fixed one (see module docstring)."""
    return table(cell, "side").ev(gap, offset)


def section_gradient(gap: ArrayLike, offset: ArrayLike, cell) -> Array:
    """d section / d gap and d section / d offset, stacked on a last axis of length 2."""
    t = table(cell, "side")
    return np.stack([t.ev(gap, offset, dgap=1), t.ev(gap, offset, doff=1)], axis=-1)


def substrate_section(gap: ArrayLike, offset: ArrayLike, cell) -> Array:
    """C' (F/m per unit overlap) of the moving finger to the grounded substrate (whole finger),
    with its right face at `gap`; 0 without a substrate."""
    return table(cell, "substrate").ev(gap, offset)


def tip(gap: ArrayLike, offset: ArrayLike, cell) -> Array:
    """C (F) of one finger end: the tip facing the opposite base across the end gap `gap`, from
    the end cross-section's C' per unit width times the finger width."""
    return table(cell, "tip").ev(gap, offset) * float(cell.width)


def tip_gradient(gap: ArrayLike, offset: ArrayLike, cell) -> Array:
    """d tip / d end gap and / d offset (F/m), on a last axis of length 2."""
    t = table(cell, "tip")
    return np.stack([t.ev(gap, offset, dgap=1), t.ev(gap, offset, doff=1)], axis=-1) * float(cell.width)


def textbook_ratio(cell) -> float:
    """The 2-D side capacitance at the nominal gap and zero offset (one direct converged solve,
    no table) over the textbook eps t / g of one side."""
    g = Geometry.of(cell)
    right, _, _ = solve_cell(g, g.gap, 0.0)
    return right / (g.eps * g.thickness / g.gap)
