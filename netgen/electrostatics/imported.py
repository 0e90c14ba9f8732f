"""Capacitance tables from external field solvers (the structure file's [import] capacitance):
`.npz` with q (npts, n) in SI (m, rad), c (npts, nel) plate-electrode capacitances in F,
`coordinates` (n,) and `electrodes` (nel,) names, optional `holdout_q`, `holdout_c` (held-out
check points; otherwise every fifth point is held out); or `.csv` with columns
q:<coordinate> ... and C:<electrode> ..., and an optional `set` column (fit / check).
NaN capacitances (touching) are dropped. They replace the extractor's samples; the fit is the
same as for netgen's own."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import StructureError
from ..files import read_csv
from .sampling import Samples


def read_capacitance(path: str | Path) -> dict:
    """Capacitance table: q (SI), c (F), coordinate and electrode names, optional held-out set."""
    path = Path(path)
    where = "import.capacitance"
    if path.suffix == ".csv":
        header, rows = read_csv(path, where, text_columns=("set",))
        qcols = [i for i, h in enumerate(header) if h.startswith("q:")]
        ccols = [i for i, h in enumerate(header) if h.startswith("C:")]
        if not qcols or not ccols:
            raise StructureError(str(path), where, "no q:<coordinate> or C:<electrode> columns",
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
                raise StructureError(str(path), where, f"missing arrays {missing}", "save q, c, coordinates, electrodes (np.savez)")
            data = {k: z[k] for k in z.files}
        data["coordinates"] = [str(n) for n in data["coordinates"]]
        data["electrodes"] = [str(n) for n in data["electrodes"]]
    for key in ("q", "c", "holdout_q", "holdout_c"):
        if key in data:
            data[key] = np.atleast_2d(np.asarray(data[key], float))
    if data["q"].shape[0] != data["c"].shape[0] or data["q"].shape[1] != len(data["coordinates"]) \
            or data["c"].shape[1] != len(data["electrodes"]):
        raise StructureError(str(path), where, f"q {data['q'].shape} and c {data['c'].shape} do not match "
                             f"{len(data['coordinates'])} coordinates and {len(data['electrodes'])} electrodes",
                             "one row per sample point, one column per coordinate / electrode")
    return data


def columns(path: str, wanted: list[str], have: list[str], what: str, fix: str) -> list[int]:
    """The table's column of each wanted name, or a StructureError naming the missing one."""
    for name in wanted:
        if name not in have:
            raise StructureError(str(path), "import.capacitance", f"no column for {what} {name!r} (table has {have})", fix)
    return [have.index(name) for name in wanted]


def samples(path: str, names: list[str], electrodes: list[str], scales: np.ndarray) -> tuple[Samples, Samples]:
    """Grid and held-out Samples from an imported capacitance table, its columns mapped to the
    model's coordinate `names` and `electrodes` by name."""
    t = read_capacitance(path)
    where = "import.capacitance"
    cols = columns(path, names, t["coordinates"], "coordinate",
                   "give one q column per model coordinate, named like the coordinates")
    els = columns(path, electrodes, t["electrodes"], "electrode",
                  "give one C column per electrode, named like the model's electrodes")
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
        raise StructureError(str(path), where, "too few valid sample points", "give more capacitance samples")
    return grid, holdout
