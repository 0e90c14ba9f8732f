"""The lateral etch bias's laws (netgen.model.process.etch_laws) against closed forms and re-runs: the
figures quoted in docs/process.md and CHANGELOG.md. Run from the repository root:
    .venv/bin/python bench/process_etch.py
"""

from __future__ import annotations

import math
import time

from support import process_cases

from netgen.build import build_model
from netgen.mechanics import mechanics
from netgen.model.process import coordinate_values, process_laws
from netgen.structure import parse_structure

# the cases of tests/model/test_process_etch.py (tests/oracles/process_cases.py)
ETCHES, RANGE = process_cases.ETCHES, process_cases.RANGE
guided, proof_text, rerun = process_cases.guided, process_cases.proof_text, process_cases.rerun


def main() -> None:
    """Print the largest deviations of the etch laws from the closed forms and the re-runs."""
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


if __name__ == "__main__":
    main()
