"""The lateral etch bias's laws (netgen.model.process.etch_laws, capacitance_laws) against closed forms,
re-runs and full rebuilds: the figures quoted in docs/process.md and CHANGELOG.md. Run from the
repository root:
    .venv/bin/python bench/process_etch.py              (flexures, outline and holes, textbook combs)
    .venv/bin/python bench/process_etch.py --field2d    (also accelerometer_xyz's field2d combs: the
        2-D finger cell solved at four more finger widths, minutes of CPU the first time, then cached)
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from support import process_cases

from netgen.build import build_model
from netgen.core.constants import EPS0
from netgen.mechanics import mechanics
from netgen.model.process import capacitance_at, coordinate_values, process_laws
from netgen.structure import parse_structure

# the cases of tests/model/test_process_etch.py (tests/oracles/process_cases.py)
ETCHES, RANGE = process_cases.ETCHES, process_cases.RANGE
guided, proof_text, rerun = process_cases.guided, process_cases.proof_text, process_cases.rerun
PROCESS = '[process]\nparameters = ["etch"]\n'


def against_rebuilds(label: str, nominal, rebuild) -> None:
    """The etch laws of `nominal` against full rebuilds (rebuild(etch) -> MacroModel) at
    process_cases.PERFORATED_ETCHES: modal frequencies and capacitances at 100 points of the box (the
    same physical displacements), with the stated errors."""
    law = nominal.process["etch"]
    print(
        f"{label}: stated etch errors: mechanics {law['max_rel_error']:.2e}, capacitance "
        f"{law['capacitance_max_rel_error']:.2e}; fit errors up to {max(f.max_rel_error for f in nominal.capacitances):.2e}"
        + (
            f"; capacitance without the combs' state factors {law['capacitance_stateless_max_rel_error']:.2e}"
            if "capacitance_stateless_max_rel_error" in law
            else ""
        )
    )
    x = np.random.default_rng(5).uniform(-0.15, 0.15, (100, nominal.ncoords))
    worst_f = worst_c = 0.0
    for etch in process_cases.PERFORATED_ETCHES:
        model = rebuild(etch)
        for v, ref in enumerate(model.coordinates):
            m, k, _ = coordinate_values(nominal.process, v, etch=etch)
            worst_f = max(worst_f, abs(math.sqrt(k / m) / math.sqrt(ref.stiffness / ref.mass) - 1))
        ref_c = model.capacitance(x * nominal.scales / model.scales)
        worst_c = max(worst_c, float(np.max(np.abs(capacitance_at(nominal, x, etch) / ref_c - 1))))
    print(
        f"  against rebuilds at etch {process_cases.PERFORATED_ETCHES}: frequencies {worst_f:.2e}, C at 100 points {worst_c:.2e}"
    )


def kink(xyz) -> None:
    """accelerometer_xyz's stiffness and modal frequencies from the law against the mechanics re-run at
    etches straddling its torsion knot at 0 (2 um legs on its 2 um layer, netgen.model.etch_knots)."""
    worst_k = worst_f = 0.0
    for etch in (-0.1e-6, -0.02e-6, -0.005e-6, -0.001e-6, 0.001e-6, 0.005e-6, 0.02e-6, 0.04e-6, 0.1e-6):
        ref = mechanics(parse_structure(process_cases.xyz_text(etch), "xyz.toml"))
        for v in range(xyz.ncoords):
            m, k, _ = coordinate_values(xyz.process, v, etch=etch)
            worst_k = max(worst_k, abs(k / ref.stiffnesses[v] - 1))
            worst_f = max(worst_f, abs(math.sqrt(k / m * ref.masses[v] / ref.stiffnesses[v]) - 1))
    print(
        f"  knots {xyz.process['etch'].get('knots', [])} um; law against re-runs at etch -0.1 .. 0.1 um straddling "
        f"the knot (down to +-1 nm): stiffness {worst_k:.2e}, frequencies {worst_f:.2e}"
    )


def outline_and_combs(field2d: bool) -> None:
    """The perforated crab-leg mass (3 um legs) and accelerometer_xyz (textbook combs; with `field2d`
    its own 2-D finger cell) against rebuilds, and the textbook comb against its closed form."""
    t0 = time.process_time()
    px = build_model(parse_structure(process_cases.perforated(process=PROCESS), "px.toml"))
    print(f"perforated crab-leg mass build with etch: {time.process_time() - t0:.1f} s CPU")
    against_rebuilds(
        "perforated crab-leg mass", px, lambda e: build_model(parse_structure(process_cases.perforated(e), "px.toml"))
    )
    xyz = build_model(parse_structure(process_cases.xyz_text(process=PROCESS), "xyz.toml"))
    against_rebuilds(
        "accelerometer_xyz, textbook combs",
        xyz,
        lambda e: build_model(parse_structure(process_cases.xyz_text(e), "xyz.toml")),
    )
    kink(xyz)
    k = [f.electrode for f in xyz.capacitances].index("xp_t")
    worst = max(
        abs(
            capacitance_at(xyz, np.zeros((1, xyz.ncoords)), e)[0, k]
            / (20 * EPS0 * 2e-6 * (30e-6 - 2 * e) / (1.5e-6 + 2 * e))
            - 1
        )
        for e in process_cases.PERFORATED_ETCHES
    )
    print(f"  comb xp_t at rest against 20 eps t (L0 - 2 etch) / (g + 2 etch): {worst:.2e}")
    if field2d:
        t0 = time.process_time()
        real = lambda text: text.replace('comb_model = "textbook"', 'comb_model = "field2d"')  # noqa: E731
        f2 = build_model(parse_structure(real(process_cases.xyz_text(process=PROCESS)), "xyz.toml"))
        print(f"accelerometer_xyz, field2d combs, build with etch: {time.process_time() - t0:.1f} s CPU")
        against_rebuilds(
            "accelerometer_xyz, field2d combs",
            f2,
            lambda e: build_model(parse_structure(real(process_cases.xyz_text(e)), "xyz.toml")),
        )


def main() -> None:
    """Print the largest deviations of the etch laws from the closed forms and the re-runs."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--field2d", action="store_true", help="also accelerometer_xyz's field2d combs (slow once)")
    args = parser.parse_args()
    text = guided(process='[process]\nparameters = ["etch"]' + RANGE).replace(
        'rigid = ["z"]', 'rigid = ["z", "x", "y"]'
    )
    s = parse_structure(text, "cg.toml")
    m = mechanics(s)
    law = process_laws(s, m, mechanics, [], 0.0, 0.3)
    worst = 0.0
    for etch in ETCHES:
        ratio = 1.0 - etch * 1e6  # (w - 2 e) / w at w = 2 um
        for name, power in (("x", 3), ("y", 1), ("z", 1)):
            v = list(m.names).index(name)
            worst = max(worst, abs(coordinate_values(law, v, etch=etch)[1] / m.stiffnesses[v] / ratio**power - 1))
    print(f"clamped-guided k_x ~ w^3, k_y, k_z ~ w: largest |law / closed form - 1| = {worst:.2e}")
    t0 = time.process_time()
    folded = build_model(parse_structure(proof_text(params='["tscale", "etch"]'), "pm.toml"))
    print(f"folded proof mass (tscale, etch) build: {time.process_time() - t0:.1f} s CPU")
    err = folded.process["etch"]["max_rel_error"]
    print(f"stated etch error (fit residuals and the (tscale, etch) corners): {err:.2e}")
    worst_f = 0.0
    for etch in ETCHES:
        for v, (mass, k) in enumerate(rerun(10.0, etch)):
            mm, kk, _ = coordinate_values(folded.process, v, etch=etch)
            worst_f = max(worst_f, abs(math.sqrt(kk / mm) / math.sqrt(k / mass) - 1))
    print(f"folded modal frequencies, law against re-run at etch {ETCHES}: largest deviation {worst_f:.2e}")
    worst_c = 0.0
    for tau in (0.9, 1.1):
        for etch in (-0.2e-6, 0.3e-6):
            for v, (_, k) in enumerate(rerun(10.0 * tau, etch)):
                worst_c = max(worst_c, abs(coordinate_values(folded.process, v, tscale=tau, etch=etch)[1] / k - 1))
    print(f"folded stiffness at the (tscale, etch) corners: largest deviation {worst_c:.2e}")
    outline_and_combs(args.field2d)


if __name__ == "__main__":
    main()
