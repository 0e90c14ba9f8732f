"""`netgen sigma-delta STRUCTURE.toml -o DIR`: the sigma-delta force-feedback loop (the paper's
levitation loop, for any device: the structure's [loop] table or --loop LOOP.toml) around the
structure's macromodel, with spectra (netgen.testbench.sigma_delta.runner)."""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

from ...arguments import existing_file, integer, number, output_folder, positive
from ...errors import SimulationError
from ...folders import OutputFolder
from ...model import MacroModel
from ...units import parse_quantity
from .loop import RELTOL_RANGE, RELTOL_TEXT, Tone
from .loopfile import read_loop_file, read_structure_loop
from .ngspice import MIN_SEGMENT, SEGMENT_S
from .runner import BACKENDS, TIMEOUT, backend_design, model_folder, model_for, run

# the run's result set in DIR (sigma-delta.manifest.json names it) and the caches it shares with
# earlier runs there (compiled Verilog-A, by content hash)
RESULTS = "sigma-delta"
MIN_CYCLES, MAX_CYCLES = 64, 1 << 24  # the analysis needs 64; 2^24 periods write ~250 GB of raw file
TS_MAX = 1.0  # s
SHARED = ("osdi",)
# the files a run writes (its set when a folder from before manifests holds them)
RESULT_FILES = (
    "bitstreams.npz",
    "spectra.npz",
    "summary.json",
    "spectra.png",
    "coordinates.png",
    "sigma_delta.cir",
    "sigma_delta.log",
    "sigma_delta.sim",
    "sigma_delta.vacask.log",
)


def parse_pressure(text: str) -> float:
    """A pressure option: a number in Pa or a quantity string ('100 Pa', '1 mbar', '1 atm')."""
    try:
        value = float(text)
    except ValueError:
        try:
            value = parse_quantity(text, "pressure")
        except ValueError as exc:
            raise ValueError(f"--pressure {text!r}: {exc}") from None
    if not (value > 0 and math.isfinite(value)):
        raise ValueError(f"--pressure {text!r} must be a positive, finite pressure, e.g. '100 Pa' or '1 mbar'")
    return value


