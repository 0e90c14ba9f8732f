"""Process spread as instance parameters (opt-in: only for a structure with [process], and only the
parameters it declares; netgen.structure.process_table): the laws by which a built model's numbers change with the
device-layer thickness (tscale), Young's modulus (escale), the die temperature (temp, degC), a
gap offset per electrode set (dg_<set>, m) and the flexures' lateral etch bias (etch, m), derived here
once so that emitters only render them.

- tscale: mass, stiffness and damping of every coordinate as cubic polynomials in tscale, fitted to
  the mechanics (netgen.mechanics) and damping (netgen.mechanics.damping) re-run with the conductor's
  and the flexures' thickness scaled at fit_points (five points, four coefficients: the largest
  relative residual is the parameter's stated error; 0 to round-off for the power laws t, t^3 of rigid masses,
  beams in bending and Kirchhoff plates; torsion is not a power law). Without comb fingers or etch
  holes the capacitances are left unchanged; with combs or holes (thickness_capacitance) every
  electrode's is times a cubic in tscale fitted to the extractor (a textbook comb's eps t / g: tscale;
  a field2d comb's fringe does not grow with t, and its share varies over the fit box: stated).
- escale and temp: K(tscale, E) = e * A(tscale) + B(tscale), with A the part proportional to the
  modulus (beams, frames, plates) and B the rest (residual stress, given springs), separated by a
  re-run at the modulus scaled by E_PROBE; e = escale * (1 + modulus_tc * (temp - T0)).
- temp in the damping: the squeeze-film part of the damping times mu_eff(T) / mu_eff(T0), with
  Sutherland's law mu ~ T^1.5 / (T + S) and the mean free path ~ mu sqrt(T) / p in Veijola's
  rarefaction mu / (1 + 9.638 Kn^1.159) (netgen.mechanics.squeeze_film), as a polynomial in
  (T - T0) / 100 K fitted on the declared temp_range, the gas in an open or a sealed cavity; and k_B T
  in the thermal noise (netgen.model.process_film).
- dg_<set>: moving a plate electrode set (side above or below) away by dg is, exactly, moving the
  conductor by -dg along z towards the other side (for any tilt and any plate mode: both add to the
  rigid translation), so each of the set's capacitance terms reads xs_z - sign dg / L_z, whatever its
  fit form. Needs the coordinate z; the fit's box moves with it (quoted accuracy while
  |xs_z - sign dg / L_z| <= range). The squeeze film of the side a set alone faces follows it exactly,
  times mu_eff(g + dg) g^3 / (mu_eff(g) (g + dg)^3) (netgen.model.process_film.film_law).
- etch: a proof mass's flexure beams w - 2 etch, a beam conductor's width (a cantilever's tip back
  by etch: etched_beam), or a plate's outline (a piston's sides - 2 etch, a free disk's radius - etch,
  an electrode drawn on the plate's edge receding with it: etched_plate); per coordinate the ratio of each law part to
  its nominal value as a cubic in etch / 1 um from re-runs at thickness 1, multiplied onto the tscale
  law (etch_laws: exact for the beams' w^3 and w laws and products of power laws in t and w; the
  product's misfit at the (tscale, etch) box's corners is part of the stated error); the inertial loads
  follow the etched body (netgen.model.process_loads); with tscale the capacitance laws' product gets
  a cross factor where it misfits at those corners (cross_capacitance).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from ..mechanics import Mechanics
from ..mechanics.damping import damping as damping_of
from ..mechanics.damping import squeeze_film_damping
from ..structure import Structure
from ..structure.process_table import BEAM_KINDS, PLATE_KINDS
from ..structure.schema import Process
from .etch_combs import gap_shifts
from .etch_cross import CAPACITANCE_POINTS, ROUND_OFF, check_sets, cross_capacitance, misfit
from .etch_fill import fill_shifts
from .etch_geometry import comb_across, comb_shifts, etched, is_comb
from .etch_geometry import etched_beam as etched_beam  # re-exported: the beams' etch
from .etch_geometry import etched_comb as etched_comb  # re-exported: the combs' etch
from .etch_geometry import scaled as scaled  # re-exported: the thickness and modulus re-runs
from .etch_knots import ETCH_UNIT, basis, edge_knots, identity, knot_points, record_knots, tip_knots
from .etch_state import TSCALE, state_factor, state_laws
from .process_film import GAP_SIDES, KELVIN, film_law, temperature_law
from .process_film import viscosity_ratio as viscosity_ratio  # re-exported: tests/model/test_process.py
from .process_values import LAW_KEYS as LAW_KEYS  # re-exported: the laws' evaluation at a point
from .process_values import capacitance_at as capacitance_at
from .process_values import coordinate_values as coordinate_values
from .process_values import energy_factor as energy_factor
from .process_values import film_at as film_at
from .process_values import law_value as law_value
from .process_values import modulus_factor as modulus_factor
from .process_values import ratio_value as ratio_value

E_PROBE = 1.1  # modulus factor of the re-run separating K into e A + B


def fit_points(p: Process) -> tuple[float, ...]:
    """The thicknesses the mechanics are re-run at: five across the declared tscale range (two each
    side of the nominal, which is one of them), or the nominal alone without tscale."""
    if not p.wants("tscale"):
        return (1.0,)
    lo, hi = p.tscale_range
    return (lo, (lo + 1.0) / 2, 1.0, (1.0 + hi) / 2, hi)


def power_fit(
    x: tuple[float, ...], values: np.ndarray, scale: np.ndarray, nominal: float = 1.0, knots: tuple[float, ...] = ()
) -> tuple[np.ndarray, float]:
    """Cubic polynomials c0 + c1 x + c2 x^2 + c3 x^3 per column of `values` (least squares over the
    points: one more than the coefficients; c0 then set so the fit is exact at x = 1), and the
    largest residual at the points relative to `scale` (per point and column: the quantity it is a
    part of, there; relative to the largest value over the range it understated the error at the
    thin end by the cube of the range).
    One point (no tscale): the constant. With `knots` (etch only) the cubic plus truncated powers
    (netgen.model.etch_knots.basis)."""
    if len(x) == 1:
        return np.column_stack([values[0]] + [np.zeros_like(values[0])] * 3), 0.0
    v = basis(x, knots) if knots else np.vander(np.array(x), 4, increasing=True)
    coef, *_ = np.linalg.lstsq(v, values, rcond=None)
    # the least-squares round-off of exact laws (the Vandermonde matrix over 0.9..1.1 has a condition
    # number near 1e6: 1e-16 x 1e6 = 1e-10 relative), then the nominal point exactly (default
    # parameters = the model's own numbers: a ratio of exactly 1) by scaling the polynomial, which
    # keeps a pure power law's zeros (adding the misfit to c0 wrote a round-off c0 into the netlist)
    coef[np.abs(coef) < 1e-9 * np.max(np.abs(coef), axis=0, initial=0.0)] = 0.0
    one = x.index(nominal)
    at_one = v[one] @ coef
    ok = at_one != 0.0
    coef[:, ok] *= values[one][ok] / at_one[ok]
    coef[0, ~ok] += values[one][~ok]
    err = float(np.max(np.abs(v @ coef - values) / np.where(scale > 0, scale, 1.0), initial=0.0))
    return coef.T, err if err > ROUND_OFF else 0.0


def mechanics_laws(s: Structure, m: Mechanics, run, film: bool, p: Process) -> tuple[list[dict], list[float]]:
    """Per coordinate the tscale polynomials of mass, K's modulus part A and rest B, and the damping
    without and with its squeeze film, from `run(structure)` -> Mechanics (netgen.mechanics.mechanics)
    re-run at fit_points (the nominal m reused) and, for escale or temp, at E_PROBE (else A = 0: the
    modulus never varies); and each polynomial's residual."""
    rows: dict[str, list] = {k: [] for k in ("mass", "a", "b", "d_rest", "d_film")}
    modulus = p.wants("escale") or p.wants("temp")
    points = fit_points(p)
    for tau in points:
        m1 = m if tau == 1.0 else run(scaled(s, tau))
        m2 = run(scaled(s, tau, E_PROBE)) if modulus else m1
        if m1.names != m.names or m2.names != m.names:
            raise ValueError("the coordinates change with the thickness")
        a = (m2.stiffnesses - m1.stiffnesses) / (E_PROBE - 1.0)
        rest, total = damping_parts(scaled(s, tau), m1, film)
        for key, val in zip(rows, (m1.masses, a, m1.stiffnesses - a, rest, total - rest)):
            rows[key].append(np.asarray(val, dtype=float))
    laws, errors = {}, []
    arrays = {k: np.array(v) for k, v in rows.items()}
    stiff, damp = np.abs(arrays["a"] + arrays["b"]), np.abs(arrays["d_rest"] + arrays["d_film"])
    totals = {"mass": np.abs(arrays["mass"]), "a": stiff, "b": stiff, "d_rest": damp, "d_film": damp}
    for key, vals in arrays.items():
        laws[key], err = power_fit(points, vals, totals[key])
        errors.append(err)
    return [{k: [float(c) for c in laws[k][v]] for k in laws} for v in range(len(m.names))], errors


