"""Higher-order sigma-delta loops: NTF synthesis against the delta-sigma toolbox's published
values and closed forms, loop-filter coefficients that reproduce the designed NTF, the sampled
mechanics against the kinematics of a free mass, and the numpy reference loop's noise shaping
(netgen.testbench.sigma_delta.ntf, filters, analysis; tests/oracles/sigma_delta_reference.py)."""

from __future__ import annotations

import numpy as np
import pytest

from netgen.testbench.sigma_delta import analysis, filters, ntf
from tests.oracles import sigma_delta_reference as reference

# the levitated disk's z channel (bench/sigma_delta_ideal_loop.py): a free mass, 1 V of readout
# per 1/34.57 um, the feedback pulse 0.50-0.94 T_s with 2 % edges, sampled at 0.34 T_s
TS = 1e-6
DISK_Z = filters.Mechanics(1.6377e-8, 0.0, 0.0, 0.7415e-6, 34.57e6, TS, 0.34, filters.trapezoid_pulse(0.5, 0.94, 0.02))
# a proof mass on springs (resonance 2 kHz, Q 50), the same readout and timing
SPRUNG = filters.Mechanics(
    1e-8,
    1e-8 * (2 * np.pi * 2e3) ** 2,
    1e-8 * 2 * np.pi * 2e3 / 50,
    0.7e-6,
    3e7,
    TS,
    0.34,
    filters.trapezoid_pulse(0.5, 0.94, 0.02),
)


def test_order5_osr32_ntf_is_the_toolbox_example():
    """synthesizeNTF(5, 32, 1) of Schreier's toolbox (its documentation's example):
    (z - 1)(z^2 - 1.997 z + 1)(z^2 - 1.992 z + 1) / ((z - 0.7778)(z^2 - 1.613 z + 0.6649)(z^2 - 1.796 z + 0.8549))."""
    h = ntf.synthesize_ntf(5, 32, 1, 1.5)
    quad = lambda r: np.real(np.poly([r, np.conj(r)]))[1:]  # noqa: E731
    zq = sorted(tuple(np.round(quad(q), 3)) for q in h.zeros if q.imag > 1e-9)
    pq = sorted(tuple(np.round(quad(p), 4)) for p in h.poles if p.imag > 1e-9)
    assert zq == sorted([(-1.997, 1.0), (-1.992, 1.0)])
    assert pq == sorted([(-1.6131, 0.6649), (-1.7961, 0.8549)])
    assert [round(p.real, 4) for p in h.poles if abs(p.imag) < 1e-9] == [0.7778]
    assert np.sum(np.abs(h.zeros - 1) < 1e-12) == 1


def test_order2_ntf_meets_h_inf_and_the_fir_limit():
    """Zeros at DC; |NTF| on the unit circle peaks at H_inf = 1.5 (at z = -1); an H_inf above the
    FIR limit |1 - (-1)|^2 = 4 leaves the poles at 0, NTF = (1 - z^-1)^2."""
    h = ntf.synthesize_ntf(2, 64, 0, 1.5)
    assert np.allclose(h.zeros, 1.0)
    w = np.linspace(0, np.pi, 20001)
    mag = np.abs((np.exp(1j * w) - 1) ** 2 / np.prod([np.exp(1j * w) - p for p in h.poles], axis=0))
    assert mag.max() == pytest.approx(1.5, abs=1e-6) and w[np.argmax(mag)] == pytest.approx(np.pi)
    assert np.allclose(ntf.synthesize_ntf(2, 64, 0, 5.0).poles, 0.0)


def test_optimal_zeros_are_the_closed_forms():
    """ds_optzeros: order 3 at 0, +-sqrt(3/5); order 4 at +-sqrt(3/7 +- sqrt(9/49 - 3/35)); with the
    mechanics' two zeros at DC, order 4's free pair minimises 1/9 - 2a^2/7 + a^4/5: a^2 = 5/7."""
    assert np.allclose(ntf.optimal_zeros(3), [-np.sqrt(0.6), 0, np.sqrt(0.6)])
    r = np.sqrt(9 / 49 - 3 / 35)
    assert np.allclose(ntf.optimal_zeros(4), sorted([s * np.sqrt(3 / 7 + t * r) for s in (-1, 1) for t in (-1, 1)]))
    assert np.allclose(ntf.optimal_zeros(4, fixed_dc=2), [-np.sqrt(5 / 7), 0, 0, np.sqrt(5 / 7)], atol=1e-6)


