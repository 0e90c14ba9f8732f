"""Re-solve the examples' comb cross-section tables and ship them (netgen.electrostatics.comb_section.SHIPPED):
build each example with combs in an empty private cache (NETGEN_CACHE), so every table it needs is
solved at the package's GRID and SETTINGS, copy the new tables into netgen/electrostatics/comb_tables/,
and print the CPU time the solves took; by default also accelerometer_xyz's combs at the etched finger
widths (the etch law's points and the suite's rebuilds, netgen.model.etch_combs), at the tscale
law's finger thicknesses (netgen.model.process.thickness_capacitance) and both scaled and etched
(netgen.model.process.cross_capacitance, cross_cells). Run it after a
change of the cell, the grid, the ranges or the solver settings (each renames every table); run it
under `nice -n 10` (minutes of CPU).

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


def etched_cells() -> None:
    """accelerometer_xyz with its field2d combs and etch declared, and rebuilt at the suite's etches
    (tests/model/test_process_etch_field2d.py): the etched finger cells' tables (netgen.model.etch_combs)."""
    from support import process_cases

    from netgen.build import build_model
    from netgen.structure import parse_structure

    def field2d(text: str) -> str:
        return text.replace('comb_model = "textbook"', 'comb_model = "field2d"')

    build_model(
        parse_structure(field2d(process_cases.xyz_text(process='[process]\nparameters = ["etch"]\n')), "x.toml")
    )
    for etch in process_cases.PERFORATED_ETCHES:
        build_model(parse_structure(field2d(process_cases.xyz_text(etch)), "x.toml"))


def thick_cells() -> None:
    """accelerometer_xyz with its field2d combs and tscale declared (the fingers at the law's five
    thicknesses, netgen.model.process.thickness_capacitance; the suite's rebuilds at 0.9 and 1.1 are
    two of them): the thicker and thinner finger cells' tables."""
    from support import process_cases

    from netgen.build import build_model
    from netgen.structure import parse_structure

    text = process_cases.xyz_thick(process='[process]\nparameters = ["tscale"]\n')
    build_model(parse_structure(text.replace('comb_model = "textbook"', 'comb_model = "field2d"'), "x.toml"))


def cross_cells() -> None:
    """accelerometer_xyz with its field2d combs and tscale and etch declared (the cross factor's fit at
    the (tscale, etch) box's corners, netgen.model.process.cross_capacitance) and rebuilt at the points
    tests/model/test_process_cross_field2d.py and bench/process_cross.py read inside the box: the
    finger cells both thinner or thicker and etched."""
    from support import process_cases

    from netgen.build import build_model
    from netgen.structure import parse_structure

    def text(tscale: float = 1.0, etch: float = 0.0, process: str = "") -> str:
        body = process_cases.xyz_text(etch, process).replace('comb_model = "textbook"', 'comb_model = "field2d"')
        return body.replace('thickness = "2 um"', f'thickness = "{2.0 * tscale!r} um"')

    build_model(parse_structure(text(process='[process]\nparameters = ["tscale", "etch"]\n'), "x.toml"))
    for tscale, etch in ((0.9, -1e-7), (0.95, 0.04e-6), (1.05, -0.05e-6)):
        build_model(parse_structure(text(tscale, etch), "x.toml"))


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
        if not a.examples:
            t0 = time.process_time()
            etched_cells()
            print(f"accelerometer_xyz's etched cells: {time.process_time() - t0:.1f} s CPU")
            t0 = time.process_time()
            thick_cells()
            print(f"accelerometer_xyz's cells at the tscale law's thicknesses: {time.process_time() - t0:.1f} s CPU")
            t0 = time.process_time()
            cross_cells()
            print(f"accelerometer_xyz's cells both scaled and etched: {time.process_time() - t0:.1f} s CPU")
        target = ROOT / "netgen" / "electrostatics" / "comb_tables"
        target.mkdir(exist_ok=True)
        for table in sorted((Path(cache) / "comb_sections").glob("*.npz")):
            shutil.copy(table, target / table.name)
            print(f"shipped {table.name}")


if __name__ == "__main__":
    main()
