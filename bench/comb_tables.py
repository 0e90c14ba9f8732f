"""Re-solve the examples' comb cross-section tables and ship them (netgen.electrostatics.comb_section.SHIPPED):
build each example with combs in an empty private cache (NETGEN_CACHE), so every table it needs is
solved at the package's GRID and SETTINGS, copy the new tables into netgen/electrostatics/comb_tables/,
and print the CPU time the solves took. Run it after a change of the cell, the grid, the ranges or the
solver settings (each renames every table); run it under `nice -n 10` (minutes of CPU).

    nice -n 10 .venv/bin/python bench/comb_tables.py [examples/accelerometer_xyz.toml ...]
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path

from support import ROOT


def main() -> None:
    """Solve, copy and time the tables of the named examples (default: every example with a comb)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("examples", nargs="*", type=Path)
    a = ap.parse_args()
    examples = a.examples or [p for p in sorted((ROOT / "examples").glob("*.toml")) if "_comb" in p.read_text()]
    with tempfile.TemporaryDirectory() as cache:
        os.environ["NETGEN_CACHE"] = cache
        from netgen.build import build
        from netgen.electrostatics import comb_section
        from netgen.structure import load_structure

        comb_section.SHIPPED = Path(cache) / "none"  # solve, do not read the shipped copies
        for path in examples:
            t0 = time.process_time()
            build(load_structure(path))
            used = time.process_time() - t0
            print(f"{path.name}: built in {used:.1f} s CPU (the comb tables' solves and the fit)")
        target = ROOT / "netgen" / "electrostatics" / "comb_tables"
        target.mkdir(exist_ok=True)
        for table in sorted((Path(cache) / "comb_sections").glob("*.npz")):
            shutil.copy(table, target / table.name)
            print(f"shipped {table.name}")


if __name__ == "__main__":
    main()
