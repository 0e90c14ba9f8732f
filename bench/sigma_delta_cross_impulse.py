"""The first channel's feedback impulse per period in a loop of several channels (the levitated
disk: z on cifb order 4, the tilts on lead2), split by what the single-channel numpy reference
leaves out: the other channels' bits and bit products, and every coordinate's position times
each bit pattern (a position-dependent feedback force).

    .venv/bin/python bench/sigma_delta_cross_impulse.py [--model netlists/levitated_disk.json]
        [--loop LOOP.toml] [--cycles 8192] [-o DIR]

One ngspice run of the compiled loop (bench/sigma_delta_orders.py's set-up, the feedback step)
saves the channel's velocity node and every coordinate's position node. Per period the velocity
change over the feedback phase (0.47-0.97 T_s) is regressed on the channel's bit, a constant,
the tone, its own position's integral (what the reference has), and on the groups below; each
group's part over one bit's impulse is an error of the fed-back force, which the loop passes to
the bitstream unshaped, so its in-band PSD (median over 400 Hz..5 kHz, dB/Hz re one bit's force)
is the floor it sets. Groups: "tilt bits" (the other channels' bits alone), "bit products" (the
channel's bit times the others', the force table's cross terms), "own position x pattern",
"other positions x pattern" (each other rigid coordinate's position times the 8 bit patterns),
"modes x pattern". The groups are collinear (a tilt's mean position times a bit product is a
bit product), so their sum is the figure; the parts show which terms carry it. Also prints the
MacroModel's own dF/dq per bit pattern at rest next to the regression's coefficient for the
largest position terms (they agree: the regression measures the model's electrostatics).
Last, the causal check: the numpy reference of the channel run with the measured error added to
its feedback (the terms with the channel's bit as a relative change of its force g[n], the rest
as a force h[n], the 8192-period sequences tiled 4x), its z-bit PSD per octave against the
reference's own and the error's.
Measured on the disk (docs/sigma-delta-validation.md, "The disk's second floor").
"""

from __future__ import annotations

import argparse
import itertools
import json
from pathlib import Path

import numpy as np
from scipy import linalg
from sigma_delta_orders import setup
from support import sigma_delta_reference as reference

from netgen.testbench.sigma_delta import Tone, analysis, filters, ngspice, psd
from netgen.testbench.sigma_delta.loop import selected

WINDOW = (0.47, 0.97)  # sense off .. reset off: only the feedback, springs and input act on the mass
NPERSEG = 8192
BAND = (400.0, 5000.0)  # where the disk's circuit spectrum was flat


