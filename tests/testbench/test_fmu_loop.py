"""The sigma-delta loop with the mechanics in the model's FMU (netgen.testbench.sigma_delta.fmu,
examples/fmu_sigma_delta.py) against the same Design in ngspice-xspice (compiled netgen_sdloop and
netgen_es): the z accelerometer, 2^10 periods with the feedback as a step, 128 with the ramped
feedback against ngspice at the tolerances where its bits stop moving."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from netgen.core.errors import LoopError
from netgen.model import MacroModel
from netgen.testbench import sigma_delta as sd
from netgen.testbench.sigma_delta import fmu, runner
from netgen.testbench.sigma_delta.loop import Choices
from tests.fixtures import NETLISTS, ROOT, using_ngspice

pytest.importorskip("fmpy")

STRUCTURE = ROOT / "examples" / "accelerometer_z.toml"
MODEL = NETLISTS / "accelerometer_z" / "accelerometer_z.json"
CYCLES = 1024


def step_loop(tmp_path):
    """The structure's [loop] with the feedback as a step (`[loop.timing] fb_edge = 0`)."""
    text = STRUCTURE.read_text()
    path = tmp_path / "loop.toml"
    path.write_text(text[text.index("[loop]") :] + "\n[loop.timing]\nfb_edge = 0\n")
    return sd.read_loop_file(path)


def test_first_bits_as_ngspice_xspice(tmp_path):
    """The first 64 bits of the FMU loop are ngspice-xspice's, and so is the mean over 2^10.
    The loop runs with the feedback as a step (fb_edge = 0): ngspice integrates a step's constant
    V^2 force exactly (backward Euler after the breakpoint), where the ramped feedback's impulse
    error depends on its time steps inside the ramps (CHANGELOG, the compiled loop's floor): two
    ngspice runs of the ramped loop at reltol 1e-3 and 1e-4 part after 33 bits (1e-4 and 1e-5 after
    26), so their bits are no reference beyond that; with the step the FMU loop and ngspice agreed
    on all of the first 128 bits when this test was written. The decisions within the first 64 at
    the FMU's DP45 tolerance 1e-9 have margins |y| far above its error; the bit means of the two
    runs agree within 2 bits of 1024 (the mean of a +-1 stream moves by 2/N per flipped bit, and the
    first-order loop's running sum is bounded, so after they part the counts differ by a few)."""
    model = MacroModel.load_json(MODEL)
    loop = step_loop(tmp_path)
    d = runner.backend_design(model, 1e-6, loop, None, "ngspice-xspice", Choices())
    request = sd.RunRequest(
        1e-6, CYCLES, None, progress=False, plots=False, simulator="ngspice-xspice", loop=loop, designed=d
    )
    lib = MODEL.with_suffix(".lib")
    with using_ngspice("39"):
        ref = sd.run(model, lib, tmp_path / "ngspice", request)
    got = fmu.run(model, d, CYCLES)
    ref_bits = ref["clock"]["bits_z"]
    assert np.array_equal(got["bits_z"][:64], ref_bits[:64])
    assert abs(int(got["bits_z"].sum()) - int(ref_bits.sum())) <= 4


def test_ramped_feedback_first_bits_as_converged_ngspice(tmp_path):
    """With the design's ramped feedback, the first 64 bits of the FMU loop are those of
    ngspice-xspice run where ngspice's bits stop moving with its tolerances: reltol 1e-6 with
    abstol 1e-20 A and vntol 1e-14 V. At ngspice's default absolute tolerances (1e-12 A, 1e-6 V,
    near the charge amplifier's per-period signal) its runs at reltol 1e-3..1e-6 and maximum steps
    0.05 and 0.01 T_s part from each other and from the FMU loop after 12-60 periods; with the
    absolute tolerances lowered, its runs at reltol 1e-6 and 1e-7 agree with each other and with
    the FMU loop on the first 117 (bench/fmu_convergence.py, docs/fmu.md), and the FMU loop
    matches an independent DOP853 integration of the MacroModel within 2e-9 of the dither
    amplitude. ngspice's remaining error is a drift of the trajectory that grows as t^2 (its ramp
    integration, deterministic, not round-off): in the decision variable, in dither amplitudes, at
    the FMU loop's closest decisions of the first 64 periods it is 1e-3 against a margin of 0.018
    (period 8), 0.023 against 0.059 (33), 0.044 against 0.062 (46) and 0.086 against 0.098 (60;
    measured at reltol 1e-7), so the 64 bits hold with that margin; a CPU's round-off (1e-16)
    cannot cross it."""

    model = MacroModel.load_json(MODEL)
    loop = sd.read_structure_loop(STRUCTURE)
    d = runner.backend_design(model, 1e-6, loop, None, "ngspice-xspice", Choices())
    tight = replace(d, reltol=1e-6, abstol=1e-20, vntol=1e-14)
    request = sd.RunRequest(
        1e-6, 128, None, progress=False, plots=False, simulator="ngspice-xspice", loop=loop, designed=tight
    )
    with using_ngspice("39"):
        ref = sd.run(model, MODEL.with_suffix(".lib"), tmp_path / "ngspice", request)
    got = fmu.run(model, d, 128)
    assert np.array_equal(got["bits_z"][:64], ref["clock"]["bits_z"][:64])


def test_designed_filter_refused():
    """A state-space loop filter is not mirrored by the FMU loop: LoopError (exit 2), not a wrong loop."""
    model = MacroModel.load_json(MODEL)
    loop = sd.read_structure_loop(STRUCTURE)
    d = runner.backend_design(model, 1e-6, loop, None, "ngspice-xspice", Choices())
    d.channels[0]["filter"] = {"kind": "cifb", "order": 4}
    with pytest.raises(LoopError, match="lead2"):
        fmu.Loop.of(d)