def damping_parts(s: Structure, m: Mechanics, film: bool) -> tuple[np.ndarray, np.ndarray]:
    """(damping without the squeeze film, total damping) per coordinate."""
    total, _ = damping_of(s, m)
    if not film or s.damping is None:
        return total, total
    rest, _ = damping_of(dataclasses.replace(s, damping=dataclasses.replace(s.damping, squeeze_film=False)), m)
    return rest, total


def gap_sets(s: Structure, names: list[str], electrodes) -> tuple[list[dict], str]:
    """The electrode sets a gap offset applies to exactly (plates above/below with coordinate z),
    each {"set", "electrodes", "sign"}; and the reason when there are none."""
    if "z" not in names:
        return [], "no coordinate z: a gap offset is not a shift of a coordinate of this model"
    sets: dict[str, dict] = {}
    for e in electrodes:
        if e.side not in GAP_SIDES:
            continue
        row = sets.setdefault(e.group, {"set": e.group, "electrodes": [], "sign": GAP_SIDES[e.side]})
        if row["sign"] != GAP_SIDES[e.side]:
            row["mixed"] = True
        row["electrodes"].append(e.name)
    out = [r for r in sets.values() if not r.pop("mixed", False)]
    return out, "" if out else "no electrode set lies above or below the conductor"


