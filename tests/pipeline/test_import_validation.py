"""Bad [import] data never becomes a model: good exports (netgen.export) of three cheap structures
(a cantilever with three eigenmodes, a piston on its spring, a free disk with rigid coordinates
only) corrupted systematically into several hundred bad Matrix Market, mode-shape and capacitance
files; each built in-process through netgen.cli.commands.main must exit 2 with no traceback and a message
that names the file, the row or entry where there is one, and a fix. The good files, and a table
with an exact repeated row, still build, with the native build's numbers.

`python -m tests.pipeline.test_import_validation` prints the per-class table (tried / tracebacks /
accepted / refused without the file, row or fix) of the same generator.
"""

from __future__ import annotations

import contextlib
import io
import re
import sys
import traceback
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import scipy.io
import scipy.sparse

from netgen import export
from netgen.build import build
from netgen.cli.commands import main
from netgen.electrostatics.imported import merge_duplicates, read_capacitance
from netgen.electrostatics.sampling import blas_threads
from netgen.structure import parse_structure
from tests.fixtures import ROOT
from tests.oracles.small_disk import IMPORT_DISK

DISK = IMPORT_DISK

KEYS = ("mass_matrix", "stiffness_matrix", "modes", "capacitance")
NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


@dataclass
class Base:
    """One good exported set: the structure text, its folder and the good files' bytes."""

    name: str
    text: str
    folder: Path
    files: dict[str, Path]
    native: object

    def read(self, key: str) -> bytes:
        return self.files[key].read_bytes()


@dataclass
class Case:
    """One bad file: its class, the base it corrupts, which [import] key it replaces, its bytes
    and a text the message must contain (the row or entry), if any."""

    cls: str
    base: str
    key: str
    suffix: str
    data: bytes
    expect: str | None = None
    others: tuple[tuple[str, str, bytes], ...] = ()  # good replacements of other keys: (key, suffix, bytes)


def make_bases(root: Path) -> dict[str, Base]:
    """Native builds of the three structures, exported in every import format."""
    out = {}
    for name, text in (
        ("beam", (ROOT / "examples" / "cantilever.toml").read_text()),
        ("piston", (ROOT / "examples" / "piston.toml").read_text()),
        ("disk", DISK),
    ):
        native = build(parse_structure(text, f"{name}.toml"))
        folder = root / name
        files = export.export(native, folder, csv_too=True)
        for key in ("mass_matrix", "stiffness_matrix"):  # the coordinate format too
            a = scipy.io.mmread(str(files[key]))
            files[key + "_coo"] = folder / f"{key}_coo.mtx"
            scipy.io.mmwrite(str(files[key + "_coo"]), scipy.sparse.coo_matrix(a), precision=17, symmetry="symmetric")
        out[name] = Base(name, text, folder, files, native)
    return out


def structure_text(base: Base, replace: dict[str, str], modes: str = "modes.npz", cap: str = "capacitance.npz") -> str:
    """The structure with an [import] table of the good files but for `replace`."""
    files = {"mass_matrix": "M.mtx", "stiffness_matrix": "K.mtx", "modes": modes, "capacitance": cap} | replace
    return base.text + "\n[import]\n" + "".join(f'{k} = "{files[k]}"\n' for k in KEYS)


# ------------------------------------------------------------------ the corruptions


def npz(**arrays) -> bytes:
    """An .npz archive's bytes (object arrays pickled, as np.savez does)."""
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def mtx(a: np.ndarray, field: str = "real", symmetry: str = "symmetric") -> bytes:
    """A dense matrix in Matrix Market coordinate format (lower triangle for symmetric)."""
    n = a.shape[0]
    rows = [(i, j) for j in range(n) for i in range(n) if (i >= j or symmetry == "general") and a[i, j] != 0]
    body = "".join(f"{i + 1} {j + 1} {float(a[i, j])!r}\n" for i, j in rows)
    return f"%%MatrixMarket matrix coordinate {field} {symmetry}\n{n} {a.shape[1]} {len(rows)}\n{body}".encode()


def garbage(seed: int, size: int = 400) -> bytes:
    """Random bytes (with NULs)."""
    return np.random.default_rng(seed).integers(0, 256, size, dtype=np.uint8).tobytes()


