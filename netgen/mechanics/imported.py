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
from scipy.interpolate import CloughTocher2DInterpolator, CubicSpline
from scipy.spatial import ConvexHull, cKDTree

from ..core.files import load_npz, read_csv
from ..core.reader import identifier
from ..core.text import shown, text_problem
from ..structure import RIGID_COORDINATES, Structure
from .base import RIGID, Mechanics, rigid_field
from .fields import P2Field
from .import_checks import (
    check_duplicate_nodes,
    check_full,
    check_nodes,
    fail,
    line_of,
    modal_values,
    read_matrix,
    where_row,
)

WHERE = "import.modes"


MODES_ARRAYS = ("nodes", "vectors", "names", "labels", "length_scale", "triangles", "w_rows")


def read_modes(path: str | Path) -> dict:
    """Node coordinates, vertical displacements per coordinate, names (and optional triangles,
    w_rows, length_scale, labels), each checked for type, shape, range and finiteness."""
    path = Path(path)
    if path.suffix == ".csv":
        t = read_csv(path, WHERE)
        if t.header[:2] != ["x", "y"] or len(t.header) < 3:
            raise fail(
                path,
                WHERE,
                f"header {t.header[:3]} does not start with x, y, <coordinate>",
                "write a header line: x,y,z,tilt_x,m1,... (one column per coordinate)",
                t.header_line,
            )
        data = {"nodes": t.values[:, :2], "vectors": t.values[:, 2:], "names": t.header[2:], "lines": t.lines}
    else:
        data = load_npz(path, WHERE, ("nodes", "vectors", "names"), MODES_ARRAYS)
        data["names"] = text_array(path, data, "names")
        data["lines"] = None
    data["path"] = str(path)
    check_arrays(path, data)
    if "w_rows" not in data and "triangles" not in data:
        keep = check_duplicate_nodes(str(path), data["nodes"], data["vectors"], data["lines"])
        data["nodes"], data["vectors"] = data["nodes"][keep], data["vectors"][keep]
        data["lines"] = None if data["lines"] is None else data["lines"][keep]
    return data


def text_array(path: Path, data: dict, key: str) -> list[str]:
    """A 1-D array of strings of an .npz (names, labels)."""
    a = data[key]
    if a.ndim != 1 or a.dtype.kind not in "US":
        raise fail(
            path,
            WHERE,
            f"{key} is a {a.dtype} array of shape {a.shape}, not a list of strings",
            f"save {key}=np.array(['z', 'm1', ...]) (one string per coordinate)",
        )
    return [x.decode("utf-8", "replace") if isinstance(x, bytes) else str(x) for x in a]


def numeric(path: Path, data: dict, key: str, kinds: str = "iuf") -> np.ndarray:
    """An array of an .npz (or CSV) that must hold plain numbers."""
    a = np.asarray(data[key])
    if a.dtype.kind not in kinds:
        raise fail(
            path,
            WHERE,
            f"{key} holds {a.dtype} values, not {'integers' if kinds == 'iu' else 'numbers'}",
            f"save {key} as a {'integer' if kinds == 'iu' else 'float'} array",
        )
    return a


