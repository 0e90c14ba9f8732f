"""Charge conservation of the z accelerometer's model inside a real charge amplifier (the OTA of
examples/sc_readout.inc with a feedback capacitor, reset once and then never again), on ngspice 39
and 46. The electrodes are switched every 1 us between VCM +- 0.5 V (top and bottom opposite).

Clamped: the mass held by an external spring-damper on f_z (K = 1e6 N/m, critically damped: the
+-0.5 V forces cancel at rest, the OTA's offset leaves a force of ~1e-9 N, so |z| < 1e-15 m and
C changes by < 1e-9 of itself). The amplifier's output then drifts only by the simulator's
charge errors and the switch leakage; the model must not add to them. Each converged time point
leaves a residual on the summing node of at most abstol + reltol |I| in the device currents
(ngspice's convergence test), i.e. a charge abstol * h per step, which accumulates; the model's
own charges are states (C(0) (V_i - V_p) on a linear capacitor plus c_ref * v(qn_i) on another:
their currents telescope under trapezoidal integration), so they add no accumulating error, only
c_ref (reltol |v(qn)| + vntol) ~ 1e-18 C at any instant. Allowed difference of the two drifts:
2 abstol T (both runs' accumulated residuals, T the run length) + 2 C_ref vntol, as a voltage on Cf.

Free: the mass driven through a_in (-3000 m/s^2: z rises ~0.6 um, xs ~ 0.3, in 20 us) while the
electrodes switch. The charge the feedback capacitor collected, Cf (V_out - V_sum), must equal
the change of the plate charge MacroModel.plate_charge(x(t), V(t), V_sum(t)) evaluated along the
simulated x_z, within 1e-3 of its swing: the OTA input gate's charge moves with V_sum by
C_gs dV_sum (~25 fF x < 1 mV = 2.5e-17 C against a swing of ~1e-13 C) and the time points are
compared at quiet instants (0.8 us after each edge, 10 closed-loop time constants).
"""

from __future__ import annotations

import numpy as np
import pytest

from netgen.model import MacroModel
from netgen.sim import ngspice
from tests.fixtures import using_ngspice
from tests.oracles import sc_readout as sc

PERIODS_CLAMPED = 25
PERIODS_FREE = 10


@pytest.mark.parametrize("release", ["39", "46"])
def test_clamped_model_drifts_like_fixed_capacitors(release, tmp_path):
    """The output drift over 25 periods with the clamped model equals the fixed capacitors' drift
    within 2 abstol T / Cf + 2 C_ref vntol / Cf (module docstring, sc_readout.drift_bound)."""
    drift = {}
    with using_ngspice(release):
        for sensor in ("clamped", "fixed"):
            plot = ngspice.run_ngspice(sc.charge_netlist(sensor, PERIODS_CLAMPED), tmp_path / sensor, sensor)[0]
            v = sc.quiet(plot, PERIODS_CLAMPED)
            even = v["out"][::2]  # the same electrode state each time
            drift[sensor] = even[-1] - even[0]
            if sensor == "clamped":
                assert np.abs(v["x_z"]).max() < 1e-9  # um: the clamp holds (< 1e-15 m)
    allowed = sc.drift_bound(PERIODS_CLAMPED)
    assert abs(drift["clamped"] - drift["fixed"]) <= allowed, (drift, allowed)


@pytest.mark.parametrize("release", ["39", "46"])
def test_free_model_charge_matches_macromodel(release, tmp_path):
    """Cf (V_out - V_sum) tracks the MacroModel's plate charge along the simulated z within 1e-3
    of the swing (module docstring)."""
    model = MacroModel.load_json(sc.MODEL_JSON)
    with using_ngspice(release):
        plot = ngspice.run_ngspice(sc.charge_netlist("free", PERIODS_FREE), tmp_path, "free")[0]
    v = sc.quiet(plot, PERIODS_FREE)
    assert (
        np.ptp(v["x_z"] * 1e-6 / model.coordinates[0].scale) > 0.2
    )  # the mass moved through a fifth of the gap at least
    err, swing = sc.charge_error(model, v)
    assert err <= 1e-3 * swing, (err / swing, swing)
