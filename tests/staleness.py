"""Is a committed model (netlists/) still what a fresh build makes? The comparison the staleness
tests use (tests/pipeline/test_outputs.py, tests/test_netlists.py).

A build is a chain of floating-point computations, and another CPU or BLAS rounds differently.
Most numbers follow their inputs to within rounding; the plate fits' COEFFICIENTS do not: a sum of
1/P_k terms has near-null directions (more plates trade area for gap without changing C, cond(J)
1.7e4-1.1e5 at the fit, bench/fit_conditioning.py) and the capped Levenberg-Marquardt run
(netgen.fit.capacitance.MAX_NFEV) takes a rounding-dependent path, so a 1e-9 change of the samples
moves the coefficients by up to 7e-3 (bench/fit_function_change.py). Where a fit is small enough to
converge (netgen.fit.capacitance.settled) it does: the clamped-clamped beam's single capped run
stopped where its C still moved by twice its error between two 1e-12 changes of the samples. What the netlist COMPUTES
(C, dC/dq, the strain energy) is what must stay. So a rebuilt model matches a committed one when:

1. the texts with every number masked are identical (structure, names, comments' words);
2. every number that is not a fit coefficient agrees within RTOL (relative), and relative-error
   figures within 2 RTOL absolute (r = a/b - 1 from a, b each good to RTOL is good to 2 RTOL
   whatever r's size); the netlists' numbers are checked by rendering the REBUILT model with the
   COMMITTED fits (`with_fits`) and comparing that with the committed text at RTOL, so every
   non-fit number of the text is the rebuild's and every coefficient the committed one;
3. the fitted functions agree (`compare_functions`): C within FIT_SHARE of the fit's own held-out
   max relative error, dC/dxs within the same fraction of what such a change can do to a slope,
   the strain energy and its force within RTOL. The fits' error figures (max/rms/grid relative
   error) move by at most the function change and are held to the same bound.

RTOL = 1e-7: the non-fit numbers pass through sums, linear solves and symmetric eigen-solves whose
relative rounding is eps (2.2e-16) times an amplification: a dot product of n terms n eps (n <=
1e4 samples or quadrature points: 2e-12), a least-squares fit cond * eps (cond <= 8.4 for the
scaled design matrices, bench/fit_conditioning.py); the largest is a beam's mode shape: its
eigenvector takes a rounding component along mode j of eps lambda_max / (lambda_j - lambda_1), and
the peak normalisation (netgen.mechanics.beam.beam_modes) passes it to the modal mass and stiffness
to first order. On the cantilever's 60-element Hermite pencil eps lambda_max / (lambda_2 -
lambda_1) = 2.2e-8 (lambda_max / lambda_1 = 3.8e9; test_netlists.test_rtol_covers_the_beams
computes it for every beam example): times 2 for a mode's value at the first mode's peak and 2 for
two builds rounding apart, 8.7e-8. (The cantilever's modal masses moved by 1.6e-9 under OpenBLAS's
Sandybridge kernels against the Haswell ones, over the 1e-9 this constant once held, measured.) The
planted changes in the tests (a mass by 1e-6) are 10 RTOL.

FIT_SHARE = 0.01: the fit's held-out max relative error e is the accuracy the model states (in
every netlist header and the JSON). A rebuilt fit whose C differs by delta <= e / 100 states the
same accuracy to two digits and is, to within 1 % of its own error, the same approximation;
another fit of the same capacitance (other samples, another patch grid or degree, a changed
extractor) differs from it by about its own error: two approximations each within e differ by up
to 2 e, and measured (tests/test_netlists.py) by more than FIT_SHARE e. The rounding-level
re-fits differ by 4e-13..1e-6 e for a 1e-12 change of the samples and at most 6.2e-3 e for a 1e-9
change (coefficients moved by 7e-3, ten times the 8e-4 seen between two machines;
bench/fit_function_change.py). For exact fits (e ~ 0: one plate, a linear 1/C) the function is as
well determined as any least-squares result: RTOL.

The slope: a relative change delta(x) of C bounded by tau on the box |xs| <= r changes
dC/dxs = d(C (1 + delta))/dxs - dC/dxs = C ddelta/dxs + delta dC/dxs. By Markov's inequality a
polynomial of degree m bounded by tau on [-r, r] has slope at most m^2 tau / r; the relative
change of a sum of 1/P_k with P_k of degree d behaves as a degree m = 2 d polynomial to first
order (a ratio of degree-d changes), so |d(dC/dxs)| <= tau (m^2 max C / r + max |dC/dxs|).
"""

from __future__ import annotations

import dataclasses
import json
import re

import numpy as np

from netgen.model import MacroModel

RTOL = 1e-7
FIT_SHARE = 0.01

