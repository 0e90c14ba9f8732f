"""The etch on beam conductors (netgen.model.process.etched_beam): the figures quoted in docs/process.md
and CHANGELOG.md. The cantilever and clamped-clamped beam of tests/oracles/beam_etch (the electrode
past the beam) against Euler-Bernoulli and full rebuilds, and examples/cantilever.toml as drawn (its
electrode is the beam's own outline, so an under-etched beam overhangs it: a kink at etch 0 that the
cubic ratio missed; now a knot there and a state factor for the overhanging tip, also read against
the field solution on the etched structure, since the rebuild's own fit is the looser one there).
Run from the repository root:
    .venv/bin/python bench/process_etch_beams.py
"""

from __future__ import annotations

import math
import time

import numpy as np
from support import beam_etch, process_balance

from netgen.build import build_model, electrodes, extractor, mechanics, plate_outline
from netgen.model.process import capacitance_at, coordinate_values
from netgen.structure import parse_structure

ETCHES, PROCESS, drawn_text = beam_etch.ETCHES, beam_etch.PROCESS, beam_etch.drawn_text


def report(label: str, model, rebuild, name: str | None) -> None:
    """Frequencies, modal mass and stiffness against Euler-Bernoulli (name: a beam_etch case), the
    capacitances at 100 points and the cantilever's pull-in against the rebuilds."""
    law = model.process["etch"]
    print(
        f"{label}: stated mechanics {law['max_rel_error']:.1e}, capacitance {law['capacitance_max_rel_error']:.1e}, "
        f"fits {model.capacitances[0].max_rel_error:.1e}"
    )
    box = np.array(
        [model.sampling.get("coordinate_range", {}).get(c.name, model.sampling["range"]) for c in model.coordinates]
    )
    x = np.random.default_rng(3).uniform(-1.0, 1.0, (100, model.ncoords)) * box
    for e in ETCHES:
        ref = rebuild(e)
        laws = [coordinate_values(model.process, v, etch=e) for v in range(model.ncoords)]
        f = [math.sqrt(k / m) / (2 * math.pi) for m, k, _ in laws]
        line = f"  etch {e * 1e6:+.1f} um: f vs rebuild {max(abs(a / c.frequency_hz - 1) for a, c in zip(f, ref.coordinates)):.1e}"
        if name:
            rm, rk, rf = beam_etch.modal_ratios(name, e)
            dm = max(abs(m / c.mass / rm - 1) for (m, _, _), c in zip(laws, model.coordinates))
            dk = max(abs(k / c.stiffness / rk - 1) for (_, k, _), c in zip(laws, model.coordinates))
            df = max(abs(a / c.frequency_hz / rf - 1) for a, c in zip(f, model.coordinates))
            line += f", vs Euler-Bernoulli m {dm:.1e} k {dk:.1e} f {df:.1e} (f ratio {rf:.6f})"
        dc = np.max(np.abs(capacitance_at(model, x, e) / ref.capacitance(x) - 1))
        zero = np.zeros((1, model.ncoords))
        rest = capacitance_at(model, zero, e)[0, 0] / ref.capacitance(zero)[0, 0]
        line += f"; C at 100 points vs rebuild {dc:.1e} (its fit states {ref.capacitances[0].max_rel_error:.1e}"
        line += f"; at rest {rest - 1:+.1e}: the ratio)"
        if name is None:  # the law against the extractor re-run on the etched structure (not a fit)
            s = parse_structure(drawn_text(e, process=""), "cantilever.toml")
            plate = plate_outline(s)
            field = extractor(s, plate).prepare(electrodes(s), plate, mechanics(s).basis).capacitance(x * model.scales)
            law_x = capacitance_at(model, x, e)[:, 0]
            line += f"; vs the field solution: law {np.max(np.abs(law_x / np.asarray(field)[:, 0] - 1)):.1e}"
            line += f", rebuild's fit {np.max(np.abs(ref.capacitance(x)[:, 0] / np.asarray(field)[:, 0] - 1)):.1e}"
        if model.name == "cantilever":
            k = [m[1] for m in laws]
            v_law = process_balance.pull_in(process_balance.LawAt(model, e), k)
            v_ref = process_balance.pull_in(ref, [c.stiffness for c in ref.coordinates])
            line += f"; pull-in {v_law:.5f} V vs {v_ref:.5f} V ({v_law / v_ref - 1:+.1e})"
        print(line)


def built(text: str, name: str):
    """The MacroModel of a structure text."""
    return build_model(parse_structure(text, f"{name}.toml"))


def main() -> None:
    t0 = time.time()
    for name in ("cantilever", "cc_beam"):
        model = built(beam_etch.beam_text(name), name)
        report(
            f"{name} (electrode past the beam)",
            model,
            lambda e, n=name: built(beam_etch.beam_text(n, e, process=""), n),
            name,
        )
    model = built(drawn_text(), "cantilever")
    label = "examples/cantilever.toml as drawn (electrode = the beam's outline)"
    report(label, model, lambda e: built(drawn_text(e, process=""), "cantilever"), None)
    print(f"{time.time() - t0:.0f} s")


if __name__ == "__main__":
    main()
