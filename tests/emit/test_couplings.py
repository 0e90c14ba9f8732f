"""Constant electrode-electrode couplings through every emitted form (netgen.emit; the MacroModel's
coupling matrix), on the reference model with a hand-made coupling matrix: adjacent sectors of a
ring couple at 10 % of the electrode's capacitance at rest, the inner and outer electrode of a
sector at 5 % (the BEM check of docs/bem.md, 'A disk between 8 + 8 sector electrodes', found 5-15 %).

- the .lib, _xspice.lib and .va headers list every capacitor with its value, and the netlists hold
  one linear capacitor (or ddt contribution) per pair with exactly that value;
- a model without couplings emits the committed netlists byte for byte (tests/emit/test_veriloga.py
  checks the .va; here the .lib and _xspice.lib);
- ngspice (39 and 46; the B-source and the xspice form): the current into a grounded electrode when
  a coupled neighbour is ramped, plate grounded, is C_c dV/dt (its plate capacitor carries no
  charge at 0 V), against the value written into the matrix;
- openvaf-py: the .va's electrode charges at 200 random points equal the Python model's, and
  their coupling part equals sum_j C_ij (V_i - V_j) computed here by hand;
- VACASK against ngspice: a floating electrode (1 Gohm to ground) beside driven neighbours follows
  the capacitive divider of its couplings; both simulators within 1 % of its peak.
"""

from __future__ import annotations

import re

import numpy as np
import openvaf_py
import pytest

from netgen.emit import write_outputs
from netgen.model import MacroModel
from netgen.sim.ngspice import run_ngspice
from netgen.sim.vacask import VacaskBench, compile_va, run_vacask
from tests.fixtures import (
    EMISSIONS,
    ROOT,
    Bench,
    emission_id,
    emitted_library,
    states,
    transient_drive,
    using_ngspice,
    va_residuals,
    va_volts,
)

JSON = ROOT / "netlists" / "levitated_disk.json"
FLOAT = "top_r2s2"  # the floating electrode of the VACASK comparison (neighbours top_r2s1, top_r2s3, top_r1s2)


def hand_matrix(model: MacroModel) -> np.ndarray:
    """The couplings written into the model: names <side>_r<ring>s<sector>; adjacent sectors of one
    ring and side (4 per ring) 10 % of the first electrode's C(0), the two rings of a sector 5 %."""
    c0 = model.capacitance(np.zeros(model.ncoords))[0]
    parsed = [re.fullmatch(r"(top|bot)_r(\d)s(\d)", e.name).groups() for e in model.electrodes]
    n = len(parsed)
    out = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1, n):
            (si, ri, ki), (sj, rj, kj) = parsed[i], parsed[j]
            if si != sj:
                continue
            if ri == rj and (int(ki) - int(kj)) % 4 in (1, 3):
                out[i, j] = out[j, i] = 0.10 * c0[i]
            elif ki == kj:
                out[i, j] = out[j, i] = 0.05 * min(c0[i], c0[j])
    return out


@pytest.fixture(scope="module")
def coupled(tmp_path_factory):
    """(model, folder): the reference model with hand_matrix couplings, emitted in every form."""
    model = MacroModel.load_json(JSON)
    model.coupling = hand_matrix(model)
    folder = tmp_path_factory.mktemp("coupled")
    write_outputs(model, folder, "all")
    return MacroModel.load_json(folder / f"{model.name}.json"), folder


def test_json_round_trip_keeps_the_matrix(coupled):
    """The couplings survive the JSON (pairs, upper triangle) as the symmetric hand-made matrix."""
    model, _ = coupled
    np.testing.assert_array_equal(model.coupling, hand_matrix(MacroModel.load_json(JSON)))
    assert np.count_nonzero(np.triu(model.coupling)) == 24  # 2 sides x (2 rings x 4 + 4 sectors)


