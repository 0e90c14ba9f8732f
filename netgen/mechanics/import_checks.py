"""Checks of imported FEM data (netgen.mechanics.imported) that keep a bad export from becoming a
model: Matrix Market files read with their header, size, field, symmetry and entries checked;
the modal masses and stiffnesses against what the structure's coordinates are (rigid-body motions
of a free conductor have no stiffness, a suspended one's do; an eigenmode has a frequency); the
mode-shape nodes against the conductor outline. Each failure is a StructureError naming the file,
the entry or row, the problem and the fix.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import scipy.io
from scipy.spatial import cKDTree

from ..core.errors import StructureError
from ..core.files import read_bytes
from ..geometry.layout import plate_outline
from ..structure import RIGID_COORDINATES, Structure

MAX_SIZE = 20000  # dense N x N matrices beyond this do not fit the importer's memory
SYMMETRY_TOLERANCE = 1e-9  # relative to the largest entry
ZERO_FREQUENCY = 1e-3  # a rigid coordinate below this fraction of the lowest eigenfrequency is free
FREE_RIGID_HZ = 1.0  # ... or below this without eigenmodes
NODE_OUTSIDE = 0.01  # nodes beyond the outline by more than this fraction of its size
NODE_SPACING = 0.125  # the farthest conductor point from a node, as a fraction of its size
EXPORT_FIX = "export the matrix in Matrix Market format (.mtx, real values; see docs/import.md)"


def fail(path: str | Path, where: str, problem: str, fix: str, line: int | None = None) -> StructureError:
    """A StructureError for an imported file."""
    return StructureError(str(path), where, problem, fix, line)


def read_matrix(path: str | Path, where: str, sizes: dict[int, str]) -> np.ndarray:
    """A square, symmetric, finite Matrix Market matrix as a dense array; `sizes` maps each size
    the model accepts to what it means (checked before any value is read). A file that does not
    start with the %%MatrixMarket banner is refused without quoting it (it may be any file)."""
    head = read_bytes(path, where, "a Matrix Market file", StructureError, "table")[:14]
    try:
        if head.lower() != b"%%matrixmarket":
            raise ValueError("no %%MatrixMarket banner on the first line")
        rows, cols, entries, fmt, field, symmetry = scipy.io.mminfo(str(path))
    except Exception as exc:  # noqa: BLE001 (any header failure is the user's file)
        raise fail(
            path,
            where,
            f"not a Matrix Market file ({exc if head.lower() == b'%%matrixmarket' else 'no %%MatrixMarket banner'})",
            EXPORT_FIX + "; the first line must be '%%MatrixMarket matrix coordinate real symmetric'",
        ) from None
    if field not in ("real", "integer", "double"):
        raise fail(
            path,
            where,
            f"the header declares {field!r} values"
            + (" (a sparsity pattern only, no numbers)" if field == "pattern" else ""),
            "export the real-valued matrix (field 'real' in the %%MatrixMarket header)",
            1,
        )
    if symmetry not in ("general", "symmetric"):
        raise fail(
            path,
            where,
            f"the header declares a {symmetry!r} matrix; mass and stiffness are symmetric",
            "export the symmetric matrix ('symmetric' or 'general' in the %%MatrixMarket header)",
            1,
        )
    if rows != cols or rows == 0:
        raise fail(
            path,
            where,
            f"the header declares a {rows} x {cols} matrix, not a nonempty square one",
            "export the full square matrix",
        )
    if rows not in sizes:
        accepted = "; ".join(f"{n} x {n} ({what})" for n, what in sizes.items())
        raise fail(
            path,
            where,
            f"the header declares {rows} x {rows}; the modes file needs {accepted}",
            "export the matrices of the same model as the modes file",
        )
    scan_entries(path, where, fmt, symmetry, rows, entries)
    a = parse_matrix(path, where, fmt, entries)
    check_matrix(path, where, a)
    return a


def scan_entries(path: str | Path, where: str, fmt: str, symmetry: str, n: int, entries: int) -> None:
    """Every data line after the size line is one entry ('row column value' or 'value'), each
    number whole (scipy reads '1.0.0' as 1 and fills a short array-format file with zeros), and
    there are as many as the header declares."""
    raw = (
        read_bytes(path, where, "a Matrix Market file", StructureError, "table").decode("utf-8", "replace").splitlines()
    )
    data = [(no, ln.split()) for no, ln in enumerate(raw, start=1) if ln.strip() and not ln.startswith("%")][1:]
    declared = entries if fmt == "coordinate" else n * (n + 1) // 2 if symmetry == "symmetric" else n * n
    fix = "re-export the file: one 'row column value' (coordinate) or 'value' (array) per line, 1-based indices"
    width = 3 if fmt == "coordinate" else 1
    for no, tokens in data:
        if len(tokens) != width:
            raise fail(path, where, f"{len(tokens)} fields where the {fmt} format has {width}", fix, no)
        try:
            if width == 3 and not (1 <= int(tokens[0]) <= n and 1 <= int(tokens[1]) <= n):
                raise fail(path, where, f"index ({tokens[0]}, {tokens[1]}) outside 1..{n}", fix, no)
            float(tokens[-1])
        except ValueError:
            raise fail(
                path,
                where,
                f"{' '.join(tokens)!r} is not {'two indices and a number' if width == 3 else 'a number'}",
                fix,
                no,
            ) from None
    if len(data) != declared:
        raise fail(
            path,
            where,
            f"the header declares {declared} entries, the file has {len(data)}"
            f" ({'truncated' if len(data) < declared else 'too long'})",
            "re-export the file: the size line (rows columns [entries]) must match the values that follow",
        )


def parse_matrix(path: str | Path, where: str, fmt: str, entries: int) -> np.ndarray:
    """scipy.io.mmread, its errors (truncated, too long, bad numbers, indices out of range) with the
    line; repeated coordinate entries refused (tools disagree whether to add them)."""
    try:
        a = scipy.io.mmread(str(path))
    except Exception as exc:  # noqa: BLE001
        line = re.match(r"Line (\d+)", str(exc))
        hint = f" (the header declares {entries} entries)" if "runcated" in str(exc) or "long" in str(exc) else ""
        raise fail(
            path,
            where,
            f"{exc}{hint}".rstrip("."),
            "re-export the file: the size line (rows columns entries) must match the entries that follow, "
            "one 'row column value' per line with 1-based indices",
            int(line.group(1)) if line else None,
        ) from None
    if fmt == "coordinate":
        coo = a.tocoo()
        keys = coo.row.astype(np.int64) * coo.shape[1] + coo.col
        uniq, count = np.unique(keys, return_counts=True)
        if np.any(count > 1):
            k = int(uniq[np.argmax(count > 1)])
            i, j = divmod(k, coo.shape[1])
            raise fail(
                path,
                where,
                f"entry ({i + 1}, {j + 1}) is given more than once"
                " (a symmetric file stores each off-diagonal pair once, in the lower triangle)",
                "give each entry once",
            )
        a = coo.toarray()
    return np.asarray(a, dtype=float)


def check_matrix(path: str | Path, where: str, a: np.ndarray) -> None:
    """Finite and symmetric, naming the first bad entry (1-based, as in the file)."""
    bad = np.argwhere(~np.isfinite(a))
    if len(bad):
        i, j = bad[0]
        raise fail(
            path,
            where,
            f"entry ({i + 1}, {j + 1}) is {a[i, j]} ({len(bad)} non-finite entries)",
            "export finite values (a NaN or inf means the FEM solve failed)",
        )
    asym = np.abs(a - a.T)
    if asym.max() > SYMMETRY_TOLERANCE * max(np.abs(a).max(), 1e-300):
        i, j = np.unravel_index(np.argmax(asym), a.shape)
        raise fail(
            path,
            where,
            f"matrix is not symmetric: entry ({i + 1}, {j + 1}) = {a[i, j]:.6g} but ({j + 1}, {i + 1}) = {a[j, i]:.6g}",
            "export the symmetric mass/stiffness matrix",
        )


def check_full(m_path: str, k_path: str, M: np.ndarray, K: np.ndarray) -> None:
    """Full FE matrices: M positive definite, K positive semidefinite."""
    try:
        np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        raise fail(
            m_path,
            "import.mass_matrix",
            "M is not positive definite (a degree of freedom without mass)",
            "export the consistent or lumped mass matrix of the model with every DOF massive",
        ) from None
    ev = np.linalg.eigvalsh(K)
    if ev[0] < -1e-9 * max(abs(ev[-1]), 1e-300):
        raise fail(
            k_path,
            "import.stiffness_matrix",
            f"K is not positive semidefinite (eigenvalue {ev[0]:.3e} against {ev[-1]:.3e})",
            "export the stiffness matrix of a stable structure (no prestress beyond buckling, no negative springs)",
        )


def modal_values(
    s: Structure, names: list[str], mass: np.ndarray, stiff: np.ndarray, m_path: str, k_path: str
) -> np.ndarray:
    """The modal stiffnesses, checked: positive masses, no negative stiffness, an eigenmode at a
    nonzero frequency, a free conductor's rigid motions at zero stiffness (set to exactly 0) and a
    suspended one's on their springs."""
    for k, name in enumerate(names):
        if not mass[k] > 0:
            raise fail(
                m_path,
                "import.mass_matrix",
                f"modal mass of {name!r} (entry ({k + 1}, {k + 1})) is {mass[k]:.6g}; M must be positive definite",
                "export the mass matrix (kg) of the same model",
            )
    scale = max(float(np.abs(stiff).max()), 1e-300)
    for k, name in enumerate(names):
        if stiff[k] < -1e-9 * scale:
            raise fail(
                k_path,
                "import.stiffness_matrix",
                f"modal stiffness of {name!r} (entry ({k + 1}, {k + 1})) "
                f"is {stiff[k]:.6g}; K must be positive semidefinite",
                "export the stiffness matrix (N/m) of a stable structure",
            )
    stiff = np.maximum(stiff, 0.0)
    freq = np.sqrt(stiff / mass) / (2 * math.pi)
    rigid = np.array([n in RIGID_COORDINATES for n in names])
    elastic_f = freq[~rigid]
    for k, name in enumerate(names):
        if not rigid[k] and not freq[k] > 1e-6 * max(float(freq.max()), 1e-300):
            raise fail(
                k_path,
                "import.stiffness_matrix",
                f"eigenmode {name!r} (entry ({k + 1}, {k + 1})) is at "
                f"{freq[k]:.3g} Hz: an eigenmode has a nonzero frequency",
                "rename the column z / tilt_x / tilt_y if it is a rigid-body motion, or drop the mode",
            )
    free = getattr(s.conductor, "stiffness", None) is None  # kinds on springs (piston) carry their stiffness
    limit = ZERO_FREQUENCY * float(elastic_f.min()) if len(elastic_f) else FREE_RIGID_HZ
    for k in np.flatnonzero(rigid):
        if free and freq[k] > limit:
            raise fail(
                k_path,
                "import.stiffness_matrix",
                f"rigid coordinate {names[k]!r} (entry ({k + 1}, {k + 1})) "
                f"has stiffness {stiff[k]:.4g} ({freq[k]:.3g} Hz), but a {s.conductor.kind.replace('_', ' ')} has no "
                f"restoring force (limit {limit:.3g} Hz)",
                "export the free-free model (no supports), or name the column as an eigenmode",
            )
        if free:
            stiff[k] = 0.0
        elif not freq[k] > 0:
            raise fail(
                k_path,
                "import.stiffness_matrix",
                f"rigid coordinate {names[k]!r} (entry ({k + 1}, {k + 1})) "
                f"has no stiffness, but the {s.conductor.kind} is on springs",
                "export K with the suspension springs (N/m, N*m/rad)",
            )
    return stiff


