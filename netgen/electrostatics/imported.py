"""Capacitance tables from external field solvers (the structure file's [import] capacitance):
`.npz` with q (npts, n) in SI (m, rad), c (npts, nel) plate-electrode capacitances in F,
`coordinates` (n,) and `electrodes` (nel,) names, optional `holdout_q`, `holdout_c` (held-out
check points; otherwise every fifth point is held out); or `.csv` with columns
q:<coordinate> ... and C:<electrode> ..., and an optional `set` column (fit / check).
NaN capacitances (touching) are dropped. They replace the extractor's samples; the fit is the
same as for netgen's own.

A table is checked before the fit sees it (each error names the file, the row and the fix):
finite coordinates, capacitances positive and finite or NaN, within a factor PLAUSIBLE of the
structure's own parallel-plate estimate eps A / g (a table in pF is 1e12 off), coordinates inside
the touching amplitudes, no point given twice with different capacitances (equal repeats are
merged, the first kept), and enough independent fit points for the fit's terms.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.errors import StructureError
from ..core.files import load_npz, read_csv
from .sampling import Samples

WHERE = "import.capacitance"
PLAUSIBLE = 100.0  # largest factor between a capacitance and eps A / g of its electrode
POINTS_PER_TERM = 2  # fit points per polynomial term: least squares with as many residuals as unknowns
NPZ_ARRAYS = ("q", "c", "coordinates", "electrodes", "holdout_q", "holdout_c")


@dataclass
class Table:
    """A capacitance table: q (npts, n) SI, c (npts, nel) F, the names of its columns, whether each
    row is a held-out check point (None: every fifth), and each row's place in the file."""

    path: str
    q: np.ndarray
    c: np.ndarray
    coordinates: list[str]
    electrodes: list[str]
    check: np.ndarray | None
    rows: list[str]  # 'row 3 of holdout_q' / 'row 3'
    lines: np.ndarray | None  # CSV line of each row

    def fail(self, r: int | None, problem: str, fix: str) -> StructureError:
        """An error naming the file, row r (and its CSV line)."""
        at = f"{self.rows[r]}: " if r is not None else ""
        line = int(self.lines[r]) if r is not None and self.lines is not None else None
        return StructureError(self.path, WHERE, at + problem, fix, line)


def read_capacitance(path: str | Path) -> Table:
    """Capacitance table (CSV or NPZ), its columns and shapes checked."""
    path = Path(path)
    return read_csv_table(path) if path.suffix == ".csv" else read_npz_table(path)


def read_csv_table(path: Path) -> Table:
    """q:<coordinate>, C:<electrode> and an optional set column (fit / check)."""
    t = read_csv(path, WHERE, text_columns=("set",))
    for h in t.header:
        if h != "set" and not (h[:2] in ("q:", "C:") and h[2:].isidentifier()):
            raise StructureError(
                str(path),
                WHERE,
                f"column {h!r} is neither q:<coordinate>, C:<electrode> nor set",
                "write a header like q:z,q:m1,C:top,C:bot[,set]",
                t.header_line,
            )
    qcols = [i for i, h in enumerate(t.header) if h.startswith("q:")]
    ccols = [i for i, h in enumerate(t.header) if h.startswith("C:")]
    if not qcols or not ccols:
        raise StructureError(
            str(path),
            WHERE,
            "no q:<coordinate> or C:<electrode> columns",
            "write a header like q:z,q:m1,C:top,C:bot[,set]",
        )
    check = None
    if "set" in t.text:
        sets = t.text["set"]
        bad = np.flatnonzero(~np.isin(sets, ["fit", "check"]))
        if len(bad):
            raise StructureError(
                str(path),
                WHERE,
                f"set = {sets[bad[0]]!r} is neither fit nor check",
                "write fit (a point the fit uses) or check (a held-out point)",
                int(t.lines[bad[0]]),
            )
        check = sets == "check"
    return Table(
        str(path),
        t.values[:, qcols],
        t.values[:, ccols],
        [t.header[i][2:] for i in qcols],
        [t.header[i][2:] for i in ccols],
        check,
        [f"row {k + 1}" for k in range(len(t.values))],
        t.lines,
    )


