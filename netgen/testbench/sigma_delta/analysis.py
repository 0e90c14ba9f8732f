"""From a run's raw plot to its figures: bits and coordinates once per period, Welch spectra of
the bitstreams normalised to the fed-back force/torque (the paper's normalisation), in-band
noise floors, SNR, shaping slope, notches and peaks, latch quality, the levitation check, the
momentum balance against gravity and the gas film's Brownian floor; for the loop-order bench
(bench/sigma_delta_orders.py) the test-tone frequency and the dynamic-range curve."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy import signal

from ...core.constants import K_B
from ...core.errors import SimulationError
from ...model import MacroModel
from .loop import CLEAN_LATCH, Design, Tone, duty


def per_clock(plot, d: Design, cycles: int, model: MacroModel, start: int = 0) -> dict[str, np.ndarray]:
    """Bits (+-1) and coordinates sampled once per period, in the feedback phase; where the plot
    has the lead-filter outputs v(y_<c>), the comparator input y + dither at the end of the latch
    window (`cmp_<c>`, V; `start`: the first period's index, for the dither's phase)."""
    t = np.asarray(plot["time"])
    if t[-1] < 0.999 * cycles * d.ts:
        raise SimulationError(f"ngspice stopped at t = {t[-1]:.4g} s of {cycles * d.ts:.4g} s")
    at = (np.arange(cycles) + 0.5 * (d.t.fb_on + d.t.fb_off)) * d.ts
    n = np.arange(cycles)
    out: dict[str, np.ndarray] = {}
    for ch in d.channels:
        c = ch["name"]
        level = np.interp(at, t, plot[f"v(b_{c})"])
        out[f"bits_{c}"] = np.where(level > 0.5, 1, -1).astype(np.int8)
        out[f"latch_{c}"] = level  # the held latch level (ideally 0 or 1): soft decisions
        y = _optional(plot, f"v(y_{c})")
        if y is not None:
            y = np.interp((n + d.t.clk + d.t.sample) * d.ts, t, y)
            out[f"cmp_{c}"] = y + ch["dither_v"] * np.sin(ch["dither_step"] * (n + start))
    for c in model.coordinates:
        out[f"x_{c.name}"] = np.interp(at, t, plot[f"v(x_{c.name})"])
    out["time"] = at
    return out


def _optional(plot, name: str) -> np.ndarray | None:
    """A vector the plot may lack (the lead-filter outputs of a run that did not save them)."""
    try:
        return plot[name]
    except KeyError:
        return None


def psd(bits: np.ndarray, ts: float, nperseg: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Welch PSD of a +-1 bitstream (Hann, 50 % overlap): the spectrum normalised to the square
    of the fed-back force/torque, one-sided, in 1/Hz."""
    n = nperseg or min(len(bits), max(256, len(bits) // 8))
    return signal.welch(bits.astype(float), fs=1.0 / ts, window="hann", nperseg=n, detrend="constant")


def features(f: np.ndarray, p: np.ndarray, min_db: float = 6.0) -> tuple[list[dict], list[dict]]:
    """Notches and peaks of a PSD: deviations of > min_db from its running median (log f window)."""
    db = 10 * np.log10(p[1:] + 1e-300)
    ff = f[1:]
    width = max(5, len(db) // 40) | 1
    base = signal.medfilt(db, width)
    out = []
    for sign in (-1, 1):
        idx, props = signal.find_peaks(sign * (db - base), height=min_db, distance=width)
        out.append([{"freq_hz": float(ff[i]), "depth_db": float(sign * (db[i] - base[i]))} for i in idx])
    notches = sorted(out[0], key=lambda r: -r["depth_db"])[:10]
    peaks = sorted(out[1], key=lambda r: -r["depth_db"])[:10]
    return notches, peaks


def band_metrics(f: np.ndarray, p: np.ndarray, ts: float, osr: float, tone_hz: float | None, dc_bins: int = 1) -> dict:
    """In-band noise floor (median, dB re F_fb^2/Hz), noise power, SNR of the tone at `tone_hz`
    (its +-3 bins: the Hann main lobe), noise-shaping slope over the decade below the band edge.
    The band starts at bin `dc_bins`: 1, every bin above DC (the command's summary); the
    loop-order bench starts at 2 (DC_BINS), since there the first bin holds the Hann
    main lobe of the bitstream's large mean, a DC input's (gravity at a mean bit of 0.5)."""
    fb = 0.5 / ts / osr
    df = f[1] - f[0]
    band = (f >= dc_bins * df) & (f <= fb)
    mask = band.copy()
    if not band.any():  # run too short: no PSD bin inside the band
        return {
            "band_hz": [None, float(fb)],
            "noise_floor_db_per_hz": None,
            "inband_noise_db": None,
            "note": "band has no PSD bins: run more cycles",
        }
    out: dict = {"band_hz": [float(f[band][0]), float(fb)]}
    if tone_hz and not tone_hz <= fb:  # above the band edge: no in-band tone to quote
        out["tone_note"] = f"the tone at {tone_hz:g} Hz is above the band edge {fb:g} Hz: no tone level or SNR"
        tone_hz = None
    if tone_hz:
        near = band & (np.abs(f - tone_hz) <= 3 * df)
        mask &= ~near
        sig = float(np.sum(p[near]) * df)
        out["tone_power"] = sig
        out["tone_level_db"] = float(10 * np.log10(sig)) if sig > 0 else None
    if mask.sum() < 2:  # run too short to resolve the band
        out.update({"noise_floor_db_per_hz": None, "inband_noise_db": None, "note": "band has < 2 bins"})
        return out
    noise = float(np.sum(p[mask]) * df)
    out["noise_floor_db_per_hz"] = float(10 * np.log10(np.median(p[mask])))
    out["inband_noise_db"] = float(10 * np.log10(noise))
    if tone_hz and out["tone_level_db"] is not None:
        out["snr_db"] = float(out["tone_level_db"] - out["inband_noise_db"])
    lo, hi = fb / 10, fb
    sel = (f >= lo) & (f <= hi) & mask
    if sel.sum() > 3:
        slope, at = np.polyfit(np.log10(f[sel]), 10 * np.log10(p[sel]), 1)
        out["slope_db_per_decade"] = float(slope)
        out["slope_fit"] = {"band_hz": [float(lo), float(hi)], "db_at_1hz": float(at)}
    return out


# the first bin above DC lies in the Hann main lobe of the bitstream's mean (a DC input such as
# gravity makes it large: in a fourth-order loop at a mean bit of 0.5 that one bin held -83.6 dB
# against -95 dB for the rest of the band), so the bench's noise starts at bin 2
DC_BINS = 2


def tone_frequency(ts: float, nperseg: int, osr: float, fraction: float = 0.25) -> float:
    """A test-tone frequency at the centre of a PSD bin near `fraction` of the band edge."""
    df = 1.0 / (ts * nperseg)
    return df * max(3, round(fraction * 0.5 / (ts * osr) / df))


def dynamic_range(
    run: Callable[[float], tuple[np.ndarray, bool]],
    amplitudes: np.ndarray,
    ts: float,
    osr: float,
    tone_hz: float,
    nperseg: int | None = None,
    skip: int = 0,
) -> dict:
    """SNR against input amplitude (fractions of full scale): `run(a)` gives the bitstream and
    whether the loop held; the maximum stable amplitude is the largest held amplitude below the
    first that was lost; the dynamic range is the amplitude span from SNR = 0 dB (extrapolated on
    the 1 dB/dB line from the smallest amplitude) to the peak SNR."""
    rows, max_stable, lost = [], None, False
    for a in np.asarray(amplitudes, dtype=float):
        v, held = run(float(a))
        m = band_metrics(*psd(v[skip:], ts, nperseg), ts, osr, tone_hz, DC_BINS) if held else {}  # lost: no SNR
        rows.append(
            {
                "amplitude": float(a),
                "amplitude_dbfs": float(20 * np.log10(a)),
                "held": held,
                "sqnr_db": m.get("snr_db"),
                "noise_db": m.get("inband_noise_db"),
            }
        )
        lost = lost or not held
        if held and not lost:
            max_stable = float(a)
    held = [r for r in rows if r["held"]]
    if not held:
        return {"rows": rows, "max_stable_amplitude": None, "peak_sqnr_db": None, "dynamic_range_db": None}
    best = max(held, key=lambda r: r["sqnr_db"])
    low = min(held, key=lambda r: r["amplitude"])
    zero_db = low["amplitude_dbfs"] - low["sqnr_db"]  # input level of SNR = 0 dB
    return {
        "rows": rows,
        "max_stable_amplitude": max_stable,
        "peak_sqnr_db": best["sqnr_db"],
        "dynamic_range_db": float(best["amplitude_dbfs"] - zero_db),
    }


def tone_fit(bits: np.ndarray, t: np.ndarray, freq: float, ts: float, osr: int) -> dict:
    """The tone in a +-1 bitstream by a least-squares sine at its known frequency (exact where the
    PSD's bins are wider than the tone's distance from DC, which short runs have): amplitude in
    bits (1 = the full-scale force), its power B^2/2 in dB, and the SQNR: that power over the
    in-band power of the bitstream with the fitted sine (and its mean) removed."""
    a = np.column_stack([np.sin(2 * np.pi * freq * t), np.cos(2 * np.pi * freq * t), np.ones_like(t)])
    c = np.linalg.lstsq(a, bits.astype(float), rcond=None)[0]
    amp = float(np.hypot(c[0], c[1]))
    f, p = psd(bits - a @ c, ts)
    band = (f > 0) & (f <= 0.5 / ts / osr)
    noise = float(np.sum(p[band]) * (f[1] - f[0]))
    out = {
        "tone_amplitude_bits": amp,
        "tone_fit_db": float(10 * np.log10(amp * amp / 2 + 1e-300)),
        "residual_inband_noise_db": float(10 * np.log10(noise + 1e-300)),
    }
    if freq <= 0.5 / ts / osr and noise > 0:  # an SQNR is of an in-band tone
        out["sqnr_db"] = out["tone_fit_db"] - out["residual_inband_noise_db"]
    return out


def scale_factor(inputs: np.ndarray, bit_means: np.ndarray, full_scale: float | None = None) -> dict:
    """Bitstream mean against the applied input (a DC sweep): the least-squares line's slope (the
    scale factor, bit mean per input unit) and offset, and the linearity: the largest residual
    from that line in % of full scale (full_scale: the input at a bit mean of 1; default
    1 / |slope|). Why here: the accelerometer's acceptance figure (docs/sigma-delta.md)."""
    x, y = np.asarray(inputs, float), np.asarray(bit_means, float)
    if len(x) < 3:
        raise ValueError("a scale-factor fit needs at least 3 inputs")
    slope, offset = np.polyfit(x, y, 1)
    fs = full_scale or 1.0 / abs(slope)
    resid = y - (slope * x + offset)
    return {
        "scale_factor": float(slope),
        "offset": float(offset),
        "full_scale_input": float(fs),
        "max_nonlinearity_pct_fs": float(np.max(np.abs(resid)) / abs(slope) / fs * 100),
        "residuals": resid.tolist(),
    }


def analyse(clock: dict, d: Design, tone: Tone | None = None, osr: int = 64, skip: int = 0) -> dict:
    """Summary per channel: spectra features, noise floor, SNR, bit mean and force balance."""
    summary: dict = {
        "ts": d.ts,
        "fs_hz": 1 / d.ts,
        "osr": osr,
        "cycles": int(len(clock["time"])),
        "skip": skip,
        "vfb": d.vfb,
        "vs": d.vs,
        "lead": d.lead,
        "channels": {},
        "spectra": {},
    }
    for c in d.names:
        bits = clock[f"bits_{c}"][skip:]
        f, p = psd(bits, d.ts)
        notches, peaks = features(f, p)
        m = band_metrics(f, p, d.ts, osr, tone.freq if tone else None)
        if tone:
            m |= tone_fit(bits, clock["time"][skip:], tone.freq, d.ts, osr)
        summary["channels"][c] = {
            "bit_mean": float(bits.mean()),
            "fed_back_level_si": d.level(c),
            "bit_mean_needed": d.channel(c)["bit_mean_needed"],
            "filter": d.channel(c)["filter"],
            **m,
            "notches": notches,
            "peaks": peaks,
            **latch_quality(clock, c, skip, d.latch_resolution),
        }
        summary["spectra"][c] = (f, p)
    summary["gravity_balance"] = gravity_balance(clock, d, skip)
    summary["coordinates"] = {
        k[2:]: {"mean": float(v[skip:].mean()), "min": float(v[skip:].min()), "max": float(v[skip:].max())}
        for k, v in clock.items()
        if k.startswith("x_")
    }
    return summary


def latch_quality(clock: dict, channel: str, skip: int = 0, resolution: float | None = None) -> dict:
    """How cleanly the latch held its decision: the worst distance of the held level from 0 or 1;
    the periods where the electrode drive's restoring bit(x) = (1 + tanh(40 (x - 1/2))) / 2 is
    more than 1e-3 off 0/1 (distance > 0.41): a partial feedback force while the bitstream records
    +-1; the held levels more than CLEAN_LATCH off 0/1 (`unclean_latches`) and of those the ones the
    comparator's stated `resolution` (V, Design.latch_resolution) does not explain: |y + dither| at
    the latch instant (cmp_<c>) at or above it, or not recorded (`unexplained_latches`). Empty for
    clocks without latch levels (older bitstream files)."""
    level = clock.get(f"latch_{channel}")
    if level is None:
        return {}
    err = np.minimum(np.abs(level[skip:]), np.abs(level[skip:] - 1.0))
    restored = 0.5 - 0.5 * np.tanh(40.0 * (0.5 - err))  # drive error of bit() at that level
    unclean = err > CLEAN_LATCH
    out = {
        "partial_latches": int(np.sum(restored > 1e-3)),
        "max_latch_error": float(err.max(initial=0.0)),
        "unclean_latches": int(unclean.sum()),
    }
    y = clock.get(f"cmp_{channel}")
    if y is None or resolution is None:
        return out | {"unexplained_latches": out["unclean_latches"]}
    y = np.abs(y[skip:])
    return out | {
        "below_resolution": int(np.sum(y < resolution)),
        "unexplained_latches": int(np.sum(unclean & (y >= resolution))),
        "min_cmp_over_resolution": float(y.min(initial=np.inf) / resolution),
    }


def levitation(clock: dict, model: MacroModel, limit: float = 0.02) -> dict:
    """Did the loop hold the plate? The first period where a coordinate leaves `limit` of its
    touching amplitude (the reference loop keeps them within 0.02 % at T_s = 1 us and 0.25 % at
    3.2 us, where the (3,0) modes overload it); a lost plate makes the spectra
    those of a plate at the stop, so the command reports it instead of a silent result."""
    for n in range(len(clock["time"])):
        for c in model.coordinates:
            touch = c.scale / c.port_units[1]
            if abs(clock[f"x_{c.name}"][n]) > limit * touch:
                return {
                    "held": False,
                    "lost_at_period": n,
                    "coordinate": c.name,
                    "value": float(clock[f"x_{c.name}"][n]),
                    "limit": limit * touch,
                }
    return {"held": True, "limit_fraction_of_touch": limit}


def gravity_balance(clock: dict, d: Design, skip: int = 0) -> dict:
    """Momentum balance on the balanced channel (Design.balance: the disk's z) between the clock samples a = skip and b = N - 2: the mean
    electrostatic force implied by the bits (the model's centre force of each bit pattern x the
    feedback duty, plus the sense-phase force) against -F_dc + m (v_b - v_a) / (t_b - t_a) (F_dc:
    the DC input force, -m g for gravity), with
    v from central differences of x_z, + the damping impulse B(0) (x_b - x_a) / (t_b - t_a) (exact
    for a dashpot; a film branch adds its force change / corner, negligible for corners far above
    the loop's motion) + the suspension's spring impulse K mean(x) (the samples' trapezoid mean; 0
    for a free mass such as the levitated disk, up to 1.8 % of m g on accelerometer_xyz's 64-period
    run). Samples sit mid-feedback, so the end periods count half. An applied tone
    force and the thermal noise force are not included (the first averages out only over whole
    tone periods; the second's impulse is ~1e-3 of m g T at 100 Pa over 128 periods)."""
    name, unit = d.balance["channel"], d.channels[d.balance["index"]]["force_unit_si"]
    pats = np.stack([clock[f"bits_{c}"] for c in d.names], axis=1)
    lookup = {tuple(r["pattern"]): r["f"][name] * unit for r in d.table}
    fz = np.array([lookup[tuple(p)] for p in pats.tolist()])
    a, b = skip, len(fz) - 2
    if b - a < 8:
        raise ValueError(f"too few clock samples after skipping {skip} for a force balance")
    weights = np.ones(b - a + 1)
    weights[[0, -1]] = 0.5
    sense = d.sense_force[d.balance["coord"]] * duty(d.t, d.t.sense_on, d.t.sense_off)
    mean = float(np.dot(weights, fz[a : b + 1]) / (b - a) * d.duty + sense)
    x = clock[f"x_{name}"] * d.balance["x_unit_si"]  # the port: 1 V = 1 um (or 1 mrad)
    v = lambda n: (x[n + 1] - x[n - 1]) / (2 * d.ts)  # noqa: E731
    inertia = d.mass * (v(b) - v(a)) / ((b - a) * d.ts)
    damping = d.damping * (x[b] - x[a]) / ((b - a) * d.ts)
    spring = d.balance["stiffness"] * float(np.dot(weights, x[a : b + 1]) / (b - a))
    weight = -d.balance["dc_force_n"]
    need = weight + inertia + damping + spring
    # no DC input: the ratio of two near-zero forces says nothing; the residual force does
    full = d.channels[d.balance["index"]]["full_scale_force_si"]
    ratio = float(mean / need) if abs(weight) > 1e-3 * full else None
    return {
        "channel": name,
        "mean_force_n": mean,
        "weight_n": weight,
        "inertial_n": float(inertia),
        "damping_n": float(damping),
        "spring_n": spring,
        "ratio": ratio,
        "residual_n": float(mean - need),
        "window": [a, b],
    }


def thermal_floor(model: MacroModel, d: Design) -> dict:
    """The gas film's Brownian force floor per channel, in the spectra's normalisation:
    S_F = 4 k_B T Re B(0) (damper plus film branches, in band) over the fed-back level squared,
    dB re F_fb^2/Hz; with the model's noise switch (noise sources in the netlist or not)."""
    damping = model.report.get("damping", {})
    temp = float(damping.get("temperature_K", 300.0))
    noise = bool(damping.get("noise", False))
    out = {
        "noise_sources_emitted": noise,
        "temperature_K": temp,
        "pressure_Pa": damping.get("squeeze_film", {}).get("pressure_Pa"),
        "channels": {},
    }
    if noise:  # measured: `setseed`, `set rndseed` and `.options seed` all leave TRNOISE unseeded
        out["reproducibility"] = (
            "statistical only: ngspice 39 fills the Gaussian pool of TRNOISE from its "
            "process id (trannoise/wallace.c initw) and no seed option reaches it"
        )
    for c in d.names:
        b = float(model.coordinates[d.channel(c)["coord"]].admittance(0.0).real)
        floor = 10 * np.log10(4 * K_B * temp * b / d.level(c) ** 2) if b > 0 else None
        out["channels"][c] = {"damping_si": b, "thermal_floor_db_per_hz": floor}
    return out