def check_nodes(s: Structure, path: str, nodes: np.ndarray, lines: np.ndarray | None) -> None:
    """The nodes (m) cover the conductor: none beyond its outline (wrong units or another part),
    every point of it near a node (beams: along x)."""
    plate = plate_outline(s)
    c = s.conductor
    if c.outline_shape == "disk":
        x0, x1, y0, y1 = -c.radius, c.radius, -c.radius, c.radius
    else:
        x0, x1, y0, y1 = c.outline()
    size = plate.size if not c.one_dimensional else x1 - x0
    tol = NODE_OUTSIDE * size
    if c.outline_shape == "disk":
        out = np.hypot(nodes[:, 0], nodes[:, 1]) - c.radius
    else:
        out = np.maximum.reduce([x0 - nodes[:, 0], nodes[:, 0] - x1, y0 - nodes[:, 1], nodes[:, 1] - y1])
    if c.one_dimensional:
        out = np.maximum(x0 - nodes[:, 0], nodes[:, 0] - x1)
    bad = np.flatnonzero(out > tol)
    if len(bad):
        r = int(bad[0])
        raise fail(
            path,
            "import.modes",
            f"node {where_row(r, lines)} at ({nodes[r, 0]:.6g}, {nodes[r, 1]:.6g}) m "
            f"lies outside the conductor (x {x0:.6g}..{x1:.6g}, y {y0:.6g}..{y1:.6g} m)",
            "give the node coordinates in m (or set length_scale in the .npz) for the conductor's nodes only",
            line_of(r, lines),
        )
    if c.one_dimensional:
        xs = np.unique(np.concatenate([[x0, x1], np.clip(nodes[:, 0], x0, x1)]))
        widest = float(np.diff(xs).max())
        if widest > NODE_SPACING * size:
            raise fail(
                path,
                "import.modes",
                f"the nodes do not cover the beam: {widest:.3g} m of its {size:.3g} m have no node",
                "export the mode shapes at nodes along the whole beam",
            )
        return
    px, py, _ = plate.area_rule(16)
    dist, _ = cKDTree(nodes).query(np.column_stack([px, py]))
    if dist.max() > NODE_SPACING * size:
        k = int(np.argmax(dist))
        raise fail(
            path,
            "import.modes",
            f"the nodes do not cover the conductor: the point ({px[k]:.4g}, {py[k]:.4g}) m "
            f"is {dist[k]:.3g} m from the nearest node ({NODE_SPACING:g} of the conductor's size {size:.3g} m allowed)",
            "export the mode shapes on the nodes of the whole conductor surface (x, y in m)",
        )