def process_laws(
    s: Structure, m: Mechanics, run, electrodes, scale_z: float, sampling_range: float, extract=None
) -> dict:
    """The model's process entry (MacroModel.process): laws, ranges and errors of the parameters the
    structure's [process] declares (netgen.structure.process_table checked them against the
    structure); {} without [process] (nothing is re-run, the model is what it was). `extract`:
    (structure, n) -> the extractor's capacitances at rest and at n points of the fit box
    (netgen.build.capacitance_sampler), for the etch's capacitance laws (None: none built)."""
    p = s.process
    if p is None:
        return {}
    d = s.damping
    film = bool(d and d.squeeze_film)  # compressible: d_film is the branches' remainder damper
    per, errors = mechanics_laws(s, m, run, film, p)
    t0 = d.temperature if d else 300.0
    sets, _ = gap_sets(s, list(m.names), electrodes) if p.wants("dg") else ([], "")
    dg_max = sampling_range * scale_z / 4 if scale_z else 0.0
    etch_err = etch_laws(s, m, run, film, p, per) if p.wants("etch") else 0.0
    solved = squeeze_film_damping(s, m) if film and sets else None  # one film solve for every gap set
    out: dict[str, Any] = {
        "parameters": list(p.parameters),
        "temperature_C": t0 - KELVIN,
        "modulus_tc_per_K": p.modulus_tc,
        "tscale": {
            "range": list(p.tscale_range),
            "max_rel_error": max(errors),
            "fit_points": list(fit_points(p)),
            "capacitance": "unchanged (plate electrodes)",
        }
        | (
            thickness_capacitance(s, p, extract, [e.name for e in electrodes], list(m.names))
            if tscale_combs(s, p, extract)
            else {}
        ),
        "escale": {"range": list(p.escale_range), "max_rel_error": max(errors[1:3])},
        "temp": {
            "range_C": list(p.temp_range),
            "viscosity": temperature_law(s, p.temp_range, m) if film and p.wants("temp") else {},
        },
        "coordinates": per,
        "gaps": [dict(r, max_m=dg_max) | film_law(s, m, r, dg_max, solved) for r in sets],
    }
    if p.wants("etch"):
        # the plates' fill shift (netgen.model.etch_fill): along z, not where a gap offset reads xs_z too
        fill = ([e.name for e in electrodes if e.side in GAP_SIDES and not sets], sampling_range * scale_z / 2)
        out["etch"] = etch_record(s, p, etch_err, extract, [e.name for e in electrodes], list(m.names), fill)
        if "capacitance_laws" in out["tscale"] and "capacitance" in out["etch"]:
            out["etch"] |= cross_capacitance(
                s, p, extract, [e.name for e in electrodes], list(m.names), out["tscale"], out["etch"]
            )
    if m.strain_energy is not None:
        out["strain_energy"] = energy_law(s, m, run, p)
    if d and d.squeeze_film and d.film_model == "compressible":  # r_j ~ mu_eff, the gas spring r_j w_j ~ p_a
        out["temp"]["film_branches"] = "the compressible film's branch dampers times the ratio, corners over it"
    return out


