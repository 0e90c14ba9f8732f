"""Data from external FEM and field solvers (the structure file's [import] table).

Formats (all SI: m, kg, N/m, F):

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
- Capacitance table (.npz): `q` (npts, n) coordinates in SI (m, rad), `c` (npts, nel)
  plate-electrode capacitances in F, `coordinates` (n,) and `electrodes` (nel,) names;
  optional `holdout_q`, `holdout_c` (held-out check points; otherwise every fifth point is
  held out). NaN capacitances (touching) are dropped.
  Capacitance table (.csv): columns q:<coordinate> ... and C:<electrode> ..., optional `set`
  column (fit / check).

The fit and the emitters are the same as for netgen's own data (pipeline.fit_all, assemble).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import scipy.io
from scipy.interpolate import CloughTocher2DInterpolator, CubicSpline
from scipy.spatial import ConvexHull, cKDTree

from .fit import holdout_points, sampling_grid
from .structure import RIGID_COORDINATES, StructureError

KINDS = {"z": ("translation", "m"), "tilt_x": ("rotation", "rad"), "tilt_y": ("rotation", "rad")}


def _fail(path: str, where: str, problem: str, fix: str) -> StructureError:
    return StructureError(str(path), where, problem, fix)


# ------------------------------------------------------------------ readers

def read_matrix(path: str | Path, where: str) -> np.ndarray:
    """A square, symmetric, finite Matrix Market matrix as a dense array."""
    try:
        a = scipy.io.mmread(str(path))
    except Exception as exc:                       # noqa: BLE001 (any parse failure is the user's file)
        raise _fail(path, where, f"not a Matrix Market file: {exc}",
                    "export the matrix in Matrix Market coordinate format (.mtx, see README)")
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
        header, rows = _read_csv(path, where)
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


def read_capacitance(path: str | Path) -> dict:
    """Capacitance table: q (SI), c (F), coordinate and electrode names, optional held-out set."""
    path = Path(path)
    where = "import.capacitance"
    if path.suffix == ".csv":
        header, rows = _read_csv(path, where, text_columns=("set",))
        qcols = [i for i, h in enumerate(header) if h.startswith("q:")]
        ccols = [i for i, h in enumerate(header) if h.startswith("C:")]
        if not qcols or not ccols:
            raise _fail(path, where, "no q:<coordinate> or C:<electrode> columns",
                        "write a header like q:z,q:m1,C:top,C:bot[,set]")
        check = rows["set"] == "check" if "set" in header else None
        values = rows["values"]
        q, c = values[:, qcols], values[:, ccols]
        data = {"q": q, "c": c, "coordinates": [header[i][2:] for i in qcols],
                "electrodes": [header[i][2:] for i in ccols]}
        if check is not None:
            data.update({"holdout_q": q[check], "holdout_c": c[check], "q": q[~check], "c": c[~check]})
    else:
        with np.load(path, allow_pickle=False) as z:
            missing = [k for k in ("q", "c", "coordinates", "electrodes") if k not in z]
            if missing:
                raise _fail(path, where, f"missing arrays {missing}", "save q, c, coordinates, electrodes (np.savez)")
            data = {k: z[k] for k in z.files}
        data["coordinates"] = [str(n) for n in data["coordinates"]]
        data["electrodes"] = [str(n) for n in data["electrodes"]]
    for key in ("q", "c", "holdout_q", "holdout_c"):
        if key in data:
            data[key] = np.atleast_2d(np.asarray(data[key], float))
    if data["q"].shape[0] != data["c"].shape[0] or data["q"].shape[1] != len(data["coordinates"]) \
            or data["c"].shape[1] != len(data["electrodes"]):
        raise _fail(path, where, f"q {data['q'].shape} and c {data['c'].shape} do not match "
                    f"{len(data['coordinates'])} coordinates and {len(data['electrodes'])} electrodes",
                    "one row per sample point, one column per coordinate / electrode")
    return data


def _read_csv(path: Path, where: str, text_columns: tuple[str, ...] = ()):
    with open(path, newline="", encoding="utf-8") as fh:
        lines = [r for r in csv.reader(fh) if r and not r[0].lstrip().startswith("#")]
    if len(lines) < 2:
        raise _fail(path, where, "no data rows", "write a header line and one row per point")
    header = [h.strip() for h in lines[0]]
    keep = [i for i, h in enumerate(header) if h not in text_columns]
    try:
        values = np.array([[float(r[i]) for i in keep] for r in lines[1:]])
    except (ValueError, IndexError) as exc:
        raise _fail(path, where, f"cannot read the numbers: {exc}", "numbers only, one per column")
    if not text_columns:
        return header, values
    out = {"values": values}
    for name in text_columns:
        if name in header:
            out[name] = np.array([r[header.index(name)].strip() for r in lines[1:]])
    return [header[i] for i in keep] + [h for h in header if h in text_columns], out


# ------------------------------------------------------------------ shapes

def shape_function(s, data: dict):
    """basis(x, y) -> (npts, n) from the imported nodal values (see the module docstring)."""
    unit = float(data.get("length_scale", 1.0))
    nodes = data["nodes"] * unit
    w = data["vectors"][np.asarray(data["w_rows"], int)] if "w_rows" in data else data["vectors"]
    kind = s.conductor.kind
    rigid = [k for k, n in enumerate(data["names"]) if n in RIGID_COORDINATES]
    if rigid:
        _check_rigid(data, nodes, w, rigid)
        elastic = [k for k in range(w.shape[1]) if k not in rigid]
        inner = _shapes(s, data, nodes, w[:, elastic], unit)
        fields = {"z": lambda x, y: np.ones_like(x), "tilt_x": lambda x, y: y, "tilt_y": lambda x, y: -x}

        def basis(x, y):
            x, y = np.ravel(np.asarray(x, float)), np.ravel(np.asarray(y, float))
            out = np.empty((len(x), w.shape[1]))
            for k in rigid:
                out[:, k] = fields[data["names"][k]](x, y)
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


def _shapes(s, data: dict, nodes: np.ndarray, w: np.ndarray, unit: float):
    """Interpolation of elastic mode shapes w (npts, k) given at the nodes (m)."""
    kind = s.conductor.kind
    if "triangles" in data and np.shape(data["triangles"])[1] == 6 and kind == "free_disk":
        ratio = unit / s.conductor.radius          # nodes in units of the radius stay bit-exact
        return _p2_disk(data["nodes"] if ratio == 1.0 else data["nodes"] * ratio, w,
                        np.asarray(data["triangles"], int), s.conductor.radius)
    if kind in ("clamped_clamped_beam", "cantilever"):
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
    from .mechanics import _P2Field
    v0, v1, v2 = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
    inverse = np.linalg.inv(np.stack([v1 - v0, v2 - v0], axis=-1))
    verts = np.unique(p[tri[:, :3]].reshape(-1, 2), axis=0)
    rim = verts[ConvexHull(verts).vertices]
    angles = np.mod(np.arctan2(rim[:, 1], rim[:, 0]), 2 * np.pi)
    order = np.argsort(angles)
    field = _P2Field(origin=v0, inverse=inverse, nodes=w[tri], tree=cKDTree(p[tri[:, :3]].mean(axis=1)),
                     rim_angles=np.append(angles[order], angles[order[0]] + 2 * np.pi),
                     rim_points=np.vstack([rim[order], rim[order][:1]]))
    return lambda x, y: field(np.ravel(x) / radius, np.ravel(y) / radius)


# ------------------------------------------------------------------ pipeline stages

def mechanics(s):
    """The Mechanics stage from imported M, K and modes."""
    from .pipeline import Mechanics
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
    kinds = [KINDS.get(nm, ("mode", "m")) for nm in names]
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


def samples(s, m, described, scales: np.ndarray):
    """Grid and held-out Samples from the imported capacitance table (columns mapped by name)."""
    from .pipeline import Samples
    path = s.imports.capacitance
    t = read_capacitance(path)
    where = "import.capacitance"
    cols = []
    for nm in m.names:
        if nm not in t["coordinates"]:
            raise _fail(path, where, f"no column for coordinate {nm!r} (table has {t['coordinates']})",
                        "give one q column per model coordinate, named like the coordinates")
        cols.append(t["coordinates"].index(nm))
    els = []
    for e in described:
        if e.name not in t["electrodes"]:
            raise _fail(path, where, f"no column for electrode {e.name!r} (table has {t['electrodes']})",
                        "give one C column per electrode, named like the model's electrodes")
        els.append(t["electrodes"].index(e.name))
    q, c = t["q"][:, cols], t["c"][:, els]
    if "holdout_q" in t:
        hq, hc = t["holdout_q"][:, cols], t["holdout_c"][:, els]
    else:
        check = np.arange(len(q)) % 5 == 4
        q, c, hq, hc = q[~check], c[~check], q[check], c[check]

    def keep(q, c):
        ok = np.all(np.isfinite(c), axis=1)
        return Samples(q[ok] / scales, c[ok], int((~ok).sum()))
    grid, holdout = keep(q, c), keep(hq, hc)
    if len(grid.x) < 2 or len(holdout.x) < 1:
        raise _fail(path, where, "too few valid sample points", "give more capacitance samples")
    return grid, holdout


def build(s, progress: bool = False, **parallel):
    """pipeline.build with the imported stages substituted (mechanics and/or capacitance samples)."""
    from . import pipeline
    imp = s.imports
    m = mechanics(s) if imp.modes else pipeline.mechanics(s)
    ext, described, prepared = pipeline.prepare(s, m)
    scales = pipeline.coordinate_scales(prepared, m, ext)
    if imp.capacitance:
        grid, holdout = samples(s, m, described, scales)
    else:
        grid = pipeline.sample_grid(s, prepared, scales, progress, **parallel)
        holdout = pipeline.sample_holdout(s, prepared, scales, progress, **parallel)
    fits = pipeline.fit_all(s, ext, described, m.basis, scales, grid, holdout, progress)
    model = pipeline.assemble(s, m, ext, described, scales, grid, holdout, fits)
    model.report["import"] = {k: Path(v).name for k, v in vars(imp).items() if v}
    if imp.capacitance:
        model.report["electrostatics"] = {"extractor": f"imported table {Path(imp.capacitance).name}"}
    return pipeline.Build(s, m, ext, prepared, scales, grid, holdout, fits, model)


# ------------------------------------------------------------------ exporters (round trips, format examples)

def export(b, folder: str | Path, csv_too: bool = False) -> dict[str, Path]:
    """Write a build's modal M and K (.mtx), mode shapes (.npz: exact quadratic triangles for the
    free disk, beam nodes for beams) and capacitance samples (.npz) in the import formats."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    m, s = b.mechanics, b.structure
    out = {"mass_matrix": folder / "M.mtx", "stiffness_matrix": folder / "K.mtx",
           "modes": folder / "modes.npz", "capacitance": folder / "capacitance.npz"}
    scipy.io.mmwrite(str(out["mass_matrix"]), np.diag(m.masses), precision=17, symmetry="symmetric")
    scipy.io.mmwrite(str(out["stiffness_matrix"]), np.diag(m.stiffnesses), precision=17, symmetry="symmetric")
    nodes, tri, unit = _export_nodes(s)
    vectors = m.basis(nodes[:, 0] * unit, nodes[:, 1] * unit)
    if s.conductor.kind == "free_disk" and s.coordinates.modes:   # the nonconforming elements' own values
        elastic = [k for k, kind in enumerate(m.kinds) if kind == "mode"]
        vectors[:, elastic] = _disk_mode_values(s)
    extra = {"triangles": tri} if tri is not None else {}
    np.savez(out["modes"], nodes=nodes, vectors=vectors, names=np.array(m.names), labels=np.array(m.labels),
             length_scale=unit, **extra)
    grid_x, grid_c = _with_touching(b.grid, sampling_grid(len(b.scales), s.sampling.levels, s.sampling.range))
    hold_x, hold_c = _with_touching(b.holdout, holdout_points(len(b.scales), s.fit.holdout, s.sampling.range,
                                                              s.fit.seed))
    np.savez(out["capacitance"], q=grid_x * b.scales, c=grid_c, holdout_q=hold_x * b.scales,
             holdout_c=hold_c, coordinates=np.array(m.names),
             electrodes=np.array([e.name for e in b.model.electrodes]))
    if csv_too:
        out["modes_csv"], out["capacitance_csv"] = folder / "modes.csv", folder / "capacitance.csv"
        np.savetxt(out["modes_csv"], np.column_stack([nodes * unit, vectors]), delimiter=",", comments="",
                   header=",".join(["x", "y"] + list(m.names)), fmt="%.17g")
        rows = np.vstack([np.column_stack([b.grid.x * b.scales, b.grid.c]),
                          np.column_stack([b.holdout.x * b.scales, b.holdout.c])])
        with open(out["capacitance_csv"], "w", newline="", encoding="utf-8") as fh:
            wr = csv.writer(fh)
            wr.writerow([f"q:{n}" for n in m.names] + [f"C:{e.name}" for e in b.model.electrodes] + ["set"])
            for k, r in enumerate(rows):
                wr.writerow([repr(float(v)) for v in r] + ["fit" if k < len(b.grid.x) else "check"])
    return out


