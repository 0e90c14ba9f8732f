"""Interrupted and concurrent `netgen build` / `netgen sigma-delta` runs into a folder that holds an
earlier run's complete results: after each, is the folder the complete old set or the complete
new set, with nothing half-written, nothing left over and no traceback?

    .venv/bin/python bench/interrupts.py [--signals 30] [--pairs 10] [--commands build,sigma-delta]

Per command: `--signals` SIGTERM and as many SIGINT interrupts at uniformly random times over an
uninterrupted run's wall time (start-up and imports included), and `--pairs` pairs of runs into
one folder at once (the old and the new variant, started together). Prints one table row per
command and kind: tried / mixed / stale / partial files / tracebacks / other exit codes.

- mixed: files of both runs in the folder (a new file beside an old one), or files whose bytes
  are not those the manifest names;
- stale: one run's files only, but not its complete set as its manifest names it (a file
  missing, no manifest: results that cannot be told current);
- partial files: temp or staging files left, or a file that belongs to neither run;
- tracebacks: a Python traceback on stderr;
- other exit: an exit code that is neither 0 (finished) nor 130 (interrupted);
- before netgen: the signal came while the interpreter itself was starting, before netgen's
  first line (Python's default action: killed, or for SIGINT its own traceback from site.py);
  counted apart, not as tracebacks or exit codes (netgen cannot act before it runs).

The build variants are the piston example and the same with a 2.5 um gap (so every file differs),
written with --format all and --format ngspice --no-plots (so the sets have different files
too). The sigma-delta variants are 64 periods without plots and 128 with (the reference model
from netlists/, the compiled loop); their files are told apart by content (the cycles in
summary.json, bitstreams.npz and the manifest) and checked against the manifest's SHA-256s.
"""

from __future__ import annotations

import argparse
import hashlib
import io
import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from support import ROOT

NETGEN = [str(ROOT / ".venv/bin/netgen")]
USER_FILE = "my_notes.txt"  # a user's own file in the output folder: never touched


# ----------------------------------------------------------------------------- the two commands


def build_variants(work: Path) -> tuple[list[str], list[str]]:
    """The old and the new `netgen build` command lines (output folder appended by the caller)."""
    text = (ROOT / "examples/piston.toml").read_text(encoding="utf-8")
    other = work / "piston_wide_gap.toml"
    other.write_text(text.replace('gap = "2 um"', 'gap = "2.5 um"'), encoding="utf-8")
    old = ["build", str(ROOT / "examples/piston.toml"), "--format", "all", "-q"]
    new = ["build", str(other), "--format", "ngspice", "--no-plots", "-q"]
    return old, new


def sigma_delta_variants(work: Path) -> tuple[list[str], list[str]]:
    """The old and the new `netgen sigma-delta` command lines (short runs of the compiled loop)."""
    base = [
        "sigma-delta",
        str(ROOT / "examples/levitated_disk.toml"),
        "--model",
        str(ROOT / "netlists/levitated_disk.json"),
        "--simulator",
        "ngspice-xspice",
        "-q",
    ]
    return base + ["--cycles", "64", "--no-plots"], base + ["--cycles", "128"]


COMMANDS = {"build": build_variants, "sigma-delta": sigma_delta_variants}
SET_NAME = {"build": "piston", "sigma-delta": "sigma-delta"}
# what a sigma-delta run keeps beside its set: caches and a failed run's files (not results)
NOT_RESULTS = {"osdi", "sigma-delta.failed"}


def run(argv: list[str], out: Path, timeout: float = 600) -> subprocess.CompletedProcess:
    """One netgen run into `out`, to the end."""
    return subprocess.run(NETGEN + argv + ["-o", str(out)], capture_output=True, text=True, timeout=timeout)


# ----------------------------------------------------------------------------- what a folder holds


def files(folder: Path) -> dict[str, bytes]:
    """Every regular file at the top of `folder` (not the user's) by name."""
    return {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file() and p.name != USER_FILE}


def leftovers(folder: Path) -> list[str]:
    """Temp, staging and probe files anywhere under `folder`."""
    return sorted(
        str(p.relative_to(folder))
        for p in folder.rglob("*")
        if p.name.startswith(".") or p.name.endswith(".tmp") or ".tmp." in p.name
    )


def identity(command: str, name: str, data: bytes, refs: dict[str, dict[str, bytes]]) -> str | None:
    """Which run ("old", "new"; "both" if it cannot tell) a file belongs to; None if neither. A
    build's files are byte-identical run to run; a sigma-delta run's are told by the periods they
    hold (the PNGs: only the new run plots)."""
    if command == "build":
        hits = [k for k, ref in refs.items() if ref.get(name) == data]
        return hits[0] if len(hits) == 1 else ("both" if hits else None)
    cycles = {64: "old", 128: "new"}
    try:
        if name.endswith(".png"):
            return "new" if name in refs["new"] else None
        if name == "summary.json":
            return cycles.get(json.loads(data)["requested_cycles"])
        if name == "bitstreams.npz":
            return cycles.get(len(np.load(io.BytesIO(data))["time"]))
        if name == "sigma-delta.manifest.json":
            return cycles.get(json.loads(data)["arguments"]["cycles"])
    except (ValueError, KeyError, OSError):
        return None
    return "both" if name in refs["old"] or name in refs["new"] else None  # the manifest's SHA-256 decides


