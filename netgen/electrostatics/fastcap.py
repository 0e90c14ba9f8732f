"""The multipole extractor: the Maxwell capacitance matrix of the moving plate and every fixed
electrode from FastCap2 (`fastcap2` on PyPI: collocation of constant-charge flat panels, the
dense system never formed: GMRES with multipole-accelerated products).

Why beside the dense BEM (netgen.electrostatics.bem): the dense matrix needs 10 N^2 bytes and
stops at g/R = 0.0115 (12.9 GB); FastCap's memory and time grow about linearly with the panels,
so the reference disk at its own gap (g/R = 0.0063) fits (docs/fastcap.md, 'Costs').

Panels (netgen.electrostatics.fastcap_mesh): quads, graded from edge_to_gap gaps at free edges
(and, on the plate, at the electrodes' outlines in projection) to element_to_gap gaps inside
(panel size tied to the smallest gap). Every solve runs on `levels`
mesh levels (2 or more; sizes in the ratio `refinement`) at `expansion_order`, Richardson-
extrapolates (with three levels or more at the order observed from the last three, bem.extrapolate;
the correction is the discretisation error estimate), and solves the coarse level again at
`check_order`: the change is the multipole error estimate. Both are recorded per solve.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from ..core.constants import EPS0
from ..core.errors import SimulationError, SimulatorNotFound, StructureError
from ..geometry.shapes import Array, Basis, Electrode, Plate
from .base import ProbePoints
from .bem import MaxwellMatrix, central_differences, extrapolate, relative_change
from .bem_mesh import Sizes
from .fastcap_mesh import Layered, Panels, electrode_panels, layered_panels, plate_panels
from .parallel_plate import ParallelPlateExtractor, PreparedParallelPlate
from .perforation import Perforation

FASTCAP_INSTALL = "pip install 'netgen[fastcap]'  (or: pip install fastcap2==2.1)"
# peak memory per panel of one solve (bytes, Python and numpy included): it grows with the panels
# (bench/fastcap_levels.py on the reference disk: 24-25 kB at 38k-68k panels, 28.7 kB at 124k, all
# at expansion order 4; 32.0 kB at order 6 on 38k), so 32 kB covers both orders up to ~124k panels
BYTES_PER_PANEL = 32e3
# CPU seconds per panel of one solve (order 4 and 6 mixed) on this project's 2-core AMD EPYC:
# 0.19-0.64 ms for sheets (2k-46k panels, docs/fastcap.md), 1.1 ms for a 2 um thick perforated
# plate (its hole walls); 1 ms, so the estimate is within about 5x either way
SECONDS_PER_PANEL = 1e-3


class FastcapBudgetError(SimulationError):
    """The panels of a solve need more memory than the budget allows."""


@dataclass(frozen=True)
class FastcapSettings:
    """How the multipole extractor meshes and solves (lengths in units of the smallest gap).

    edge_to_gap: panel size at free edges; element_to_gap: largest panel; growth: size ratio of
    neighbouring panel rows; refinement: size ratio of the two mesh levels; expansion_order: the
    multipole order of the solves; check_order: the order of the check solve on the coarse level;
    iter_tol: FastCap's GMRES tolerance; richardson_order: convergence order in the panel size
    assumed by the extrapolation (2: measured on coaxial disks, docs/fastcap.md); levels: mesh
    levels solved (3 or more: the order observed from the last three when it lies in 0.5..4);
    element_to_size: largest panel in units of the plate's size; memory_budget: bytes per solve.
    A structure file sets them in [electrostatics.fastcap] (netgen.structure.fastcap_table).
    """

    edge_to_gap: float = 0.25
    element_to_gap: float = 2.0
    growth: float = 1.5
    refinement: float = math.sqrt(2.0)
    expansion_order: int = 4
    check_order: int = 6
    iter_tol: float = 1e-4
    richardson_order: float = 2.0
    levels: int = 2
    element_to_size: float = 0.2
    memory_budget: float = 8e9

    def sizes(self, gap: float, level: int, size: float = math.inf) -> Sizes:
        """Panel sizes (m) of mesh level `level` (0 = coarsest) for the smallest gap and a plate of `size`."""
        f = 1.0 / self.refinement**level
        h_max = min(self.element_to_gap * gap, self.element_to_size * size)
        return Sizes(min(self.edge_to_gap * gap, h_max / 2.0) * f, h_max * f, self.growth)


def _fastcap():
    """The fastcap2 module, or SimulatorNotFound saying how to install it."""
    try:
        import fastcap2
    except ImportError:
        raise SimulatorNotFound(f"the fastcap extractor needs fastcap2; install it with: {FASTCAP_INSTALL}") from None
    return fastcap2


def check_budget(panels: int, budget: float) -> None:
    """FastcapBudgetError when a solve of `panels` does not fit `budget` bytes (BYTES_PER_PANEL)."""
    need = BYTES_PER_PANEL * panels
    if need > budget:
        raise FastcapBudgetError(
            f"fastcap: {panels} panels need about {need / 1e9:.1f} GB (estimated before the solve, "
            f"{BYTES_PER_PANEL / 1e3:g} kB per panel), above the memory budget of {budget / 1e9:.1f} GB; raise "
            "memory_budget_gb in [electrostatics.fastcap], or raise edge_to_gap / element_to_gap"
        )


def _add(surface, panels: Panels, refs: Array | None = None) -> None:
    """Add the panels to a fastcap2 Surface (with a reference point per panel, if given)."""
    corners = panels.corners
    tri = np.all(corners[:, 2] == corners[:, 3], axis=1)
    for k, (c, is_tri) in enumerate(zip(corners.tolist(), tri)):
        rp = {} if refs is None else {"rp": tuple(refs[k])}
        if is_tri:  # fastcap2 2.1's Surface.add_tri calls the quad entry point: the core's triangle one
            surface._add_tri(tuple(c[0]), tuple(c[1]), tuple(c[2]), *rp.values())
        else:
            surface.add_quad(tuple(c[0]), tuple(c[1]), tuple(c[2]), tuple(c[3]), **rp)


def _add_conductor(fc, problem, i: int, conductor: Panels | Layered, eps_r: float) -> None:
    """Conductor i: one surface in the gap medium, or (under a dielectric layer) its face in the
    layer, its back and walls in the medium, and the layer's free surface as a dielectric interface
    (permittivities relative to the medium's: perm_factor carries eps_r)."""
    if isinstance(conductor, Panels):
        surface = fc.Surface(name=f"c{i}")
        _add(surface, conductor)
        problem.add(surface)
        return
    inside = conductor.eps_r / eps_r
    for part, outside in ((conductor.face, inside), (conductor.rest, 1.0)):
        if len(part):  # a guarded face (tests) is a conductor of its own, without back or walls
            surface = fc.Surface(name=f"c{i}")
            _add(surface, part)
            problem.add(surface, group=f"g{i}", outside_perm=outside)
    if not len(conductor.interface):
        return
    surface = fc.Surface(title=f"layer{i}")
    _add(surface, conductor.interface, conductor.refs)
    problem.add(surface, kind=fc.Problem.DIELEC, outside_perm=1.0, inside_perm=inside)


def solve_panels(
    conductors: Sequence[Panels | Layered], eps_r: float, order: int, iter_tol: float
) -> tuple[Array, dict]:
    """Maxwell matrix (n, n) in F of conductors given as panel sets (Layered: under a dielectric
    layer), symmetrised; and the solve's record (panels, order, seconds, asymmetry = max |C - C^T| / max |C|)."""
    fc = _fastcap()
    t0 = time.perf_counter()
    problem = fc.Problem(title="netgen")
    problem.expansion_order, problem.iter_tol = int(order), float(iter_tol)
    problem.perm_factor = float(eps_r)
    for i, conductor in enumerate(conductors):
        _add_conductor(fc, problem, i, conductor, eps_r)
    C = np.asarray(problem.solve(), dtype=float)
    order_of = [int(name.split("%")[0][1:]) for name in problem.conductors()]
    inv = np.argsort(order_of)
    C = C[np.ix_(inv, inv)]
    asym = float(np.max(np.abs(C - C.T)) / np.max(np.abs(C)))
    record = {
        "panels": int(sum(len(p) for p in conductors)),
        "order": int(order),
        "seconds": time.perf_counter() - t0,
        "asymmetry": asym,
    }
    return 0.5 * (C + C.T), record


def converged(
    levels: Sequence[Sequence[Panels | Layered]], eps_r: float, settings: FastcapSettings, names
) -> MaxwellMatrix:
    """The Maxwell matrix from two or more mesh levels (coarse to fine) at expansion_order,
    Richardson-extrapolated (bem.extrapolate: from three levels at the observed order), with the
    coarse level solved again at check_order; error = discretisation estimate (the correction) +
    multipole estimate (the order change)."""
    need = max(sum(len(p) for p in lv) for lv in levels)
    check_budget(need, settings.memory_budget)
    sols, records = [], []
    for lv in levels:
        c, r = solve_panels(lv, eps_r, settings.expansion_order, settings.iter_tol)
        sols.append(c)
        records.append(r)
    check, rk = solve_panels(levels[0], eps_r, settings.check_order, settings.iter_tol)
    best, p = extrapolate(sols, settings.refinement, settings.richardson_order)
    mesh_error, order_error = relative_change(best, sols[-1]), relative_change(check, sols[0])
    record = {
        **asdict(settings),
        "solves": [*records, rk],
        "richardson_order_used": p,
        "mesh_error": mesh_error,
        "order_error": order_error,
        "asymmetry": max(r["asymmetry"] for r in (*records, rk)),
    }
    return MaxwellMatrix(tuple(names), best, sols[-1], mesh_error + order_error, record)


class PreparedFastcap:
    """FastcapExtractor bound to electrodes, plate and basis: panels and basis values once per
    level (numpy only, so it pickles to executor workers); every q is a converged solve."""

    # sampling.sample_chunks' task size: a point is seconds of solving, so each is its own task
    # (in chunks of 256 a design of a few dozen points would be one task on one worker)
    points_per_task = 1

    def __init__(
        self,
        electrodes: Sequence[Electrode],
        plate: Plate,
        basis: Basis,
        eps_r: float,
        thickness: float,
        settings: FastcapSettings,
        source: str | None = None,
        perforation: Perforation | None = None,
    ):
        """Panel every level, refusing before the work when the finest exceeds the budget."""
        self.electrodes = tuple(electrodes)
        self.holes = None if perforation is None else (perforation.hole, perforation.pitch)
        self.eps_r, self.eps, self.thickness, self.settings = eps_r, EPS0 * eps_r, thickness, settings
        self.geometry: PreparedParallelPlate = ParallelPlateExtractor(eps=self.eps, fringe=None).prepare(
            electrodes, plate, basis
        )
        self.ncoords = self.geometry.ncoords
        self.gap = min(e.gap for e in electrodes)
        self.names = ("plate",) + tuple(e.name for e in electrodes)
        self.levels = [self.level(plate, basis, k) for k in range(max(2, settings.levels))]
        panels = sum(len(p) for p in (self.levels[-1][0], *self.levels[-1][2]))
        if BYTES_PER_PANEL * panels > settings.memory_budget:
            problem = (
                f"edge_to_gap = {settings.edge_to_gap:g}, element_to_gap = {settings.element_to_gap:g} give "
                f"{panels} panels on the finest level, about {BYTES_PER_PANEL * panels / 1e9:.3g} GB, above the "
                f"memory budget of {settings.memory_budget / 1e9:g} GB"
            )
            if source is None:
                fix = "raise FastcapSettings.edge_to_gap or element_to_gap, or memory_budget, or lower levels"
                raise FastcapBudgetError(f"fastcap: {problem}; {fix}")
            fix = (
                "in [electrostatics.fastcap] raise edge_to_gap or element_to_gap, or memory_budget_gb, or lower levels"
            )
            raise StructureError(source, "electrostatics.fastcap", problem, fix)

    def level(self, plate: Plate, basis: Basis, k: int) -> tuple[Panels, Array, tuple[Panels | Layered, ...]]:
        """Level k: the undeformed plate, its basis at every panel corner (n*4, ncoords), the
        electrodes (Layered under a dielectric layer)."""
        sizes = self.settings.sizes(self.gap, k, plate.size)
        facing = tuple(e.shape for e in self.electrodes)
        p = plate_panels(plate, self.thickness, sizes, holes=self.holes, facing=facing)
        xy = p.corners.reshape(-1, 3)
        phi = np.asarray(basis(xy[:, 0], xy[:, 1]), dtype=float).reshape(len(xy), -1)
        half = self.thickness / 2.0
        return p, phi, tuple(self._electrode(e, sizes, e.sign * (half + e.gap), plate) for e in self.electrodes)

    @staticmethod
    def _electrode(e: Electrode, sizes, z: float, plate: Plate) -> Panels | Layered:
        """An electrode's panels at height z (graded towards the plate's rim over it): a sheet, or a
        box under its dielectric layer."""
        if e.dielectric_thickness > 0.0:
            return layered_panels(e, sizes, z, -e.sign, plate=plate)
        return electrode_panels(e, sizes, z, plate=plate)

    def panels(self, q: ArrayLike, level: int) -> list[Panels | Layered]:
        """The conductors at q on mesh level `level`: the moved plate, then the electrodes."""
        plate, phi, sheets = self.levels[level]
        dz = (phi @ np.asarray(q, dtype=float)).reshape(len(plate), 4)
        return [plate.moved(dz), *sheets]

    def estimate(self) -> dict:
        """Panels of every level, and the memory and CPU time of one converged Maxwell matrix,
        estimated before any solve (BYTES_PER_PANEL for the finest level; SECONDS_PER_PANEL for
        the levels plus the coarse level's check solve)."""
        panels = [len(plate) + sum(len(p) for p in sheets) for plate, _, sheets in self.levels]
        return {
            "panels": panels,
            "memory_bytes": BYTES_PER_PANEL * max(panels),
            "cpu_seconds": SECONDS_PER_PANEL * (sum(panels) + panels[0]),
        }

    def fingerprint_arrays(self) -> list[Array]:
        """The arrays that identify the panels (bem_sampling.key_of's store folder)."""
        return [
            a
            for plate, phi, sheets in self.levels
            for a in (
                plate.corners,
                phi,
                *[b for p in sheets for b in (p.arrays() if isinstance(p, Layered) else [p.corners])],
            )
        ]

    def maxwell(self, q: ArrayLike) -> MaxwellMatrix:
        """The converged Maxwell matrix at generalized coordinates q (ncoords,)."""
        q = np.asarray(q, dtype=float).reshape(self.ncoords)
        g = self.geometry.min_gap(q)
        if np.isfinite(g).any() and np.min(g[np.isfinite(g)]) <= 0.0:
            raise ValueError("the plate touches an electrode at this q")
        t0 = time.perf_counter()
        m = converged([self.panels(q, k) for k in range(len(self.levels))], self.eps_r, self.settings, self.names)
        m.settings["seconds"] = time.perf_counter() - t0
        return m

    def capacitance(self, Q: ArrayLike) -> Array:
        """Plate-electrode capacitances (nsamples, nelectrodes) in F; nan where the plate touches."""
        q = np.atleast_2d(np.asarray(Q, dtype=float))
        out = np.full((q.shape[0], len(self.electrodes)), np.nan)
        gaps = self.geometry.min_gap(q)
        for i, row in enumerate(q):
            g = np.atleast_2d(gaps)[i]
            if not (np.isfinite(g).any() and np.min(g[np.isfinite(g)]) <= 0.0):
                out[i] = self.maxwell(row).plate_electrode
        return out[0] if np.ndim(Q) == 1 else out

    def gradient(self, Q: ArrayLike) -> Array:
        """dC_i/dq_v by central differences of solves on the same panels (a step closing 2 % of the gap)."""
        amp = np.abs(self.geometry.probe.phi).max(axis=0)
        step = 0.02 * self.gap / np.where(amp > 0, amp, 1.0)
        return central_differences(Q, step, len(self.electrodes), lambda row: self.maxwell)

    def min_gap(self, Q: ArrayLike) -> Array:
        """Smallest local gap under each electrode (the parallel-plate geometry's)."""
        return self.geometry.min_gap(Q)

    def probe_points(self) -> ProbePoints:
        """The contact model's stop candidates (the parallel-plate geometry's)."""
        return self.geometry.probe_points()


@dataclass(frozen=True)
class FastcapExtractor:
    """Multipole-accelerated panel capacitances (FastCap2): relative permittivity, plate thickness
    (m; 0: a sheet), settings (FastcapSettings), the plate's etch-hole grid (None: solid; meshed
    as holes through the plate, fastcap_mesh.perforated_face)."""

    eps_r: float = 1.0
    thickness: float = 0.0
    settings: FastcapSettings = field(default_factory=FastcapSettings)
    source: str | None = None
    perforation: Perforation | None = None

    @property
    def description(self) -> str:
        """What it computes and with which settings (the model report's extractor line)."""
        st = self.settings
        return (
            f"multipole panels (FastCap2, quads, {max(2, st.levels)} mesh levels + Richardson order "
            f"{'observed, else ' if st.levels >= 3 else ''}{st.richardson_order:g}): "
            f"edge_to_gap {st.edge_to_gap:g}, element_to_gap {st.element_to_gap:g}, refinement "
            f"{st.refinement:.3g}, expansion order {st.expansion_order} (check {st.check_order}), "
            f"memory budget {st.memory_budget / 1e9:g} GB"
            + (
                ""
                if self.perforation is None
                else f"; etch holes {self.perforation.hole:g} m on a {self.perforation.pitch:g} m pitch meshed"
                + (f" through {self.thickness:g} m" if self.thickness > 0.0 else "")
            )
        )

    def prepare(self, electrodes: Sequence[Electrode], plate: Plate, basis: Basis) -> PreparedFastcap:
        """Panel the structure once (both levels); each sample is then a converged solve."""
        return PreparedFastcap(
            electrodes, plate, basis, self.eps_r, self.thickness, self.settings, self.source, self.perforation
        )

    def coupling(self, electrodes: Sequence[Electrode], plate: Plate) -> Array:
        """Electrode-electrode capacitances (nel, nel) in F at the undeformed position."""
        prepared = self.prepare(electrodes, plate, lambda x, y: np.zeros((np.size(x), 1)))
        return prepared.maxwell(np.zeros(1)).coupling


def settings_of(s) -> FastcapSettings:
    """FastcapSettings from the structure's [electrostatics.fastcap] table (netgen.structure.fastcap_table:
    keys, types and ranges checked there; memory_budget_gb in GB)."""
    given = dict(getattr(s.electrostatics, "fastcap", ()))
    if "memory_budget_gb" in given:
        given["memory_budget"] = float(given.pop("memory_budget_gb")) * 1e9
    return FastcapSettings(**given)


def from_structure(s, plate: Plate) -> FastcapExtractor:
    """The extractor for a structure (s: netgen.structure.Structure): permittivity, thickness, settings,
    and a proof mass's etch holes (conductor.hole, hole_pitch), meshed through the plate's thickness
    (its Perforation carries the thickness, as the parallel-plate extractor's does: one grid, one form)."""
    thickness = float(getattr(s.conductor, "thickness", 0.0))
    hole, pitch = float(getattr(s.conductor, "hole", 0.0)), float(getattr(s.conductor, "hole_pitch", 0.0))
    return FastcapExtractor(
        eps_r=s.electrostatics.relative_permittivity,
        thickness=thickness,
        settings=settings_of(s),
        source=str(s.source),
        perforation=Perforation(hole, pitch, thickness=thickness) if hole else None,
    )
