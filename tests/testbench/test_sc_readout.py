"""A short run of the transistor-level switched-capacitor readout (examples/sc_readout.inc) around
the committed z accelerometer, on ngspice 39 and 46: two DC accelerations in one run (+3 then
-3 m/s^2, 45 periods each, the first 20 of each left to settle: the start and the step leave
the mass with a velocity that the loop takes ~20 periods to take out), the mass held and the
bitstream's mean against the force balance.

Reference: mean(bit) = (G a / d - F_bottom) / (F_top - F_bottom), F_i = 1/2 dC_i/dz V_fb^2 from the
model JSON (netgen.model.MacroModel, tests/oracles/sc_readout.balance), d = 0.70 us / 2 us, V_fb = 0.9 V.
Tolerance: momentum over the N averaged periods gives exactly
  mean - balance = m (v_end - v_start) / (N d T_s (F_top - F_bottom))
(plus the spring, k z / (d (F_top - F_bottom)) < 1e-4 here at |z| < 10 nm): the loop's velocity
spread expressed in bit impulses (tests/oracles/sc_readout.bit_impulse), measured along the run as the
range of the per-period mean velocities, plus one bit for the per-period means against the
instantaneous velocities at the window's ends, over N.
Held: |z| below 20 nm (1 % of the 2 um gap) throughout; a point-mass model of this loop with its
lead stays within 0.2 nm, without the lead it wanders to ~70 nm.
"""

from __future__ import annotations

import numpy as np
import pytest

from netgen.model import MacroModel
from tests.fixtures import using_ngspice
from tests.oracles import sc_readout as sc

EACH = 45  # periods per DC input
SETTLE = 20  # periods skipped after the start and after the input step
ACCEL = (3.0, -3.0)


@pytest.mark.parametrize("release", ["39", "46"])
def test_bitstream_tracks_dc_acceleration(release, tmp_path):
    """The mass held within 1 % of the gap; each input's bit mean within (1 + velocity spread) / N
    of the force balance; the two means on either side of 1/2."""
    model = MacroModel.load_json(sc.MODEL_JSON)
    with using_ngspice(release):
        r = sc.run(tmp_path, sc.steps(list(ACCEL), EACH), EACH * len(ACCEL))
    assert np.abs(r.x_um).max() < 0.02
    impulse = sc.bit_impulse(model)
    for i, a in enumerate(ACCEL):
        first, last = i * EACH + SETTLE, (i + 1) * EACH
        n = last - first
        v = sc.period_velocity(r, first)[:n]
        tol = (1 + np.ptp(v) / impulse) / n
        mean = r.bits[first:last].mean()
        assert abs(mean - sc.balance(model, a)) <= tol, (a, mean, sc.balance(model, a), tol)
    assert r.bits[SETTLE:EACH].mean() > 0.5 > r.bits[EACH + SETTLE :].mean()