def classify(command: str, folder: Path, refs: dict[str, dict[str, bytes]], user: bytes) -> dict[str, bool]:
    """mixed / stale / partial of one folder after a run (see the module docstring)."""
    have = files(folder)
    owners = {n: identity(command, n, d, refs) for n, d in have.items()}
    partial = bool(leftovers(folder)) or None in owners.values() or (folder / USER_FILE).read_bytes() != user
    kinds = {o for o in owners.values() if o in ("old", "new")}
    manifest = folder / f"{SET_NAME[command]}.manifest.json"
    try:
        named = json.loads(manifest.read_text())["files"]
    except (OSError, ValueError, KeyError):
        named = {}
    wrong = [n for n, h in named.items() if n in have and hashlib.sha256(have[n]).hexdigest() != h]
    agrees = bool(named) and not wrong and all(n in have for n in named)
    mixed = len(kinds) > 1 or bool(wrong)
    complete = (
        any(set(have) == set(ref) for ref in refs.values()) and agrees and set(named) | {manifest.name} == set(have)
    )
    stale = not mixed and not partial and not complete
    return {"mixed": mixed, "stale": stale, "partial": partial}


def references(command: str, work: Path) -> tuple[list[str], list[str], dict[str, dict[str, bytes]]]:
    """Both variants run to the end once, into folders of their own: their complete sets."""
    old, new = COMMANDS[command](work)
    refs = {}
    for key, argv in (("old", old), ("new", new)):
        out = work / f"reference_{key}"
        done = run(argv, out)
        if done.returncode != 0:
            raise SystemExit(f"{command} {key} reference run failed:\n{done.stderr[-2000:]}")
        refs[key] = files(out)
    return old, new, refs


def prepared(work: Path, refs: dict[str, dict[str, bytes]], k: int) -> tuple[Path, bytes]:
    """A folder holding the old run's complete set (a copy of its reference run's files) and a
    user's file; (folder, that file's bytes)."""
    out = work / f"try{k}"
    out.mkdir()
    for name, data in refs["old"].items():
        (out / name).write_bytes(data)
    user = f"my own notes {k}\n".encode()
    (out / USER_FILE).write_bytes(user)
    return out, user


# ----------------------------------------------------------------------------- the experiments


