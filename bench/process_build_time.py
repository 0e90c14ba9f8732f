"""Build wall time with and without [process] (netgen.model.process): the piston and the
single-axis accelerometer, each built as committed and with a [process] table appended, REPEAT
times interleaved (the minimum is reported: other processes on the machine only add time).

    .venv/bin/python bench/process_build_time.py [--code DIR] [--inprocess]

--code DIR runs another checkout's netgen (e.g. `git archive main | tar -x -C /tmp/main`) with
this venv, for the opt-out path against main's. --inprocess times build_model + the ngspice
emitter inside one interpreter (REPEAT x 3 builds after a warm-up), without the command's
start-up, imports and report (about 6 s of each `netgen build` here), which hide a small change."""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
REPEAT = 3
PROCESS = '\n[process]\nparameters = ["dg", "tscale", "escale", "temp"]\n'
CASES = {
    "piston": ("piston.toml", ""),
    "piston+[process]": ("piston.toml", PROCESS),
    "accelerometer_z": ("accelerometer_z.toml", ""),
    "accelerometer_z+[process]": ("accelerometer_z.toml", PROCESS),
}


def one_build(example: str, extra: str, code: Path | None) -> float:
    """Wall time of one `netgen build` (ngspice .lib only) of the example with `extra` appended."""
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / example
        src.write_text((ROOT / "examples" / example).read_text() + extra)
        env = dict(os.environ)
        if code:
            env["PYTHONPATH"] = str(code)
        cmd = [sys.executable, "-c", "from netgen.cli import main; main()", "build", str(src)]
        start = time.perf_counter()
        subprocess.run([*cmd, "-o", str(Path(tmp) / "out"), "-q"], check=True, env=env, cwd=tmp)
        return time.perf_counter() - start


INPROCESS = """
import sys, time
from pathlib import Path
from netgen.build import build_model
from netgen.emit import ngspice
from netgen.structure import parse_structure
text = Path(sys.argv[1]).read_text()
ngspice.subcircuit(build_model(parse_structure(text, "x.toml")))
times = []
for _ in range(int(sys.argv[2])):
    t0 = time.perf_counter()
    ngspice.subcircuit(build_model(parse_structure(text, "x.toml")))
    times.append(time.perf_counter() - t0)
print(min(times))
"""


def in_process(example: str, extra: str, code: Path | None) -> float:
    """The fastest of 3 in-process builds (build_model + ngspice emitter) after a warm-up one."""
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / example
        src.write_text((ROOT / "examples" / example).read_text() + extra)
        env = dict(os.environ) | ({"PYTHONPATH": str(code)} if code else {})
        out = subprocess.run(
            [sys.executable, "-c", INPROCESS, str(src), "3"],
            check=True,
            env=env,
            cwd=tmp,
            capture_output=True,
            text=True,
        )
        return float(out.stdout.split()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--code", type=Path, help="another checkout's root to import netgen from")
    ap.add_argument("--cases", nargs="*", default=list(CASES))
    ap.add_argument("--inprocess", action="store_true", help="time build_model + emit only")
    a = ap.parse_args()
    timer = in_process if a.inprocess else one_build
    times: dict[str, list[float]] = {k: [] for k in a.cases}
    for _ in range(REPEAT):
        for k in a.cases:
            times[k].append(timer(*CASES[k], a.code))
    for k, v in times.items():
        print(f"{k:28s} min {min(v):8.4f} s   all {' '.join(f'{x:.4f}' for x in v)}")


if __name__ == "__main__":
    main()
