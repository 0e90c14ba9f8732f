"""Mechanics from external FEM tools (the structure file's [import] mass_matrix,
stiffness_matrix and modes), all SI (m, kg, N/m):

- Mass and stiffness matrices: Matrix Market files (scipy.io.mmread; ANSYS `*SMAT`/HBMAT ->
  converted, COMSOL "Export matrices"), either modal (n x n for the n coordinates) or full
  (N x N, the FE degrees of freedom, with the full eigenvectors in the modes file). The
  modal matrices Phi^T M Phi and Phi^T K Phi must be diagonal (mass-orthogonal eigenvectors,
  the default of both tools): the MacroModel's coordinates are mass-orthogonal.
- Modes (.npz): `nodes` (npts, 2) x, y of the conductor's nodes; `vectors` (npts, n) the
  vertical displacement of each node per unit of each coordinate, or (N, n) full eigenvectors
  with `w_rows` (npts,) the row of each node's vertical DOF; optional `length_scale` (m per unit
  of the node coordinates, default 1); `names` (n,) coordinate names
  (z, tilt_x, tilt_y are rigid-body motions, anything else an eigenmode); optional `labels`,
  and optional `triangles` (ne, 6): quadratic triangles (3 vertices, then the midpoints of
  edges 01, 12, 02) over which the shapes are interpolated exactly. Without triangles the
  shapes are interpolated by Clough-Tocher cubics on the Delaunay triangulation of the nodes
  (beams: a cubic spline along x).
  Modes (.csv): columns x, y, then one column per coordinate (header = names).

The capacitance tables are read by netgen.electrostatics.imported; the writers of all four
formats are netgen.export.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import scipy.io
from scipy.interpolate import CloughTocher2DInterpolator, CubicSpline
from scipy.spatial import ConvexHull, cKDTree

from ..errors import StructureError
from ..files import read_csv
from ..structure import RIGID_COORDINATES, Structure
from .base import RIGID, Mechanics, rigid_field
from .fields import P2Field


def _fail(path: str | Path, where: str, problem: str, fix: str) -> StructureError:
    return StructureError(str(path), where, problem, fix)


def read_matrix(path: str | Path, where: str) -> np.ndarray:
    """A square, symmetric, finite Matrix Market matrix as a dense array."""
    try:
        a = scipy.io.mmread(str(path))
    except Exception as exc:                       # noqa: BLE001 (any parse failure is the user's file)
        raise _fail(path, where, f"not a Matrix Market file: {exc}",
                    "export the matrix in Matrix Market coordinate format (.mtx, see docs/import.md)")
    a = a.toarray() if hasattr(a, "toarray") else np.asarray(a)
    a = np.asarray(a, dtype=float)
    if a.ndim != 2 or a.shape[0] != a.shape[1] or a.shape[0] == 0:
        raise _fail(path, where, f"matrix of shape {a.shape} is not square", "export the full square matrix")
    if not np.all(np.isfinite(a)):
        raise _fail(path, where, "matrix has non-finite entries", "check the export")
    if np.abs(a - a.T).max() > 1e-9 * max(np.abs(a).max(), 1e-300):
        raise _fail(path, where, "matrix is not symmetric", "export the symmetric mass/stiffness matrix")
    return a


def read_modes(path: str | Path) -> dict:
    """Node coordinates, vertical displacements per coordinate, names (and optional triangles)."""
    path = Path(path)
    where = "import.modes"
    if path.suffix == ".csv":
        header, rows = read_csv(path, where)
        if header[:2] != ["x", "y"] or len(header) < 3:
            raise _fail(path, where, f"header {header[:3]} does not start with x, y, <coordinate>",
                        "write a header line: x,y,z,tilt_x,m1,... (one column per coordinate)")
        data = {"nodes": rows[:, :2], "vectors": rows[:, 2:], "names": header[2:]}
    else:
        with np.load(path, allow_pickle=False) as z:
            missing = [k for k in ("nodes", "vectors", "names") if k not in z]
            if missing:
                raise _fail(path, where, f"missing arrays {missing}", "save nodes, vectors and names (np.savez)")
            data = {k: z[k] for k in z.files}
        data["names"] = [str(n) for n in data["names"]]
    nodes, vectors = np.asarray(data["nodes"], float), np.asarray(data["vectors"], float)
    if nodes.ndim != 2 or nodes.shape[1] != 2:
        raise _fail(path, where, f"nodes has shape {nodes.shape}, expected (npts, 2)", "give x, y per node in m")
    if vectors.ndim != 2 or vectors.shape[1] != len(data["names"]):
        raise _fail(path, where, f"vectors has shape {vectors.shape} for {len(data['names'])} names",
                    "one column per coordinate name")
    if "w_rows" not in data and vectors.shape[0] != nodes.shape[0]:
        raise _fail(path, where, f"{vectors.shape[0]} vector rows for {nodes.shape[0]} nodes",
                    "give one row per node, or full eigenvectors with w_rows")
    if not (np.all(np.isfinite(nodes)) and np.all(np.isfinite(vectors))):
        raise _fail(path, where, "non-finite node coordinates or eigenvector entries", "check the export")
    for n in data["names"]:
        if not n.isidentifier() or "error" in n.lower():
            raise _fail(path, where, f"coordinate name {n!r} is not a simple identifier",
                        "use letters, digits and _ (e.g. m1, m2)")
    data["nodes"], data["vectors"], data["path"] = nodes, vectors, str(path)
    return data


def shape_function(s: Structure, data: dict):
    """basis(x, y) -> (npts, n) from the imported nodal values (see the module docstring)."""
    unit = float(data.get("length_scale", 1.0))
    nodes = data["nodes"] * unit
    w = data["vectors"][np.asarray(data["w_rows"], int)] if "w_rows" in data else data["vectors"]
    rigid = [k for k, n in enumerate(data["names"]) if n in RIGID_COORDINATES]
    if rigid:
        _check_rigid(data, nodes, w, rigid)
        elastic = [k for k in range(w.shape[1]) if k not in rigid]
        inner = _shapes(s, data, nodes, w[:, elastic], unit)

        def basis(x, y):
            x, y = np.ravel(np.asarray(x, float)), np.ravel(np.asarray(y, float))
            out = np.empty((len(x), w.shape[1]))
            for k in rigid:
                out[:, k] = rigid_field(data["names"][k], x, y)
            if elastic:
                out[:, elastic] = inner(x, y)
            return out
        return basis
    return _shapes(s, data, nodes, w, unit)


def _check_rigid(data: dict, nodes: np.ndarray, w: np.ndarray, rigid: list[int]) -> None:
    """Rigid-body coordinates use their exact fields (z: 1, tilt_x: y, tilt_y: -x); the imported
    nodal values must agree with them."""
    exact = {"z": np.ones(len(nodes)), "tilt_x": nodes[:, 1], "tilt_y": -nodes[:, 0]}
    for k in rigid:
        name = data["names"][k]
        ref = exact[name]
        if np.abs(w[:, k] - ref).max() > 1e-6 * max(np.abs(ref).max(), 1e-300):
            raise _fail(data.get("path", "modes"), "import.modes", f"column {name!r} is not the rigid-body field "
                        f"({'1' if name == 'z' else 'y' if name == 'tilt_x' else '-x'} per unit, x, y in m)",
                        "rename the column if it is an eigenmode, or export the rigid motion per unit amplitude")


def _shapes(s: Structure, data: dict, nodes: np.ndarray, w: np.ndarray, unit: float):
    """Interpolation of elastic mode shapes w (npts, k) given at the nodes (m)."""
    if "triangles" in data and np.shape(data["triangles"])[1] == 6 and s.conductor.outline_shape == "disk":
        ratio = unit / s.conductor.radius          # nodes in units of the radius stay bit-exact
        return _p2_disk(data["nodes"] if ratio == 1.0 else data["nodes"] * ratio, w,
                        np.asarray(data["triangles"], int), s.conductor.radius)
    if s.conductor.one_dimensional:                       # beams: the shapes vary along x only
        xs, inv = np.unique(nodes[:, 0], return_inverse=True)
        mean = np.zeros((len(xs), w.shape[1]))
        np.add.at(mean, inv, w)
        mean /= np.bincount(inv)[:, None]
        spline = CubicSpline(xs, mean, axis=0)
        return lambda x, y: spline(np.clip(np.ravel(x), xs[0], xs[-1]))
    interp = CloughTocher2DInterpolator(nodes, w)
    tree = cKDTree(nodes)

    def basis(x, y):
        pts = np.stack([np.ravel(x), np.ravel(y)], axis=1)
        out = interp(pts)
        bad = np.isnan(out).any(axis=1)
        if bad.any():                                      # outside the node hull: nearest node
            out[bad] = w[tree.query(pts[bad])[1]]
        return out
    return basis


def _p2_disk(p: np.ndarray, w: np.ndarray, tri: np.ndarray, radius: float):
    """Exact quadratic-triangle interpolation on a disk mesh, node coordinates p in units of the
    radius (points between the mesh polygon and the circle projected radially onto the polygon,
    as netgen's own plate modes do)."""
    v0, v1, v2 = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
    inverse = np.linalg.inv(np.stack([v1 - v0, v2 - v0], axis=-1))
    verts = np.unique(p[tri[:, :3]].reshape(-1, 2), axis=0)
    rim = verts[ConvexHull(verts).vertices]
    angles = np.mod(np.arctan2(rim[:, 1], rim[:, 0]), 2 * np.pi)
    order = np.argsort(angles)
    field = P2Field(origin=v0, inverse=inverse, nodes=w[tri], tree=cKDTree(p[tri[:, :3]].mean(axis=1)),
                    rim_angles=np.append(angles[order], angles[order[0]] + 2 * np.pi),
                    rim_points=np.vstack([rim[order], rim[order][:1]]))
    return lambda x, y: field(np.ravel(x) / radius, np.ravel(y) / radius)


# ------------------------------------------------------------------ the stage

def mechanics(s: Structure) -> Mechanics:
    """The Mechanics stage from imported M, K and modes."""
    imp = s.imports
    data = read_modes(imp.modes)
    M = read_matrix(imp.mass_matrix, "import.mass_matrix")
    K = read_matrix(imp.stiffness_matrix, "import.stiffness_matrix")
    names, n = data["names"], len(data["names"])
    if M.shape != K.shape:
        raise _fail(imp.stiffness_matrix, "import.stiffness_matrix", f"K is {K.shape}, M is {M.shape}",
                    "export M and K of the same model")
    if M.shape[0] == n:
        mr, kr, form = M, K, "modal"
    elif M.shape[0] == data["vectors"].shape[0]:
        phi = data["vectors"]
        mr, kr, form = phi.T @ M @ phi, phi.T @ K @ phi, "full (projected on the eigenvectors)"
    else:
        raise _fail(imp.mass_matrix, "import.mass_matrix", f"M is {M.shape}: neither {n} x {n} (modal) nor "
                    f"{data['vectors'].shape[0]} square (full, one row per eigenvector entry)",
                    "export the modal matrices or the full matrices matching the eigenvectors")
    mass, stiff = np.diag(mr).copy(), np.diag(kr).copy()
    off = max(_offdiag(mr), _offdiag(kr))
    if off > 1e-6:
        raise _fail(imp.modes, "import.modes", f"the modal matrices are not diagonal (largest relative "
                    f"off-diagonal {off:.2e})", "export mass-orthogonal eigenvectors (both tools' default)")
    if np.any(mass <= 0) or np.any(stiff < -1e-9 * np.abs(stiff).max()):
        raise _fail(imp.mass_matrix, "import.mass_matrix", "modal masses must be positive and stiffnesses >= 0",
                    "check the export")
    stiff = np.maximum(stiff, 0.0)
    kinds = [RIGID.get(nm, ("mode", "m")) for nm in names]
    labels = [str(x) for x in data["labels"]] if "labels" in data else [
        "" if nm in RIGID_COORDINATES else nm for nm in names]
    freqs = np.sqrt(stiff / mass) / (2 * math.pi)
    basis = shape_function(s, data)
    report = {"imported": {"mass_matrix": Path(imp.mass_matrix).name, "stiffness_matrix": Path(imp.stiffness_matrix).name,
                           "modes": Path(imp.modes).name, "matrices": form, "nodes": int(len(data["nodes"])),
                           "modal_offdiagonal_max": off}}
    return Mechanics(list(names), [k for k, _ in kinds], [u for _, u in kinds], labels, mass, stiff, freqs,
                     basis, report)


def _offdiag(a: np.ndarray) -> float:
    d = np.sqrt(np.abs(np.outer(np.diag(a), np.diag(a))))
    off = np.abs(a - np.diag(np.diag(a)))
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(d > 0, off / d, np.where(off > 0, np.inf, 0.0))
    return float(r.max()) if r.size else 0.0