def check_arrays(path: Path, data: dict) -> None:
    """Shapes, finiteness and index ranges of the modes arrays (rows named as in the file)."""
    names, lines = data["names"], data["lines"]
    nodes = numeric(path, data, "nodes").astype(float)
    vectors = numeric(path, data, "vectors").astype(float)
    if nodes.ndim != 2 or nodes.shape[1] != 2 or len(nodes) == 0:
        raise fail(path, WHERE, f"nodes has shape {nodes.shape}, expected (npts, 2)", "give x, y per node in m")
    if vectors.ndim != 2 or vectors.shape[1] != len(names):
        raise fail(
            path, WHERE, f"vectors has shape {vectors.shape} for {len(names)} names", "one column per coordinate name"
        )
    for n in names:
        if not identifier(n) or "error" in n.lower():
            raise fail(
                path,
                WHERE,
                f"coordinate name {shown(n)} is not a simple identifier",
                "use letters, digits and _ (e.g. m1, m2)",
            )
        if names.count(n) > 1:
            raise fail(path, WHERE, f"coordinate {n!r} is named twice", "give each coordinate one column")
    if "labels" in data and len(np.ravel(data["labels"])) != len(names):
        raise fail(
            path,
            WHERE,
            f"{len(np.ravel(data['labels']))} labels for {len(names)} coordinates",
            "give one label per coordinate (or none)",
        )
    for k, label in enumerate(np.ravel(data.get("labels", ()))):
        if text_problem(str(label)):
            raise fail(
                path,
                f"{WHERE}.labels[{k}]",
                f"label {shown(str(label))} {text_problem(str(label))}",
                "write each label as one line of printable text (e.g. '2,0c'; no line breaks or other "
                "control characters): labels are copied into the netlist headers",
            )
    for key, a in (("nodes", nodes), ("vectors", vectors)):
        bad = np.argwhere(~np.isfinite(a))
        if len(bad):
            r, k = bad[0]
            col = (["x", "y"] if key == "nodes" else names)[k]
            raise fail(
                path,
                WHERE,
                f"{key} {where_row(int(r), lines)}, column {col!r}, is {a[r, k]}",
                "export finite node coordinates and displacements",
                line_of(int(r), lines),
            )
    data["nodes"], data["vectors"] = nodes, vectors
    check_optional(path, data, len(nodes), len(vectors))
    if "w_rows" not in data and len(vectors) != len(nodes):
        raise fail(
            path,
            WHERE,
            f"{len(vectors)} vector rows for {len(nodes)} nodes",
            "give one row per node, or full eigenvectors with w_rows",
        )
    w = vectors[data["w_rows"]] if "w_rows" in data else vectors
    for k, n in enumerate(names):
        if not np.any(w[:, k]):
            raise fail(
                path,
                WHERE,
                f"coordinate {n!r} has zero displacement at every node",
                "export the mode shape (vertical displacement per unit amplitude), or drop the column",
            )


def check_optional(path: Path, data: dict, npts: int, nrows: int) -> None:
    """length_scale (positive), w_rows (one vector row per node), triangles (6 node indices each)."""
    if "length_scale" in data:
        unit = numeric(path, data, "length_scale")
        if unit.size != 1 or not math.isfinite(float(unit.ravel()[0])) or not float(unit.ravel()[0]) > 0:
            raise fail(
                path,
                WHERE,
                f"length_scale = {unit.tolist()} is not one positive number",
                "save length_scale = metres per unit of the node coordinates (1.0 for m)",
            )
        data["length_scale"] = float(unit.ravel()[0])
    for key, shape, hi in (("w_rows", (npts,), nrows), ("triangles", (None, 6), npts)):
        if key not in data:
            continue
        a = numeric(path, data, key, "iu")
        if (
            a.ndim != len(shape)
            or any(want is not None and got != want for got, want in zip(a.shape, shape))
            or a.size == 0
        ):
            raise fail(
                path,
                WHERE,
                f"{key} has shape {a.shape}, expected {tuple('n' if d is None else d for d in shape)}",
                "w_rows: the vertical-DOF row of each node; triangles: 6 node indices per quadratic triangle",
            )
        if a.min() < 0 or a.max() >= hi:
            raise fail(
                path,
                WHERE,
                f"{key} holds index {int(a.max() if a.max() >= hi else a.min())} outside 0..{hi - 1}",
                f"give 0-based indices below {hi}",
            )
        data[key] = a.astype(int)


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
            raise fail(
                data.get("path", "modes"),
                WHERE,
                f"column {name!r} is not the rigid-body field "
                f"({'1' if name == 'z' else 'y' if name == 'tilt_x' else '-x'} per unit, x, y in m)",
                "rename the column if it is an eigenmode, or export the rigid motion per unit amplitude",
            )


def _shapes(s: Structure, data: dict, nodes: np.ndarray, w: np.ndarray, unit: float):
    """Interpolation of elastic mode shapes w (npts, k) given at the nodes (m)."""
    if "triangles" in data and np.shape(data["triangles"])[1] == 6 and s.conductor.outline_shape == "disk":
        ratio = unit / s.conductor.radius  # nodes in units of the radius stay bit-exact
        return _p2_disk(
            data["nodes"] if ratio == 1.0 else data["nodes"] * ratio,
            w,
            np.asarray(data["triangles"], int),
            s.conductor.radius,
        )
    if s.conductor.one_dimensional:  # beams: the shapes vary along x only
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
        if bad.any():  # outside the node hull: nearest node
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
    field = P2Field(
        origin=v0,
        inverse=inverse,
        nodes=w[tri],
        tree=cKDTree(p[tri[:, :3]].mean(axis=1)),
        rim_angles=np.append(angles[order], angles[order[0]] + 2 * np.pi),
        rim_points=np.vstack([rim[order], rim[order][:1]]),
    )
    return lambda x, y: field(np.ravel(x) / radius, np.ravel(y) / radius)