def _disk_mode_values(s) -> np.ndarray:
    """Per-element quadratic node values (6 per triangle) of the free disk's selected modes: the
    Morley field is discontinuous across elements, so values at shared nodes are not unique."""
    from . import mechanics as mech
    d = s.conductor
    modes = mech.free_disk_modes(d.radius, d.thickness, d.youngs_modulus, d.poisson_ratio, d.density,
                                 list(s.coordinates.modes) if not isinstance(s.coordinates.modes, int)
                                 else s.coordinates.modes, refine=s.fem.refine)
    return modes._field.nodes.reshape(-1, modes._field.nodes.shape[-1])


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


def _export_nodes(s) -> tuple[np.ndarray, np.ndarray | None, float]:
    """Nodes (and quadratic triangles) at which the shapes are exported."""
    c = s.conductor
    if c.kind == "free_disk":
        from .mechanics import _P2_NODES, _unit_disk
        mesh = _unit_disk(c.poisson_ratio, s.fem.refine).basis.mesh
        p, t = mesh.p, mesh.t
        a = np.stack([p[:, t[1]] - p[:, t[0]], p[:, t[2]] - p[:, t[0]]], axis=-1)      # (2, ne, 2)
        pts = p[:, t[0]][:, :, None] + np.einsum("ien,nk->iek", a, _P2_NODES)          # (2, ne, 6)
        pts[:, :, 0], pts[:, :, 1], pts[:, :, 2] = p[:, t[0]], p[:, t[1]], p[:, t[2]]   # exact vertices
        nodes = pts.transpose(1, 2, 0).reshape(-1, 2)                 # in units of the radius
        return nodes, np.arange(len(nodes)).reshape(-1, 6), c.radius
    x0, x1, y0, y1 = c.outline()
    if c.kind in ("clamped_clamped_beam", "cantilever"):
        x = np.linspace(x0, x1, 8 * c.elements + 1)
        return np.column_stack([x, np.zeros_like(x)]), None, 1.0
    x, y = np.meshgrid(np.linspace(x0, x1, 41), np.linspace(y0, y1, 41))
    return np.column_stack([x.ravel(), y.ravel()]), None, 1.0
