"""Generated bad command lines for every subcommand: one argument wrong at a time, the others
valid. Each must be refused before any work with exit 2, one message that names the argument
(or the file) and says what to do, and no traceback.

    .venv/bin/python bench/cli_arguments.py [-v]

Prints one row per subcommand: tried / tracebacks / accepted (exit 0) / wrong exit code /
messages without the argument or a fix. Runs in one process (cli.main), a few seconds.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import re
import sys
import tempfile
from pathlib import Path

from support import ROOT

from netgen.cli import commands as cli

NUMBERS = ["0", "-1", "-0", "nan", "inf", "-inf", "1e400", "1e-400", "abc", "", " ", "1,5", "0x10"]
INTEGERS = ["0", "-5", "1.5", "1e3", "abc", "", str(1 << 40), "10"]
FIX = re.compile(r"fix:|--help|e\.g\.|give |choose |check |must |use |drop |keep |between |at least|is not|not a", re.I)


def bad_paths(work: Path) -> dict[str, list[str]]:
    """Bad output folders and bad input files, made in `work`."""
    a_file = work / "a_file.txt"
    a_file.write_text("x\n")
    binary = work / "binary.cir"
    binary.write_bytes(bytes(range(256)))
    (work / "a_dir").mkdir()
    return {
        "output": [
            "",
            " ",
            str(a_file),
            str(a_file / "sub"),
            "/proc/netgen-x",
            "/sys/netgen-x",
            "/dev/null",
            "/proc/self/fd",
        ],
        "input": [str(work / "missing.toml"), str(work / "a_dir"), "", str(binary)],
    }


def cases(work: Path) -> list[tuple[str, list[str], str]]:
    """(subcommand, argv, the argument it gets wrong) for every generated case."""
    paths = bad_paths(work)
    out = str(work / "out")
    piston, disk = str(ROOT / "examples/piston.toml"), str(ROOT / "examples/levitated_disk.toml")
    model, sweep = str(ROOT / "netlists/levitated_disk.json"), str(ROOT / "examples/sweep_ts.toml")
    netlist = work / "ok.cir"
    netlist.write_text("* ok\nV1 a 0 1\nR1 a 0 1k\n.op\n.end\n")
    found: list[tuple[str, list[str], str]] = []
    build = ["build", piston, "-q", "--no-plots"]
    found += [("build", build + ["-o", p], "-o") for p in paths["output"]]
    found += [("build", ["build", p, "-o", out, "-q"], "structure") for p in paths["input"]]
    found += [("build", build + ["-o", out, "--sample-store", p], "--sample-store") for p in paths["output"]]
    found += [
        ("build", build + ["-o", out, "--scheduler", s], "--scheduler")
        for s in ("processes:0", "processes:-2", "processes:x", "nowhere", "local:0", "")
    ]
    found += [("build", build + ["-o", out, "--format", f], "--format") for f in ("spice3", "", "ALL")]
    sim = ["simulate", str(netlist)]
    found += [("simulate", sim + ["-o", p], "-o") for p in paths["output"]]
    found += [("simulate", ["simulate", p, "-o", out], "netlist") for p in paths["input"]]
    found += [("simulate", sim + ["-o", out, "--timeout", v], "--timeout") for v in NUMBERS]
    found += [("simulate", sim + ["-o", out, "--simulator", s], "--simulator") for s in ("spice3", "")]
    sd = ["sigma-delta", disk, "--model", model, "-q", "--no-plots"]
    found += [("sigma-delta", sd + ["-o", p], "-o") for p in paths["output"]]
    for option, values in (
        ("--ts", NUMBERS),
        ("--cycles", INTEGERS),
        ("--segment", INTEGERS[1:]),
        ("--lead", ["nan", "inf", "abc", "", "100"]),
        ("--dither", ["nan", "-0.5", "2", "x"]),
        ("--reltol", ["0", "nan", "1", "x"]),
        ("--timeout", NUMBERS),
        ("--tone", ["z", "z:1", "z:x:5", "z:1:-5", "z:nan:5", "q:1:5", "z:1:1e9", ""]),
        ("--pressure", ["0", "-1", "nan", "inf", "1 furlong", ""]),
        ("--simulator", ["spice3"]),
        ("--film", ["gas"]),
    ):
        found += [("sigma-delta", sd + ["-o", out, option, v], option) for v in values]
    found += [("sigma-delta", ["sigma-delta", disk, "-o", out, "--model", p, "-q"], "--model") for p in paths["input"]]
    found += [("sweep", ["sweep", disk, sweep, "-o", p, "-q"], "-o") for p in paths["output"]]
    found += [
        ("sweep", ["sweep", disk, sweep, "-o", out, "-q", "--scheduler", s], "--scheduler")
        for s in ("processes:0", "nowhere")
    ]
    found += [
        ("codemodel", ["codemodel", "--no-such-option"], "--no-such-option"),
        ("codemodel", ["codemodel", "extra"], "extra"),
    ]
    return found


def attempt(argv: list[str]) -> tuple[int, str]:
    """cli.main on argv in this process: (exit code, stderr)."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = cli.main(argv)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
    return code, err.getvalue()


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("-v", "--verbose", action="store_true", help="every case's message")
    args = p.parse_args()
    rows: dict[str, dict[str, int]] = {}
    with tempfile.TemporaryDirectory(prefix="netgen-cli-args-") as tmp:
        os.chdir(tmp)
        for command, argv, what in cases(Path(tmp)):
            code, err = attempt(argv)
            last = err.strip().splitlines()[-1] if err.strip() else ""
            named = what.lstrip("-") in err or any(a in err for a in argv[1:2]) or "argument" in err or "--help" in err
            bad = {
                "traceback": "Traceback" in err,
                "accepted": code == 0,
                "wrong_exit": code not in (0, 2),
                "no_fix": code != 0 and not (named and FIX.search(err)),
            }
            row = rows.setdefault(command, {"tried": 0} | {k: 0 for k in bad})
            row["tried"] += 1
            for k, v in bad.items():
                row[k] += int(v)
            if args.verbose or any(bad.values()):
                print(f"  {command} {what} {argv[-1]!r}: exit {code}: {last[:160]}", file=sys.stderr)
    print(f"{'command':<12} {'tried':>5} {'tracebacks':>10} {'accepted':>8} {'wrong exit':>10} {'no fix':>6}")
    for command, row in rows.items():
        print(
            f"{command:<12} {row['tried']:>5} {row['traceback']:>10} {row['accepted']:>8} {row['wrong_exit']:>10} "
            f"{row['no_fix']:>6}"
        )
    total = {k: sum(r[k] for r in rows.values()) for k in next(iter(rows.values()))}
    print(
        f"{'all':<12} {total['tried']:>5} {total['traceback']:>10} {total['accepted']:>8} {total['wrong_exit']:>10} "
        f"{total['no_fix']:>6}"
    )


if __name__ == "__main__":
    main()
