"""The cost of a sample design before the work: the number of extractor samples of the design,
the extractor's time per point (a short calibration on the structure's own extractor) and the
plate fit's time (a calibrated cost per Levenberg-Marquardt step, m p^2 for m samples and p
coefficients); a design over the `--max-minutes` budget is refused with its fix. Also the
design's entries of the model JSON's "sampling" report.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ..core.errors import StructureError
from ..electrostatics.sampling import CORNER_CHECKS, box_factors, design_points
from ..structure import Structure
from ..structure.schema import smolyak_count
from .capacitance import MAX_NFEV, PATCH_GRIDS, SETTLE_WORK

EXPECTED_TRIALS = 5  # patch grids an electrode that meets fit.tolerance tries (1, 2, 4, 6, 9 plates)
CALIBRATION_POINTS = 32  # extractor points timed (fewer when one point takes over 0.5 s)


@dataclass(frozen=True)
class Estimate:
    """Expected work of a build's sampling and fit stages."""

    design: str
    samples: int  # design points (adaptive: its budget)
    checks: int  # held-out points (+ the adaptive design's probe points)
    per_point_s: float  # extractor time per point (calibrated)
    extractor_s: float
    fit_s: float
    fit_max_s: float  # every patch grid tried (the fits that miss fit.tolerance try them all)

    @property
    def minutes(self) -> float:
        """The expected minutes (the budget check; fit_max_s is printed beside it)."""
        return (self.extractor_s + self.fit_s) / 60.0

    def text(self) -> str:
        """One line for the build's progress output."""
        return (
            f"{self.design} design: {self.samples} samples + {self.checks} check points; estimated "
            f"extractor {self.extractor_s:.1f} s ({self.per_point_s * 1e3:.2f} ms/point), fit {self.fit_s:.1f} s "
            f"(up to {self.fit_max_s:.1f} s when fits miss fit.tolerance)"
        )


def sample_count(s: Structure, ncoords: int) -> int:
    """Design points of the structure's [sampling] without building them (adaptive: the budget)."""
    o = s.sampling
    if o.design == "grid":
        return o.levels**ncoords
    if o.design == "sparse":
        return smolyak_count(ncoords, o.level)
    return o.points


def extractor_time(prepared, s: Structure, scales: np.ndarray) -> float:
    """Seconds per point of the structure's extractor, timed on the first design points."""
    x = (
        design_points(s.sampling, len(scales))[:CALIBRATION_POINTS]
        if s.sampling.design != "grid"
        else np.random.default_rng(0).uniform(-s.sampling.range, s.sampling.range, (CALIBRATION_POINTS, len(scales)))
        * box_factors(s.sampling, len(scales))
    )
    t0 = time.perf_counter()
    prepared.capacitance(x[:1] * scales)
    one = time.perf_counter() - t0
    if one > 0.5 or len(x) == 1:
        return one
    t0 = time.perf_counter()
    prepared.capacitance(x[1:] * scales)
    return (time.perf_counter() - t0) / (len(x) - 1)


def lm_step_time() -> float:
    """Seconds per (sample x coefficient^2) of one Levenberg-Marquardt step (MINPACK's QR),
    timed on a random problem of 2000 samples and 48 coefficients."""
    rng = np.random.default_rng(0)
    a = rng.standard_normal((2000, 48))
    y = rng.standard_normal(2000)
    t0 = time.perf_counter()
    least_squares(lambda v: a @ v - y, np.zeros(48), jac=lambda v: a, method="lm", max_nfev=4)
    return (time.perf_counter() - t0) / (5 * 2000 * 48**2)


def fit_time(
    s: Structure, samples: int, ncoords: int, electrodes: int, step: float, trials: int = EXPECTED_TRIALS
) -> float:
    """Expected plate-fit seconds: per electrode `trials` patch grids (as many as the samples
    determine and max_terms allows), MAX_NFEV steps of samples x coefficients^2 each, or up to
    SETTLE_WORK where that is more (netgen.fit.capacitance.settled: small fits converge)."""
    nterm = math.comb(ncoords + s.fit.degree, s.fit.degree)
    if s.fit.target != "plates":
        return electrodes * samples * nterm**2 * step
    plates = [a * b for a, b in PATCH_GRIDS if a * b <= s.fit.max_terms and a * b * nterm <= samples]
    per = sum(max(samples * (k * nterm) ** 2 * MAX_NFEV, SETTLE_WORK) * step for k in plates[:trials])
    if s.sampling.design == "adaptive":
        rounds = max(1, (samples - 18 * (ncoords + 1)) // (3 * (ncoords + 1)))
        per *= 1 + 2 * rounds / EXPECTED_TRIALS / 2  # about two trials per round at the mean size
    return electrodes * per


def estimate(s: Structure, prepared, scales: np.ndarray, electrodes: int) -> Estimate:
    """The expected sampling and fit time of the structure's design."""
    n = len(scales)
    samples = sample_count(s, n)
    checks = s.fit.holdout + (samples + 3 * max(s.fit.holdout, 6 * (n + 1)) if s.sampling.design == "adaptive" else 0)
    checks += 1 << n if n <= CORNER_CHECKS else 0  # the box's corners (netgen.electrostatics.sampling.sample_corners)
    per_point, step = extractor_time(prepared, s, scales), lm_step_time()
    return Estimate(
        s.sampling.design,
        samples,
        checks,
        per_point,
        per_point * (samples + checks),
        fit_time(s, samples, n, electrodes, step),
        fit_time(s, samples, n, electrodes, step, len(PATCH_GRIDS)),
    )


def check(s: Structure, est: Estimate, max_minutes: float) -> None:
    """Refuse a design whose estimate exceeds the budget, naming the cheaper designs."""
    if est.minutes <= max_minutes:
        return
    raise StructureError(
        s.source,
        "[sampling] design",
        f"the {est.design} design's estimated cost is {est.minutes:.1f} min ({est.text()}), "
        f"over --max-minutes {max_minutes:g}",
        'set design = "sparse" (level = 2) or "adaptive" in [sampling], use fewer modes, or raise --max-minutes',
    )


def design_report(s: Structure, extra: dict) -> dict:
    """The design's entries of the model JSON's "sampling" (none for the grid: its JSON unchanged)."""
    o = s.sampling
    if o.design == "grid":
        return {}
    keys = {
        "sparse": {"level": o.level},
        "lhs": {"points": o.points, "design_seed": o.seed},
        "sobol": {"points": o.points, "design_seed": o.seed},
        "adaptive": {"budget": o.points, "design_seed": o.seed},
    }[o.design]
    return {"design": o.design} | keys | extra