def read_npz_table(path: Path) -> Table:
    """q, c, coordinates, electrodes and optional holdout_q, holdout_c of an .npz."""
    z = load_npz(path, WHERE, ("q", "c", "coordinates", "electrodes"), NPZ_ARRAYS)
    if ("holdout_q" in z) != ("holdout_c" in z):
        raise StructureError(
            str(path),
            WHERE,
            "holdout_q and holdout_c come together",
            "save both held-out arrays, or neither (then every fifth point is held out)",
        )
    names = {k: strings(path, z[k], k) for k in ("coordinates", "electrodes")}
    parts = [("", "q", "c")] + ([("holdout_", "holdout_q", "holdout_c")] if "holdout_q" in z else [])
    qs, cs, rows = [], [], []
    for _, kq, kc in parts:
        q = matrix(path, z[kq], kq, len(names["coordinates"]), "coordinates")
        c = matrix(path, z[kc], kc, len(names["electrodes"]), "electrodes")
        if len(q) != len(c):
            raise StructureError(
                str(path), WHERE, f"{kq} has {len(q)} rows, {kc} {len(c)}", "one row per sample point in both"
            )
        qs.append(q)
        cs.append(c)
        rows += [f"row {k} (0-based) of {kq}/{kc}" for k in range(len(q))]
    check = np.concatenate([np.full(len(q), bool(p)) for q, (p, _, _) in zip(qs, parts)]) if len(parts) > 1 else None
    return Table(str(path), np.vstack(qs), np.vstack(cs), names["coordinates"], names["electrodes"], check, rows, None)


def strings(path: Path, a: np.ndarray, key: str) -> list[str]:
    """A 1-D array of names."""
    if a.ndim != 1 or a.dtype.kind not in "US" or len(a) == 0:
        raise StructureError(
            str(path),
            WHERE,
            f"{key} is a {a.dtype} array of shape {a.shape}, not a list of names",
            f"save {key}=np.array(['z', 'm1']) (one name per column)",
        )
    return [x.decode("utf-8", "replace") if isinstance(x, bytes) else str(x) for x in a]


def matrix(path: Path, a: np.ndarray, key: str, ncols: int, what: str) -> np.ndarray:
    """A numeric (npts, ncols) array (1-D for one column)."""
    if a.dtype.kind not in "iuf":
        raise StructureError(str(path), WHERE, f"{key} holds {a.dtype} values, not numbers", f"save {key} as floats")
    if a.ndim == 1 and ncols == 1:
        a = a[:, None]
    if a.ndim != 2 or a.shape[1] != ncols:
        raise StructureError(
            str(path),
            WHERE,
            f"{key} has shape {a.shape}, expected (npts, {ncols}) for the {ncols} {what}",
            f"one row per sample point, one column per name in {what}",
        )
    return a.astype(float)


def columns(t: Table, wanted: list[str], have: list[str], what: str, fix: str) -> list[int]:
    """The table's column of each wanted name; a missing or an extra name is refused."""
    for name in wanted:
        if name not in have:
            raise t.fail(None, f"no column for {what} {name!r} (table has {have})", fix)
    for name in have:
        if name not in wanted:
            raise t.fail(
                None,
                f"column for {what} {name!r} that the model does not have (it has {wanted})",
                f"remove the column, or name it as one of {wanted}",
            )
        if have.count(name) > 1:
            raise t.fail(None, f"{what} {name!r} has two columns", "give each name one column")
    return [have.index(name) for name in wanted]


def check_values(t: Table, names: list[str], electrodes: list[str], scales: np.ndarray, estimates: np.ndarray) -> None:
    """Finite coordinates inside the touching amplitudes; capacitances positive, finite or NaN,
    and within PLAUSIBLE of eps A / g."""
    bad = np.argwhere(~np.isfinite(t.q))
    if len(bad):
        r, k = bad[0]
        raise t.fail(int(r), f"q:{names[k]} is {t.q[r, k]}", "give every coordinate a finite value (SI: m, rad)")
    bad = np.argwhere(np.isinf(t.c) | (t.c <= 0))
    if len(bad):
        r, k = bad[0]
        raise t.fail(
            int(r),
            f"C:{electrodes[k]} = {t.c[r, k]} is not a positive finite capacitance",
            "give capacitances in F (> 0); mark a touching point by NaN",
        )
    x = t.q / scales
    finite = np.all(np.isfinite(t.c), axis=1)
    bad = np.argwhere((np.abs(x) >= 1) & finite[:, None])
    if len(bad):
        r, k = bad[0]
        raise t.fail(
            int(r),
            f"q:{names[k]} = {t.q[r, k]:.6g} is beyond the touching amplitude {scales[k]:.4g} "
            f"{'rad' if names[k].startswith('tilt') else 'm'} (the plate would pass the electrode)",
            "give coordinates in SI units (m, rad), or mark touching points with NaN capacitances (the "
            "touching amplitude follows from the mode shapes: they must be the ones the table was computed with)",
        )
    for k, (name, est) in enumerate(zip(electrodes, estimates)):
        if not est > 0:
            continue
        ratio = t.c[:, k] / est
        bad = np.flatnonzero((ratio > PLAUSIBLE) | (ratio < 1 / PLAUSIBLE))
        if len(bad):
            r = int(bad[0])
            factor = 10.0 ** (-3 * round(math.log10(ratio[r]) / 3))
            raise t.fail(
                r,
                f"C:{name} = {t.c[r, k]:.4g} is {ratio[r]:.3g} times the parallel-plate estimate "
                f"eps A / g = {est:.4g} F of the electrode",
                f"values are in farads; multiply by {factor:g}",
            )