def run(args) -> dict:
    """Build the loop, run it once, regress and report."""
    model, d, mech, _ = setup(args.model, args.ts, args.order, 64, None, loop=args.loop)
    name, coords = d.names[0], [c.name for c in model.coordinates]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    lib, control = ngspice.xspice_library(model, out, ngspice.code_models(False))
    tone_hz = analysis.tone_frequency(args.ts, NPERSEG, 64)
    tone = Tone(name, args.tone_fs * mech.full_scale * mech.mass * 1e6, tone_hz)  # uN on f_<q>
    nodes = [f"x1.u_{name}"] + [f"x1.xs_{c}" for c in coords]
    net = ngspice.testbench(
        model,
        d,
        lib.resolve(),
        args.cycles,
        "sigma_delta.raw",
        tone,
        ngspice.Settings("xspice", control, chunks=1),
        ngspice.Segment(states=nodes),
    )
    plot = ngspice.simulate(net, out, d.ts * args.cycles, False)
    t = np.asarray(plot["time"])
    per = periods(t, d.ts)
    du = window_mean(t, np.asarray(plot[nodes[0]]), per, d.ts, diff=True)
    bits = {
        c: np.where(np.interp((per + 0.72) * d.ts, t, np.asarray(plot[f"v(b_{c})"])) > 0.5, 1.0, -1.0) for c in d.names
    }
    pos = {c: window_mean(t, np.asarray(plot[f"v(x1.xs_{c})"]), per, d.ts) for c in coords}
    groups, labels = regressors(model, d, bits, pos, per, d.ts, tone_hz)
    m = np.hstack([np.stack(g, axis=1) for g in groups.values()])
    owner = [k for k, g in groups.items() for _ in g]
    scale = np.where(np.std(m, axis=0) > 0, np.std(m, axis=0), 1.0)
    coef = np.linalg.lstsq(m / scale, du, rcond=None)[0] / scale
    unit = coef[0]  # one bit's velocity change
    res = {
        "model": args.model,
        "channels": d.names,
        "fb_edge": d.t.fb_ramp,
        "periods": args.cycles,
        "max_abs_xs": {c: float(np.max(np.abs(plot[f"v(x1.xs_{c})"]))) for c in coords},
        "floor_db_per_hz": {},
        "rms": {},
    }
    parts = {k: [k] for k in groups if k != "reference"}
    parts["all but the reference's"] = list(parts)
    parts["residual"] = []
    for k, g in parts.items():
        e = (
            (du - m @ coef) / unit
            if k == "residual"
            else m[:, [i for i, o in enumerate(owner) if o in g]]
            @ coef[[i for i, o in enumerate(owner) if o in g]]
            / unit
        )
        res["floor_db_per_hz"][k], res["rms"][k] = floor(e, d.ts)
    res["bits_floor_db_per_hz"] = floor(bits[name], d.ts)[0]
    res["coefficients"] = {
        lab: float(c / unit * (WINDOW[1] - WINDOW[0]) * d.ts if "x" in lab.split(" ")[0:1] else c / unit)
        for lab, c in zip(labels, coef)
    }
    res["model_dfdq"] = model_slopes(model, d, coords)
    own = np.array([o != "reference" and name in lab.split(" ")[-1].split("*") for o, lab in zip(owner, labels)])
    rest = np.array([o != "reference" for o in owner]) & ~own
    g, h = m[:, own] @ coef[own] / unit * bits[name][:], m[:, rest] @ coef[rest] / unit
    res["injected_octaves_db_per_hz"] = injected(
        model,
        d,
        mech,
        f_filter(d),
        g,
        h,
        args,
        tone_hz,
        (du - m @ coef) / unit + m[:, own | rest] @ coef[own | rest] / unit,
    )
    return res


def f_filter(d):
    """The first channel's loop filter."""
    return filters.Filter.from_dict(d.channels[0]["filter"])


OCTAVES = [244.0, 488.0, 977.0, 1953.0, 3906.0, 7812.0]


