"""The adaptive sample design ([sampling] design = "adaptive"): fit, look for the largest error
on probe points the fit has not seen, move the worst of them into the training set, refit, until
every electrode's probe error meets fit.tolerance or the budget of `points` training samples is
spent. The probes are the continuation of a seeded Sobol sequence, so the same structure gives the
same design; the reported errors stay those on the structure's own held-out points.

The probe pool is what the patch counts and the points are chosen on, so its error is optimistic:
before the design stops it checks a fresh pool of the same size, which no choice has seen, and
only stops when that pool meets the bound too (else the fresh pool joins the probes, and it goes on).
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np

from ..electrostatics import designs
from ..electrostatics.sampling import Samples, box_factors
from ..geometry.shapes import Electrode
from ..structure import Structure
from .capacitance import (
    PATCH_GRIDS,
    CapacitanceFit,
    FitData,
    check_determined,
    fit_electrode,
    refuse_unphysical,
    with_errors,
)

STALL = 4  # rounds without progress before the design stops short of its budget
OVERSAMPLE = 2.0  # at least two samples per fitted coefficient: fewer would let a plate sum interpolate
SAFETY = 0.5  # stop when every probe error is below half fit.tolerance: a max over a few hundred
# random points is itself uncertain, and the held-out points are other points
VALIDATIONS = 4  # fresh pools the design may draw to confirm a stop (each failed one joins the probes)


@dataclass
class AdaptiveResult:
    """The grown training set, the final fits and the history of each round."""

    samples: Samples
    fits: list[CapacitanceFit]
    probes: int  # extractor calls spent on probe points
    rounds: list[dict] = field(default_factory=list)
    converged: bool = False


class ProbeStream:
    """Seeded Sobol points (a different seed from the design's start) handed out in order."""

    def __init__(self, ncoords: int, half_range: float, seed: int, total: int, factors: np.ndarray | None = None):
        count = 1 << max(0, total - 1).bit_length()
        self.points = designs.sobol(ncoords, count, half_range, seed + 7919)
        if factors is not None:  # per-coordinate ranges (netgen.electrostatics.sampling.box_factors)
            self.points = self.points * factors
        self.next = 0

    def take(self, k: int) -> np.ndarray:
        out = self.points[self.next : self.next + k]
        self.next += len(out)
        return out


def adaptive_fits(
    s: Structure,
    shapes: list[Electrode],
    basis,
    scales: np.ndarray,
    start: Samples,
    evaluate: Callable[[np.ndarray], Samples],
    holdout: Samples,
    progress: bool = False,
) -> AdaptiveResult:
    """Grow `start` by the probe points of largest relative error (over all electrodes, in units
    of fit.tolerance) until every probe error is below SAFETY x fit.tolerance or len(train) reaches
    [sampling] points. Each electrode keeps the fit of the last round that refitted it (errors on
    the held-out points at the end). `evaluate(x)` samples the extractor at scaled points x."""
    n, tol, budget = len(scales), s.fit.tolerance, s.sampling.points
    check_determined(s, start.x)
    batch, pool_size = 3 * (n + 1), 2 * max(s.fit.holdout, 6 * (n + 1))  # probes: twice the held-out points
    stream = ProbeStream(
        n, s.sampling.range, s.sampling.seed, budget + (2 + 2 * VALIDATIONS) * pool_size, box_factors(s.sampling, n)
    )
    train, probes = start, evaluate(stream.take(pool_size))
    spent, validations, since = design_size(probes), 0, 0
    fits, used = fit_round(s, shapes, basis, scales, train, probes, Round(range(len(shapes)), [0] * len(shapes)))
    result = AdaptiveResult(train, fits, spent)
    while True:
        err = errors(fits, probes)
        worst = err.max(axis=0)
        result.rounds.append(
            {"samples": len(train.x), "probe_max_rel_error": float(worst.max()), "failing": int(np.sum(worst > tol))}
        )
        say(
            progress,
            f"adaptive: {len(train.x)} samples, probe max error {worst.max():.2e} "
            f"({int(np.sum(worst > tol))} electrode(s) above {tol:g})",
        )
        if worst.max() <= SAFETY * tol and validations < VALIDATIONS and len(stream.points) - stream.next >= pool_size:
            fresh = evaluate(stream.take(pool_size))  # points no patch or point choice has seen
            spent, validations = spent + design_size(fresh), validations + 1
            fresh_worst = errors(fits, fresh).max(axis=0)
            result.rounds[-1]["validation_max_rel_error"] = float(fresh_worst.max())
            say(progress, f"adaptive: fresh validation pool max error {fresh_worst.max():.2e}")
            probes = probes + Samples(fresh.x, fresh.c, 0, fresh.x)
            if fresh_worst.max() > SAFETY * tol:
                err, worst = errors(fits, probes), np.maximum(worst, fresh_worst)
                since = len(result.rounds)  # progress is judged on the larger pool from here
            else:
                result.converged = True
                break
        if (
            worst.max() <= SAFETY * tol
            or design_size(train) >= budget
            or stream.next >= len(stream.points)
            or (stalled(result.rounds[since:]) and form_limited(s, worst, used))
        ):
            result.converged = bool(worst.max() <= SAFETY * tol) and not validations  # unconfirmed else
            break
        score = (err / (SAFETY * tol)).max(axis=1)
        pick = np.argsort(-score, kind="stable")[: min(batch, budget - design_size(train))]
        pick = pick[score[pick] > 1.0]
        keep = np.setdiff1d(np.arange(len(probes.x)), pick)
        train = train + Samples(probes.x[pick], probes.c[pick], 0, probes.x[pick])
        fresh = evaluate(stream.take(len(pick)))
        spent += design_size(fresh)
        probes = Samples(probes.x[keep], probes.c[keep], 0, probes.x[keep]) + fresh
        failing = [i for i in range(len(shapes)) if worst[i] > SAFETY * tol]
        fits, used = fit_round(s, shapes, basis, scales, train, probes, Round(failing, used, fits))
    final = [with_errors(f, train.x, train.c[:, i], holdout.x, holdout.c[:, i]) for i, f in enumerate(fits)]
    refuse_unphysical(s, final, train.x, holdout.x)
    result.samples, result.fits, result.probes = train, final, spent
    return result


def errors(fits: list[CapacitanceFit], points: Samples) -> np.ndarray:
    """Relative error of every fit at every point, shape (npoints, nelectrodes)."""
    return np.abs(np.stack([f.value(points.x) for f in fits], axis=1) / points.c - 1.0)


def form_limited(s: Structure, worst: np.ndarray, used: list[int]) -> bool:
    """Every electrode above the bound already fits with the most plates fit.max_terms allows: more
    points cannot help it (below that, more points unlock the next patch grid, OVERSAMPLE per term)."""
    top = max(k for k, (a, b) in enumerate(PATCH_GRIDS) if a * b <= s.fit.max_terms or k == 0)
    return all(used[i] >= top for i in np.flatnonzero(worst > SAFETY * s.fit.tolerance))


def stalled(rounds: list[dict]) -> bool:
    """No round of the last STALL improved the worst probe error by 10 %: more points of the same
    kind will not help (the fit form or fit.max_terms limits it, and the warning says so)."""
    if len(rounds) <= STALL:
        return False
    best_before = min(r["probe_max_rel_error"] for r in rounds[:-STALL])
    return min(r["probe_max_rel_error"] for r in rounds[-STALL:]) > 0.9 * best_before


@dataclass(frozen=True)
class Round:
    """One refit round: the electrodes to refit (`which`), each electrode's patch grid so far
    (`used`) and the last round's fits (`previous`; None: the first round)."""

    which: Iterable[int]
    used: list[int]
    previous: list[CapacitanceFit] | None = None


def fit_round(
    s: Structure,
    shapes: list[Electrode],
    basis,
    scales: np.ndarray,
    train: Samples,
    check: Samples,
    r: Round,
) -> tuple[list[CapacitanceFit], list[int]]:
    """Refit the electrodes r.which on `train` (their patch count starting where the last round
    ended, r.used: a warm start), keep the others (r.previous); errors against `check`."""
    which, previous = r.which, r.previous
    fits: list[CapacitanceFit | None] = list(previous) if previous else [None] * len(shapes)
    used = list(r.used)
    for i in which:
        fit, used[i] = fit_electrode(s, shapes[i], basis, scales, FitData.of(train, check, i), used[i], OVERSAMPLE)
        fits[i] = with_errors(fit, train.x, train.c[:, i], check.x, check.c[:, i])
    done = [f for f in fits if f is not None]
    assert len(done) == len(fits)  # the first round (no previous fits) refits every electrode
    return done, used


def design_size(samples: Samples) -> int:
    """Every design point of `samples`, touching ones included (the point budget counts them)."""
    assert samples.points is not None  # sample_points and the rounds below keep every design point
    return len(samples.points)


def say(progress: bool, text: str) -> None:
    """A progress line on stderr."""
    if progress:
        print(text, file=sys.stderr)