# Standalone numbers (not digits inside names such as top_r1s1 or p_top_r1s1_2).
NUMBER = re.compile(r"(?<![\w.])[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?(?![\w.])")
# Dimensionless residual diagnostics of the FEM (orthogonality of the side conditions, the
# rotation-mode coupling that should vanish): rounding noise at 1e-12..1e-17 that no
# relative tolerance can compare; they must only stay negligible.
NOISE = re.compile(
    r"^report\.mechanics\.(side_conditions\.\w+|rotation_mode_coupling\.(A|\w+_linear)_rel_max|flexure\.coupling_max)$"
)
COEFFICIENT = re.compile(r"^capacitances\[\d+\]\.terms\[\d+\]\.coeffs\[\d+\]$")  # judged by their function
FIT_ERROR = re.compile(r"^capacitances\[(\d+)\]\.(max_rel_error|rms_rel_error|grid_max_rel_error)$")
MISSED = re.compile(r"^validity\.fit_tolerance_missed\[\d+\]\.max_rel_error$")  # a fit's error again
WARNING = "validity.fit_warning"  # the same errors printed with 4 digits
RELATIVE = re.compile(r"rel_error|error_rel")  # a relative error: absolute rounding (module docstring)
# A sign with its number: a rounding-level coefficient (a symmetry zero) may print "+ 1e-17" or
# "- 2e-17"; the rebuilt text's layout is compared with these masked, its numbers and signs
# through with_fits (text_problems).
SIGNED = re.compile(r"(?:[-+]\s+)?" + NUMBER.pattern)
# Numbers netgen.model.contact stores rounded to a fixed number of decimals (the stop points'
# directions a to 9, late_contact_max to 6): a value at a rounding boundary flips the last one.
ROUNDED = {re.compile(r"^contact\.points\[\d+\]\.a\[\d+\]$"): 1e-9, re.compile(r"^contact\.late_contact_max$"): 1e-6}


# ----------------------------------------------------------------------------- text


def display_ulp(token: str) -> float:
    """One unit in the last printed digit of a rounded number (e.g. '1.669e-03' -> 1e-6)."""
    mantissa, _, exp = token.lower().partition("e")
    decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
    return 10.0 ** (int(exp or 0) - decimals)


def logical_lines(text: str) -> list[str]:
    """Lines with SPICE continuation lines ('+' first) appended to the line they continue."""
    out: list[str] = []
    for line in text.splitlines():
        if line.startswith("+") and out:
            out[-1] += " " + line[1:].strip()
        else:
            out.append(line)
    return out


def compare_text(
    new: str, old: str, what: str, rounded_lines: str | None = None, numbers: bool = True, signs: bool = True
) -> list[str]:
    """Problems between two texts: text with every number masked must match exactly, and (if
    `numbers`) the numbers within RTOL. On `rounded_lines` (comments of a netlist: numbers printed
    with a few digits) a number may also flip its last printed digit (not more than 1e-3
    relative), which a rounding-level difference can do at a rounding boundary. SPICE continuation
    lines ("+ ...") are joined to their line first: a long parameter vector wraps where its digits
    make it reach the width, so a last-digit change can move a value to the next line. Without
    `signs` a number's sign operator is masked with it (SIGNED)."""
    mask = NUMBER if signs else SIGNED
    problems = []
    new_lines, old_lines = logical_lines(new), logical_lines(old)
    if len(new_lines) != len(old_lines):
        problems.append(f"{what}: {len(new_lines)} lines now, {len(old_lines)} committed")
    for k, (a, b) in enumerate(zip(new_lines, old_lines), start=1):
        if mask.sub("#", a) != mask.sub("#", b):
            problems.append(f"{what}:{k}: text differs\n    now:       {a[:160]}\n    committed: {b[:160]}")
            continue
        if not numbers:
            continue
        rounded = rounded_lines is not None and a.startswith(rounded_lines)
        for ta, tb in zip(NUMBER.findall(a), NUMBER.findall(b)):
            va, vb = float(ta), float(tb)
            tol = RTOL * max(abs(va), abs(vb))
            if rounded:
                tol += min(display_ulp(ta), display_ulp(tb), 1e-3 * max(abs(va), abs(vb)))
            if abs(va - vb) > tol:
                problems.append(f"{what}:{k}: {ta} now, {tb} committed")
                break
    return problems


# ----------------------------------------------------------------------------- JSON numbers


def fit_tolerances(committed: dict) -> list[float]:
    """Per capacitance fit: FIT_SHARE of its held-out max relative error, at least RTOL."""
    return [max(FIT_SHARE * f["max_rel_error"], RTOL) for f in committed.get("capacitances", [])]


