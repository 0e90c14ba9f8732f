"""The calibrated reference model: examples/levitated_disk.toml with the BEM-derived correction
extrapolated to its gap (bench/bem_extrapolate.py --json), through `extractor = "calibrated"` and
a couplings file, then the ngspice-vs-VACASK transient with its couplings and the folders of the
sigma-delta comparison with and without them:

    .venv/bin/python bench/bem_calibrated_reference.py EXTRAPOLATION.json OUT [--transient]
    .venv/bin/python bench/bem_calibrated_reference.py DIRECT.json OUT      # bench/fastcap_levels.py --calibration-json

DIRECT.json (bench/fastcap_levels.py --calibration-json) is the FastCap solution at the reference
gap itself, in the same form: the file is then OUT/maxwell_direct.json and says so.

What the couplings file holds, and why it is one: BEM cannot solve the reference gap here (g/R =
0.0063 needs 104k elements on the finest level, ~100 GB: bench/bem_extrapolate.py's cost lines), so OUT/maxwell_extrapolated.json
is not a field solution. It holds Maxwell matrices at q = 0 and +-h along z, tilt_x, tilt_y (h =
5 % of each touching amplitude) built from the extrapolation: plate-electrode entries
C_i(q) = C_pp,i(0) / (1 + y_C,i) + (C_pp,i(q) - C_pp,i(0)) / (1 + y_v,i), with y the extrapolated
(analytic - BEM) / BEM of C and of dC/dq_v (ring and side means; tilt_y takes tilt_x's by the
quarter-turn symmetry), and the extrapolated coupling matrix (constant). The calibrated extractor
fits each electrode's fringe (a_i, b_i) to those values and takes the couplings as they are, which
is what "extrapolated fringe coefficients and constant coupling matrix" means; the file's
description says it is an extrapolation, and the model's calibration entry names the file.

OUT/model: the calibrated model (.json, .lib, _xspice.lib, .va); OUT/plain: the same model with
its couplings set to zero (the sigma-delta control). The sigma-delta commands it prints run the two.
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np
from support import ROOT

from netgen.cli.commands import main as netgen
from netgen.electrostatics import EXTRACTORS
from netgen.electrostatics.sampling import coordinate_scales
from netgen.emit import write_outputs
from netgen.geometry.layout import electrodes, plate_outline
from netgen.mechanics import mechanics
from netgen.model import MacroModel
from netgen.structure.parse import parse_structure

REFERENCE = ROOT / "examples" / "levitated_disk.toml"
STEP = 0.05  # +-h: this fraction of each rigid coordinate's touching amplitude
RIGID = ("z", "tilt_x", "tilt_y")


def ring_value(per: dict, name: str) -> float:
    """The extrapolated value of `name`'s ring and side (mean over the sectors that have one)."""
    side, ring = re.fullmatch(r"(top|bot)_(r\d)s\d", name).groups()
    rows = [v["value"] for n, v in per.items() if n.startswith(f"{side}_{ring}")]
    return float(np.mean(rows))


