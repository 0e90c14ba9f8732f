"""The capacitance fits' stated error (held-out random points) against their error at the sampled
box's corners and face centres, where a polynomial's misfit tends to peak.

    .venv/bin/python bench/fit_corners.py [STRUCTURE.toml ...]

Builds each structure (default: the examples whose build takes under 2 min), evaluates the extractor
the build sampled with (Build.prepared, the same scales) at the 2^n corners of the box and at its
2n face centres (points where the plate touches an electrode are dropped, as the build drops them),
and prints per electrode: the stated max_rel_error, the max over the held-out random points alone, the
max relative error of the fit's C against the extractor at the corners and at the face centres, and the
ratio of the worst of those to the stated one (the stated error covers the corners up to
netgen.electrostatics.sampling.CORNER_CHECKS coordinates: ratio <= 1 there unless a face centre exceeds it).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from support import ROOT

from netgen.build import build
from netgen.electrostatics.sampling import box_corners, box_factors, sample_points
from netgen.structure import load_structure

# every example structure builds in under 20 s here (levitated_disk the slowest, 13 s); sweep_ts.toml is a
# sweep file, not a structure
CHEAP = (
    "piston",
    "piston_process",
    "accelerometer_z",
    "accelerometer_xyz",
    "cantilever",
    "cantilever_fb",
    "cc_beam",
    "gyroscope_z",
    "calibrated_disk",
    "levitated_disk",
)


def face_centres(sampling, n: int) -> np.ndarray:
    """The 2n centres of the box's faces (one coordinate at +-its half-width, the others 0)."""
    half = sampling.range * box_factors(sampling, n)
    return np.concatenate([np.diag(half), -np.diag(half)])


def errors_at(b, x: np.ndarray, what: str) -> tuple[np.ndarray, int]:
    """Each fit's max relative error against the extractor at scaled points x, and how many of the
    points were dropped because the plate touches there."""
    got = sample_points(b.prepared, x, b.scales, False, what)
    err = np.array([np.max(np.abs(f.value(got.x) / got.c[:, i] - 1.0)) for i, f in enumerate(b.fits)])
    return err, got.excluded


def measure(path: Path) -> list[dict]:
    """One structure's rows: per electrode the stated error and the corner and face-centre errors."""
    t = time.perf_counter()
    b = build(load_structure(path))
    seconds = time.perf_counter() - t
    n = len(b.scales)
    corner, dropped_c = errors_at(b, box_corners(b.structure.sampling, n), "corners")
    face, dropped_f = errors_at(b, face_centres(b.structure.sampling, n), "face centres")
    held = np.abs(np.column_stack([f.value(b.holdout.x) for f in b.fits]) / b.holdout.c - 1.0).max(axis=0)
    rows = []
    for i, f in enumerate(b.fits):
        rows.append(
            {
                "example": path.stem,
                "electrode": f.electrode,
                "n": n,
                "build_s": seconds,
                "stated": f.max_rel_error,
                "random": float(held[i]),
                "corners": float(corner[i]),
                "faces": float(face[i]),
                "ratio": max(corner[i], face[i]) / f.max_rel_error if f.max_rel_error > 0 else float("inf"),
                "dropped": dropped_c + dropped_f,
            }
        )
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("structures", nargs="*", help="structure files (default: the cheap examples)")
    args = p.parse_args(argv)
    paths = [Path(a) for a in args.structures] or [ROOT / "examples" / f"{e}.toml" for e in CHEAP]
    print(
        f"{'example':16s} {'electrode':10s} {'n':>2s} {'build s':>8s} {'stated':>9s} {'random':>9s} {'corners':>9s} "
        f"{'faces':>9s} {'ratio':>6s} {'touch':>5s}"
    )
    for path in paths:
        for r in measure(path):
            print(
                f"{r['example']:16s} {r['electrode']:10s} {r['n']:2d} {r['build_s']:8.1f} {r['stated']:9.2e} {r['random']:9.2e} "
                f"{r['corners']:9.2e} {r['faces']:9.2e} {r['ratio']:6.2f} {r['dropped']:5d}",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
