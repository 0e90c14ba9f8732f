"""How much rounding room tests/pipeline/test_import_validation.py's disk comparisons have: the
free disk (two mirror-image sectors, rigid z and tilt_x) built natively, its exported capacitance
table imported again (as given, with every row twice, under 1 and the default number of BLAS
threads), then with one sample moved by one ulp. Prints the largest relative change of the
written .lib numbers against the native build's, and its ratio to the test's 1e-6 bound.

    nice -n 10 .venv/bin/python bench/import_ulp_sensitivity.py --trials 8
    for s in 0 1 2 3; do PYTHONHASHSEED=$s .venv/bin/python bench/import_ulp_sensitivity.py --trials 0; done
"""

from __future__ import annotations

import argparse
import io
import re
import tempfile
from pathlib import Path

import numpy as np
import support
from threadpoolctl import threadpool_limits

from netgen import export
from netgen.build import build
from netgen.cli.commands import main
from netgen.structure import parse_structure

DISK = support.oracle("small_disk").IMPORT_DISK  # tests/pipeline/test_import_validation.py's disk
BOUND = 1e-6  # the test's relative bound (tests/pipeline/test_import_validation.py ULP_BOUND) between imported and native .lib numbers
NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


def lib_numbers(folder: Path) -> np.ndarray:
    """The numbers of disk.lib's element lines (comments skipped), as the test reads them."""
    lines = [ln for ln in (folder / "disk.lib").read_text().splitlines() if not ln.lstrip().startswith("*")]
    return np.array([float(v) for v in NUMBER.findall("\n".join(lines))])


def npz(**arrays) -> bytes:
    """An .npz archive's bytes."""
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def built(root: Path, tag: str, table: dict[str, np.ndarray] | None) -> np.ndarray:
    """The .lib numbers of a CLI build: native (table None) or importing `table` with the exported mechanics."""
    text = DISK
    if table is not None:
        (root / f"{tag}.npz").write_bytes(npz(**table))
        text += "\n[import]\n" + "".join(
            f'{k} = "{v}"\n'
            for k, v in (("mass_matrix", "M.mtx"), ("stiffness_matrix", "K.mtx"), ("modes", "modes.npz"))
        )
        text += f'capacitance = "{tag}.npz"\n'
    (root / f"{tag}.toml").write_text(text)
    assert main(["build", str(root / f"{tag}.toml"), "-o", str(root / f"out_{tag}"), "-q", "--no-plots"]) == 0
    return lib_numbers(root / f"out_{tag}")


def worst(got: np.ndarray, want: np.ndarray) -> float:
    """Largest relative difference over the nonzero numbers."""
    nz = want != 0
    return float(np.max(np.abs(got[nz] - want[nz]) / np.abs(want[nz])))


def run(trials: int) -> None:
    root = Path(tempfile.mkdtemp(prefix="ulp_"))
    files = export.export(build(parse_structure(DISK, "disk.toml")), root)
    with np.load(files["capacitance"]) as z:
        good = {k: z[k] for k in z.files}
    native = built(root, "native", None)
    twice = good | {"q": np.vstack([good["q"], good["q"]]), "c": np.vstack([good["c"], good["c"]])}
    with threadpool_limits(limits=1, user_api="blas"):
        one = built(root, "one_thread", good)
    for tag, got in (("as given", built(root, "given", good)), ("rows twice", built(root, "twice", twice))):
        print(
            f"import {tag:12s} max rel diff to native {worst(got, native):.1e}  bit-identical {np.array_equal(got, native)}"
        )
    print(
        f"import 1 BLAS thread  max rel diff to native {worst(one, native):.1e}  bit-identical {np.array_equal(one, native)}"
    )
    rng = np.random.default_rng(1)
    moved = []
    for t in range(trials):
        c = good["c"].copy()
        k = int(rng.integers(0, c.size))
        c.flat[k] = np.nextafter(c.flat[k], np.inf if t % 2 else -np.inf)
        moved.append(worst(built(root, f"ulp{t}", good | {"c": c}), native))
        print(f"one ulp in sample {k:2d}: max rel change {moved[-1]:.2e}")
    if moved:
        top = max(moved)
        print(f"one ulp in one sample: max rel change {top:.2e} = {top / BOUND:.2f} of the test's {BOUND:g} bound")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=8, help="perturbed tables (one sample, one ulp each)")
    run(ap.parse_args().trials)
