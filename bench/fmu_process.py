"""The FMU's process parameters against the closed forms and ngspice (tests/emit/test_fmu_process.py,
tests/oracles/fmu_process.py): the figures quoted in docs/embedding.md and CHANGELOG.md. Run from the
repository root:
    .venv/bin/python bench/fmu_process.py          # all tables
    .venv/bin/python bench/fmu_process.py --etch   # the etch's capacitance law only
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
from support import oracle


def main() -> None:
    """Print per case the FMU's deviations from the closed form and from ngspice."""
    fp = oracle("fmu_process")
    with tempfile.TemporaryDirectory(prefix="fmu-process-") as tmp:
        folder = Path(tmp)
        model, lib, path = fp.build(folder)
        if "--etch" in sys.argv[1:]:
            etch_tables(fp, folder, model, lib, path)
            return
        print(f"ngspice budget {fp.ngspice_budget(model):.2e} of the peak (its first {fp.NG_STOP * 1e6:g} us)")
        print("load case            zeta   f/kHz   FMU-closed  integ     static    FMU-ngspice  FMU-.op")
        cases = [(n, v, "f_z") for n, vals in fp.VALUES.items() for v in vals]
        for name, v, load in cases + [("tscale", v, "a_in") for v in fp.VALUES["tscale"]]:
            r = fp.step_case(model, lib, path, name, v, folder, load=load)
            print(
                f"{load} {name}={v:<9g} {r['zeta']:.3f} {r['f_hz'] / 1e3:7.3f} {r['err']:.2e}    {r['integ']:.2e}  "
                f"{r['static']:.2e}  {r['ngspice']:.2e}     {r['op']:.2e}"
            )
        print("case            z/nm      z-closed  charge-closed  integ(z)  FMU-ngspice  FMU-.op")
        for dg in fp.DG:
            r = fp.gap_case(model, lib, path, dg, folder)
            print(
                f"dg_bot={dg:<9g} {r['z_m'] * 1e9:8.3f}  {r['z']:.2e}  {r['q']:.2e}       {r['z_integ']:.2e}  "
                f"{r['ngspice']:.2e}     {r['op']:.2e}"
            )

        fm, flib, fpath = fp.film_build(folder)
        misfit = fm.process["temp"]["viscosity"]["max_rel_error"]
        print(f"squeeze film: nominal b {fm.coordinates[0].damping:.4e} N s/m, stated viscosity misfit {misfit:.2e}")
        print("temp/C   b/(N s/m)    b/b0 - law  ngspice .ac - FMU")
        for t in fp.FILM_TEMPS:
            r = fp.film_case(fm, flib, fpath, t, folder)
            print(f"{t:6g}   {r['b']:.6e}  {r['ratio']:.2e}    {r['ngspice']:.2e}")
        etch_tables(fp, folder, model, lib, path)


def etch_tables(fp, folder: Path, model, lib, path) -> None:
    """The etch's capacitance law: the guided plate's ratio (closed form, .op) and accelerometer_xyz's
    comb shift (static balance against ngspice's .op, charge against the model's law)."""
    from netgen.model.process import capacitance_at

    print("plate etch/nm   z-closed  charge-closed  integ(z)  FMU-.op")
    for etch in fp.ETCH_CAPS:
        r = fp.etch_case(model, lib, path, etch, folder)
        print(f"{etch * 1e9:8g}        {r['z']:.2e}  {r['q']:.2e}       {r['z_integ']:.2e}  {r['op']:.2e}")
    xyz, xlib, xpath = fp.comb_build(folder)
    scale = np.array([c.scale for c in xyz.coordinates])
    k = [f.electrode for f in xyz.capacitances].index(fp.COMB)
    print(f"comb {fp.COMB} at {fp.COMB_VOLTS:g} V: etch/nm  x/nm    rot_z/urad  FMU-.op   cond(J)  charge-law")
    for etch in fp.ETCH_CAPS:
        q, charge, cond = fp.comb_balance(xyz, xpath, etch)
        op = fp.comb_op(xyz, xlib, etch, folder)
        err = float(np.max(np.abs(q - op) / scale) / np.max(np.abs(q) / scale))
        ref = capacitance_at(xyz, (q / scale)[None, :], etch)[0, k] * fp.COMB_VOLTS
        print(
            f"{'':22}{etch * 1e9:8g}  {q[0] * 1e9:6.3f}  {q[2] * 1e6:9.3f}  {err:.2e}  {cond:.3f}    "
            f"{abs(charge / ref - 1):.2e}"
        )
    print("comb stop: etch/nm  q''/x off the springs' 20 nm before / after the etched gap 1.5 um + 2 etch")
    for etch in fp.ETCH_CAPS:
        before, after = fp.comb_stop_onset(xyz, xpath, etch, 1.5e-6, 20e-9)
        print(f"{'':11}{etch * 1e9:8g}  {before:.2e} / {after:.3f}")


if __name__ == "__main__":
    main()
