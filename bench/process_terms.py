"""The figures of tests/emit/test_process_inertial.py and tests/emit/test_process_energy.py: the
Coriolis coupling of the tilts (.lib, FMU) and the stretching beam's static deflection (.lib, FMU
force residual) at tscale/escale against rebuilds, with the law and with it dropped (the model
before netgen.model.process_loads.inertial_law / energy_law). Run: .venv/bin/python bench/process_terms.py"""

from __future__ import annotations

import copy
import math
import tempfile
from pathlib import Path

import numpy as np
from support import oracle

from netgen.build import build_model
from netgen.emit import ngspice as emit_ngspice
from netgen.sim import fmu
from netgen.sim.ngspice import run_ngspice
from netgen.structure import parse_structure

te, ti = oracle("process_energy"), oracle("process_inertial")


def coriolis(model, refs, label: str) -> None:
    d = Path(tempfile.mkdtemp())
    (d / "gyp.lib").write_text(emit_ngspice.subcircuit(model))
    for t in ti.TSCALES:
        ref = refs[t]
        got = complex(run_ngspice(ti.netlist(str(d / "gyp.lib"), t, ""), d)[0]["v(xtx)"][0]) * ti.SI
        want = ti.reference_ac(ref, 2 * math.pi * ti.FREQ)
        inst = fmu.Instance(fmu.built(model), cosim=False)
        inst.set({"tscale": t, "w_z": ti.OMEGA})
        inst.start()
        st = np.zeros(6)
        st[5] = ti.V0
        inst.set_states(st)
        acc = float(inst.get(["qdd_tilt_x"])[0])
        inst.close()
        aw = -ti.OMEGA * ref.inertial.gyroscopic["z"][1][2] * ti.V0 / ref.coordinates[1].mass
        print(f"coriolis {label} tscale {t}: .lib {abs(got / want - 1):.2e}  FMU {abs(acc / aw - 1):.2e}")


def stretching(model, refs, label: str) -> None:
    d = Path(tempfile.mkdtemp())
    (d / "cc_beam.lib").write_text(emit_ngspice.subcircuit(model))
    for case in te.CASES:
        net = f"""* s
.include {d / "cc_beam.lib"}
X1 0 0 f1 x1 0 x2 0 x3 cc_beam tscale={case[0]!r} escale={case[1]!r}
Vf f1 0 DC {te.FORCE * 1e6!r}
.options reltol=1e-10 vntol=1e-12
.op
.end
"""
        got = float(run_ngspice(net, d)[0]["v(x1)"].real[0]) * 1e-6
        want = te.rest(refs[case])[0]
        share = abs(te.rest(refs[case], energy=0.0)[0] / want - 1)
        print(f"stretching {label} {case}: .lib {abs(got / want - 1):.2e} (linear off by {share:.3f})")


def main() -> None:
    gyp = build_model(parse_structure(ti.structure(ti.T_UM) + ti.PROCESS, "gyp.toml"))
    refs = {t: build_model(parse_structure(ti.structure(ti.T_UM * t), "gyp.toml")) for t in ti.TSCALES}
    print("stated tscale error", gyp.process["tscale"]["max_rel_error"])
    dropped = copy.deepcopy(gyp)
    dropped.process.pop("inertial")
    coriolis(gyp, refs, "law")
    coriolis(dropped, refs, "dropped")
    beam = build_model(parse_structure(te.text() + te.PROCESS, "cc_beam.toml"))
    brefs = {c: build_model(parse_structure(te.text(*c), "cc_beam.toml")) for c in te.CASES}
    print("stated bound", te.bound(beam))
    stretching(beam, brefs, "law")
    dropped = copy.deepcopy(beam)
    dropped.process.pop("strain_energy")
    stretching(dropped, brefs, "dropped")


if __name__ == "__main__":
    main()