def compare_json(new, old, path: str = "", fit_tol: list[float] | None = None) -> list[str]:
    """Problems between two parsed JSON trees: same structure, strings and integers equal, floats
    within RTOL (relative errors: 2 RTOL absolute; NOISE diagnostics: both below 1e-9). With
    `fit_tol` (fit_tolerances of the committed tree) the fit coefficients are skipped (compare
    them with compare_functions) and the fits' error figures agree within their fit's tolerance."""
    if isinstance(old, dict):
        if not isinstance(new, dict) or list(new) != list(old):
            return [f"{path or 'top'}: keys {list(new) if isinstance(new, dict) else type(new)} vs {list(old)}"]
        return [p for k in old for p in compare_json(new[k], old[k], f"{path}.{k}" if path else k, fit_tol)]
    if isinstance(old, list):
        if not isinstance(new, list) or len(new) != len(old):
            return [f"{path}: length {len(new) if isinstance(new, list) else type(new)} vs {len(old)}"]
        return [p for i, (a, b) in enumerate(zip(new, old)) for p in compare_json(a, b, f"{path}[{i}]", fit_tol)]
    if isinstance(old, float) or isinstance(new, float):
        if isinstance(new, bool) or not isinstance(new, (int, float)):
            return [f"{path}: {new!r} vs {old!r}"]
        return [] if _close(new, old, path, fit_tol) else [f"{path}: {new!r} now, {old!r} committed"]
    if fit_tol and path == WARNING and isinstance(new, str) and isinstance(old, str):
        return [] if _same_warning(new, old, max(fit_tol)) else [f"{path}: {new!r} vs {old!r}"]
    return [] if new == old and type(new) is type(old) else [f"{path}: {new!r} vs {old!r}"]


def _close(new: float, old: float, path: str, fit_tol: list[float] | None) -> bool:
    """One JSON number against its committed value (see compare_json)."""
    if NOISE.match(path):
        return abs(new) < 1e-9 and abs(old) < 1e-9
    if fit_tol is not None and COEFFICIENT.match(path):
        return True
    error = FIT_ERROR.match(path) if fit_tol is not None else None
    if error:
        return abs(new - old) <= fit_tol[int(error.group(1))]
    if MISSED.match(path):  # which fit: the entry names its electrode; the largest tolerance bounds it
        return abs(new - old) <= max(fit_tol or [0.0]) if fit_tol is not None else abs(new - old) <= 2 * RTOL
    if RELATIVE.search(path):
        return abs(new - old) <= 2 * RTOL
    unit = next((u for pattern, u in ROUNDED.items() if pattern.match(path)), 0.0)
    return abs(new - old) <= unit + RTOL * max(abs(new), abs(old))


def _same_warning(new: str, old: str, tol: float) -> bool:
    """The fit warning: same words, its printed errors within `tol` plus their last printed digit."""
    if NUMBER.sub("#", new) != NUMBER.sub("#", old):
        return False
    pairs = zip(NUMBER.findall(new), NUMBER.findall(old))
    return all(abs(float(a) - float(b)) <= tol + min(display_ulp(a), display_ulp(b)) for a, b in pairs)


# ----------------------------------------------------------------------------- the fitted functions


def compare_functions(new: MacroModel, old: MacroModel, x: np.ndarray) -> list[str]:
    """What the two models compute at the scaled points x (inside the sampled box): per electrode C
    within its fit tolerance tau (fit_tolerances of `old`), dC/dxs within tau (m^2 max C / r + max
    |dC/dxs|) (module docstring), and the strain energy U and its force within RTOL of their
    largest value."""
    if [f.electrode for f in new.capacitances] != [f.electrode for f in old.capacitances]:
        return ["capacitances: other electrodes"]
    tau = fit_tolerances(old.to_dict())
    c_new, c_old = new.capacitance(x), old.capacitance(x)
    g_new, g_old = (m.capacitance_gradient(x) * m.scales[None, None, :] for m in (new, old))
    r = float(old.sampling.get("range", 1.0))
    problems = []
    for i, f in enumerate(old.capacitances):
        dc = float(np.max(np.abs(c_new[:, i] / c_old[:, i] - 1.0)))
        m = 2 * f.degree
        slope = tau[i] * (m * m * float(np.max(np.abs(c_old[:, i]))) / r + float(np.max(np.abs(g_old[:, i]))))
        dg = float(np.max(np.abs(g_new[:, i] - g_old[:, i])))
        if not dc <= tau[i]:
            problems.append(f"C of {f.electrode}: changed by {dc:.2e} relative > {tau[i]:.2e}")
        if not dg <= slope:
            problems.append(f"dC/dxs of {f.electrode}: changed by {dg:.3e} F > {slope:.3e} F")
    problems += _compare_energy(new, old, x)
    return problems


