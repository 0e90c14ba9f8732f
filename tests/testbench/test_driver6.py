"""The six-slot electrode driver of the Verilog-A loop (blocks.va's sd_driver6, VACASK and
ngspice-osdi): an electrode that serves five or six channels gets it (vacask.drivers), and in
ngspice 46 through OSDI it drives V_s phs + V_fb phf sel with sel the product of its slots' bit
matches, and feeds w_k times the electrode current into slot k's charge amplifier (the hand
formula of the module's comment); its first four slots behave as sd_driver4's."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from netgen.emit import osdi
from netgen.sim import ngspice as sim_ngspice
from netgen.testbench.sigma_delta import vacask
from tests.fixtures import using_ngspice

VS, VFB, CEL, RAMP = 0.5, 2.0, 1e-12, 1e-6
S = [1, -1, 1, -1, 1, -1]
W = [1.0, -1.0, 0.5, 2.0, -3.0, 4.0]


def design(channels: int, used: int) -> SimpleNamespace:
    """The parts of a Design that vacask.drivers reads: one electrode serving `used` of `channels`."""
    sel = [S[k] if k < used else 0 for k in range(channels)]
    w = [W[k] if k < used else 0.0 for k in range(channels)]
    return SimpleNamespace(
        vs=VS,
        vfb=VFB,
        channels=[{"name": f"c{k}"} for k in range(channels)],
        electrodes=[{"name": "el", "w": w, "sel": sel}],
    )


@pytest.mark.parametrize("used, model, slots", [(3, "drvn", 4), (4, "drvn", 4), (5, "drv6", 6), (6, "drv6", 6)])
def test_an_electrode_serving_five_or_six_channels_gets_the_six_slot_driver(used, model, slots):
    (drv,) = vacask.drivers(design(6, used))
    assert drv["model"] == model and len(drv["nodes"]) == 4 + 2 * slots
    assert drv["nodes"][4 : 4 + used] == [f"b_c{k}" for k in range(used)] and set(
        drv["nodes"][4 + used : 4 + slots]
    ) <= {"0"}


def netlist(blocks: str, bits: list[int]) -> str:
    """sd_driver6 (all six slots) and sd_driver4 (the first four) on a capacitor each, the
    feedback phase ramped 0 -> 1 over RAMP, the charge-amplifier nodes on 0 V ammeters."""
    params = " ".join(f"s{k + 1}={S[k]} w{k + 1}={W[k]}" for k in range(6))
    params4 = " ".join(f"s{k + 1}={S[k]} w{k + 1}={W[k]}" for k in range(4))
    lines = [
        "* sd_driver6 against the hand formula",
        ".model drv6 sd_driver6",
        ".model drv4 sd_driver4",
        "Vphs phs 0 1",
        f"Vphf phf 0 PWL(0 0 {RAMP} 1)",
        "Vrst rst 0 0",
    ]
    lines += [f"Vb{k + 1} b{k + 1} 0 {b}" for k, b in enumerate(bits)]
    lines += [
        f"N6 el6 phs phf rst {' '.join(f'b{k + 1}' for k in range(6))} {' '.join(f'c{k + 1}' for k in range(6))} "
        f"drv6 vs={VS} vfb={VFB} {params}",
        f"C6 el6 0 {CEL}",
        f"N4 el4 phs phf rst b1 b2 b3 b4 d1 d2 d3 d4 drv4 vs={VS} vfb={VFB} {params4}",
        f"C4 el4 0 {CEL}",
    ]
    lines += [f"Vc{k + 1} c{k + 1} 0 0" for k in range(6)] + [f"Vd{k + 1} d{k + 1} 0 0" for k in range(4)]
    saves = (
        "v(el6) v(el4) "
        + " ".join(f"i(vc{k + 1})" for k in range(6))
        + " "
        + " ".join(f"i(vd{k + 1})" for k in range(4))
    )
    lines += [
        ".control",
        "set noaskquit",
        f"pre_osdi {blocks}",
        f"tran {RAMP / 100} {RAMP} 0 {RAMP / 100}",
        f"write drv.raw {saves}",
        ".endc",
        ".end",
    ]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("bits, on", [([1, 0, 1, 0, 1, 0], True), ([1, 0, 1, 0, 1, 1], False)])
def test_the_six_slot_driver_follows_its_formula_in_ngspice_through_osdi(tmp_path, bits, on):
    """All six bits matching their entries: the electrode ramps to V_s + V_fb, the capacitor's
    current C V_fb / RAMP flows from the driver, slot k carries w_k times it; one mismatch in slot
    6: V_s only, no current. Slots 1-4 equal sd_driver4's with the same entries whenever slots 5
    and 6 match."""
    with using_ngspice("46") as v:
        if not v.osdi:
            pytest.fail(f"{v.label} cannot load OSDI 0.5 (the suite's ngspice 46 can)")
        blocks = osdi.compiled(vacask.blocks_source(), "sigma_delta_blocks", tmp_path / "osdi")
        plot = sim_ngspice.run_control(netlist(str(blocks.resolve()), bits), tmp_path, "drv", "drv.raw")
    t = np.asarray(plot["time"])
    mid = (t > 0.3 * RAMP) & (t < 0.9 * RAMP)
    sel = 1.0 if on else 0.0
    np.testing.assert_allclose(plot["v(el6)"][-1], VS + VFB * sel, rtol=1e-6, atol=1e-9)
    current = CEL * VFB * sel / RAMP  # into the electrode capacitor
    for k in range(6):
        got = np.asarray(plot[f"i(vc{k + 1})"])[mid]
        np.testing.assert_allclose(np.abs(got), abs(W[k]) * current, rtol=1e-3, atol=1e-12)
        assert on is False or np.all(np.sign(got) == np.sign(W[k]) * np.sign(plot["i(vc1)"][mid][0]))
    if on:
        np.testing.assert_allclose(plot["v(el4)"][-1], plot["v(el6)"][-1], rtol=1e-9)
        for k in range(4):
            np.testing.assert_allclose(
                np.asarray(plot[f"i(vd{k + 1})"])[mid], np.asarray(plot[f"i(vc{k + 1})"])[mid], rtol=1e-6, atol=1e-15
            )
