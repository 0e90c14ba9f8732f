"""Damping per coordinate: Q or damping ratio of the eigenmodes, Rayleigh alpha M + beta K, and
the squeeze film of both gaps (netgen.mechanics.squeeze_film), incompressible or as Maxwell
branches of the compressible film. Diagonal in the mass-orthogonal basis; the report says what
is dropped and where the model is valid."""

from __future__ import annotations

import math

import numpy as np

from ..core.constants import GASES
from ..core.errors import StructureError
from ..structure import Structure
from . import squeeze_film as sf
from .base import Mechanics


def damping(s: Structure, m: Mechanics) -> tuple[np.ndarray, dict]:
    """Damping per coordinate (SI) and its report: Q / damping ratio (a per-coordinate entry
    overrides the eigenmode default), plus Rayleigh alpha M + beta K, plus squeeze film."""
    n = len(m.names)
    d = s.damping
    if d is None:
        return np.zeros(n), {}
    omega = 2 * np.pi * m.frequencies
    out = d.rayleigh_alpha * m.masses + d.rayleigh_beta * m.stiffnesses
    zeta = _modal_ratios(s, m.names, m.kinds)
    out = out + 2.0 * zeta * m.masses * omega
    film = squeeze_film_damping(s, m) if d.squeeze_film else {}
    if film:
        out = out + film["diagonal"]
    report = _damping_report(s, out, film)
    if film.get("branches"):
        report["branches"] = film["branches"]  # popped by netgen.build.assemble into Coordinate.film
    return out, report


def _modal_ratios(s: Structure, names: list[str], kinds: list[str]) -> np.ndarray:
    """Damping ratio zeta per coordinate from q_factor / damping_ratio entries (0 if none)."""
    d = s.damping
    ratios = {k: 1 / (2 * v) for k, v in d.q_factor} | dict(d.damping_ratio)  # Q = 1 / (2 zeta)
    default = ratios.pop("*", 0.0)
    given = ratios
    unknown = sorted(set(given) - set(names))
    if unknown:
        raise StructureError(
            s.source,
            "damping",
            f"damping given for unknown coordinate(s) {unknown}",
            f"use the coordinate names {names} (modes = <count> names them only after the FEM)",
        )
    return np.array([given.get(nm, default if kind == "mode" else 0.0) for nm, kind in zip(names, kinds)])


def squeeze_film_damping(s: Structure, m: Mechanics) -> dict:
    """Reynolds squeeze-film damping of both sides' gaps (the plate disk, p = 0 at its rim)."""
    d, c = s.damping, s.conductor
    gas = GASES[d.gas]
    gaps = {}
    for e in s.electrode_sets:
        if getattr(e, "side", None) in ("above", "below"):  # comb fingers have no film of their own
            air = e.gap - getattr(e, "dielectric_thickness", 0.0)  # the film ends at a layer's surface
            gaps[e.side] = min(air, gaps.get(e.side, math.inf))
    if c.outline_shape == "disk":
        radius = c.radius
        mesh = sf.disk_mesh(radius, d.fem_refine)
        reynolds = {gap: sf.reynolds_matrix(mesh, m.basis) for gap in set(gaps.values())}  # shared by all gaps
    else:  # a proof mass: its rectangle, with its holes
        radius = min(c.length, c.width) / 2
        mesh = sf.centred_rectangle_mesh(c.length, c.width, 2**d.fem_refine)
        reynolds = {
            gap: sf.reynolds_matrix(
                mesh, m.basis, sf.perforation_leak(gap, c.thickness, c.hole, c.hole_pitch) if c.hole else 0.0
            )
            for gap in set(gaps.values())
        }
    total, sides = np.zeros((len(m.names), len(m.names))), {}
    for side, gap in sorted(gaps.items()):
        mu = sf.effective_viscosity(gas, d.pressure, gap)
        side_b = 12.0 * mu / gap**3 * reynolds[gap]
        total += side_b
        sigma = [sf.squeeze_number(mu, 2 * np.pi * f, radius, d.pressure, gap) for f in m.frequencies]
        sides[side] = {
            "gap_m": gap,
            "knudsen": sf.knudsen(gas, d.pressure, gap),
            "mu_eff_Pa_s": mu,
            "diagonal": [float(v) for v in np.diag(side_b)],  # this side's part (incompressible)
            "squeeze_number_at_f0": [float(v) for v in sigma],
            "compressible_at_f0": _compressible_at_f0(mesh, m, gap, mu, d.pressure)
            if c.outline_shape == "disk"
            else "not computed for a perforated proof mass",
        }
    worst = max(v for side in sides.values() for v in side["squeeze_number_at_f0"])
    if d.film_model == "compressible":
        return compressible_film(s, m, mesh, gaps, total, sides)
    note = (
        "incompressible model valid (squeeze number < 1 at every modal frequency)"
        if worst < 1
        else f"squeeze number up to {worst:.3g} > 1: the film also stiffens and the incompressible "
        "damping overestimates the real one at those modes (compressible model not implemented)"
    )
    return {
        "diagonal": np.diag(total).copy(),
        "off_diagonal_ratio": sf.off_diagonal_ratio(total),
        "sides": sides,
        "validity": note,
    }