def interrupted(command: str, work: Path, old, new, refs, sig: signal.Signals, delay: float, k: int) -> dict:
    """The new run into the old run's folder, stopped by `sig` after `delay` s."""
    out, user = prepared(work, refs, k)
    proc = subprocess.Popen(NETGEN + new + ["-o", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(delay)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=600)
    return outcome(command, out, refs, user, [(proc.returncode, err)])


def concurrent(command: str, work: Path, old, new, refs, k: int) -> dict:
    """The old and the new run into one folder (holding the old set) at the same time."""
    out, user = prepared(work, refs, k)
    procs = [
        subprocess.Popen(NETGEN + argv + ["-o", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for argv in (new, old)
    ]
    done = [(p.wait(timeout=600), p.communicate()[1]) for p in procs]
    return outcome(command, out, refs, user, done)


def before_netgen(rc: int, err: str) -> bool:
    """Did the signal stop the interpreter before netgen's first line ran (Python's own start-up:
    killed by the signal's default action, or a KeyboardInterrupt in site.py or the script's
    import line)? Then no netgen code could act, and nothing was written."""
    frames = [ln for ln in err.splitlines() if ln.strip().startswith('File "')]
    own = [f for f in frames if "/netgen/" in f and "/bin/netgen" not in f]
    return (
        (rc in (-signal.SIGINT, -signal.SIGTERM) and not err.strip())
        or "Fatal Python error" in err
        or ("Traceback" in err and not own)
    )


def outcome(command: str, out: Path, refs, user: bytes, runs: list[tuple[int, str]]) -> dict:
    """The folder's classification, plus tracebacks and unexpected exit codes of the runs."""
    result = classify(command, out, refs, user)
    early = [before_netgen(rc, err) for rc, err in runs]
    result["startup"] = any(early)
    result["traceback"] = any("Traceback" in err for (_, err), e in zip(runs, early) if not e)
    result["other_exit"] = any(rc not in (0, 130) for (rc, _), e in zip(runs, early) if not e)
    result["detail"] = [
        f"rc {rc}: " + (err.strip() if "Traceback" in err else " ".join(err.strip().splitlines()[-1:]))
        for rc, err in runs
    ]
    return result


def wall_time(command: str, work: Path, new: list[str], refs: dict[str, dict[str, bytes]]) -> float:
    """Wall time of an uninterrupted new run into an old folder (the span the interrupts cover);
    the folder it leaves must be the complete new set."""
    out, user = prepared(work, refs, 0)
    start = time.perf_counter()
    done = run(new, out)
    wall = time.perf_counter() - start
    assert done.returncode == 0, done.stderr[-2000:]
    assert classify(command, out, refs, user) == {"mixed": False, "stale": False, "partial": False}
    return wall


def selfcheck(command: str, work: Path, refs: dict[str, dict[str, bytes]]) -> None:
    """The classifier on folders made to be wrong: it must see each fault (else it cannot fail)."""

    def folder(name: str, content: dict[str, bytes]) -> Path:
        out = work / f"check_{name}"
        out.mkdir()
        for f, data in content.items():
            (out / f).write_bytes(data)
        (out / USER_FILE).write_bytes(b"mine\n")
        return out

    old, new = refs["old"], refs["new"]
    manifest = f"{SET_NAME[command]}.manifest.json"
    shared = sorted(set(old) & set(new) - {manifest})
    base, other = (new, old) if set(old) - set(new) else (old, new)
    extra = sorted(set(other) - set(base))[0]  # a file only one of the runs writes
    cases = {
        "old": (dict(old), set()),
        "new": (dict(new), set()),
        "mixed": (dict(new) | {shared[0]: old[shared[0]]}, {"mixed"}),
        "beside": (dict(base) | {extra: other[extra]}, {"mixed"}),
        "partial": (dict(new) | {f".{shared[0]}.x.tmp": b"half"}, {"partial"}),
        "no_manifest": ({k: v for k, v in new.items() if k != manifest}, {"stale"}),
        "incomplete": ({k: v for k, v in new.items() if k != shared[-1]}, {"stale"}),
    }
    for name, (content, faults) in cases.items():
        got = {k for k, v in classify(command, folder(name, content), refs, b"mine\n").items() if v}
        assert got == faults, f"classifier self-check {command} {name}: {got} != {faults}"


def measure(command: str, signals: int, pairs: int, seed: int = 1, verbose: bool = False) -> dict[str, dict]:
    """Rows of the table for one command: {kind: {tried, mixed, stale, partial, traceback, other_exit}}."""
    rng = random.Random(seed)
    rows: dict[str, dict] = {}
    with tempfile.TemporaryDirectory(prefix=f"netgen-interrupts-{command}-") as tmp:
        work = Path(tmp)
        old, new, refs = references(command, work)
        selfcheck(command, work, refs)
        span = wall_time(command, work, new, refs)
        k = 0
        plan = [(s.name, s) for s in (signal.SIGTERM, signal.SIGINT) for _ in range(signals)]
        for kind, sig in plan:
            k += 1
            delay = rng.uniform(0.05, span)
            r = interrupted(command, work, old, new, refs, sig, delay, k)
            add(rows, kind, r, verbose, f"{command} {kind} at {delay:.2f} s")
        for _ in range(pairs):
            k += 1
            add(rows, "concurrent pair", concurrent(command, work, old, new, refs, k), verbose, f"{command} pair")
    return rows


def add(rows: dict, kind: str, result: dict, verbose: bool, label: str) -> None:
    """Count one experiment into its row."""
    keys = ("mixed", "stale", "partial", "traceback", "other_exit", "startup")
    row = rows.setdefault(kind, {"tried": 0} | {k: 0 for k in keys})
    row["tried"] += 1
    for key in keys:
        row[key] += int(result[key])
    if verbose or any(result[key] for key in keys):
        flags = [key for key in keys if result[key]]
        print(f"  {label}: {', '.join(flags) or 'ok'} {result['detail']}", file=sys.stderr, flush=True)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--signals", type=int, default=30, help="interrupts per signal and command (default 30)")
    p.add_argument("--pairs", type=int, default=10, help="concurrent pairs per command (default 10)")
    p.add_argument("--commands", default="build,sigma-delta", help="comma-separated: build, sigma-delta")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("-v", "--verbose", action="store_true", help="one line per experiment on stderr")
    args = p.parse_args()
    print(
        f"{'command':<12} {'kind':<16} {'tried':>5} {'mixed':>5} {'stale':>5} {'partial':>7} {'tracebacks':>10} "
        f"{'other exit':>10} {'before netgen':>13}"
    )
    for command in args.commands.split(","):
        start = time.perf_counter()
        for kind, row in measure(command, args.signals, args.pairs, args.seed, args.verbose).items():
            print(
                f"{command:<12} {kind:<16} {row['tried']:>5} {row['mixed']:>5} {row['stale']:>5} "
                f"{row['partial']:>7} {row['traceback']:>10} {row['other_exit']:>10} {row['startup']:>13}",
                flush=True,
            )
        print(f"{command}: {time.perf_counter() - start:.0f} s", file=sys.stderr)


if __name__ == "__main__":
    os.environ.setdefault("PYTHONDONTWRITEBYTECODE", "1")
    main()
