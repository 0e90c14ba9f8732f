"""Scan the Verilog-A of every structure example (built with `netgen build --format veriloga`),
the committed netlists/levitated_disk.va and the loop blocks (blocks.va) for the product
openvaf-r miscompiles, c*(a + b*t) with c*a = c*b = 1 (tests/oracles/va_scan.py; the emitter folds it,
netgen.emit.veriloga.misfolds). Exit 1 if any is found.

    nice -n 10 .venv/bin/python bench/va_fault_scan.py [--keep DIR]

Measured (8 examples, 43 s on 2 busy cores): 0 faulty products in 1031 analog statements of the
ten files.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

from support import ROOT, va_scan

from netgen.cli import commands as cli


def structure_examples() -> list[Path]:
    """The examples that are structures (a sweep file is not)."""
    return [p for p in sorted((ROOT / "examples").glob("*.toml")) if "[conductor]" in p.read_text(encoding="utf-8")]


def main() -> int:
    """Build, scan, print one line a file; 1 if any faulty product."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--keep", type=Path, help="build into this folder (default: a temp folder)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="va-scan-") as tmp:
        out = args.keep or Path(tmp)
        files = [ROOT / "netlists" / "levitated_disk.va", ROOT / "netgen" / "testbench" / "sigma_delta" / "blocks.va"]
        for example in structure_examples():
            if cli.main(["build", str(example), "-o", str(out / example.stem), "--format", "veriloga", "-q"]) != 0:
                print(f"{example.name}: build failed")
                return 1
            files += sorted((out / example.stem).glob("*.va"))
        total, found = 0, 0
        for va in files:
            text = va.read_text(encoding="utf-8")
            rows, n = va_scan.scan(text), len(va_scan.statements(text))
            total, found = total + n, found + len(rows)
            print(
                f"{va.relative_to(out) if va.is_relative_to(out) else va.relative_to(ROOT)}: {n} statements, "
                f"{len(rows)} faulty products" + "".join(f"\n  {r.module}: {r.statement}" for r in rows)
            )
        print(f"{found} faulty products in {total} analog statements of {len(files)} files")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
