"""Maxwell capacitance matrices from a user's field solver (the structure's [electrostatics]
couplings = "file"): the constant electrode-electrode couplings, and with extractor = "calibrated"
the calibration points (netgen.electrostatics.calibration).

Formats (conductor names: the plate, "plate", and the model's electrode names):

- `.csv`: one Maxwell matrix at rest, header `conductor,<name>,<name>,...`, one row per conductor
  in the header's order, the first cell its name, values in F (COMSOL's global matrix
  evaluation, ANSYS CMATRIX);
- `.json`: `{"conductors": [names], "points": [{"q": {"<coordinate>": value (SI)}, "maxwell":
  [[...]]}, ...]}`, or `{"conductors": [...], "maxwell": [[...]]}` for one matrix at rest.

Checked as read (each error names the file, the entry and the fix, like the other imported
tables, netgen.electrostatics.imported): names known and each once, every electrode present (the
plate too for a calibration), square finite matrices, symmetric within SYMMETRY, positive
diagonal, off-diagonal entries <= 0 (a file of positive two-terminal "mutual" capacitances is
named as such), every row's capacitance to infinity M_ii + sum_j M_ij >= -SYMMETRY M_ii, the
plate-electrode entries within PLAUSIBLE of eps A / g (a table in pF is 1e12 off), coordinates
known and inside the touching amplitudes.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.errors import StructureError
from ..core.files import did_you_mean, read_csv, read_text
from .imported import PLAUSIBLE

WHERE = "electrostatics.couplings"
SYMMETRY = 1e-3  # |M_ij - M_ji| / sqrt(M_ii M_jj) accepted (field solvers' reciprocity error)
PLATE = "plate"
FIX_FORMAT = (
    'write {"conductors": ["plate", "<electrode>", ...], "points": [{"q": {"z": 0.0}, "maxwell": '
    "[[...], ...]}]} (F, SI coordinates), or a CSV Maxwell matrix with header conductor,<name>,..."
)


@dataclass(frozen=True)
class MaxwellFile:
    """Maxwell matrices read from a file: conductors as in the file, q (npts, ncoords) in the model's
    coordinate order (SI), matrices (npts, n, n) in F."""

    path: str
    conductors: list[str]
    q: np.ndarray
    maxwell: np.ndarray

    def fail(self, where: str, problem: str, fix: str, line: int | None = None) -> StructureError:
        return StructureError(self.path, f"{WHERE} ({where})" if where else WHERE, problem, fix, line)

    def ordered(self, electrodes: list[str], plate: bool) -> np.ndarray:
        """The matrices with rows and columns in the order [plate,] electrodes (the plate only if `plate`)."""
        names = ([PLATE] if plate else []) + list(electrodes)
        idx = [self.conductors.index(n) for n in names]
        return self.maxwell[:, idx][:, :, idx]


def read(path: str | Path, coordinates: list[str]) -> MaxwellFile:
    """A Maxwell-matrix file (CSV or JSON), its structure checked; values are checked by `check`."""
    path = Path(path)
    return read_csv_matrix(path, len(coordinates)) if path.suffix == ".csv" else read_json(path, coordinates)


def read_csv_matrix(path: Path, ncoords: int) -> MaxwellFile:
    """A CSV Maxwell matrix at rest: header conductor,<names>; the first cell of each row its name."""
    t = read_csv(path, WHERE, text_columns=("conductor",))
    if "conductor" not in t.text or t.header[-1] != "conductor" or len(t.header) < 3:
        raise StructureError(
            str(path),
            WHERE,
            "the header must start with conductor, then the conductor names",
            "write a header like conductor,plate,top,bot",
            t.header_line,
        )
    names = t.header[:-1]
    rows = [str(r) for r in t.text["conductor"]]
    if rows != names:
        k = next(
            i for i in range(max(len(rows), len(names))) if i >= len(rows) or i >= len(names) or rows[i] != names[i]
        )
        line = int(t.lines[min(k, len(t.lines) - 1)])
        raise StructureError(
            str(path),
            WHERE,
            f"row {k + 1} is conductor {rows[k] if k < len(rows) else '(none)'!r}, "
            f"the header's column {k + 2} {names[k] if k < len(names) else '(none)'!r}",
            "give one row per conductor, in the header's order (a square matrix)",
            line,
        )
    out = MaxwellFile(str(path), names, np.zeros((1, ncoords)), t.values[None, :, :])
    check_names(out, names, lambda k: t.header_line)
    return out


def read_json(path: Path, coordinates: list[str]) -> MaxwellFile:
    """A JSON file of Maxwell matrices at named coordinate points."""
    try:
        doc = json.loads(read_text(path, WHERE, "a JSON document", kind="json"))
    except json.JSONDecodeError as exc:
        raise StructureError(str(path), WHERE, f"not JSON: {exc}", FIX_FORMAT, exc.lineno) from None
    if not isinstance(doc, dict) or "conductors" not in doc or ("points" in doc) == ("maxwell" in doc):
        raise StructureError(
            str(path), WHERE, "need an object with conductors and either points or maxwell", FIX_FORMAT
        )
    for k in doc:
        if k not in ("conductors", "points", "maxwell", "unit", "description", "solver"):
            raise StructureError(
                str(path),
                WHERE,
                f"unknown key {k!r}",
                f"{did_you_mean(k, ['conductors', 'points', 'maxwell'])}"
                "the keys are conductors, points (or maxwell), unit, description, solver",
            )
    if doc.get("unit", "F") != "F":
        raise StructureError(
            str(path),
            f"{WHERE} (unit)",
            f"unit {doc['unit']!r}: the matrices must be in F",
            'convert to farads and write "unit": "F" (or leave it out)',
        )
    names = doc["conductors"]
    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
        raise StructureError(str(path), f"{WHERE} (conductors)", "conductors must be a list of names", FIX_FORMAT)
    points = doc["points"] if "points" in doc else [{"q": {}, "maxwell": doc["maxwell"]}]
    if not isinstance(points, list) or not points:
        raise StructureError(str(path), f"{WHERE} (points)", "points must be a non-empty list", FIX_FORMAT)
    q, mats = np.zeros((len(points), len(coordinates))), []
    for p, point in enumerate(points):
        where = f"points[{p}]"
        if not isinstance(point, dict) or set(point) - {"q", "maxwell"} or "maxwell" not in point:
            raise StructureError(
                str(path), f"{WHERE} ({where})", 'each point is {"q": {...}, "maxwell": [[...]]}', FIX_FORMAT
            )
        q[p] = point_coordinates(path, where, point.get("q", {}), coordinates)
        mats.append(matrix(path, where, point["maxwell"], len(names)))
    out = MaxwellFile(str(path), list(names), q, np.stack(mats))
    check_names(out, names, lambda k: None)
    return out


def point_coordinates(path: Path, where: str, q, coordinates: list[str]) -> np.ndarray:
    """A point's {coordinate: value} in the model's order; unnamed coordinates are 0."""
    if not isinstance(q, dict):
        raise StructureError(
            str(path),
            f"{WHERE} ({where}.q)",
            "q must map coordinate names to values (SI)",
            'write "q": {"z": 1e-7, "tilt_x": 0.0}',
        )
    out = np.zeros(len(coordinates))
    for name, value in q.items():
        if name not in coordinates:
            raise StructureError(
                str(path),
                f"{WHERE} ({where}.q.{name})",
                f"the model has no coordinate {name!r}",
                f"{did_you_mean(name, coordinates)}the coordinates are {', '.join(coordinates)}",
            )
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise StructureError(
                str(path),
                f"{WHERE} ({where}.q.{name})",
                f"{value!r} is not a finite number",
                "give the coordinate in SI units (m, rad)",
            )
        out[coordinates.index(name)] = value
    return out


def matrix(path: Path, where: str, m, n: int) -> np.ndarray:
    """A square n x n matrix of finite numbers."""
    if not isinstance(m, list) or len(m) != n or not all(isinstance(r, list) and len(r) == n for r in m):
        raise StructureError(
            str(path),
            f"{WHERE} ({where}.maxwell)",
            f"not a {n} x {n} matrix (one row and column per conductor)",
            "give a square list of lists in the order of conductors",
        )
    for i, row in enumerate(m):
        for j, v in enumerate(row):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise StructureError(
                    str(path),
                    f"{WHERE} ({where}.maxwell[{i}][{j}])",
                    f"{v!r} is not a finite number",
                    "numbers in F only",
                )
    return np.array(m, dtype=float)


def check_names(f: MaxwellFile, names: list[str], line) -> None:
    """Conductor names are distinct text without control characters."""
    for k, n in enumerate(names):
        if not n.isidentifier():
            raise f.fail(
                "conductors",
                f"conductor {k + 1} {n!r} is not a name",
                "use the model's electrode names and plate",
                line(k),
            )
        if names.index(n) != k:
            raise f.fail("conductors", f"conductor {n!r} is given twice", "give each conductor once", line(k))


def check(f: MaxwellFile, electrodes: list[str], need_plate: bool, estimates: np.ndarray, scales: np.ndarray) -> None:
    """The matrices against the model: names, symmetry, signs, capacitance to infinity, units
    (plate-electrode entries against eps A / g `estimates`), coordinates inside the touching amplitudes."""
    known = [PLATE] + list(electrodes)
    for n in f.conductors:
        if n not in known:
            raise f.fail(
                "conductors",
                f"conductor {n!r} is neither the plate nor an electrode of the model",
                f"{did_you_mean(n, known)}the conductors are {', '.join(known)}",
            )
    missing = [n for n in ([PLATE] if need_plate else []) + list(electrodes) if n not in f.conductors]
    if missing:
        raise f.fail(
            "conductors",
            f"no row for {', '.join(missing)}",
            "give the Maxwell matrix of every electrode"
            + (" and the plate (a calibration fits the plate-electrode entries)" if need_plate else ""),
        )
    for p, m in enumerate(f.maxwell):
        check_matrix(f, p, m)
        if PLATE in f.conductors:
            check_units(f, p, m, electrodes, estimates)
    bad = np.argwhere(np.abs(f.q / scales) >= 1.0)
    if len(bad):
        p, v = bad[0]
        raise f.fail(
            f"points[{p}].q",
            f"coordinate {v + 1} = {f.q[p, v]:.6g} is beyond the touching amplitude "
            f"{scales[v]:.4g} (the plate would pass an electrode)",
            "give coordinates in SI units (m, rad)",
        )


def check_matrix(f: MaxwellFile, p: int, m: np.ndarray) -> None:
    """One Maxwell matrix: positive diagonal, symmetric, off-diagonal <= 0, rows summing to >= 0."""
    names, at = f.conductors, (f"points[{p}]" if len(f.maxwell) > 1 or f.path.endswith(".json") else "matrix")
    d = np.diag(m)
    for i in np.flatnonzero(~(d > 0)):
        raise f.fail(
            f"{at}, {names[i]}-{names[i]}",
            f"diagonal entry {d[i]!r} F is not positive",
            "the diagonal of a Maxwell matrix is each conductor's self capacitance (> 0)",
        )
    scale = np.sqrt(np.outer(d, d))
    asym = np.abs(m - m.T) / scale
    if asym.max() > SYMMETRY:
        i, j = np.unravel_index(int(np.argmax(asym)), m.shape)
        raise f.fail(
            f"{at}, {names[i]}-{names[j]}",
            f"not symmetric: {m[i, j]:.6g} against {m[j, i]:.6g} F "
            f"({asym[i, j]:.2g} of sqrt(M_ii M_jj), more than {SYMMETRY:g})",
            "give the solver's symmetrised matrix (M + M^T)/2, or refine its mesh",
        )
    off = m - np.diag(d)
    if off.max() > SYMMETRY * d.min():
        i, j = np.unravel_index(int(np.argmax(off)), m.shape)
        raise f.fail(
            f"{at}, {names[i]}-{names[j]}",
            f"off-diagonal entry {m[i, j]:.6g} F is positive",
            "a Maxwell matrix has M_ij = -C_ij <= 0 off the diagonal; if the solver wrote two-terminal "
            "(mutual) capacitances, negate the off-diagonal entries and put the row totals on the diagonal",
        )
    total = m.sum(axis=1)
    for i in np.flatnonzero(total < -SYMMETRY * d):
        raise f.fail(
            f"{at}, row {names[i]}",
            f"the row sums to {total[i]:.6g} F: a negative capacitance to infinity",
            "the diagonal must be at least the sum of the row's coupling capacitances; check the matrix",
        )


def check_units(f: MaxwellFile, p: int, m: np.ndarray, electrodes: list[str], estimates: np.ndarray) -> None:
    """Plate-electrode entries within PLAUSIBLE of eps A / g (the units check of imported tables)."""
    k = f.conductors.index(PLATE)
    for e, est in zip(electrodes, estimates):
        if e not in f.conductors or not est > 0:
            continue
        ratio = -m[k, f.conductors.index(e)] / est
        if ratio > PLAUSIBLE or ratio < 1 / PLAUSIBLE:
            factor = 10.0 ** (-3 * round(math.log10(max(ratio, 1e-300)) / 3)) if ratio > 0 else 1.0
            raise f.fail(
                f"points[{p}], plate-{e}",
                f"-M = {-m[k, f.conductors.index(e)]:.4g} F is {ratio:.3g} times "
                f"the parallel-plate estimate eps A / g = {est:.4g} F",
                f"values are in farads; multiply by {factor:g}"
                if ratio > 0
                else "the plate-electrode entry must be negative (M_ij = -C_ij)",
            )
