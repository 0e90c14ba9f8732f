"""How soon two copies of a chaotic sigma-delta loop part: the first period at which the numpy
reference loop (netgen.testbench.sigma_delta.reference) and the same loop with its force, readout
gain, stiffness and input each perturbed by eps * N(0, 1) (relative) decide differently, over
seeds. A circuit simulation is such a perturbed copy (its integration error, exact electrostatics,
switch transients; and on another CPU, another step placement), so the tests that compare a
circuit's bits with the reference's over "the first N periods" take N from the low quantile of
this distribution at the circuit's mismatch, not from one machine's first difference.

    .venv/bin/python bench/first_difference.py [SEEDS]

prints, per loop of the tests (tests/testbench/test_sd_orders_loop.py, test_loop_orders.py,
test_sd_orders_behavioural.py) and per eps, the first difference's 1 % and 5 % quantiles and median.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from netgen.build import build_model
from netgen.model import MacroModel
from netgen.structure import load_structure
from netgen.testbench import sigma_delta as sd
from netgen.testbench.sigma_delta import filters, loopfile, reference

ROOT = Path(__file__).resolve().parents[1]
TS = 1e-6
CIFB = '[loop]\nchannels = ["z"]\n[loop.filter]\nkind = "{kind}"\norder = {order}\nosr = 64\n[loop.input]\nacceleration = 9.81\n'


def loops(tmp: Path) -> dict[str, tuple]:
    """(mech, filter, input, periods) of each test's loop."""
    out = {}
    disk = MacroModel.load_json(ROOT / "netlists" / "levitated_disk.json")
    d = sd.design(disk, TS)
    mech = filters.mechanics_of(disk, d, "z")
    out["disk cifb4 (test_sd_orders_loop)"] = (
        mech,
        filters.design(mech, 4, 64, 1.4, "cifb"),
        reference.Input(filters.dc_acceleration(disk, d, "z")),
        192,
    )
    acc = build_model(load_structure(ROOT / "examples" / "accelerometer_z.toml"), progress=False)
    for kind, order, step, periods, name in (
        ("cifb", 4, True, 400, "acc cifb4 step (test_loop_orders)"),
        ("cifb", 4, False, 120, "acc cifb4 ramps (test_sd_orders_behavioural)"),
        ("crfb", 5, False, 100, "acc crfb5 ramps (test_sd_orders_behavioural)"),
    ):
        p = tmp / "loop.toml"
        p.write_text(CIFB.format(kind=kind, order=order), encoding="utf-8")
        d = sd.design(acc, TS, spec=loopfile.read_loop_file(p), step=step)
        m = filters.mechanics_of(acc, d, "z")
        out[name] = (
            m,
            filters.Filter.from_dict(d.channels[0]["filter"]),
            reference.Input(filters.dc_acceleration(acc, d, "z")),
            periods,
        )
    return out


def first_differences(mech, f, inp, periods: int, eps: float, seeds: int) -> np.ndarray:
    """The first differing period of the perturbed copies against the unperturbed loop."""
    base = reference.simulate(mech, f, periods, inp)["v"]
    out = np.empty(seeds, dtype=int)
    for s in range(seeds):
        g = np.random.default_rng(s).standard_normal(4) * eps
        m = replace(
            mech, force=mech.force * (1 + g[0]), gain=mech.gain * (1 + g[1]), stiffness=mech.stiffness * (1 + g[2])
        )
        v = reference.simulate(m, f, periods, reference.Input(inp.dc * (1 + g[3])))["v"]
        same = v == base
        out[s] = periods if same.all() else int(np.argmin(same))
    return out


def main() -> None:
    import tempfile

    seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 200
    with tempfile.TemporaryDirectory() as tmp:
        for name, (mech, f, inp, periods) in loops(Path(tmp)).items():
            for eps in (1e-6, 1e-5, 1e-4, 1e-3, 1e-2):
                fd = first_differences(mech, f, inp, periods, eps, seeds)
                q1, q5, q50 = np.quantile(fd, [0.01, 0.05, 0.5])
                print(
                    f"{name:45s} eps {eps:.0e}: first difference 1 % {q1:5.0f}  5 % {q5:5.0f}  median {q50:5.0f}  min {fd.min()}"
                )


if __name__ == "__main__":
    main()