def merge_duplicates(t: Table) -> np.ndarray:
    """Rows kept: a point given twice with other capacitances is refused, an equal repeat merged."""
    _, first, inverse = np.unique(t.q, axis=0, return_index=True, return_inverse=True)
    inverse = np.ravel(inverse)
    for r in np.flatnonzero(first[inverse] != np.arange(len(t.q))):
        f = int(first[inverse[r]])
        if not np.array_equal(t.c[r], t.c[f], equal_nan=True):
            raise t.fail(
                int(r),
                f"the point q = {t.q[r].tolist()} repeats {t.rows[f]}"
                f"{f' (line {int(t.lines[f])})' if t.lines is not None else ''} with other capacitances "
                f"({t.c[r].tolist()} against {t.c[f].tolist()})",
                "give each point once (equal repeated rows are merged)",
            )
    return np.sort(first)


def fit_terms(n: int, degree: int) -> int:
    """Coefficients of a polynomial of total degree `degree` in n coordinates."""
    return math.comb(n + degree, degree)


def check_independent(t: Table, x: np.ndarray, degree: int) -> None:
    """The fit points determine a degree-`degree` polynomial with room to spare: at least
    POINTS_PER_TERM points per term and a design matrix of full rank."""
    n, terms = x.shape[1], fit_terms(x.shape[1], degree)
    need = POINTS_PER_TERM * terms
    span = np.max(np.abs(x), axis=0) if len(x) else np.ones(n)
    exps = [e for d in range(degree + 1) for e in itertools.combinations_with_replacement(range(n), d)]
    u = x / np.where(span > 0, span, 1.0)
    design = (
        np.stack([np.prod(u[:, list(e)], axis=1) if e else np.ones(len(u)) for e in exps], axis=1)
        if len(x)
        else np.zeros((0, terms))
    )
    rank = int(np.linalg.matrix_rank(design)) if len(x) else 0
    if len(x) < need or rank < terms:
        still = [f"q:{t.coordinates[k]}" for k in range(n) if not span[k] > 0] if len(x) else []
        raise t.fail(
            None,
            f"the degree-{degree} fit in {n} coordinates has {terms} terms and needs at least "
            f"{need} independent points; the table's fit rows give {len(x)} (rank {rank})"
            + (f"; coordinates {still} never vary" if still else ""),
            f"give at least {need} fit points that vary every coordinate (e.g. netgen's grid of "
            f"levels^{n} points), or lower fit.degree",
        )


def table(path: str, names: list[str], electrodes: list[str]) -> Table:
    """An imported capacitance table with its columns mapped to the model's coordinate `names`
    and `electrodes` by name (read before the extractor is prepared: a bad file stops early)."""
    t = read_capacitance(path)
    cols = columns(
        t, names, t.coordinates, "coordinate", "give one q column per model coordinate, named like the coordinates"
    )
    els = columns(
        t, electrodes, t.electrodes, "electrode", "give one C column per electrode, named like the model's electrodes"
    )
    t.q, t.c, t.coordinates, t.electrodes = t.q[:, cols], t.c[:, els], list(names), list(electrodes)
    return t


def samples(t: Table, scales: np.ndarray, estimates: np.ndarray, degree: int) -> tuple[Samples, Samples]:
    """Grid and held-out Samples of a table (netgen.electrostatics.imported.table), checked
    against the touching amplitudes `scales`, eps A / g per electrode (`estimates`, the units
    check) and the fit's total degree (the count of independent points)."""
    check_values(t, t.coordinates, t.electrodes, scales, estimates)
    check = t.check if t.check is not None else np.arange(len(t.q)) % 5 == 4
    keep = merge_duplicates(t)
    q, c, check = t.q[keep], t.c[keep], check[keep]
    ok = np.all(np.isfinite(c), axis=1)
    check_independent(t, q[~check & ok] / scales, degree)
    if not np.any(check & ok):
        raise t.fail(
            None,
            "no held-out check point with finite capacitances",
            "add rows with set = check (CSV) or holdout_q / holdout_c (.npz)",
        )

    def subset(sel):
        return Samples(q[sel & ok] / scales, c[sel & ok], int((sel & ~ok).sum()))

    return subset(~check), subset(check)
