"""The process parameters against full rebuilds on the committed examples at full size: the
cantilever's pull-in (examples/cantilever.toml with tscale, escale, temp) and the levitated disk's
gravity balance voltage (examples/levitated_disk.toml as it is: three rigid coordinates, four
plate modes, its 2e-3 fits; with [process] parameters dg and tscale), each at the ends of the
parameters' ranges, with the build and rebuild times. tests/model/test_process_pull_in.py runs the
same readings on the cantilever and on a z-only disk.

    OMP_NUM_THREADS=1 .venv/bin/python bench/process_pull_in.py [--skip-disk]
"""

from __future__ import annotations

import argparse
import time

import support

from netgen.build import build
from netgen.model.process import coordinate_values
from netgen.structure import parse_structure

ob = support.oracle("process_balance")
TC = -60e-6
T0_C = 26.85
CANTILEVER_PROCESS = f"""
[process]
parameters = ["tscale", "escale", "temp"]
temp_range = [-40, 125]
modulus_tc = {TC}
"""


def cantilever(t: float = 2.0, e: float = 169.0, process: bool = True):
    text = (support.ROOT / "examples/cantilever.toml").read_text()
    text = text.replace('thickness = "2 um"', f'thickness = "{t!r} um"')
    text = text.replace('youngs_modulus = "169 GPa"', f'youngs_modulus = "{e!r} GPa"')
    return build(parse_structure(text + (CANTILEVER_PROCESS if process else ""), "cantilever.toml")).model


def disk(t: float = 10.0, top_gap: float = 3.0, process: bool = True):
    text = (support.ROOT / "examples/levitated_disk.toml").read_text()
    text = text.replace('thickness = "10 um"', f'thickness = "{t!r} um"')
    top = 'name = "top"\nside = "above"\ngap = "3 um"'
    assert top in text, "examples/levitated_disk.toml changed: update bench/process_pull_in.py"
    text = text.replace(top, top.replace("3 um", f"{top_gap!r} um"))
    process_table = '\n[process]\nparameters = ["dg", "tscale"]\n' if process else ""
    return build(parse_structure(text + process_table, "levitated_disk.toml"))


def timed(f, *args, **kw):
    t0, c0 = time.perf_counter(), time.process_time()
    out = f(*args, **kw)
    return out, time.perf_counter() - t0, time.process_time() - c0


def run_cantilever() -> None:
    nominal, wall, cpu = timed(cantilever)
    print(f"cantilever [process] build {wall:.1f} s wall, {cpu:.1f} s CPU")
    for name, value in ob.CASES:
        key = "temp_c" if name == "temp" else name
        k = [coordinate_values(nominal.process, v, **{key: value})[1] for v in range(nominal.ncoords)]
        v_law = ob.pull_in(nominal, k)
        t = 2.0 * (value if name == "tscale" else 1.0)
        e = 169.0 * (value if name == "escale" else 1.0) * (1 + TC * (value - T0_C) if name == "temp" else 1.0)
        rebuilt, wall, cpu = timed(cantilever, t, e, False)
        v_reb = ob.pull_in(rebuilt, [c.stiffness for c in rebuilt.coordinates])
        print(
            f"  {name}={value:g}: pull-in {v_law:.8g} V, rebuild {v_reb:.8g} V, {v_law / v_reb - 1:+.1e} (rebuild {wall:.1f} s)"
        )


def run_disk() -> None:
    nominal, wall, cpu = timed(disk)
    law = nominal.model.process
    print(f"levitated disk [process] dg, tscale build {wall:.1f} s wall, {cpu:.1f} s CPU")
    errors = [f.max_rel_error for f in nominal.model.capacitances]
    print(f"  fits' held-out errors up to {max(errors):.1e}")
    for tscale, dg_nm in [(0.9, 0.0), (1.1, 0.0), (1.0, -150.0), (1.0, 150.0)]:
        dg = dg_nm * 1e-9
        v = [c.name for c in nominal.model.coordinates].index("z")
        v_law = ob.balance_voltage(ob.top_slope(nominal, -dg), coordinate_values(law, v, tscale=tscale)[0])
        rebuilt, wall, cpu = timed(disk, 10.0 * tscale, 3.0 + dg_nm * 1e-3, False)
        v_reb = ob.balance_voltage(ob.top_slope(rebuilt, 0.0), rebuilt.model.coordinates[v].mass)
        field = ob.top_slope(nominal, -dg, False) / ob.top_slope(rebuilt, 0.0, False) - 1
        print(
            f"  tscale={tscale:g} dg_top={dg_nm:g} nm: balance {v_law:.8g} V, rebuild {v_reb:.8g} V, "
            f"{v_law / v_reb - 1:+.1e} (field solution's slopes {field:+.1e}; rebuild {wall:.1f} s wall, {cpu:.1f} s CPU)"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip-disk", action="store_true", help="the cantilever only (the disk's builds take minutes)")
    args = ap.parse_args()
    run_cantilever()
    if not args.skip_disk:
        run_disk()
    print("(balance voltages: all top electrodes at V, the disk and the bottom electrodes at 0)")


if __name__ == "__main__":
    main()