def tscale_combs(s: Structure, p: Process, extract) -> bool:
    """tscale is declared on a structure whose capacitances move with the thickness, comb fingers
    (textbook or field2d: the 2-D section tables per finger thickness, netgen.electrostatics.comb_section)
    or a perforated mass (its hole walls' fringe, netgen.electrostatics.perforation), and an extractor
    to fit the ratio with."""
    moved = any(is_comb(e) for e in s.electrode_sets) or bool(getattr(s.conductor, "hole", 0.0))
    return p.wants("tscale") and extract is not None and moved


def thickness_capacitance(s: Structure, p: Process, extract, names: list[str], coords: list[str]) -> dict:
    """Each electrode's capacitance under tscale as C(q; tscale) = ratio(tscale) C(q; 1), the ratio a
    cubic in tscale (1 at 1) fitted to the extractor at rest at fit_points on the scaled structure
    (fingers, conductor and flexures tscale times as thick). A textbook comb's eps t L / g is linear
    in t at every state: the ratio is tscale, exact. What is not linear in t (a field2d comb's fringe
    above and below the fingers and the substrate's share, netgen.electrostatics.comb_section, which
    vary with the gap and the out-of-plane offset; a perforated plate's hole walls,
    netgen.electrostatics.perforation; a thick plate's edge) makes the ratio depend on the state: a
    comb's gets the state factor 1 + u P1(xs) + u^2 P2(xs), u = tscale - 1 ("state",
    netgen.model.etch_state, fitted at the same thicknesses). The stated error is the largest
    |ratio C(q; 1) / C(q; tscale) - 1| over check_sets (rest, CAPACITANCE_POINTS random points and the
    box's corners, held out of the state fit) at the re-run thicknesses, and the cubic's residual."""
    points = fit_points(p)
    rest = np.array([extract(scaled(s, t), 0)[0] for t in points])
    coef, err = power_fit(points, rest / rest[points.index(1.0)], np.ones_like(rest))
    combs = {
        k: (np.zeros(len(coords)), [float(x) for x in coef[k]])
        for k, n in enumerate(names)
        if n in comb_shifts(s, coords)
    }
    states = state_laws(s, extract, scaled, combs, points, CAPACITANCE_POINTS, axis=TSCALE)
    bare = err
    for t in (x for x in points if x != 1.0):
        for xs, corners in check_sets(s, len(coords)):
            n = 0 if corners else CAPACITANCE_POINTS
            moved = extract(scaled(s, t), n, corners=corners)
            ref = extract(s, n, corners=corners) * np.array([float(np.dot(c, [1.0, t, t**2, t**3])) for c in coef])
            bare = max(bare, misfit(ref, moved))
            for k, law in states.items():
                ref[:, k] *= state_factor(law, xs, t, TSCALE)
            err = max(err, misfit(ref, moved))
    laws = [
        {"electrode": n, "ratio": [float(x) for x in c]} | ({"state": states[k]} if k in states else {})
        for k, (n, c) in enumerate(zip(names, coef))
    ]
    return {
        "capacitance": "times pc_<electrode>, a cubic in tscale (textbook comb fingers ~ t; field2d fingers and hole walls fitted)",
        "capacitance_laws": [r for r in laws if r["ratio"] != [1.0, 0.0, 0.0, 0.0]],
        "capacitance_max_rel_error": err if err > ROUND_OFF else 0.0,
    } | ({"capacitance_stateless_max_rel_error": bare} if states else {})


def etch_points(p: Process) -> tuple[float, ...]:
    """The etch biases (m) the mechanics are re-run at: five across etch_range, the nominal 0 among them."""
    lo, hi = p.etch_range
    return (lo, lo / 2, 0.0, hi / 2, hi)