@pytest.mark.parametrize("suffix, marker", [(".lib", "*"), ("_xspice.lib", "*"), (".va", "//")])
def test_headers_list_every_coupling(coupled, suffix, marker):
    """The header names each capacitor with its value in fF; the body has exactly those elements."""
    model, folder = coupled
    text = (folder / f"{model.name}{suffix}").read_text()
    names = [e.name for e in model.electrodes]
    listed = dict(re.findall(rf"^{re.escape(marker)}     Cc_(\w+) = ([0-9.e+-]+) fF", text, re.M))
    assert "Constant electrode-electrode couplings: 24 capacitor(s)" in text
    if suffix == ".va":
        body = {
            (a, b): float(v)
            for a, b, v in re.findall(r"I\((\w+), (\w+)\) <\+ ddt\(([0-9.e+-]+) \* V\(\1, \2\)\);", text)
        }
    else:
        body = {(a, b): float(v) for a, b, v in re.findall(r"^Cc_\w+ (\w+) (\w+) ([0-9.e+-]+)$", text, re.M)}
    assert len(listed) == len(body) == 24
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            if model.coupling[i, j]:
                assert body[(names[i], names[j])] == model.coupling[i, j]
                assert float(listed[f"{names[i]}_{names[j]}"]) == pytest.approx(model.coupling[i, j] * 1e15, rel=1e-5)


@pytest.mark.parametrize("suffix", [".lib", "_xspice.lib"])
def test_without_couplings_the_committed_netlists_are_unchanged(tmp_path, suffix):
    """The reference model (no couplings) emits its committed netlists byte for byte."""
    model = MacroModel.load_json(JSON)
    write_outputs(model, tmp_path, "all")
    committed = ROOT / "netlists" / f"{model.name}{suffix}"
    assert (tmp_path / f"{model.name}{suffix}").read_text() == committed.read_text()
    assert "Constant electrode-electrode couplings: 0 capacitor(s).\n" in committed.read_text()


@pytest.mark.parametrize("emission", EMISSIONS, ids=emission_id)
def test_ngspice_current_is_coupling_times_slope(coupled, emission, tmp_path):
    """A 1 V/us ramp on top_r2s1, plate and every other electrode at 0 V: the current the grounded
    neighbour top_r2s2 passes to ground is C_c dV/dt (its plate capacitor holds no charge at 0 V),
    within 1e-4 of the value written into the matrix, from 0.2 us on (after the ramp's corner)."""
    release, style = emission
    model, folder = coupled
    names = [e.name for e in model.electrodes]
    cc = model.coupling[names.index("top_r2s1"), names.index(FLOAT)]
    slope = 1e6  # V/s
    with using_ngspice(release):
        lib, control = emitted_library(model, style, tmp_path, folder / f"{model.name}.lib")
        bench = Bench(
            model,
            lib,
            sources={"top_r2s1": f"PWL(0 0 1e-6 {slope * 1e-6!r})", "plate": "0"},
            options="reltol=1e-6 chgtol=1e-20",
            control=control,
        )
        plot = run_ngspice(bench.netlist(".tran 2n 1e-6 0 2n uic"), tmp_path / "ng")[0]
    t, i = plot["time"], plot[f"i(v{FLOAT})"]
    late = t > 0.2e-6
    # i(v): the current through the grounded source from its + node, i.e. what the coupling pushes into it
    err = np.abs(i[late] - cc * slope) / (cc * slope)
    print(f"{release}-{style}: C_c = {cc:.6e} F, i/slope {np.median(i[late]) / slope:.6e} F, worst {err.max():.2e}")
    assert err.max() < 1e-4


def _random_points(model: MacroModel, n: int = 200):
    """States inside the sampled box, electrode voltages +-25 V, plate +-5 V."""
    rng = np.random.default_rng(22)
    r = model.sampling["range"]
    return (
        rng.uniform(-r, r, (n, model.ncoords)),
        rng.uniform(-25.0, 25.0, (n, len(model.electrodes))),
        rng.uniform(-5.0, 5.0, n),
    )