def where_row(r: int, lines: np.ndarray | None) -> str:
    """'row 3' of an .npz array (0-based, as numpy indexes it) or of a CSV table (its line named too)."""
    return f"row {r + 1}" if lines is not None else f"row {r} (0-based)"


def line_of(r: int, lines: np.ndarray | None) -> int | None:
    """The CSV line of data row r (None for an .npz)."""
    return int(lines[r]) if lines is not None else None


def check_duplicate_nodes(path: str, nodes: np.ndarray, w: np.ndarray, lines: np.ndarray | None) -> np.ndarray:
    """Rows at one node: refused if their values differ, merged (the first kept) if they are equal.
    Returns the rows kept."""
    _, first, inverse = np.unique(nodes, axis=0, return_index=True, return_inverse=True)
    inverse = np.ravel(inverse)
    for r in np.flatnonzero(first[inverse] != np.arange(len(nodes))):
        f = int(first[inverse[r]])
        if not np.array_equal(w[r], w[f]):
            raise fail(
                path,
                "import.modes",
                f"node {where_row(int(r), lines)} repeats node {where_row(f, lines)} at "
                f"({nodes[r, 0]:.6g}, {nodes[r, 1]:.6g}) with other displacements",
                "give each node once (equal repeated rows are merged)",
                line_of(int(r), lines),
            )
    return np.sort(first)