def point_values(s: Structure, run, film: bool, modulus: bool, names: list[str], m: Mechanics | None = None) -> dict:
    """Mass, K's modulus part a and rest b, damping without and with the squeeze film per coordinate of
    structure `s` (mechanics `m` when already run), as in mechanics_laws."""
    m1 = m if m is not None else run(s)
    m2 = run(scaled(s, 1.0, E_PROBE)) if modulus else m1
    if list(m1.names) != names or list(m2.names) != names:
        raise ValueError("the coordinates change with the etch bias")
    a = (m2.stiffnesses - m1.stiffnesses) / (E_PROBE - 1.0) if modulus else np.zeros(len(names))
    rest, total = damping_parts(s, m1, film)
    vals = (m1.masses, a, m1.stiffnesses - a, rest, total - rest)
    return {k: np.asarray(v, dtype=float) for k, v in zip(LAW_KEYS, vals)}


def etch_laws(s: Structure, m: Mechanics, run, film: bool, p: Process, per: list[dict]) -> float:
    """Per coordinate the etch ratios (cubics in etch / ETCH_UNIT, 1 at 0; with the cubic's truncated
    powers at each torsion knot in the range, netgen.model.etch_knots) of mass, a, b and the damping
    parts, from re-runs at etch_points (thickness nominal; knot_points with knots), stored as
    per[v]["etch"]; the value at (tscale, etch) is the tscale law times the ratio. Returns the error:
    the largest of the fits' residuals and, with tscale, the product's misfit at the four corners of
    the (tscale, etch) box against re-runs there (0 for laws separable in t and w: k ~ t w^3 in
    plane, w t^3 out of plane; torsion is not, and its knot moves with t), relative to the total
    mass, stiffness or damping there."""
    names, modulus = list(m.names), p.wants("escale") or p.wants("temp")
    knots = record_knots(s, *p.etch_range)
    points = knot_points(*p.etch_range, knots) if knots else etch_points(p)
    rows = [point_values(etched(s, e), run, film, modulus, names, m if e == 0.0 else None) for e in points]
    u = tuple(e / ETCH_UNIT for e in points)
    errors = []
    for key in LAW_KEYS:
        vals = np.array([r[key] for r in rows])
        coef, err = power_fit(u, vals, totals(rows, key), nominal=0.0, knots=knots)
        nominal, scale = vals[points.index(0.0)], totals(rows, key)
        for v, c in enumerate(per):
            # a part at the re-runs' round-off of its total (b of pure beams: K - a) carries no ratio
            ok = abs(nominal[v]) > 1e-9 * scale[points.index(0.0), v]
            c.setdefault("etch", {})[key] = [float(x / nominal[v]) for x in coef[v]] if ok else identity(knots)
            if not ok:  # a part that is zero at the nominal etch must stay zero (no ratio can carry it)
                err = max(err, float(np.max(np.abs(vals[:, v] - nominal[v]) / np.maximum(scale[:, v], 1e-300))))
        errors.append(err)
    if p.wants("tscale"):
        errors.append(corner_misfit(s, run, film, modulus, names, p, per))
    worst = max(errors)
    return worst if worst > ROUND_OFF else 0.0


def totals(rows: list[dict], key: str) -> np.ndarray:
    """|the total| a law part belongs to, per point and coordinate: mass, stiffness a + b, damping."""
    group = {
        "mass": ("mass",),
        "a": ("a", "b"),
        "b": ("a", "b"),
        "d_rest": ("d_rest", "d_film"),
        "d_film": ("d_rest", "d_film"),
    }
    return np.abs(np.array([sum(r[k] for k in group[key]) for r in rows]))


def corner_misfit(s: Structure, run, film: bool, modulus: bool, names: list[str], p: Process, per: list[dict]) -> float:
    """The largest misfit of the product laws at the corners of the (tscale, etch) box against re-runs."""
    worst, knots = 0.0, record_knots(s, *p.etch_range)
    for tau in p.tscale_range:
        for e in p.etch_range:
            ref = point_values(etched(scaled(s, tau), e), run, film, modulus, names)
            for key in LAW_KEYS:
                scale = totals([ref], key)[0]
                for v, c in enumerate(per):
                    if scale[v] > 0:
                        worst = max(worst, abs(law_value(c, key, tau, e, knots) - ref[key][v]) / scale[v])
    return worst