def _compare_energy(new: MacroModel, old: MacroModel, x: np.ndarray) -> list[str]:
    """The nonlinear strain energy and its force, where the model has one: within RTOL."""
    u_new, u_old = new.nonlinear_energy_polynomial(), old.nonlinear_energy_polynomial()
    if u_old is None or u_new is None:
        return [] if u_old is None and u_new is None else ["nonlinear strain energy: present in one model only"]
    problems = []
    for what, a, b in (("U", u_new(x), u_old(x)), ("-dU/dq", new.nonlinear_force(x), old.nonlinear_force(x))):
        if np.max(np.abs(a - b)) > RTOL * np.max(np.abs(b)):
            problems.append(f"strain energy {what}: changed by {np.max(np.abs(a - b)) / np.max(np.abs(b)):.2e}")
    return problems


def with_fits(model: MacroModel, committed: MacroModel) -> MacroModel:
    """`model` with the committed model's capacitance fits (coefficients and error figures) and
    stop-point directions (rounded to 9 decimals, ROUNDED): what the committed netlist texts must
    be, up to RTOL, if only the fits moved along their ill-determined directions and a rounded
    value flipped its last decimal (compare_json checks both)."""
    fits = [(f.electrode, len(f.polys)) for f in model.capacitances]
    if fits != [(f.electrode, len(f.polys)) for f in committed.capacitances]:
        return model  # other fits: nothing to transplant (the JSON comparison reports them)
    contact = model.contact
    points, old_points = model.contact.get("points", []), committed.contact.get("points", [])
    if len(points) == len(old_points) and all(len(p["a"]) == len(q["a"]) for p, q in zip(points, old_points)):
        contact = contact | {"points": [p | {"a": q["a"]} for p, q in zip(points, old_points)]}
    return dataclasses.replace(model, capacitances=list(committed.capacitances), contact=contact)


def model_problems(new: MacroModel, old_json: str, x: np.ndarray, what: str) -> list[str]:
    """Items 1-3 of the module docstring for the JSON of one model (`old_json` the committed text)."""
    new_json = new.json_text()
    if new_json == old_json:
        return []
    found = compare_text(new_json, old_json, what, numbers=False)
    if found:
        return found
    old_tree = json.loads(old_json)
    found = [f"{what}: {p}" for p in compare_json(json.loads(new_json), old_tree, "", fit_tolerances(old_tree))]
    old = MacroModel.from_dict(old_tree, what)
    return found + [f"{what}: {p}" for p in compare_functions(new, old, x)]


def text_problems(new: str, old: str, hybrid: str, file: str) -> list[str]:
    """A committed netlist text against the rebuild: its words and layout against the rebuilt text
    (numbers masked), its numbers against `hybrid`, the rebuilt model rendered with the committed
    fits (with_fits), within RTOL (comment numbers: their last printed digit, see compare_text)."""
    if new == old:
        return []
    rounded = "//" if file.endswith(".va") else "*"
    return compare_text(new, old, file, numbers=False, signs=False) or compare_text(
        hybrid, old, file, rounded_lines=rounded
    )


# ----------------------------------------------------------------------------- re-fits for the tests


def refit(b, i: int, noise: float, seed: int = 0, grid: int | None = None):
    """Electrode i's plate fit redone as the build does it (netgen.fit.capacitance.fit_plates, the
    build's patch grid or PATCH_GRIDS[grid], its stated error over the box's corners too) from its samples times (1 + noise * N(0, 1)), all but
    the one at the origin that sets c_ref (a measured sample, not a fit result)."""
    from netgen.fit import capacitance as cap

    f, x, e = b.fits[i], b.grid.x, b.electrodes[i]
    k = grid if grid is not None else next(k for k, g in enumerate(cap.PATCH_GRIDS) if g[0] * g[1] == len(f.polys))
    wobble = noise * np.random.default_rng(seed).standard_normal(len(x))
    wobble[np.argmin(np.sum(x * x, axis=1))] = 0.0
    c = b.grid.c[:, i] * (1.0 + wobble)
    init = cap.patch_guess(b.structure, e, b.mechanics.basis, b.scales, cap.PATCH_GRIDS[k], cap.reference(x, c))
    fit = cap.fit_plates(
        e.name, cap.FitData(x, c, b.holdout.x, b.holdout.c[:, i], cap.rest_of(b.grid, i)), init, f.degree
    )
    return fit if b.corners is None else cap.with_corners(fit, b.corners.x, b.corners.c[:, i])


def with_fit(model: MacroModel, i: int, fit) -> MacroModel:
    """`model` with capacitance fit i replaced."""
    fits = list(model.capacitances)
    fits[i] = fit
    return dataclasses.replace(model, capacitances=fits)


def coefficient_change(a: MacroModel, b: MacroModel) -> float:
    """Largest relative change of any fit's coefficient vector between two models."""
    out = 0.0
    for f, g in zip(a.capacitances, b.capacitances):
        u, v = (np.concatenate([p.coeffs for p in h.polys]) for h in (f, g))
        out = max(out, float(np.linalg.norm(u - v) / np.linalg.norm(v)))
    return out
