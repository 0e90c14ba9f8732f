"""Writers of the [import] formats (netgen.mechanics.imported, netgen.electrostatics.imported):
any build's modal M and K (.mtx), mode shapes (.npz; exact quadratic triangles for the free
disk, beam nodes for beams) and capacitance samples (.npz, and .csv with csv_too): format
examples for FEM users and the round-trip reference of the importers."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import scipy.io

from .build import Build
from .electrostatics.sampling import box_factors, holdout_points, sampling_grid
from .mechanics import free_disk
from .mechanics.fields import P2_NODES
from .structure import FreeDisk, Structure


def export(b: Build, folder: str | Path, csv_too: bool = False) -> dict[str, Path]:
    """Write a build's modal M and K (.mtx), mode shapes (.npz: exact quadratic triangles for the
    free disk, beam nodes for beams) and capacitance samples (.npz) in the import formats."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    m, s = b.mechanics, b.structure
    out = {
        "mass_matrix": folder / "M.mtx",
        "stiffness_matrix": folder / "K.mtx",
        "modes": folder / "modes.npz",
        "capacitance": folder / "capacitance.npz",
    }
    scipy.io.mmwrite(str(out["mass_matrix"]), np.diag(m.masses), precision=17, symmetry="symmetric")
    scipy.io.mmwrite(str(out["stiffness_matrix"]), np.diag(m.stiffnesses), precision=17, symmetry="symmetric")
    nodes, tri, unit = _export_nodes(s)
    vectors = m.basis(nodes[:, 0] * unit, nodes[:, 1] * unit)
    if isinstance(s.conductor, FreeDisk) and s.coordinates.modes:  # the nonconforming elements' own values
        elastic = [k for k, kind in enumerate(m.kinds) if kind == "mode"]
        vectors[:, elastic] = _disk_mode_values(s)
    extra = {"triangles": tri} if tri is not None else {}
    np.savez(
        out["modes"],
        nodes=nodes,
        vectors=vectors,
        names=np.array(m.names),
        labels=np.array(m.labels),
        length_scale=unit,
        **extra,
    )
    n = len(b.scales)
    grid_x, grid_c = _with_touching(
        b.grid, sampling_grid(n, s.sampling.levels, s.sampling.range) * box_factors(s.sampling, n)
    )
    hold_x, hold_c = _with_touching(
        b.holdout, holdout_points(n, s.fit.holdout, s.sampling.range, s.fit.seed, box_factors(s.sampling, n))
    )
    np.savez(
        out["capacitance"],
        q=grid_x * b.scales,
        c=grid_c,
        holdout_q=hold_x * b.scales,
        holdout_c=hold_c,
        coordinates=np.array(m.names),
        electrodes=np.array([e.name for e in b.model.electrodes]),
    )
    if csv_too:
        out["modes_csv"], out["capacitance_csv"] = folder / "modes.csv", folder / "capacitance.csv"
        np.savetxt(
            out["modes_csv"],
            np.column_stack([nodes * unit, vectors]),
            delimiter=",",
            comments="",
            header=",".join(["x", "y"] + list(m.names)),
            fmt="%.17g",
        )
        rows = np.vstack(
            [np.column_stack([b.grid.x * b.scales, b.grid.c]), np.column_stack([b.holdout.x * b.scales, b.holdout.c])]
        )
        with open(out["capacitance_csv"], "w", newline="", encoding="utf-8") as fh:
            wr = csv.writer(fh)
            wr.writerow([f"q:{n}" for n in m.names] + [f"C:{e.name}" for e in b.model.electrodes] + ["set"])
            for k, r in enumerate(rows):
                wr.writerow([repr(float(v)) for v in r] + ["fit" if k < len(b.grid.x) else "check"])
    return out


def _disk_mode_values(s: Structure) -> np.ndarray:
    """Per-element quadratic node values (6 per triangle) of the free disk's selected modes: the
    Morley field is discontinuous across elements, so values at shared nodes are not unique."""
    nodes = free_disk.selected_modes(s).field.nodes
    return nodes.reshape(-1, nodes.shape[-1])


def _with_touching(samples, full: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The sample table with the dropped (touching) points of the full point set back in as NaN rows."""
    if samples.excluded == 0 or len(full) != len(samples.x) + samples.excluded:
        return samples.x, samples.c
    c = np.full((len(full), samples.c.shape[1]), np.nan)
    k = 0
    for i, row in enumerate(full):
        if k < len(samples.x) and np.array_equal(row, samples.x[k]):
            c[i] = samples.c[k]
            k += 1
    if k != len(samples.x):
        return samples.x, samples.c
    return full, c


def _export_nodes(s: Structure) -> tuple[np.ndarray, np.ndarray | None, float]:
    """Nodes (and quadratic triangles) at which the shapes are exported."""
    c = s.conductor
    if isinstance(c, FreeDisk):
        mesh = free_disk.unit_disk(c.poisson_ratio, s.fem.refine).basis.mesh
        p, t = mesh.p, mesh.t
        a = np.stack([p[:, t[1]] - p[:, t[0]], p[:, t[2]] - p[:, t[0]]], axis=-1)  # (2, ne, 2)
        pts = p[:, t[0]][:, :, None] + np.einsum("ien,nk->iek", a, P2_NODES)  # (2, ne, 6)
        pts[:, :, 0], pts[:, :, 1], pts[:, :, 2] = p[:, t[0]], p[:, t[1]], p[:, t[2]]  # exact vertices
        nodes = pts.transpose(1, 2, 0).reshape(-1, 2)  # in units of the radius
        return nodes, np.arange(len(nodes)).reshape(-1, 6), c.radius
    x0, x1, y0, y1 = c.outline()
    if c.one_dimensional:
        x = np.linspace(x0, x1, 8 * c.elements + 1)
        return np.column_stack([x, np.zeros_like(x)]), None, 1.0
    x, y = np.meshgrid(np.linspace(x0, x1, 41), np.linspace(y0, y1, 41))
    return np.column_stack([x.ravel(), y.ravel()]), None, 1.0