def etch_record(
    s: Structure,
    p: Process,
    err: float,
    extract=None,
    names: list[str] | None = None,
    coords: list[str] | None = None,
    fill: tuple[list[str], float] = ([], 0.0),
) -> dict:
    """The etch entry of the process record: range, law error, the polynomial variable, the etched
    mass outline's relative area change at the range's ends (holes included: the mass and inertia
    laws carry it exactly) and, with `extract` (structure, n -> the extractor's capacitances at rest
    and at n fixed random points of the fit box: netgen.build.capacitance_sampler), the capacitance
    laws (capacitance_laws; `fill`: the plate electrodes offered a fill shift and the half box dz)."""
    mass = s.conductor.mass  # the etched body's area times rho t: outline, holes, a beam's width and tip
    out = {
        "range_m": list(p.etch_range),
        "max_rel_error": float(err),
        "variable": "etch / 1 um",
        "area_rel": max(abs(etched(s, e).conductor.mass / mass - 1.0) for e in p.etch_range),
    }
    if s.conductor.kind in BEAM_KINDS:  # the header says what recedes (netgen.emit.process.header)
        out["beam"] = s.conductor.kind
    if s.conductor.kind in PLATE_KINDS:
        out["plate"] = s.conductor.kind
    knots = record_knots(s, *p.etch_range)
    if knots:  # the laws' torsion or edge knots (etch / 1 um; netgen.model.etch_knots)
        out["knots"] = list(knots)
    if extract is not None:
        out |= capacitance_laws(s, p, extract, names or [], coords or [], fill)
    return out


def capacitance_laws(
    s: Structure, p: Process, extract, names: list[str], coords: list[str], fill: tuple[list[str], float] = ([], 0.0)
) -> dict:
    """Each electrode's capacitance under etch as C(q; etch) = ratio(etch) C(q + shift etch; 0): the
    combs' shift (comb_shifts: exact for the parallel-plate part of a transverse comb's gap and every
    comb's overlap) and a ratio, a cubic in etch / 1 um (1 at 0), from the extractor at rest at
    etch_points: C(0; etch) / C(shift etch; 0). It carries what no shift is: the area a plate faces
    (the etched outline and the perforated mass's fill factor, netgen.electrostatics.perforation), a
    lateral comb's gap, the fingers' width in the fringe and the tips. The stated error is the largest
    |ratio C(q + shift etch; 0) / C(q; etch) - 1| over check_sets (rest, CAPACITANCE_POINTS random
    points and the box's corners) at the etch points, and the cubic's residual there. The plates of `fill`
    (names, half box dz) get a z shift too (netgen.model.etch_fill: their fill factor's etch change
    depends on the gap; such a law is marked "fill": the contact stops do not follow it). A
    transverse comb's shift across the fingers gets an effective part where the form is not a shift
    (netgen.model.etch_combs: the far gap and the fringe of the narrower finger, which a constant ratio
    cannot carry); its geometric shift, which the stops follow, is then stated apart (stop_shift).
    A comb whose law still depends on the state gets the factor 1 + u P1(xs) + u^2 P2(xs) ("state",
    netgen.model.etch_state); so does a plate's electrode (piston, free disk) whose ratio leaves more
    than that module's FLOOR: the rim strip the etch removes or adds weighs by its local gap, which
    the tilts and modes move away from the mean (a rigid disk 300 um, 3 um gaps, tilts to 0.3 of the
    touching angle, etch -0.5..1 um: 1.3e-3 with the ratio alone, 2.9e-4 with the factor). A piston's
    z alone moves every point alike: its ratio is the exact area ratio and it gets none."""
    shifts = comb_shifts(s, coords)
    geometric = comb_fit(s, p, extract, names, coords, shifts)
    plates = fill_shifts(s, extract, etched, coords, [names.index(n) for n in fill[0]], p.etch_range, fill[1])
    shifts |= {names[i]: {"z": k} for i, k in plates.items()}
    vectors = [np.array([shifts.get(n, {}).get(q, 0.0) for q in coords]) for n in names]
    memo: dict[tuple, np.ndarray] = {}

    def drawn_at(n: int, offset: np.ndarray, corners: bool = False) -> np.ndarray:
        """The drawn structure's capacitances moved by `offset` (one extraction per distinct offset)."""
        key = (n, corners, *offset.tolist())
        if key not in memo:
            memo[key] = extract(s, n, offset, corners=corners)
        return memo[key]

    knots = edge_knots(s, *p.etch_range)  # a beam's electrode edges met (netgen.model.etch_knots)
    points = knot_points(*p.etch_range, knots) if knots else etch_points(p)
    rest = np.array([extract(etched(s, e), 0)[0] for e in points])
    drawn = np.array([[drawn_at(0, v * e)[0][k] for k, v in enumerate(vectors)] for e in points])
    u = tuple(e / ETCH_UNIT for e in points)
    coef, err = power_fit(u, rest / drawn, np.ones_like(rest), nominal=0.0, knots=knots)
    ratios = [[float(x) for x in coef[k]] for k in range(len(names))]
    combs = {k: (vectors[k], ratios[k]) for k, n in enumerate(names) if n in comb_shifts(s, coords)}
    below = {names.index(n): k / ETCH_UNIT for n, k in tip_knots(s, *p.etch_range).items() if n in names}
    states = state_laws(s, extract, etched, combs, points, CAPACITANCE_POINTS, knots=knots)
    tips = {k: (vectors[k], ratios[k]) for k in below}  # an overhanging tip: the factor in (k - u)+
    states |= state_laws(s, extract, etched, tips, points, CAPACITANCE_POINTS, TIP_DEGREE, knots=knots, below=below)
    if s.conductor.kind in PLATE_KINDS:  # the receded rim's weight follows the state (docstring)
        rims = {k: (vectors[k], ratios[k]) for k in range(len(names)) if k not in states}
        states |= state_laws(s, extract, etched, rims, points, CAPACITANCE_POINTS, knots=knots)
    bare = err  # the law without the combs' state factors (the forms that leave it out state this)
    for e in (x for x in points if x != 0.0):
        for xs, corners in check_sets(s, len(coords)):
            count = 0 if corners else CAPACITANCE_POINTS
            moved = extract(etched(s, e), count, corners=corners)
            for k, v in enumerate(vectors):
                ref = ratio_value(ratios[k], e, knots) * drawn_at(count, v * e, corners)[:, k]
                bare = max(bare, misfit(ref, moved[:, k]))
                ref = ref * state_factor(states[k], xs, e) if k in states else ref
                err = max(err, misfit(ref, moved[:, k]))
    laws: list[dict[str, Any]] = []
    for n, r in zip(names, ratios):
        if r[0] != 1.0 or any(r[1:]) or shifts.get(n):
            laws.append({"electrode": n, "ratio": r} | ({"shift": shifts[n]} if shifts.get(n) else {}))
            laws[-1] |= {"fill": True} if n in fill[0] and shifts.get(n) else {}
            laws[-1] |= {"stop_shift": geometric[n]} if n in geometric else {}
            laws[-1] |= {"state": states[names.index(n)]} if names.index(n) in states else {}
    out = {"capacitance": laws, "capacitance_max_rel_error": err if err > ROUND_OFF else 0.0}
    return out | ({"capacitance_stateless_max_rel_error": bare} if states else {})


