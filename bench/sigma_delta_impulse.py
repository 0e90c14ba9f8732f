"""The feedback impulse the compiled ngspice loop delivers to the proof mass, period by period,
against the exact one: the measurement that found the circuit's flat in-band floor.

    .venv/bin/python bench/sigma_delta_impulse.py [--model examples/accelerometer_z.toml] [--cycles 4096]
        [--order 4] [--fb-edge 0.02 | 0] [-o DIR]

One ngspice run of the loop (no segments) saves the model's velocity and position nodes at every
time point. Per period n the velocity change over the feedback phase (sense off .. reset off,
0.47-0.97 T_s, where only the feedback, the springs and the input act) is regressed on the bit,
a constant, the position's integral over the window (the springs), bit x that integral (a
position-dependent feedback force: the electrostatic nonlinearity), and the tone's sine and
cosine; what is left, over the bit's coefficient, is the impulse error in units of one bit's
impulse. Its Welch spectrum in the band is the floor it puts on the bitstream (the loop passes an
error of the fed-back force to the bits unshaped, as it does the input).

With the ramped feedback (--fb-edge 0.02, the lead2 default) on the z accelerometer the error
is 8.6e-5 rms and white at about -140 dB/Hz, the circuit's floor: ngspice integrates the ramps'
V^2 force by the trapezoidal rule (backward Euler after each corner) on time steps that change
from period to period with the other nodes' truncation errors. With the feedback step
(--fb-edge 0, the designed filters' default; netgen_sdloop's fb_level) it is 8e-9 rms
(about -213 dB/Hz). Prints the figures; DIR/impulse.json keeps them.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from netgen.build import build_model
from netgen.structure import load_structure
from netgen.testbench.sigma_delta import Tone, analysis, design, filters, ngspice, psd, read_structure_loop

WINDOW = (0.47, 0.97)  # sense off .. reset off: only the feedback, springs and input act on the mass
NPERSEG = 8192


def run(args) -> dict:
    """Build, run and analyse; the figures."""
    model = build_model(load_structure(args.model), progress=False)
    spec = read_structure_loop(args.model)
    if args.order > 2:
        spec = replace(spec, filter={"kind": "cifb", "order": args.order, "osr": 64.0, "h_inf": args.h_inf})
    if args.fb_edge is not None:
        spec = replace(spec, timing={**spec.timing, "fb_edge": args.fb_edge})
    d = design(model, args.ts, spec=spec)
    name = d.channels[0]["name"]
    mech = filters.mechanics_of(model, d, name)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    lib, control = ngspice.xspice_library(model, out, ngspice.code_models(False))
    tone = Tone("a_in", args.tone_fs * mech.full_scale, analysis.tone_frequency(args.ts, NPERSEG, 64))
    nodes = [f"x1.u_{name}", f"x1.xs_{name}"]
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
    t, u, xs = (np.asarray(plot[k]) for k in ("time", f"v({nodes[0]})", f"v({nodes[1]})"))
    bits = np.asarray(plot[f"v(b_{name})"])
    e, coef = impulse_error(t, u, xs, bits, d.ts, tone.freq)
    f, p = psd(e, d.ts, min(NPERSEG, len(e) // 4))
    fb = 0.5 / d.ts / 64
    band = (f > fb / 10) & (f < fb)
    res = {
        "fb_edge": d.t.fb_ramp,
        "order": args.order,
        "periods": args.cycles,
        "points_per_period": len(t) / args.cycles,
        "impulse_error_rms": float(np.std(e)),
        "impulse_error_db_per_hz": float(10 * np.log10(np.median(p[band]))),
        "bit_x_position_over_spring": float(coef[5] / coef[2]),
    }
    (out / "impulse.json").write_text(json.dumps(res, indent=1) + "\n")
    return res


def impulse_error(t, u, xs, bits, ts: float, tone_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Per period the velocity change over WINDOW less its regression on bit, 1, the position's
    integral, bit x that integral and the tone, over the bit's coefficient; and the coefficients."""
    cycles = int(round(t[-1] / ts))
    n = np.arange(1, cycles - 1)
    a, b = WINDOW
    du = np.interp((n + b) * ts, t, u) - np.interp((n + a) * ts, t, u)
    bit = np.where(np.interp((n + 0.72) * ts, t, bits) > 0.5, 1.0, -1.0)
    grid = (n[:, None] + np.linspace(a, b, 201)[None, :]) * ts
    xm = np.trapezoid(np.interp(grid, t, xs), grid, axis=1)
    tc = (n + 0.5 * (a + b)) * ts
    x = np.stack(
        [bit, np.ones_like(bit), xm, np.sin(2 * np.pi * tone_hz * tc), np.cos(2 * np.pi * tone_hz * tc), bit * xm],
        axis=1,
    )
    coef = np.linalg.lstsq(x, du, rcond=None)[0]
    return (du - x @ coef) / coef[0], coef


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", default="examples/accelerometer_z.toml")
    p.add_argument("--cycles", type=int, default=4096)
    p.add_argument("--order", type=int, default=4, help="2: the structure's own filter; 3-5: cifb")
    p.add_argument("--h-inf", type=float, default=1.4)
    p.add_argument("--fb-edge", type=float, default=None, help="feedback edge width (T_s); 0: the step")
    p.add_argument("--tone-fs", type=float, default=0.1)
    p.add_argument("--ts", type=float, default=1e-6)
    p.add_argument("-o", "--out", default="out/sigma_delta_impulse")
    res = run(p.parse_args())
    print(", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in res.items()))


if __name__ == "__main__":
    main()