def test_va_charges_include_the_couplings(coupled):
    """openvaf-py at 200 random points: electrode charges = MacroModel.electrode_charges within 1e-9
    relative, and charge(coupled) - charge(uncoupled) = sum_j C_ij (V_i - V_j) by hand."""
    model, folder = coupled
    plain = MacroModel.load_json(JSON)
    with_c = openvaf_py.compile_va(str(folder / f"{model.name}.va"))[0]
    without = openvaf_py.compile_va(str(ROOT / "netlists" / f"{model.name}.va"))[0]
    params = {f"d_{c.name}": c.damping for c in model.coordinates} | {"fel_scale": 1.0, "mfactor": 1.0}
    x, v_el, v_plate = _random_points(model)
    q_c, q_0 = np.zeros_like(v_el), np.zeros_like(v_el)
    for p in range(len(x)):
        volts = va_volts(model, x[p], v_el[p], v_plate[p])
        rc, r0 = va_residuals(with_c, volts, params), va_residuals(without, volts, params)
        q_c[p] = [rc[e.name][1] for e in model.electrodes]
        q_0[p] = [r0[e.name][1] for e in model.electrodes]
    hand = np.array(
        [[sum(model.coupling[i, j] * (v[i] - v[j]) for j in range(len(v))) for i in range(len(v))] for v in v_el]
    )
    q_py = model.electrode_charges(x, v_el, v_plate)
    assert np.abs(q_c - q_py).max() / np.abs(q_py).max() < 1e-9
    assert np.abs((q_c - q_0) - hand).max() / np.abs(hand).max() < 1e-9
    np.testing.assert_allclose(plain.electrode_charges(x, v_el, v_plate), q_0, rtol=1e-9, atol=1e-9 * np.abs(q_0).max())


def test_vacask_and_ngspice_agree_with_couplings(coupled, tmp_path):
    """The transient drive of tests/emit/test_veriloga.py, plate grounded, with FLOAT floating on
    1 Gohm (time constant ~0.5 ms >> 20 us): its voltage is the divider of its couplings to the
    driven neighbours (0 without couplings). VACASK (the .va) and ngspice (the .lib) within 1 % of
    its peak; the coordinates too."""
    model, folder = coupled
    drive = transient_drive() | {"top_r2s3": transient_drive()["top_r2s1"]}
    stop = 20e-6
    osdi, _ = compile_va(folder / f"{model.name}.va", tmp_path / "m.osdi")
    bench = VacaskBench(
        model,
        osdi,
        sources={k: p.vacask() for k, p in drive.items()} | {"plate": "dc=0"},
        options="reltol=1e-5 chgtol=1e-20",
    )
    text = bench.netlist(f'analysis tran1 tran step=10n stop={stop!r} maxstep=10n icmode="uic"')
    text = text.replace(
        f"v_{FLOAT} ({FLOAT} 0) vsource dc=0", f"model res resistor\nr_{FLOAT} ({FLOAT} 0) res r=1e9"
    ).replace("model vsource vsource", 'load "resistor.osdi"\nmodel vsource vsource', 1)
    vac = run_vacask(text, tmp_path / "vacask")
    spice = Bench(
        model,
        folder / f"{model.name}.lib",
        sources={k: p.spice() for k, p in drive.items()} | {"plate": "0"},
        extra=[f"R{FLOAT} {FLOAT} 0 1e9"],
        driven_elsewhere={FLOAT},
        options="reltol=1e-5 chgtol=1e-20",
    )
    plot = run_ngspice(spice.netlist(f".tran 10n {stop!r} 0 10n uic"), tmp_path / "ngspice")[0]
    t = plot["time"]
    v_ng = plot[f"v({FLOAT})"]
    v_vac = np.interp(t, vac["time"], vac[FLOAT])
    peak = np.abs(v_ng).max()
    err = np.abs(v_vac - v_ng).max() / peak
    print(f"{FLOAT}: peak {peak:.4f} V, VACASK - ngspice max {err:.2e} of peak")
    assert peak > 0.1 and err < 0.01
    x_ng, _ = states(plot, model)
    for v, c in enumerate(model.coordinates):
        x_vac = np.interp(t, vac["time"], vac[f"x1:xs_{c.name}"])
        peak = np.abs(x_ng[:, v]).max()
        print(f"{c.name}: peak {peak:.3e}, difference {np.abs(x_vac - x_ng[:, v]).max() / peak:.2e} of peak")
        assert peak > 0 and np.abs(x_vac - x_ng[:, v]).max() < 0.01 * peak, c.name