FILM_POLES = 60  # Dirichlet eigenpairs of the gap region behind the compressible network


def film_max_frequency(s: Structure, m: Mechanics) -> float:
    """Highest frequency (Hz) the compressible network must reproduce: the structure's
    film_max_frequency, else 1.5x the highest modal frequency (at least 100 kHz)."""
    given = s.damping.film_max_frequency
    return given if given > 0 else max(1.5 * float(np.max(m.frequencies, initial=0.0)), 1e5)


def compressible_film(s: Structure, m: Mechanics, mesh, gaps: dict, total: np.ndarray, sides: dict) -> dict:
    """Compressible squeeze film: per coordinate the exact pole-residue expansion of both gaps,
    reduced to the fewest Maxwell branches (damper in series with a gas spring) that match it
    within 1 % up to film_max_frequency; the dropped fast poles join the plain damper."""
    d = s.damping
    gas = GASES[d.gas]
    solved = {
        gap: sf.pole_residues(mesh, m.basis, gap, sf.effective_viscosity(gas, d.pressure, gap), d.pressure, FILM_POLES)
        for gap in sorted(set(gaps.values()))
    }  # equal gaps: one solve
    per_side = [solved[gap] for _, gap in sorted(gaps.items())]
    omega_max = 2 * np.pi * film_max_frequency(s, m)
    # with gap offsets declared each branch stays one side's (a merged pole split, netgen.model.process_film)
    split = s.process is not None and s.process.wants("dg")
    remainders, branches, errors, owners = [], [], [], []
    for k in range(len(m.names)):
        full = sf.combine([side[k] for side in per_side])
        reduced, err = sf.maxwell_network(full, omega_max)
        remainders.append(reduced.remainder)
        rows = side_branches(reduced, sorted(gaps), split)
        branches.append(tuple((r, w) for r, w, _ in rows))
        owners.append(
            {"branch": [o for _, _, o in rows], "remainder": dict(zip(sorted(gaps), reduced.remainder_parts))}
        )
        errors.append(err)
    note = (
        f"compressible film: Maxwell branches (damper r in series with a gas spring r*omega_p) per "
        f"coordinate, within {max(errors):.2%} of the {FILM_POLES}-pole expansion up to "
        f"{omega_max / (2 * np.pi):.4g} Hz"
    )
    return {
        "diagonal": np.array(remainders),
        "off_diagonal_ratio": sf.off_diagonal_ratio(total),
        "sides": sides,
        "validity": note,
        "branches": branches,
        "owners": owners,  # per coordinate each branch's side and each side's remainder (not reported)
        "network": {
            "max_frequency_hz": omega_max / (2 * np.pi),
            "poles_solved": FILM_POLES,
            "max_rel_error": errors,
            "branches": [[{"damping": r, "corner_hz": w / (2 * np.pi)} for r, w in b] for b in branches],
        },
    }


def side_branches(reduced: sf.PoleResidue, sides: list[str], split: bool) -> list[tuple[float, float, str | None]]:
    """(residue, pole, side) per Maxwell branch: the side whose film alone makes it, else None; with
    `split` a pole both sides share (equal gaps) becomes one branch per side, the same pole, each its
    side's residue (the same admittance)."""
    rows: list[tuple[float, float, str | None]] = []
    for i, (r, w) in enumerate(zip(reduced.residues, reduced.poles)):
        parts = reduced.parts[i] if reduced.parts is not None else np.array([r])
        own = [(sides[t], float(p)) for t, p in enumerate(parts) if p != 0.0]
        if split and len(own) > 1:
            rows += [(p, float(w), side) for side, p in own]
        else:
            rows.append((float(r), float(w), own[0][0] if len(own) == 1 else None))
    return rows


def _compressible_at_f0(mesh, m: Mechanics, gap: float, mu: float, pressure: float) -> dict:
    """Compressible-film damping b and gas-spring stiffness k of each mode at its own frequency
    (complex Reynolds solve; informational, the model keeps the incompressible b)."""
    b, k = [], []
    for v, f in enumerate(m.frequencies):
        y = sf.compressible_admittance(mesh, m.basis, v, gap, mu, pressure, 2 * np.pi * f) if f > 0 else None
        b.append(float(y.real) if y is not None else None)
        k.append(float(-2 * np.pi * f * y.imag) if y is not None else None)
    return {"damping_N_s_per_m": b, "spring_N_per_m": k}


def _damping_report(s: Structure, out: np.ndarray, film: dict) -> dict:
    """What the damping stage did, for the JSON report and the emitters (noise switch)."""
    d = s.damping
    rep = {"temperature_K": d.temperature, "noise": d.noise, "per_coordinate": [float(v) for v in out]}
    if film:
        rep["squeeze_film"] = {
            "gas": d.gas,
            "pressure_Pa": d.pressure,
            "fem_refine": d.fem_refine,
            "diagonal": [float(v) for v in film["diagonal"]],
            "off_diagonal_ratio": film["off_diagonal_ratio"],
            "sides": film["sides"],
            "validity": film["validity"],
            **({"network": film["network"]} if "network" in film else {}),
            "model": "incompressible linearised Reynolds, Veijola mu_eff, p = 0 at the plate rim",
        }
    return rep
