"""tscale and etch together on accelerometer_xyz's own field2d combs (netgen.model.process.cross_capacitance):
the product of the two capacitance laws, with and without the cross factor 1 + (tscale - 1) (u Q1(xs) + u^2
Q2(xs)) (netgen.model.etch_state.cross_laws), against the field solution at the corners of the (tscale,
etch) box and at points inside it (the extractor of the structure scaled and etched there, at 400 fresh
points of the fit box, seed 11: not the laws' check points), beside the stated errors; and the stated
errors of each law alone against the same fresh points (the check sets of netgen.model.process.check_sets).
With --rebuild also the model against full rebuilds at those points (100 points, +-0.15 of the range,
as tests/model/test_process_etch_field2d.py), and the build times. The figures docs/process.md and
CHANGELOG.md quote. The cross points' comb tables ship (bench/comb_tables.py); run under `nice -n 10`:
    .venv/bin/python bench/process_cross.py [--rebuild]
"""

from __future__ import annotations

import argparse
import copy
import time

import numpy as np
from support import process_cases

from netgen.build import build_model
from netgen.model.process import capacitance_at, etched, scaled
from netgen.structure import parse_structure

CORNERS = ((0.9, -1e-7), (0.9, 1e-7), (1.1, -1e-7), (1.1, 1e-7))
INSIDE = ((0.95, 0.04e-6), (1.05, -0.05e-6))  # held out of the cross fit, whose points are the corners
FRESH = 400
# the rebuilds whose finger cells ship (tests/model/test_process_cross_field2d.py's): a rewritten file's
# cell parses a few ulps off the scaled and etched structure's, so each rebuild is a cell and two tables
# of its own (minutes of solves)
REBUILDS = ((0.9, -1e-7), (1.05, -0.05e-6))


def text(params: str, tscale: float = 1.0, etch: float = 0.0) -> str:
    """accelerometer_xyz (field2d combs) drawn with `params` declared, or rewritten at (tscale, etch)."""
    body = process_cases.xyz_text(etch, f"[process]\nparameters = {params}\n" if params else "")
    body = body.replace('comb_model = "textbook"', 'comb_model = "field2d"')
    return body.replace('thickness = "2 um"', f'thickness = "{2.0 * tscale!r} um"')


def held_out(model, s, points) -> list[float]:
    """max |law / extractor - 1| over the combs and FRESH fresh points at each (tscale, etch) point."""
    extract = process_cases.fresh_extractor(s, model.scales)
    drawn = process_cases.Drawn(model, s, extract)
    xs = process_cases.fresh_points(s.sampling, FRESH, len(model.coordinates), 11)
    out = []
    for t, e in points:
        with np.errstate(divide="ignore", invalid="ignore"):
            r = capacitance_at(drawn, xs, etch=e, tscale=t) / extract(etched(scaled(s, t), e), xs) - 1.0
        out.append(float(np.max(np.abs(r[np.isfinite(r)]))))
    return out


def crossless(model):
    """The model without its cross factors (the plain product of the two laws)."""
    other = copy.deepcopy(model)
    for r in other.process["etch"]["capacitance"]:
        r.pop("cross", None)
    return other


def main() -> None:
    """Print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rebuild", action="store_true", help="also full rebuilds at the points (minutes)")
    a = ap.parse_args()
    builds = {}
    for params in ('["etch"]', '["tscale"]', '["tscale", "etch"]'):
        t0 = time.process_time()
        s = parse_structure(text(params), "xyz.toml")
        builds[params] = (s, build_model(s), time.process_time() - t0)
        print(f"build with {params}: {builds[params][2]:.1f} s CPU")
    s, model, _ = builds['["etch"]']
    e = model.process["etch"]
    got = held_out(model, s, [(1.0, x) for x in (-1e-7, -0.5e-7, 0.04e-6, 0.5e-7, 1e-7)])
    print(f"etch alone: stated {e['capacitance_max_rel_error']:.2e}; held out at -0.1/-0.05/0.04/0.05/0.1 um", got)
    s, model, _ = builds['["tscale"]']
    t = model.process["tscale"]
    got = held_out(model, s, [(x, 0.0) for x in (0.9, 0.95, 1.05, 1.1)])
    print(f"tscale alone: stated {t['capacitance_max_rel_error']:.2e}; held out at 0.9/0.95/1.05/1.1", got)
    s, model, _ = builds['["tscale", "etch"]']
    e = model.process["etch"]
    print(
        f"tscale with etch: stated {e['capacitance_max_rel_error']:.2e} (plain product "
        f"{e['capacitance_product_max_rel_error']:.2e}, with the cross factor {e['capacitance_cross_max_rel_error']:.2e})"
    )
    plain, full = held_out(crossless(model), s, CORNERS + INSIDE), held_out(model, s, CORNERS + INSIDE)
    for p, x, y in zip(CORNERS + INSIDE, plain, full):
        print(
            f"  at tscale {p[0]}, etch {p[1] * 1e6:+.2f} um: held out, plain product {x:.2e}, with the cross factor {y:.2e}"
        )
    if not a.rebuild:
        return
    x = np.random.default_rng(5).uniform(-0.15, 0.15, (100, len(model.coordinates)))
    for p in REBUILDS:
        t0 = time.process_time()
        ref = build_model(parse_structure(text("", *p), "xyz.toml"))
        errs = max(f.max_rel_error for f in model.capacitances + ref.capacitances)
        want = ref.capacitance(x * model.scales / ref.scales)
        for label, m in (("plain", crossless(model)), ("cross", model)):
            got = capacitance_at(m, x, etch=p[1], tscale=p[0])
            print(
                f"  rebuild at {p}: {label} {float(np.max(np.abs(got / want - 1))):.2e} (the fits' "
                f"{errs:.2e}; bound 2 x fits + stated {2 * errs + e['capacitance_max_rel_error']:.2e}; "
                f"{time.process_time() - t0:.0f} s CPU)"
            )


if __name__ == "__main__":
    main()
