"""The levitated disk with [process] in the sigma-delta loop: the reference disk's structure file
with `[process] parameters = ["dg", "tscale", "escale", "temp"]` built (about 3 min here: nine
re-runs of the plate mechanics), its .lib run for 160 cycles in 3 segments in the behavioural
loop of ngspice 46 (with KLU, as the testbench sets it) and 39, as tests/testbench/test_sigma_delta.py
runs the committed disk. The first version of the gap offsets (two shifted-state nodes per gap set)
stopped in ngspice 46 at 0.46 us with "timestep too small"; the current one (a current source into
each affine plate network) runs through.

    .venv/bin/python bench/process_sigma_delta.py [--model DIR_WITH_levitated_disk.json]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from support import ROOT, using_ngspice

from netgen.build import build_model
from netgen.emit import ngspice as emit_ngspice
from netgen.model import MacroModel
from netgen.structure import parse_structure
from netgen.testbench import sigma_delta as sd

PROCESS = '\n[process]\nparameters = ["dg", "tscale", "escale", "temp"]\n'


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", type=Path, help="a folder with a levitated_disk.json built with [process]")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        if a.model:
            model = MacroModel.load_json(a.model / "levitated_disk.json")
        else:
            start = time.perf_counter()
            text = (ROOT / "examples/levitated_disk.toml").read_text() + PROCESS
            model = build_model(parse_structure(text, str(ROOT / "examples/levitated_disk.toml")))
            print(f"build with [process]: {time.perf_counter() - start:.0f} s")
            model.save_json(folder / "levitated_disk.json")
        lib = folder / "levitated_disk.lib"
        lib.write_text(emit_ngspice.subcircuit(model))
        for release in ("46", "39"):
            out = folder / f"sd{release}"
            start = time.perf_counter()
            with using_ngspice(release):
                s = sd.run(
                    model,
                    lib,
                    out,
                    sd.RunRequest(1e-6, 160, progress=False, plots=False, skip=32, segment=64, simulator="ngspice"),
                )
            print(f"ngspice {release}: 160 cycles in 3 segments, {time.perf_counter() - start:.0f} s, vfb {s['vfb']}")


if __name__ == "__main__":
    main()