def test_sampled_mechanics_is_the_free_mass_kinematics():
    """A free mass pushed by constant pieces a_i over [t0_i, t1_i] after the sample: at the next
    sample dv = sum a_i (t1 - t0), dq = sum a_i ((T - t0)^2 - (T - t1)^2) / 2."""
    phi, gamma = DISK_Z.period_map()
    acc = DISK_Z.force / DISK_Z.mass
    pieces = [((a - 0.34) * TS, (b - 0.34) * TS, w * acc) for a, b, w in DISK_Z.pulse]
    assert np.allclose(phi, [[1, TS], [0, 1]])
    assert gamma[1] == pytest.approx(sum(a * (t1 - t0) for t0, t1, a in pieces), rel=1e-12, abs=0)
    assert gamma[0] == pytest.approx(
        sum(a * ((TS - t0) ** 2 - (TS - t1) ** 2) / 2 for t0, t1, a in pieces), rel=1e-9, abs=0
    )
    # the squared 2 % ramps: the pulse's impulse is (0.44 - 0.02) + 2 x 0.02 / 3 periods (loop.duty)
    assert sum(w * (b - a) for a, b, w in DISK_Z.pulse) == pytest.approx(0.42 + 0.04 / 3, rel=1e-12, abs=0)


@pytest.mark.parametrize("order", [3, 4, 5])
@pytest.mark.parametrize("topology", ["cifb", "crfb"])
@pytest.mark.parametrize("mech", [DISK_Z, SPRUNG], ids=["free", "sprung"])
def test_coefficients_reproduce_the_ntf(order, topology, mech):
    """The loop's linearised NTF 1/(1 - T(z)) from the realised coefficients (T = the state-space
    loop opened at the quantizer) equals the designed NTF to 1e-6 on the unit circle, whose zeros
    are the loop's poles (the mechanics' and the integrators') and whose gain peaks at H_inf."""
    f = filters.design(mech, order, 64, 1.5, topology)
    z = np.exp(1j * np.linspace(1e-4, np.pi, 500))
    want = ntf.evaluate(filters.target_ntf(f), z)
    assert np.max(np.abs(filters.realised_ntf(mech, f, z) - want)) < 1e-6
    assert np.max(np.abs(want)) == pytest.approx(1.5, rel=1e-3)
    phi, _ = mech.period_map()
    assert np.allclose(
        np.sort_complex(filters.target_ntf(f).zeros),
        np.sort_complex(np.concatenate([np.linalg.eigvals(phi), np.linalg.eigvals(f.a)])),
    )


def _shaping(f: filters.Filter, cycles: int = 2**15, amplitude: float = 0.5) -> dict:
    """The reference loop's figures at -6 dBFS (a tone at a quarter of the band), OSR 64."""
    tone = analysis.tone_frequency(TS, 4096, 64)
    run = reference.simulate(DISK_Z, f, cycles, reference.Input(0.0, amplitude * DISK_Z.full_scale, tone))
    assert reference.stable(run, 1e-8)
    return analysis.band_metrics(*analysis.psd(run["v"][cycles // 8 :], TS, 4096), TS, 64, tone, analysis.DC_BINS)


def test_reference_noise_shaping_order2_and_order4():
    """The numpy loop shapes its quantization noise at 20 x order dB/decade over the decade below
    the band edge: order 2 (lead2) 40 +- 6, order 4 (CIFB, zeros at DC) 80 +- 10; the fourth-order
    loop's SQNR is at least 15 dB above the second-order loop's at the same input and OSR."""
    second = _shaping(filters.lead2(0.8))
    fourth = _shaping(filters.design(DISK_Z, 4, 64, 1.5, "cifb"))
    assert 34 <= second["slope_db_per_decade"] <= 46
    assert 70 <= fourth["slope_db_per_decade"] <= 90
    assert fourth["snr_db"] >= second["snr_db"] + 15
    assert second["tone_level_db"] == pytest.approx(10 * np.log10(0.5**2 / 2), abs=0.3)


def test_dynamic_range_finds_the_overload():
    """SNR rises 1 dB per dB of input, and past full scale the loop loses the mass."""
    f = filters.design(DISK_Z, 3, 64, 1.5, "cifb")
    tone = analysis.tone_frequency(TS, 2048, 64)

    def run(a: float):
        r = reference.simulate(DISK_Z, f, 2**14, reference.Input(0.0, a * DISK_Z.full_scale, tone))
        return r["v"], reference.stable(r, 1e-8)

    dr = analysis.dynamic_range(run, [0.01, 0.1, 0.5, 2.0], TS, 64, tone, 2048, skip=2048)
    rows = dr["rows"]
    assert rows[1]["sqnr_db"] - rows[0]["sqnr_db"] == pytest.approx(20, abs=3)
    assert not rows[-1]["held"] and dr["max_stable_amplitude"] == 0.5