def maxwell_file(ex: dict, out: Path) -> Path:
    """Write OUT/maxwell_extrapolated.json (see the module) and return its path."""
    s = parse_structure(REFERENCE.read_text(), str(REFERENCE))
    m, plate, shapes = mechanics(s), plate_outline(s), electrodes(s)
    names = [e.name for e in shapes]
    assert names == ex["names"], "the extrapolation is of another electrode set"
    pp = EXTRACTORS["parallel_plate"](s, plate).prepare(shapes, plate, m.basis)
    scales = coordinate_scales(pp, m.names, np.array([e.gap for e in shapes]))
    nc, n = len(m.names), len(names)
    q = [np.zeros(nc)]
    for c in RIGID:
        for sign in (1.0, -1.0):
            row = np.zeros(nc)
            row[m.names.index(c)] = sign * STEP * scales[m.names.index(c)]
            q.append(row)
    q = np.array(q)
    c_pp = pp.capacitance(q)
    diff = ex["differences"]
    y_c = np.array([ring_value(diff["C"], e) for e in names])
    y_v = {c: np.array([ring_value(diff["tilt_x" if c == "tilt_y" else c], e) for e in names]) for c in RIGID}
    cc = np.zeros((n, n))
    for pair, v in ex["couplings"].items():
        a, b = pair.split("-")
        cc[names.index(a), names.index(b)] = cc[names.index(b), names.index(a)] = v["value"]
    points = []
    for k, row in enumerate(q):
        moved = [c for c in RIGID if row[m.names.index(c)] != 0.0]
        y = y_v[moved[0]] if moved else 0.0
        c = c_pp[0] / (1.0 + y_c) + (c_pp[k] - c_pp[0]) / (1.0 + y)
        mx = np.zeros((n + 1, n + 1))
        mx[0, 1:] = mx[1:, 0] = -c
        mx[1:, 1:] = -cc
        np.fill_diagonal(mx, 0.0)
        np.fill_diagonal(mx, -mx.sum(axis=1) + 0.1 * np.abs(mx).max())  # a small capacitance to infinity each
        points.append({"q": {name: float(v) for name, v in zip(m.names, row) if v}, "maxwell": mx.tolist()})
    if "direct" in ex:  # bench/fastcap_levels.py --calibration-json: a field solution at the gap itself
        described = f"{ex['direct']}, written by bench/bem_calibrated_reference.py"
        solver = "fastcap2 2.1 (multipole panels)"
    else:
        described = (
            f"EXTRAPOLATED, not a field solution: BEM (bempp-cl, bench/bem_reference_disk.py) at "
            f"g/R = {', '.join(f'{g:g}' for g in ex['gaps'])}, extrapolated to {ex['target_g_over_R']:.4f} "
            "by bench/bem_extrapolate.py, written by bench/bem_calibrated_reference.py"
        )
        solver = "bempp-cl 0.4.2 (extrapolated)"
    doc = {
        "description": described,
        "solver": solver,
        "conductors": ["plate"] + names,
        "points": points,
    }
    path = out / ("maxwell_direct.json" if "direct" in ex else "maxwell_extrapolated.json")
    path.write_text(json.dumps(doc, indent=1) + "\n")
    return path


def structure(out: Path, maxwell: Path) -> Path:
    """OUT/levitated_disk.toml: the reference structure, calibrated against the file `maxwell`."""
    text = REFERENCE.read_text()
    head, tail = text.split("[electrostatics]")
    rest = tail[tail.index("\n[", 1) :] if "\n[" in tail[1:] else ""
    path = out / "levitated_disk.toml"
    path.write_text(head + f'[electrostatics]\nextractor = "calibrated"\ncouplings = "{maxwell.name}"\n' + rest)
    return path


def build(out: Path) -> MacroModel:
    """Build the calibrated model into OUT/model and the coupling-free control into OUT/plain."""
    code = netgen(["build", str(out / "levitated_disk.toml"), "-o", str(out / "model"), "--format", "all", "-q"])
    if code:
        raise SystemExit(code)
    model = MacroModel.load_json(out / "model" / "levitated_disk.json")
    plain = MacroModel.load_json(out / "model" / "levitated_disk.json")
    plain.coupling = np.zeros_like(plain.coupling)
    write_outputs(plain, out / "plain", "all")
    return model


def report(model: MacroModel) -> None:
    """The fringes and couplings of the model, and C(0) against the uncalibrated reference model."""
    ref = MacroModel.load_json(ROOT / "netlists" / "levitated_disk.json")
    c, c_ref = model.capacitance(np.zeros(model.ncoords))[0], ref.capacitance(np.zeros(ref.ncoords))[0]
    g, g_ref = (
        model.capacitance_gradient(np.zeros(model.ncoords))[0],
        ref.capacitance_gradient(np.zeros(ref.ncoords))[0],
    )
    print(model.calibration["source"])
    for i, e in enumerate(model.electrodes):
        f = next(r for r in model.calibration["fringe"] if r["electrode"] == e.name)
        print(
            f"  {e.name}: a {f['a']:.4f} b {f['b']:.4f}; C(0) {c[i] * 1e15:.2f} fF ({100 * (c[i] / c_ref[i] - 1):+.2f} % "
            f"against the uncalibrated model), dC/dz {100 * (g[i, 0] / g_ref[i, 0] - 1):+.2f} %"
        )
    names = [e.name for e in model.electrodes]
    pairs = [
        (names[i], names[j], model.coupling[i, j])
        for i in range(len(names))
        for j in range(i + 1, len(names))
        if model.coupling[i, j] > 0
    ]
    print(
        f"  {len(pairs)} couplings, largest: "
        + ", ".join(f"{a}-{b} {v * 1e15:.3f} fF" for a, b, v in sorted(pairs, key=lambda p: -p[2])[:6])
    )


