"""The FMU's process parameters against the closed forms and ngspice (tests/emit/test_fmu_process.py,
tests/oracles/fmu_process.py): the figures quoted in docs/embedding.md and CHANGELOG.md. Run from the
repository root:
    .venv/bin/python bench/fmu_process.py
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from support import oracle


def main() -> None:
    """Print per case the FMU's deviations from the closed form and from ngspice."""
    fp = oracle("fmu_process")
    with tempfile.TemporaryDirectory(prefix="fmu-process-") as tmp:
        folder = Path(tmp)
        model, lib, path = fp.build(folder)
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


if __name__ == "__main__":
    main()