def matrix_cases(b: Base) -> Iterator[Case]:
    """Header, size, entry and physics corruptions of M and K (array and coordinate formats)."""
    for key, short in (("mass_matrix", "M"), ("stiffness_matrix", "K")):
        dense = np.asarray(
            scipy.io.mmread(str(b.files[key])).todense()
            if scipy.sparse.issparse(scipy.io.mmread(str(b.files[key])))
            else scipy.io.mmread(str(b.files[key]))
        )
        n = dense.shape[0]
        for fmt in ("", "_coo"):
            lines = b.read(key + fmt).decode().splitlines(keepends=True)
            size = next(k for k, ln in enumerate(lines) if not ln.startswith("%"))
            body = lines[size + 1 :]
            if not body:  # a zero matrix has no coordinate entries
                continue

            def case(data, expect=None, cls="mtx header/size"):
                return Case(
                    cls, b.name, key, ".mtx", data if isinstance(data, bytes) else "".join(data).encode(), expect
                )

            yield case(lines[:-1], "truncated")
            yield case(lines + body[:1], "too long")
            yield case(
                [lines[0].replace("real", "pattern")]
                + lines[1 : size + 1]
                + [" ".join(x.split()[:-1]) + "\n" for x in body],
                "pattern",
            )
            yield case(
                [lines[0].replace("real", "complex")] + lines[1 : size + 1] + [x.rstrip() + " 0\n" for x in body],
                "complex",
            )
            yield case([lines[0].replace("symmetric", "skew-symmetric")] + lines[1:], "skew")
            yield case([lines[0].replace("symmetric", "hermitian")] + lines[1:], "hermitian")
            yield case(lines[1:], "Matrix Market")
            yield case(
                lines[:size] + [lines[size].replace(f"{n} {n}", f"{n + 1} {n + 1}", 1)] + body, f"{n + 1} x {n + 1}"
            )
            yield case(lines[:size] + [lines[size].replace(f"{n} {n}", f"{n} {n + 1}", 1)] + body, "square")
            yield case(lines[:size] + ["1000000 1000000 1\n", "1 1 1.0\n"], "1000000 x 1000000" if fmt else None)
            yield case(b"", "Matrix Market")
            yield case(garbage(len(lines) + n), "Matrix Market")
            yield case(b.read(key + fmt)[: len(b.read(key + fmt)) * 2 // 3], None)
            for bad in ("abc", "1.0.0", "--1"):
                yield case(
                    lines[:-1] + [lines[-1].rsplit(" ", 1)[0] + " " + bad + "\n" if fmt else bad + "\n"],
                    f":{len(lines)}:",
                )
            for bad in ("nan", "inf", "-inf"):
                yield case(
                    lines[:-1] + [lines[-1].rsplit(" ", 1)[0] + " " + bad + "\n" if fmt else bad + "\n"],
                    f"entry ({n}, {n})",
                    "mtx values",
                )
            if fmt:
                yield case(lines[:-1] + [f"{n + 1} {n + 1} 1.0\n"], f":{len(lines)}:")
                yield case(lines[:-1] + ["0 0 1.0\n"], f":{len(lines)}:")
                yield case(lines[:size] + [f"{n} {n} {len(body) + 1}\n"] + body + body[-1:], f"entry ({n}, {n})")
        # physics of the modal values
        for k in range(n):
            for factor in (-1.0, 0.0) if short == "M" else (-1.0,):
                a = dense.copy()
                a[k, k] *= factor
                if short == "K" and a[k, k] == 0:
                    continue
                yield Case("mtx physics", b.name, key, ".mtx", mtx(a), f"entry ({k + 1}, {k + 1})")
            if short == "K":
                a = dense.copy()
                if b.name == "beam":  # an eigenmode at 0 Hz
                    a[k, k] = 0.0
                    yield Case("mtx physics", b.name, key, ".mtx", mtx(a), f"entry ({k + 1}, {k + 1})")
                elif b.name == "disk":  # a free rigid body with a spring
                    a[k, k] = 1e-3 * (k + 1)
                    yield Case("mtx physics", b.name, key, ".mtx", mtx(a), f"entry ({k + 1}, {k + 1})")
                else:  # the piston's spring lost
                    a[k, k] = 0.0
                    yield Case("mtx physics", b.name, key, ".mtx", mtx(a), f"entry ({k + 1}, {k + 1})")
        if n > 1:
            a = dense.copy()
            a[1, 0] = a[0, 1] = 0.3 * np.sqrt(abs(dense[0, 0] * dense[1, 1])) + 1e-3 * (
                short == "K" and b.name == "disk"
            )
            yield Case("mtx physics", b.name, key, ".mtx", mtx(a), "entry (2, 1)")
            a = dense.copy()
            a[1, 0] = 0.5 * np.sqrt(abs(dense[0, 0] * dense[1, 1])) + 1.0
            yield Case("mtx header/size", b.name, key, ".mtx", mtx(a, symmetry="general"), "(2, 1)")


def modes_npz_cases(b: Base) -> Iterator[Case]:
    """Keys, types, shapes, values and coverage of a modes .npz."""
    with np.load(b.files["modes"]) as z:
        good = {k: z[k] for k in z.files}
    nodes, vectors, n = good["nodes"], good["vectors"], good["vectors"].shape[1]

    def case(cls, expect=None, **change):
        arrays = {k: v for k, v in (good | change).items() if v is not None}
        return Case(cls, b.name, "modes", ".npz", npz(**arrays), expect)

    for k in ("nodes", "vectors", "names"):
        yield case("npz keys/shapes", k, **{k: None})
    yield case("npz keys/shapes", "node", node=nodes)
    yield case("npz keys/shapes", "nodes", nodes=np.column_stack([nodes, nodes[:, :1]]))
    yield case("npz keys/shapes", "nodes", nodes=nodes[:, 0])
    yield case("npz keys/shapes", "vectors", vectors=vectors[:, :-1])
    yield case("npz keys/shapes", "names", names=good["names"][:-1])
    yield case("npz keys/shapes", "names", names=np.arange(n))
    yield case("npz keys/shapes", "names", names=good["names"].reshape(1, -1))
    yield case("npz keys/shapes", "labels", labels=np.array(["a"] * (n + 1)))
    yield case("npz keys/shapes", "vectors", vectors=vectors.astype(str))
    yield case("npz keys/shapes", "nodes", nodes=np.array([{"x": 1}] * len(nodes), dtype=object))
    for r in (0, len(nodes) // 2, len(nodes) - 1):
        for bad in (np.nan, np.inf):
            v = vectors.copy()
            v[r, r % n] = bad
            yield case("mode values", f"row {r}", vectors=v)
            p = nodes.copy()
            p[r, r % 2] = bad
            yield case("mode values", f"row {r}", nodes=p)
    if "length_scale" in good and float(good["length_scale"]) != 1.0:
        for bad in (-1.0, 0.0, np.nan, np.array([1.0, 2.0])):
            yield case("npz keys/shapes", "length_scale", length_scale=bad)
        yield case("mode coverage", "outside", length_scale=1.0)
    yield case("mode coverage", "outside", nodes=nodes * 1e6)
    half = nodes[:, 0] < 0 if b.name != "beam" else nodes[:, 0] < nodes[:, 0].mean()
    if "triangles" not in good:
        yield case("mode coverage", "cover", nodes=nodes[half], vectors=vectors[half])
        v = vectors.copy()
        p = nodes.copy()
        p[5] = p[3]
        v[5] = v[3] * 1.5 + 1e-9
        yield case("mode values", "row 5", nodes=p, vectors=v)
    else:
        t = good["triangles"]
        yield case("npz keys/shapes", "triangles", triangles=t[:, :5])
        yield case("npz keys/shapes", "triangles", triangles=t + len(nodes))
        yield case("npz keys/shapes", "triangles", triangles=t - 1)
        yield case("npz keys/shapes", "triangles", triangles=t.astype(float) + 0.5)
        yield case("npz keys/shapes", "w_rows", w_rows=np.arange(len(nodes)) + 1)
    for k in range(n):
        v = vectors.copy()
        v[:, k] = 0.0
        yield case("mode values", "zero displacement", vectors=v)
    rigid = [k for k, nm in enumerate(good["names"]) if str(nm) in ("z", "tilt_x", "tilt_y")]
    for k in rigid:
        v = vectors.copy()
        v[:, k] *= 1.5
        yield case("mode values", "rigid-body", vectors=v)
    whole = b.read("modes")
    yield Case("npz file", b.name, "modes", ".npz", whole[: len(whole) // 2], "npz")
    yield Case("npz file", b.name, "modes", ".npz", b"", "npz")
    yield Case("npz file", b.name, "modes", ".npz", garbage(7), "npz")
    buf = io.BytesIO()
    np.save(buf, vectors)
    yield Case("npz file", b.name, "modes", ".npz", buf.getvalue(), ".npy")


def csv_bytes(header: list[str], rows: list[list[str]]) -> bytes:
    return ("\n".join([",".join(header)] + [",".join(r) for r in rows]) + "\n").encode()


def csv_cases(b: Base, key: str, cls_file: str) -> Iterator[Case]:
    """File-level corruptions shared by the CSV tables: text, header and row syntax."""
    text = b.files[key + "_csv"].read_text()
    header, *rows = [ln.split(",") for ln in text.splitlines()]
    last = len(rows) + 1  # the line of the last row

    def case(data, expect=None, cls=cls_file):
        return Case(cls, b.name, key, ".csv", data, expect)

    yield case(b"", "no data rows")
    yield case(csv_bytes(header, []), "no data rows")
    yield case(garbage(3), "binary")
    yield case(text.encode().replace(b"\n", b"\xb5\n", 1), "UTF-8")
    yield case(text.encode("utf-16"), "binary")
    yield case(b"\xff\xfe" + text.encode()[:200], "UTF-8")
    for r in (1, len(rows) // 2, len(rows)):
        yield case(csv_bytes(header, rows[: r - 1] + [rows[r - 1][:-1]] + rows[r:]), f":{r + 1}:")
        yield case(csv_bytes(header, rows[: r - 1] + [rows[r - 1] + ["1"]] + rows[r:]), f":{r + 1}:")
        bad = list(rows[r - 1])
        bad[1] = "1,5e-6".replace(",", ";")
        yield case(csv_bytes(header, rows[: r - 1] + [bad] + rows[r:]), f":{r + 1}:")
        bad = list(rows[r - 1])
        bad[0] = "one"
        yield case(csv_bytes(header, rows[: r - 1] + [bad] + rows[r:]), f":{r + 1}:")
    yield case(csv_bytes(header[:1] + header[:1] + header[2:], rows), ":1:", "csv header")
    yield case(csv_bytes([""] + header[1:], rows), ":1:", "csv header")
    del last


def modes_csv_cases(b: Base) -> Iterator[Case]:
    """Header names, values and coverage of a modes CSV."""
    yield from csv_cases(b, "modes", "csv file")
    table = np.loadtxt(b.files["modes_csv"], delimiter=",", skiprows=1)
    header = b.files["modes_csv"].read_text().splitlines()[0].split(",")
    n = len(header) - 2

    def case(cls, h, t, expect=None):
        return Case(cls, b.name, "modes", ".csv", csv_bytes(h, [[repr(float(v)) for v in r] for r in t]), expect)

    yield case("csv header", ["X", "Y"] + header[2:], table, ":1:")
    yield case("csv header", header[:2], table[:, :2], ":1:")
    for bad in ("m-1", "1m", "error_mode", "m 1"):
        yield case("csv header", header[:2] + [bad] + header[3:], table, bad)
    if n > 1:
        yield case("csv header", header[:2] + [header[2]] * n, table, "twice")
    for r in (0, len(table) // 3, len(table) - 1):
        for bad in (np.nan, np.inf, -np.inf):
            t = table.copy()
            t[r, 2 + r % n] = bad
            yield case("mode values", header, t, f":{r + 2}:")
    yield case("mode coverage", header, table * np.array([1e6, 1e6] + [1.0] * n), "outside")
    keep = table[:, 0] <= table[:, 0].max() / 2
    yield case("mode coverage", header, table[keep], "cover")
    for r in (3, len(table) // 2):
        t = table.copy()
        t[r + 1, :2] = t[r, :2]
        t[r + 1, 2:] = t[r, 2:] * 0.5 + 1e-7
        yield case("mode values", header, t, f":{r + 3}:")
    for k in range(n):
        t = table.copy()
        t[:, 2 + k] = 0.0
        yield case("mode values", header, t, "zero displacement")


def cap_table(b: Base) -> tuple[list[str], np.ndarray, np.ndarray]:
    """The good capacitance CSV: header, numbers (q and C columns), set column."""
    lines = b.files["capacitance_csv"].read_text().splitlines()
    header = lines[0].split(",")
    rows = [ln.split(",") for ln in lines[1:]]
    return header, np.array([[float(v) for v in r[:-1]] for r in rows]), np.array([r[-1] for r in rows])


def capacitance_csv_cases(b: Base) -> Iterator[Case]:
    """Values, units, duplicates, sample counts and columns of a capacitance CSV."""
    yield from csv_cases(b, "capacitance", "csv file")
    header, t, sets = cap_table(b)
    nq = sum(h.startswith("q:") for h in header)

    full = header
    header = header[:-1]

    def case(cls, t, expect=None, h=None, s=sets):
        rows = [[repr(float(v)) for v in r] + [x] for r, x in zip(t, s)]
        return Case(cls, b.name, "capacitance", ".csv", csv_bytes(h or full, rows), expect)

    fit_rows = np.flatnonzero(sets == "fit")
    picks = [
        int(fit_rows[0]),
        int(fit_rows[len(fit_rows) // 2]),
        int(fit_rows[-1]),
        int(np.flatnonzero(sets == "check")[0]),
    ]
    for r in picks:
        for bad in (-t[r, nq], 0.0, np.inf, -np.inf):
            u = t.copy()
            u[r, nq] = bad
            yield case("capacitance values", u, f":{r + 2}:")
        for bad in (np.nan, np.inf):
            u = t.copy()
            u[r, r % nq] = bad
            yield case("capacitance values", u, f":{r + 2}:")
        u = t.copy()
        u[r, nq] *= 1e12
        yield case("capacitance units", u, f":{r + 2}:")
        u = t.copy()
        u[r, :nq] *= 1e6  # coordinates in um
        if np.any(u[r, :nq]):
            yield case("capacitance units", u, f":{r + 2}:")
    for factor in (1e12, 1e15, 1e9, 1e3, 1e-4, 1e-12):
        u = t.copy()
        u[:, nq:] *= factor
        yield case("capacitance units", u, "multiply by")
    for r in picks[:3]:  # conflicting repeats
        u = np.vstack([t, t[r : r + 1]])
        u[-1, nq] *= 1.01
        yield case("duplicates", u, f":{len(t) + 2}:", s=np.append(sets, "fit"))
        u = np.vstack([t[: r + 1], t[r : r + 1] * np.array([1.0] * nq + [1.1]), t[r + 1 :]])
        yield case("duplicates", u, f":{r + 3}:", s=np.insert(sets, r + 1, sets[r]))
    need = 2 * (nq + 1)
    for count in sorted({1, 2, need - 1, max(need - 2, 1)}):
        keep = np.concatenate([fit_rows[:count], np.flatnonzero(sets == "check")[:3]])
        yield case("sample count", t[keep], str(need), s=sets[keep])
    if nq > 1:
        for k in range(nq):  # a coordinate that never varies
            keep = np.flatnonzero((t[:, k] == 0) | (sets == "check"))
            yield case("sample count", t[keep], "never vary", s=sets[keep])
    yield case("capacitance values", t, "check", s=np.array(["fit"] * len(t)))
    u = sets.copy()
    u[4] = "train"
    yield case("capacitance columns", t, ":6:", s=u)
    yield case("capacitance columns", t, header[-1][2:], h=header[:-1] + ["C:drve", "set"])
    yield case("capacitance columns", t, ":1:", h=["Q:" + header[0][2:]] + header[1:] + ["set"])
    yield (
        case("capacitance columns", t[:, 1:], "no column", h=header[1:] + ["set"])
        if nq > 1
        else case("capacitance columns", t[:, 1:], "no q:", h=header[1:] + ["set"])
    )
    yield case(
        "capacitance columns",
        np.column_stack([t[:, :nq], 0 * t[:, :1], t[:, nq:]]),
        "does not have",
        h=header[:nq] + ["q:m9"] + header[nq:] + ["set"],
    )
    yield case("capacitance columns", np.column_stack([t, t[:, -1:]]), "does not have", h=header + ["C:other", "set"])
    yield case("capacitance columns", t[:, :nq], "no q:", h=header[:nq] + ["set"])


def capacitance_npz_cases(b: Base) -> Iterator[Case]:
    """Keys, types and shapes of a capacitance .npz (the values share the CSV's checks)."""
    with np.load(b.files["capacitance"]) as z:
        good = {k: z[k] for k in z.files}
    q, c = good["q"], good["c"]

    def case(cls, expect=None, **change):
        arrays = {k: v for k, v in (good | change).items() if v is not None}
        return Case(cls, b.name, "capacitance", ".npz", npz(**arrays), expect)

    for k in ("q", "c", "coordinates", "electrodes"):
        yield case("npz keys/shapes", k, **{k: None})
    yield case("npz keys/shapes", "holdout", holdout_c=None)
    yield case("npz keys/shapes", "holdout", holdout_q=None)
    yield case("npz keys/shapes", "hold_out_q", hold_out_q=good["holdout_q"])
    yield case("npz keys/shapes", "q", q=q[:-1])
    yield case("npz keys/shapes", "shape", q=np.column_stack([q, q[:, :1]]))
    yield case("npz keys/shapes", "shape", c=np.column_stack([c, c]))
    yield case("npz keys/shapes", "coordinates", coordinates=np.arange(q.shape[1]))
    yield case("npz keys/shapes", "q", q=q.astype(complex))
    yield case("npz keys/shapes", "electrodes", electrodes=np.array([None], dtype=object))
    if q.shape[1] > 1:
        yield case("npz keys/shapes", "coordinate", coordinates=good["coordinates"][::-1][:1].repeat(q.shape[1]))
    for r in (0, len(q) // 2):
        u = c.copy()
        u[r, 0] = -u[r, 0] if np.isfinite(u[r, 0]) else -1e-13
        yield case("capacitance values", f"row {r} (0-based) of q/c", c=u)
        u = good["holdout_c"].copy()
        u[r, 0] = np.inf
        yield case("capacitance values", f"row {r} (0-based) of holdout_q", holdout_c=u)
    yield case("capacitance units", "multiply by 1e-12", c=c * 1e12, holdout_c=good["holdout_c"] * 1e12)
    yield case("sample count", "needs at least", q=q[:2], c=c[:2])
    u, v = q.copy(), c.copy()
    ok = np.flatnonzero(np.all(np.isfinite(c), axis=1))
    u[ok[1]], v[ok[1]] = u[ok[0]], v[ok[0]] * 1.2
    yield case("duplicates", f"row {ok[1]} (0-based)", q=u, c=v)
    whole = b.read("capacitance")
    yield Case("npz file", b.name, "capacitance", ".npz", whole[: len(whole) // 3], "npz")
    yield Case("npz file", b.name, "capacitance", ".npz", b"", "npz")
    yield Case("npz file", b.name, "capacitance", ".npz", garbage(11), "npz")


def full_piston(b: Base, n: int = 21) -> dict[str, bytes]:
    """The piston as full FE data: n x n nodes with the z field 1, M and K diagonal over the
    nodes (each m / N, k / N), so that phi^T M phi, phi^T K phi are the native m and k."""
    x, y = np.meshgrid(np.linspace(-100e-6, 100e-6, n), np.linspace(-100e-6, 100e-6, n))
    nodes = np.column_stack([x.ravel(), y.ravel()])
    c = b.native.model.coordinates[0]
    eye = np.eye(len(nodes))
    return {
        "modes": npz(nodes=nodes, vectors=np.ones((len(nodes), 1)), names=np.array(["z"])),
        "mass_matrix": mtx(eye * c.mass / len(nodes)),
        "stiffness_matrix": mtx(eye * c.stiffness / len(nodes)),
        "M": eye * c.mass / len(nodes),
        "K": eye * c.stiffness / len(nodes),
    }


def full_matrix_cases(b: Base) -> Iterator[Case]:
    """Full N x N matrices projected on full eigenvectors: M positive definite, K semidefinite."""
    f = full_piston(b)
    M, K, n = f["M"], f["K"], len(f["M"])
    for k in (0, n // 2, n - 1):
        for factor, expect in ((0.0, "positive definite"), (-1.0, "positive definite")):
            a = M.copy()
            a[k, k] *= factor
            yield Case(
                "mtx physics",
                b.name,
                "mass_matrix",
                ".mtx",
                mtx(a),
                expect,
                (("modes", ".npz", f["modes"]), ("stiffness_matrix", ".mtx", f["stiffness_matrix"])),
            )
        a = K.copy()
        a[k, k] *= -1.0
        yield Case(
            "mtx physics",
            b.name,
            "stiffness_matrix",
            ".mtx",
            mtx(a),
            "semidefinite",
            (("modes", ".npz", f["modes"]), ("mass_matrix", ".mtx", f["mass_matrix"])),
        )


def cases(bases: dict[str, Base]) -> list[Case]:
    """Every bad file of the generator."""
    out: list[Case] = []
    for b in bases.values():
        out += list(matrix_cases(b))
        out += list(modes_npz_cases(b))
        out += list(capacitance_npz_cases(b))
        if b.name == "piston":
            out += list(full_matrix_cases(b))
        if b.name != "disk":
            out += list(modes_csv_cases(b))
            out += list(capacitance_csv_cases(b))
    return out


# ------------------------------------------------------------------ running them


@dataclass
class Outcome:
    """What a build of one case did: exit code (None: an exception escaped), stderr, output files."""

    code: int | None
    message: str
    outputs: list[str]


def run(bases: dict[str, Base], k: int, c: Case) -> tuple[Outcome, Path]:
    """Write case k's bad file beside its base's good ones and build it through netgen.cli.commands.main."""
    b = bases[c.base]
    bad = b.folder / f"case{k:03d}_{c.key}{c.suffix}"
    bad.write_bytes(c.data)
    modes = "modes.csv" if c.key == "modes" and c.suffix == ".csv" else "modes.npz"
    cap = "capacitance.csv" if c.key == "capacitance" and c.suffix == ".csv" else "capacitance.npz"
    replace = {c.key: bad.name}
    for key, suffix, data in c.others:
        (b.folder / f"case{k:03d}_{key}{suffix}").write_bytes(data)
        replace[key] = f"case{k:03d}_{key}{suffix}"
    toml = b.folder / f"case{k:03d}.toml"
    toml.write_text(structure_text(b, replace, modes, cap))
    out = b.folder / f"out{k:03d}"
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = main(["build", str(toml), "-o", str(out), "-q", "--no-plots"])
        except BaseException:  # noqa: BLE001 (a traceback is what we count)
            code, _ = None, err.write(traceback.format_exc())
    return Outcome(code, err.getvalue(), sorted(p.name for p in out.glob("*")) if out.exists() else []), bad


def verdict(o: Outcome, c: Case, bad: Path) -> str:
    """'ok', 'traceback', 'accepted', or what the refusal lacks."""
    if o.code is None or "Traceback" in o.message:
        return "traceback"
    if o.code == 0:
        return "accepted"
    if o.code != 2:
        return f"exit {o.code}"
    if str(bad) not in o.message:
        return "no file"
    if "fix:" not in o.message or not o.message.split("fix:", 1)[1].strip():
        return "no fix"
    if c.expect and c.expect not in o.message:
        return f"no {c.expect!r}"
    if o.outputs:
        return "wrote output"
    return "ok"


@pytest.fixture(scope="module")
def bases(tmp_path_factory) -> dict[str, Base]:
    return make_bases(tmp_path_factory.mktemp("imports"))


def test_bad_import_files_exit_2_naming_file_row_and_fix(bases):
    """At least 304 generated bad files: every one exit 2, no traceback, nothing written, the
    message naming the file, the row or entry, and a fix."""
    all_cases = cases(bases)
    assert len(all_cases) >= 304
    failures = []
    for k, c in enumerate(all_cases):
        o, bad = run(bases, k, c)
        v = verdict(o, c, bad)
        if v != "ok":
            failures.append(f"{k} {c.cls} {c.base} {c.key}: {v}: {o.message.strip()[-300:]}")
    assert not failures, f"{len(failures)} of {len(all_cases)}:\n" + "\n".join(failures[:20])


def lib_numbers(folder: Path, name: str) -> np.ndarray:
    """Every number of a written .lib's element and parameter lines (the comments hold the source
    path and fit errors at round-off level)."""
    text = (folder / f"{name}.lib").read_text()
    lines = [ln for ln in text.splitlines() if not ln.lstrip().startswith("*")]
    return np.array([float(v) for v in NUMBER.findall("\n".join(lines))])


def differences(got: np.ndarray, want: np.ndarray, rel: float) -> str:
    """Which .lib numbers differ by more than `rel` relative, the largest difference and the BLAS
    thread counts (netgen.electrostatics.sampling.blas_threads): what a failure must say to tell a
    rounding-level change (one ulp in one sample moves the disk's numbers by up to 4.1e-8,
    bench/import_ulp_sensitivity.py) from a wrong merge or fit."""
    if got.shape != want.shape:
        return f"{len(got)} numbers against {len(want)}"
    off = np.flatnonzero(np.abs(got - want) > rel * np.abs(want))
    worst = np.max(np.abs(got - want) / np.where(want != 0, np.abs(want), 1.0)) if len(got) else 0.0
    return (
        f"{len(off)} of {len(got)} numbers differ (indices {off[:10].tolist()}), largest relative "
        f"difference {worst:.3e}, BLAS threads {blas_threads()}"
    )


# imported against native .lib numbers: the same samples give the same bits, but a process's numpy
# reductions can round a few samples an ulp apart (their SIMD paths follow the arrays' alignment), and
# one ulp in one sample moves the disk's numbers by up to 4.1e-8 (bench/import_ulp_sensitivity.py: the
# fits settled to 1e-14, netgen.fit.capacitance.settled, follow the data along ill-determined
# directions); 1e-6 is 25 such ulps, far below what a wrong merge or fit moves (the fits' own 1e-4)
ULP_BOUND = 1e-6


@pytest.mark.parametrize("name", ["beam", "piston", "disk"])
def test_good_exports_still_build_the_native_model(bases, name, tmp_path):
    """The good NPZ set builds with exit 0 and the native model: rigid fields (piston, disk) are
    exact, so every .lib number within ULP_BOUND relative of the native build's; the beam's modes are
    a cubic spline through the exported nodes, so its masses and stiffnesses exact and its
    capacitance on the native held-out points within 1e-4. The same table with every row given
    twice merges to the original rows bit for bit and writes the same .lib within ULP_BOUND."""
    b = bases[name]
    (tmp_path / "native.toml").write_text(b.text)
    assert main(["build", str(tmp_path / "native.toml"), "-o", str(tmp_path / "native"), "-q", "--no-plots"]) == 0
    with np.load(b.files["capacitance"]) as z:
        good = {k: z[k] for k in z.files}
    (b.folder / "repeated.npz").write_bytes(
        npz(**(good | {"q": np.vstack([good["q"], good["q"]]), "c": np.vstack([good["c"], good["c"]])}))
    )
    libs = []
    for cap in ("capacitance.npz", "repeated.npz"):
        toml = b.folder / f"good_{cap}.toml"
        toml.write_text(structure_text(b, {}, cap=cap))
        assert main(["build", str(toml), "-o", str(tmp_path / cap), "-q", "--no-plots"]) == 0
        libs.append(lib_numbers(tmp_path / cap, b.native.model.name))
    once, twice = (read_capacitance(b.folder / cap) for cap in ("capacitance.npz", "repeated.npz"))
    kept = merge_duplicates(twice)
    assert np.array_equal(twice.q[kept], once.q) and np.array_equal(twice.c[kept], once.c, equal_nan=True)
    # the merged table is the original to the bit; the fit of it is the same fit in other memory, so
    # the two .lib files agree to the rounding room of an alignment-dependent reduction (ULP_BOUND)
    assert np.all(np.abs(libs[1] - libs[0]) <= ULP_BOUND * np.abs(libs[0])), "rows twice against once: " + differences(
        libs[1], libs[0], ULP_BOUND
    )
    want = lib_numbers(tmp_path / "native", b.native.model.name)
    if name != "beam":
        assert len(libs[0]) == len(want) > 50
        assert np.all(np.abs(libs[0] - want) <= ULP_BOUND * np.abs(want)), "imported against native: " + differences(
            libs[0], want, ULP_BOUND
        )
        return
    imported = build(parse_structure(toml.read_text(), str(toml)))
    for p, q in zip(imported.model.coordinates, b.native.model.coordinates):
        assert (p.name, p.mass, p.stiffness) == (q.name, q.mass, q.stiffness)
    # the imported fit is the native one; both miss the held-out solves by the fit's own held-out
    # error (1.09e-4 on the cantilever, over a flat 1e-4), bounded by the fit tolerance
    got, native = imported.model.capacitance(b.native.holdout.x), b.native.model.capacitance(b.native.holdout.x)
    assert got == pytest.approx(native, rel=1e-12, abs=0)
    assert got == pytest.approx(b.native.holdout.c, rel=b.native.structure.fit.tolerance, abs=0)


def test_full_matrices_build_the_native_piston(bases, tmp_path):
    """Full N x N M and K with full eigenvectors (netgen.mechanics.import_checks.check_full passes
    them) project to the native piston's mass and spring: the .lib numbers within 1e-9."""
    b = bases["piston"]
    f = full_piston(b)
    for key, suffix in (("modes", ".npz"), ("mass_matrix", ".mtx"), ("stiffness_matrix", ".mtx")):
        (b.folder / f"full_{key}{suffix}").write_bytes(f[key])
    toml = b.folder / "full.toml"
    toml.write_text(
        structure_text(
            b,
            {k: f"full_{k}{x}" for k, x in (("mass_matrix", ".mtx"), ("stiffness_matrix", ".mtx"))},
            modes="full_modes.npz",
        )
    )
    (tmp_path / "native.toml").write_text(b.text)
    assert main(["build", str(tmp_path / "native.toml"), "-o", str(tmp_path / "native"), "-q", "--no-plots"]) == 0
    assert main(["build", str(toml), "-o", str(tmp_path / "full"), "-q", "--no-plots"]) == 0
    got, want = lib_numbers(tmp_path / "full", "piston"), lib_numbers(tmp_path / "native", "piston")
    assert len(got) == len(want) > 50 and np.all(np.abs(got - want) <= 1e-9 * np.abs(want))


def table(tally: dict[str, dict[str, int]]) -> str:
    """The per-class markdown table."""
    rows = [
        "| class | tried | tracebacks | accepted (exit 0) | refused without file/row/fix |",
        "|---|---|---|---|---|",
    ]
    for cls, t in sorted(tally.items()) + [
        ("all", {k: sum(t[k] for t in tally.values()) for k in ("tried", "traceback", "accepted", "other")})
    ]:
        rows.append(f"| {cls} | {t['tried']} | {t['traceback']} | {t['accepted']} | {t['other']} |")
    return "\n".join(rows)


def survey(root: Path, show: Callable[[str], None] = print) -> dict[str, dict[str, int]]:
    """Run the generator and tally the verdicts per class."""
    bases = make_bases(root)
    tally: dict[str, dict[str, int]] = {}
    for k, c in enumerate(cases(bases)):
        o, bad = run(bases, k, c)
        v = verdict(o, c, bad)
        t = tally.setdefault(c.cls, {"tried": 0, "traceback": 0, "accepted": 0, "other": 0})
        t["tried"] += 1
        t[v if v in ("traceback", "accepted") else "other"] += v != "ok"
        if v != "ok" and "-v" in sys.argv:
            show(f"{k} {c.cls} {c.base} {c.key}{c.suffix}: {v}: {o.message.strip()[-250:]}")
    return tally


if __name__ == "__main__":
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        print(table(survey(Path(tmp))))