def cli(args) -> int:
    """`netgen sigma-delta`: build or reuse the model, run the loop, write DIR/summary.json etc."""
    out = Path(args.output)
    try:
        if args.tone is not None and not args.tone.strip():
            raise ValueError("--tone is empty: give COORD:AMPLITUDE:FREQ, e.g. --tone z:0.02:1000, or leave it out")
        tone = Tone.parse(args.tone) if args.tone else None
        if args.ts <= 0 or args.cycles < MIN_CYCLES:
            raise ValueError(f"need --ts > 0 and --cycles >= {MIN_CYCLES} (got {args.ts}, {args.cycles})")
        if args.segment is not None and (args.segment < 0 or 0 < args.segment < MIN_SEGMENT):
            raise ValueError(
                f"--segment {args.segment}: give at least {MIN_SEGMENT} periods per segment, or 0 "
                f"for one run (the default is {SEGMENT_S * 1e3:g} ms of simulated time)"
            )
        if tone and not (math.isfinite(tone.amplitude) and math.isfinite(tone.freq) and 0 < tone.freq < 0.5 / args.ts):
            raise ValueError(
                f"--tone {args.tone}: the amplitude must be a finite number and the frequency between 0 "
                f"and f_s/2 = {0.5 / args.ts:g} Hz, e.g. --tone z:0.02:1000"
            )
        if args.lead is not None and (not math.isfinite(args.lead) or abs(args.lead) > 10):
            raise ValueError(f"--lead {args.lead}: the lead coefficient must lie in [-10, 10] (default 0.8)")
        if args.reltol is not None and not RELTOL_RANGE[0] <= args.reltol <= RELTOL_RANGE[1]:
            raise ValueError(
                f"--reltol {args.reltol} is outside {RELTOL_TEXT}: give one inside it (default 1e-3; 1e-4 for spectra "
                "you quote: docs/sigma-delta.md)"
            )
        if args.dither is not None and not 0 <= args.dither <= 1:
            raise ValueError(f"--dither {args.dither} must be between 0 (none) and 1 (the default is 0.2)")
        pressure = parse_pressure(args.pressure) if args.pressure is not None else None
        if args.model and (args.rigid_only or pressure is not None or args.film or args.noise):
            raise ValueError(
                "--rigid-only, --pressure, --film and --noise rebuild the model from the structure file; drop --model"
            )
        if args.segment and args.simulator == "ngspice-osdi":
            raise ValueError(
                f"--segment {args.segment}: --simulator ngspice-osdi runs in one segment (ngspice's "
                ".ic cannot set the OSDI module's internal states a restart needs); drop --segment"
            )
        if args.noise and args.simulator in ("vacask", "ngspice-osdi"):
            raise ValueError(
                f"--noise needs --simulator ngspice: {args.simulator} runs the .va, whose "
                "white_noise acts in noise analyses only (no transient noise sources)"
            )
    except ValueError as exc:
        print(f"netgen: {exc}", file=sys.stderr)
        return 2
    loop = read_loop_file(args.loop) if args.loop else read_structure_loop(args.structure)  # LoopError: exit 2
    if args.model:
        model, lib = MacroModel.load_json(args.model), Path(args.model).with_suffix(".lib")
    else:
        model, lib = model_for(
            args.structure,
            model_folder(out, args.rigid_only, pressure, args.film, args.noise),
            args.rigid_only,
            args.rebuild,
            not args.quiet,
            pressure,
            args.film,
            args.noise,
        )
    inputs = [c.name for c in model.coordinates] + (["a_in"] if model.acceleration else [])
    inputs += list(model.inertial.participation)  # a_x, a_y (netgen.model.inertial)
    if tone and tone.coord not in inputs:
        print(
            f"netgen: --tone {args.tone}: the model has no coordinate {tone.coord!r}; choose one of "
            f"{', '.join(inputs)}",
            file=sys.stderr,
        )
        return 2
    choices = {"lead": args.lead, "dither": args.dither, "reltol": args.reltol}
    # the loop checked against the model before any output (LoopError: exit 2)
    d = backend_design(model, args.ts, loop, tone or loop.input.tone, args.simulator, **choices)
    info = {
        "arguments": {k: v for k, v in vars(args).items() if isinstance(v, (str, int, float, bool, type(None)))},
        "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
    inside = lib_folder(lib, out)
    with OutputFolder(
        out,
        RESULTS,
        info,
        keep_failed=True,
        shared=SHARED + ((inside,) if inside else ()),
        legacy=RESULT_FILES + (f"{model.name}_xspice.lib", f"{model.name}_osdi.lib"),
    ) as folder:
        staged = folder.stage / inside / Path(lib).name if inside else lib  # through the stage's link
        try:
            s = run(
                model,
                staged,
                folder.stage,
                args.ts,
                args.cycles,
                tone,
                progress=not args.quiet,
                plots=not args.no_plots,
                simulator=args.simulator,
                segment=args.segment,
                timeout=args.timeout,
                loop=loop,
                designed=d,
                **choices,
            )
        except SimulationError as exc:  # its paths: where the failed run's files are kept
            raise SimulationError(
                folder.failed_path(str(exc)) + f"; the last complete results are still in "
                f"{out} ({folder.manifest.name})"
            ) from None
        folder.commit()
    if not args.quiet:
        for c, ch in s["channels"].items():
            snr = f", SNR {ch['snr_db']:.1f} dB" if "snr_db" in ch else ""
            snr += f", SQNR {ch['sqnr_db']:.1f} dB (sine fit)" if "sqnr_db" in ch else ""
            floor = ch["noise_floor_db_per_hz"]
            floor = "n/a (run too short)" if floor is None else f"{floor:.1f} dB/Hz"
            print(
                f"{c}: bit mean {ch['bit_mean']:+.4f}, in-band floor {floor}"
                f"{snr}, {len(ch['notches'])} notches, {len(ch['peaks'])} peaks"
            )
        gb = s["gravity_balance"]
        th = s["thermal_noise"]["channels"]
        if any(v["thermal_floor_db_per_hz"] is not None for v in th.values()):
            print(
                "gas-film Brownian force floor (dB re F_fb^2/Hz): "
                + ", ".join(
                    f"{c} {v['thermal_floor_db_per_hz']:.1f}" for c, v in th.items() if v["thermal_floor_db_per_hz"]
                )
            )
        ratio = (
            f"mean feedback force / weight = {gb['ratio']:.4f}"
            if gb["ratio"] is not None
            else f"mean feedback force - input on {gb['channel']} = {gb['residual_n']:.3g} N"
        )
        print(f"{ratio}; wrote {out / 'summary.json'} ({s['wall_s']:.0f} s)")
    lev = s["levitation"]
    if not lev["held"]:
        print(
            f"netgen: the loop lost the plate at period {lev['lost_at_period']} ({lev['coordinate']} = "
            f"{lev['value']:.4g}, beyond {lev['limit']:.3g} in port units); the spectra describe a plate at "
            f"the stop.{lost_hint(s)} Results in {out}",
            file=sys.stderr,
        )
        return 1
    return 0


def lib_folder(lib: Path, out: Path) -> str | None:
    """The sub-folder of DIR that holds the model's .lib (DIR/model..., model_folder), which the
    staging folder links (OutputFolder shared), so the kept netlist `.include`s it relative to DIR
    and reruns there by hand; None for a .lib elsewhere (--model's: included by its absolute path)."""
    parent, base = Path(os.path.abspath(Path(lib).parent)), Path(os.path.abspath(out))
    return parent.name if parent.parent == base and parent.name not in SHARED else None


def lost_hint(s: dict) -> str:
    """What the summary says about a lost plate: missed breakpoints, partial latch decisions."""
    hints = []
    bp = s.get("breakpoints") or {}
    if bp.get("periods_with_a_missed_corner"):
        hints.append(
            f"ngspice missed an electrode-phase corner in {bp['periods_with_a_missed_corner']} "
            f"period(s), first {bp['first_period']} (docs/sigma-delta.md)"
        )
    seg = s.get("segments") or {}
    if seg.get("state_nodes") and seg.get("periods_run", 0) < s.get("requested_cycles", 0):
        hints.append(
            f"ngspice stopped after the segment that lost it ({seg['periods_run']} of "
            f"{s['requested_cycles']} periods; its netlist with the restart state is DIR/sigma_delta.cir)"
        )
    partial = {c: v.get("partial_latches") for c, v in s["channels"].items() if v.get("partial_latches")}
    if partial:
        hints.append(f"partial latch decisions {partial}")
    return (" Diagnostics: " + "; ".join(hints) + ".") if hints else ""


def add_parser(sub) -> None:
    """The `sigma-delta` subcommand's arguments."""
    p = sub.add_parser(
        "sigma-delta",
        help="run the sigma-delta force-feedback loop (the paper's levitation loop, "
        "for any device) in ngspice or VACASK, with spectra",
    )
    p.add_argument("structure", help="structure description (TOML; its [loop] table describes the loop)")
    p.add_argument(
        "--loop",
        type=existing_file("loop description"),
        help="loop description LOOP.toml (a [loop] "
        "table, as in a structure file; replaces the structure's): channels, electrodes, feedback "
        "voltage, loop filter, timing, input (docs/sigma-delta.md)",
    )
    p.add_argument(
        "-o",
        "--output",
        required=True,
        type=output_folder,
        help="output folder (bitstreams.npz, spectra, summary.json)",
    )
    p.add_argument(
        "--ts",
        type=positive("the sampling period in s", "--ts 1e-6", TS_MAX),
        default=1e-6,
        help="sampling period T_s in s (default 1e-6)",
    )
    p.add_argument(
        "--cycles",
        type=integer("the number of sampling periods", MIN_CYCLES, MAX_CYCLES, "--cycles 4096"),
        default=4096,
        help="number of sampling periods (default 4096)",
    )
    p.add_argument(
        "--tone",
        help="sinusoidal force COORD:AMPLITUDE:FREQ (amplitude in the f_ port unit, uN or nN*m), "
        "or a_in:AMPLITUDE:FREQ (frame acceleration, m/s^2)",
    )
    p.add_argument("--rigid-only", action="store_true", help="drop the eigenmodes (model built with modes = 0)")
    p.add_argument(
        "--model",
        type=existing_file("model JSON"),
        help="use this model .json (with the .lib, and for VACASK the .va, next to it) instead of building",
    )
    p.add_argument(
        "--simulator",
        choices=list(BACKENDS),
        default="ngspice",
        help="ngspice with the .lib (default); ngspice-xspice: ngspice with the model's plate terms in "
        "the compiled XSPICE code model (netgen codemodel; about 4x faster); or VACASK with the compiled "
        "Verilog-A module: the same loop, for spectra-length runs",
    )
    p.add_argument("--rebuild", action="store_true", help="rebuild the model even if DIR/model is up to date")
    p.add_argument(
        "--pressure",
        help="gas pressure of the squeeze film in both gaps, e.g. '100 Pa', '1 mbar', "
        "'1 atm' (turns squeeze-film damping on; gas and temperature from [damping])",
    )
    p.add_argument(
        "--film",
        choices=("incompressible", "compressible"),
        help="squeeze-film model (compressible: Maxwell branches, for squeeze numbers above about 1)",
    )
    p.add_argument(
        "--noise",
        action="store_true",
        help="thermal force noise of the damping (ngspice trnoise); "
        "summary.json gives the resulting Brownian floor per channel",
    )
    p.add_argument(
        "--lead",
        type=number,
        default=None,
        help="lead-compensator coefficient a in y = a*prev - cur "
        "(every lead2 channel; default: the [loop] filter's, else 0.8)",
    )
    p.add_argument(
        "--dither",
        type=number,
        default=None,
        help="comparator dither amplitude, a fraction of the one-period feedback displacement "
        "a_fb*T_s^2 (a sine near f_s/2 per channel; 0 = none; default 0.2)",
    )
    p.add_argument(
        "--reltol",
        type=number,
        default=None,
        help="relative tolerance of the simulator (default 1e-3; docs/sigma-delta.md on how it "
        "moves the in-band floors: 1e-4 for spectra you quote)",
    )
    p.add_argument(
        "--segment",
        type=integer("periods per segment", MIN_SEGMENT, MAX_CYCLES, f"--segment {MIN_SEGMENT * 64}", zero="one run"),
        default=None,
        help="ngspice: run in segments of this many periods, each restarted at t = 0 from the "
        "state the run reached (and cut at any missed breakpoint: docs/sigma-delta.md); "
        f"0 = one run; default {SEGMENT_S * 1e3:g} ms of simulated time",
    )
    p.add_argument(
        "--timeout",
        type=positive("the time limit in seconds", "--timeout 3600", 1e7),
        default=TIMEOUT,
        help=f"wall-clock limit of each simulator run in s (default {TIMEOUT:g}); a run past it is "
        "stopped and reported",
    )
    p.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or summary output")
    p.set_defaults(func=cli)