# ------------------------------------------------------------------ the stage


def mechanics(s: Structure) -> Mechanics:
    """The Mechanics stage from imported M, K and modes, each checked before it is used."""
    imp = s.imports
    data = read_modes(imp.modes)
    names, n = data["names"], len(data["names"])
    unit = float(data.get("length_scale", 1.0))
    check_nodes(s, data["path"], data["nodes"] * unit, data["lines"])
    full = data["vectors"].shape[0]
    sizes = {n: f"modal, one per coordinate of {Path(imp.modes).name}"}
    if full != n:
        sizes[full] = "full, one per eigenvector row"
    M = read_matrix(imp.mass_matrix, "import.mass_matrix", sizes)
    K = read_matrix(imp.stiffness_matrix, "import.stiffness_matrix", sizes)
    if M.shape != K.shape:
        raise fail(
            imp.stiffness_matrix,
            "import.stiffness_matrix",
            f"K is {K.shape}, M is {M.shape}",
            "export M and K of the same model",
        )
    if M.shape[0] == n:
        mr, kr, form = M, K, "modal"
    else:
        check_full(imp.mass_matrix, imp.stiffness_matrix, M, K)
        phi = data["vectors"]
        mr, kr, form = phi.T @ M @ phi, phi.T @ K @ phi, "full (projected on the eigenvectors)"
    mass, stiff = np.diag(mr).copy(), np.diag(kr).copy()
    off = max(
        diagonal(mr, imp.mass_matrix, "import.mass_matrix", form, imp.modes),
        diagonal(kr, imp.stiffness_matrix, "import.stiffness_matrix", form, imp.modes),
    )
    stiff = modal_values(s, names, mass, stiff, imp.mass_matrix, imp.stiffness_matrix)
    kinds = [RIGID.get(nm, ("mode", "m")) for nm in names]
    labels = (
        [str(x) for x in np.ravel(data["labels"])]
        if "labels" in data
        else ["" if nm in RIGID_COORDINATES else nm for nm in names]
    )
    freqs = np.sqrt(stiff / mass) / (2 * math.pi)
    basis = shape_function(s, data)
    report = {
        "imported": {
            "mass_matrix": Path(imp.mass_matrix).name,
            "stiffness_matrix": Path(imp.stiffness_matrix).name,
            "modes": Path(imp.modes).name,
            "matrices": form,
            "nodes": int(len(data["nodes"])),
            "modal_offdiagonal_max": off,
        }
    }
    return Mechanics(
        list(names), [k for k, _ in kinds], [u for _, u in kinds], labels, mass, stiff, freqs, basis, report
    )


def diagonal(a: np.ndarray, path: str, where: str, form: str, modes: str) -> float:
    """The largest relative off-diagonal entry |a_ij| / sqrt(a_ii a_jj) of a modal matrix; above
    1e-6 the coordinates are coupled, refused naming the entry (the matrix file for modal
    matrices, the modes file for projected full ones)."""
    d = np.sqrt(np.abs(np.outer(np.diag(a), np.diag(a))))
    off = np.abs(a - np.diag(np.diag(a)))
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(d > 0, off / d, np.where(off > 0, np.inf, 0.0))
    worst = float(r.max()) if r.size else 0.0
    if worst > 1e-6:
        j, i = sorted(np.unravel_index(np.argmax(r), r.shape))  # the lower triangle, as stored
        modal = form == "modal"
        raise fail(
            path if modal else modes,
            where if modal else WHERE,
            f"the modal matrix is not diagonal: entry ({i + 1}, {j + 1}) = {a[i, j]:.4g} is {worst:.2e} "
            "of sqrt(a_ii a_jj)" + ("" if modal else " (after projection on the eigenvectors)"),
            "export mass-orthogonal eigenvectors and the diagonal modal matrices (both tools' default)",
        )
    return worst