TIP_DEGREE = 4  # an overhanging tip's state factor (examples/cantilever.toml at -0.2 um over 3000
# points of the box: degree 2 leaves 5.2e-4, 3 2.8e-4, 4 1.1e-4, the fit's own error)


def comb_fit(
    s: Structure, p: Process, extract, names: list[str], coords: list[str], shifts: dict[str, dict[str, float]]
) -> dict[str, dict[str, float]]:
    """Add to each transverse comb's geometric shift (comb_shifts, updated in place) its fitted
    effective part across the fingers (netgen.model.etch_combs: the far gap and the fringe of the
    narrower finger); returns electrode -> the geometric shift of the combs changed (the contact
    stops follow it, not the effective one)."""
    across = {e: q for e, q in comb_across(s, coords).items() if e in names and shifts.get(e)}
    unit = {q: np.eye(len(coords))[coords.index(q)] for q in set(across.values())}
    combs = {names.index(e): (np.array([shifts[e].get(c, 0.0) for c in coords]), unit[q]) for e, q in across.items()}
    fitted = gap_shifts(s, extract, etched, combs, etch_points(p), CAPACITANCE_POINTS)
    geometric = {}
    for k, d in fitted.items():
        e = names[k]
        geometric[e] = dict(shifts[e])
        shifts[e][across[e]] = shifts[e].get(across[e], 0.0) + d
    return geometric