def octaves(v: np.ndarray, ts: float, tone_hz: float) -> list[float]:
    """Median PSD per octave of OCTAVES (dB/Hz), the tone's bins left out, after the first eighth."""
    f, p = psd(v[len(v) // 8 :], ts, NPERSEG)
    return [
        float(10 * np.log10(np.median(p[(f >= lo) & (f < hi) & (np.abs(f - tone_hz) > 400)])))
        for lo, hi in zip(OCTAVES, OCTAVES[1:])
    ]


def injected(model, d, mech, flt, g: np.ndarray, h: np.ndarray, args, tone_hz: float, e: np.ndarray) -> dict:
    """The reference loop (reference.simulate's equations) with the feedback v (1 + g[n]) + h[n],
    the sequences tiled 4x; octave PSDs of its bits, of the reference's own and of the error."""
    inp = reference.Input(filters.dc_acceleration(model, d, d.names[0]), args.tone_fs * mech.full_scale, tone_hz)
    a, b = reference.augmented(mech, inp)
    phi, gamma = filters.step_map(a, b, mech.ts, mech.sample, mech.pulse)
    n = 4 * len(g)
    gt, ht = np.tile(g, 4), np.tile(h, 4)

    def loop(on: float) -> np.ndarray:
        s = linalg.expm(a * mech.sample * mech.ts) @ np.array([0.0, 0.0, 1.0, 0.0, 1.0])
        u, v = np.zeros(flt.states), np.empty(n)
        for k in range(n):
            x = mech.gain * s[0] + mech.offset
            v[k] = 1.0 if float(flt.c @ u) + flt.d * (x - flt.x0) > 0 else -1.0
            u = flt.a @ u + flt.bx * (x - flt.x0) + flt.bv * v[k]
            s = phi @ s + gamma * (v[k] * (1 + on * gt[k]) + on * ht[k])
        return v

    return {
        "reference": octaves(loop(0.0), d.ts, tone_hz),
        "reference + error": octaves(loop(1.0), d.ts, tone_hz),
        "error": octaves(np.tile(e, 4), d.ts, tone_hz),
    }


def periods(t: np.ndarray, ts: float) -> np.ndarray:
    """The period indices analysed: all but the first 8 and the last."""
    return np.arange(8, int(round(t[-1] / ts)) - 1)


def window_mean(t: np.ndarray, y: np.ndarray, n: np.ndarray, ts: float, diff: bool = False) -> np.ndarray:
    """Per period: y's change over WINDOW (diff) or its integral over WINDOW (per second)."""
    a, b = WINDOW
    if diff:
        return np.interp((n + b) * ts, t, y) - np.interp((n + a) * ts, t, y)
    grid = (n[:, None] + np.linspace(a, b, 201)[None, :]) * ts
    return np.trapezoid(np.interp(grid, t, y), grid, axis=1)


def regressors(model, d, bits: dict, pos: dict, n: np.ndarray, ts: float, tone_hz: float):
    """The regressor groups (first: what the reference has; its first column the channel's bit)
    and one label per column."""
    name, others = d.names[0], d.names[1:]
    b0 = bits[name]
    patterns = pattern_columns(d.names, bits)
    tc = (n + 0.5 * sum(WINDOW)) * ts
    groups = {
        "reference": [
            b0,
            np.ones_like(b0),
            np.sin(2 * np.pi * tone_hz * tc),
            np.cos(2 * np.pi * tone_hz * tc),
            pos[name],
        ],
        "tilt bits": [bits[o] for o in others],
        "bit products": [v for k, v in patterns.items() if "*" in k],
        "own position x pattern": [pos[name] * v for k, v in patterns.items() if k != "1"],
        "other positions x pattern": [pos[c] * v for c in others for v in patterns.values()],
        "modes x pattern": [pos[c] * v for c in pos if c not in d.names for v in patterns.values()],
    }
    labels = (
        [name, "1", "sin", "cos", f"x {name}"]
        + list(others)
        + [k for k in patterns if "*" in k]
        + [f"x {name} {k}" for k in patterns if k != "1"]
        + [f"x {c} {k}" for c in others for k in patterns]
        + [f"x {c} {k}" for c in pos if c not in d.names for k in patterns]
    )
    return {k: g for k, g in groups.items() if g}, [lab for lab, k in zip(labels, label_groups(groups)) if groups[k]]


def label_groups(groups: dict) -> list[str]:
    """The group of each column, in order."""
    return [k for k, g in groups.items() for _ in g]


def pattern_columns(names: list[str], bits: dict) -> dict[str, np.ndarray]:
    """Every product of a subset of the channels' bits (the 2^C terms of the force table)."""
    out = {}
    for r in range(len(names) + 1):
        for sub in itertools.combinations(names, r):
            out["*".join(sub) or "1"] = np.prod([bits[s] for s in sub], axis=0) if sub else np.ones_like(bits[names[0]])
    return out


def table_terms(model, d, q: np.ndarray) -> np.ndarray:
    """The first channel's force at normalised position q for each bit pattern, as coefficients
    of the pattern products (pattern_columns' order), over the bit's own coefficient at rest."""
    rows, forces = [], []
    for bb in itertools.product((1.0, -1.0), repeat=len(d.names)):
        f = model.electrostatic_force(q, d.vfb * selected(d.electrodes, bb))[0][d.channels[0]["coord"]]
        cols = pattern_columns(d.names, {c: np.array([b]) for c, b in zip(d.names, bb)})
        rows.append([v[0] for v in cols.values()])
        forces.append(f)
    return np.linalg.lstsq(np.array(rows), np.array(forces), rcond=None)[0]


def model_slopes(model, d, coords: list[str]) -> dict:
    """The MacroModel's dF/dq (q normalised, as the xs_ nodes) per pattern term, over one bit's
    force, for each rigid coordinate in the loop; and the force table's terms at rest."""
    keys = list(pattern_columns(d.names, {c: np.ones(1) for c in d.names}))
    rest = table_terms(model, d, np.zeros(model.ncoords))
    out = {"at rest": dict(zip(keys, (rest / rest[1]).tolist()))}
    for c in d.names:
        i, h = coords.index(c), 1e-6
        q = np.zeros(model.ncoords)
        q[i] = h
        up = table_terms(model, d, q)
        q[i] = -h
        out[f"d/d {c}"] = dict(zip(keys, ((up - table_terms(model, d, q)) / (2 * h) / rest[1]).tolist()))
    return out


def floor(e: np.ndarray, ts: float) -> tuple[float, float]:
    """In-band PSD median over BAND (dB/Hz) after the first eighth, and the rms."""
    e = e[len(e) // 8 :]
    f, p = psd(e, ts, min(NPERSEG, len(e) // 4))
    sel = (f > BAND[0]) & (f < BAND[1])
    return float(10 * np.log10(np.median(p[sel]) + 1e-300)), float(np.std(e))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", default="netlists/levitated_disk.json")
    p.add_argument("--loop", default=None, help="a loop description (LOOP.toml) replacing the model's")
    p.add_argument("--cycles", type=int, default=8192)
    p.add_argument("--order", type=int, default=4)
    p.add_argument("--tone-fs", type=float, default=0.01)
    p.add_argument("--ts", type=float, default=1e-6)
    p.add_argument("-o", "--out", default="out/sigma_delta_cross_impulse")
    args = p.parse_args()
    res = run(args)
    (Path(args.out) / "impulse.json").write_text(json.dumps(res, indent=1) + "\n")
    print(f"{res['model']}: channels {res['channels']}, fb_edge {res['fb_edge']}, {res['periods']} periods")
    for k, v in res["floor_db_per_hz"].items():
        print(f"  {k:<28} floor {v:7.1f} dB/Hz  rms {res['rms'][k]:.3g}")
    big = sorted(
        (
            (abs(v), k)
            for k, v in res["coefficients"].items()
            if len(k.split()) == 3 or (not k.startswith("x ") and "*" in k)
        ),
        reverse=True,
    )[:4]
    print(
        "  largest terms (over one bit; position terms per normalised unit):",
        ", ".join(f"{k} {res['coefficients'][k]:+.3g}" for _, k in big),
    )
    print("  the model's at rest:", {k: f"{v:+.3g}" for k, v in res["model_dfdq"]["at rest"].items() if k != "1"})
    for c in res["channels"][1:]:
        s = res["model_dfdq"][f"d/d {c}"]
        print(f"  the model's d/d {c}:", {k: f"{v:+.3g}" for k, v in s.items() if abs(v) > 1e-3})
    print("  octaves " + ", ".join(f"{lo:g}" for lo in OCTAVES) + " Hz (dB/Hz):")
    for k, v in res["injected_octaves_db_per_hz"].items():
        print(f"    {k:<18}" + " ".join(f"{x:7.1f}" for x in v))


if __name__ == "__main__":
    main()
