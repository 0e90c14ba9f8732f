"""Build wall time with and without [process] (netgen.model.process): the piston and the
single-axis accelerometer, each built as committed and with a [process] table appended, REPEAT
times interleaved (the minimum is reported: other processes on the machine only add time).

    .venv/bin/python bench/process_build_time.py [--code DIR]

--code DIR runs another checkout's netgen (e.g. `git archive main | tar -x -C /tmp/main`) with
this venv, for the opt-out path against main's."""

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
        cmd = [sys.executable, "-c", "from netgen.runtime.entry import main; main()", "build", str(src)]
        start = time.perf_counter()
        subprocess.run([*cmd, "-o", str(Path(tmp) / "out"), "-q"], check=True, env=env, cwd=tmp)
        return time.perf_counter() - start


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--code", type=Path, help="another checkout's root to import netgen from")
    ap.add_argument("--cases", nargs="*", default=list(CASES))
    a = ap.parse_args()
    times: dict[str, list[float]] = {k: [] for k in a.cases}
    for _ in range(REPEAT):
        for k in a.cases:
            times[k].append(one_build(*CASES[k], a.code))
    for k, v in times.items():
        print(f"{k:28s} min {min(v):6.2f} s   all {' '.join(f'{x:.2f}' for x in v)}")


if __name__ == "__main__":
    main()