def finite_law(law: dict) -> bool:
    """Every number in the law is finite (JSON-safe)."""
    parts = [x for c in law.get("coordinates", []) for k in LAW_KEYS for x in c[k]]
    parts += [x for c in law.get("coordinates", []) for k in c.get("etch", {}) for x in c["etch"][k]]
    return all(math.isfinite(x) for x in parts)


def energy_law(s: Structure, m: Mechanics, run, p: Process) -> dict:
    """The fitted strain energy's law (MacroModel.nonlinear, netgen.mechanics StrainEnergy): U(q; t, E)
    = (e A(t) + B(t)) U(q) with e the modulus factor (modulus_factor), A the part proportional to the
    modulus (a beam's stretching energy E w t (int w'^2 / 2)^2 / 2L: A = t for shapes independent of
    t) and B the rest (a given spring such as k_xy x y: B = 1), cubics in tscale from the energies
    re-run at fit_points and E_PROBE, each the least-squares ratio to the nominal over sample points;
    the error includes the spread of that ratio over the points (a shape change with t). {} without
    a strain energy or a parameter that moves it (tscale, escale, temp, etch: times its etch ratio,
    energy_etch)."""
    if m.strain_energy is None or not any(p.wants(n) for n in ("tscale", "escale", "temp", "etch")):
        return {}
    q = np.random.default_rng(0).uniform(-1e-6, 1e-6, (16, len(m.names)))  # ~ um amplitudes (any scale)
    u0 = np.asarray(m.strain_energy.energy(q), dtype=float)
    etch = energy_etch(s, m, run, p, q, u0) if p.wants("etch") else {}
    ratios, spread = [], 0.0
    modulus = p.wants("escale") or p.wants("temp")
    for tau in fit_points(p):
        row = []
        for e in (1.0, E_PROBE) if modulus else (1.0,):
            mt = m if tau == 1.0 and e == 1.0 else run(scaled(s, tau, e))
            if mt.strain_energy is None:
                raise ValueError("the strain energy vanishes with the thickness or modulus")
            u = np.asarray(mt.strain_energy.energy(q), dtype=float)
            r = float(u0 @ u / (u0 @ u0))
            spread = max(spread, float(np.max(np.abs(u - r * u0)) / np.max(np.abs(u))))
            row.append(r)
        a = (row[1] - row[0]) / (E_PROBE - 1.0) if modulus else 0.0
        ratios.append([a, row[0] - a])
    coef, err = power_fit(fit_points(p), np.array(ratios), np.abs(np.array(ratios)).sum(axis=1, keepdims=True))
    worst = max(err, spread)
    worst = max(worst, etch.get("max_rel_error", 0.0))
    return {
        "law": "U x (pe A(tscale) + B(tscale)), A the modulus-proportional part, B the rest"
        + (" x R(etch)" if etch else ""),
        "a": [float(c) for c in coef[0]],
        "b": [float(c) for c in coef[1]],
        "max_rel_error": worst if worst > ROUND_OFF else 0.0,
    } | ({"etch": etch["ratio"]} if etch else {})


def energy_etch(s: Structure, m: Mechanics, run, p: Process, q: np.ndarray, u0: np.ndarray) -> dict:
    """The strain energy's etch ratio R(etch) = U(q; etch) / U(q) (a cubic in etch / 1 um, 1 at 0; the
    least-squares ratio over the sample points `q` at etch_points, the mechanics re-run on the etched
    structure) and its error: the cubic's residual and the spread of the ratio over the points (a mode
    shape that changes with the etch). A clamped-clamped beam's stretching E (w - 2 etch) t (int w'^2 /
    2)^2 / 2L: R = (w - 2 etch) / w, its modes (L fixed) unchanged: exact."""
    points, values, spread = etch_points(p), [], 0.0
    for e in points:
        me = m if e == 0.0 else run(etched(s, e))
        if me.strain_energy is None:
            raise ValueError("the strain energy vanishes with the etch bias")
        u = np.asarray(me.strain_energy.energy(q), dtype=float)
        r = float(u0 @ u / (u0 @ u0))
        spread = max(spread, float(np.max(np.abs(u - r * u0)) / np.max(np.abs(u))))
        values.append([r])
    coef, err = power_fit(tuple(e / ETCH_UNIT for e in points), np.array(values), np.array(values), nominal=0.0)
    worst = max(err, spread)
    return {"ratio": [float(c) for c in coef[0]], "max_rel_error": worst if worst > ROUND_OFF else 0.0}