def transient(model: MacroModel, folder: Path, work: Path) -> None:
    """tests/emit/test_couplings.py's floating-electrode transient on this model: ngspice (.lib) and
    VACASK (.va) within 1 % of the floating electrode's peak and of each coordinate's."""
    from support import Bench, states, transient_drive

    from netgen.sim.ngspice import run_ngspice
    from netgen.sim.vacask import VacaskBench, compile_va, run_vacask

    float_el = "top_r2s2"
    drive = transient_drive() | {"top_r2s3": transient_drive()["top_r2s1"]}
    stop = 20e-6
    work.mkdir(parents=True, exist_ok=True)
    osdi, _ = compile_va(folder / f"{model.name}.va", work / "m.osdi")
    bench = VacaskBench(
        model,
        osdi,
        sources={k: p.vacask() for k, p in drive.items()} | {"plate": "dc=0"},
        options="reltol=1e-5 chgtol=1e-20",
    )
    text = bench.netlist(f'analysis tran1 tran step=10n stop={stop!r} maxstep=10n icmode="uic"')
    text = text.replace(
        f"v_{float_el} ({float_el} 0) vsource dc=0", f"model res resistor\nr_{float_el} ({float_el} 0) res r=1e9"
    ).replace("model vsource vsource", 'load "resistor.osdi"\nmodel vsource vsource', 1)
    vac = run_vacask(text, work / "vacask")
    spice = Bench(
        model,
        folder / f"{model.name}.lib",
        sources={k: p.spice() for k, p in drive.items()} | {"plate": "0"},
        extra=[f"R{float_el} {float_el} 0 1e9"],
        driven_elsewhere={float_el},
        options="reltol=1e-5 chgtol=1e-20",
    )
    plot = run_ngspice(spice.netlist(f".tran 10n {stop!r} 0 10n uic"), work / "ngspice")[0]
    t = plot["time"]
    v_ng, v_vac = plot[f"v({float_el})"], np.interp(t, vac["time"], vac[float_el])
    peak = np.abs(v_ng).max()
    print(
        f"transient, {float_el} floating on 1 Gohm beside driven neighbours: peak {peak:.4f} V, "
        f"VACASK - ngspice max {np.abs(v_vac - v_ng).max() / peak:.2e} of the peak"
    )
    x_ng, _ = states(plot, model)
    for v, c in enumerate(model.coordinates):
        x_vac = np.interp(t, vac["time"], vac[f"x1:xs_{c.name}"])
        p = np.abs(x_ng[:, v]).max()
        print(f"  {c.name}: peak {p:.3e}, VACASK - ngspice max {np.abs(x_vac - x_ng[:, v]).max() / p:.2e} of the peak")


def main() -> None:
    """File, structure, build, report; the transient with --transient; the sigma-delta commands."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("extrapolation", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--transient", action="store_true")
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    maxwell = maxwell_file(json.loads(a.extrapolation.read_text()), a.out)
    print(f"wrote {maxwell} and {structure(a.out, maxwell)}")
    model = build(a.out)
    report(model)
    if a.transient:
        transient(model, a.out / "model", a.out / "transient")
    for label in ("model", "plain"):
        print(
            f"nice -n 10 .venv/bin/netgen sigma-delta examples/levitated_disk.toml --model {a.out / label}/levitated_disk.json "
            f"--simulator ngspice-xspice --cycles 8192 --tone z:0.02:2000 -o {a.out}/sd_{label} -q --no-plots"
        )
    print(
        f".venv/bin/python bench/couplings_sigma_delta.py {a.out}/sd_plain {a.out}/sd_model --png {a.out}/couplings_sd.png"
    )
    print(  # with and without the calibration: the committed (uncalibrated) reference model beside it
        f"nice -n 10 .venv/bin/netgen sigma-delta examples/levitated_disk.toml --model netlists/levitated_disk.json "
        f"--simulator ngspice-xspice --cycles 8192 --tone z:0.02:2000 -o {a.out}/sd_uncalibrated -q --no-plots\n"
        f".venv/bin/python bench/couplings_sigma_delta.py {a.out}/sd_uncalibrated {a.out}/sd_model "
        f"--png {a.out}/calibration_sd.png"
    )


if __name__ == "__main__":
    main()
