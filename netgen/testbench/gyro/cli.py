"""`netgen gyro STRUCTURE.toml -o DIR`: the vibratory gyroscope's closed loops around the structure's
macromodel (netgen.testbench.gyro.run): drive loop on x, sigma-delta force feedback on y (the
structure's [loop] table or --loop LOOP.toml, channel y), a rate on w_z or a rate sweep; writes
DIR/summary.json, bitstreams.npz and the PNGs, all or nothing (an OutputFolder result set)."""

from __future__ import annotations

import sys
import time
from pathlib import Path

from ...core.errors import SimulationError
from ...runtime.arguments import add_option, existing_file, output_folder
from ...runtime.folders import OutputFolder
from ..sigma_delta.cli import lib_folder
from ..sigma_delta.loopfile import read_loop_file, read_structure_loop
from ..sigma_delta.runner import model_folder, model_for
from .options import OPTIONS
from .run import GyroRequest, run, sense_design

RESULTS = "gyro"
SHARED = ("osdi",)


def request_of(args) -> GyroRequest:
    return GyroRequest(
        args.ts,
        args.cycles,
        args.rate,
        args.rate_points,
        args.rate_span,
        args.drive_amplitude,
        args.agc_gain,
        args.simulator,
        progress=not args.quiet,
        plots=not args.no_plots,
    )


def cli(args) -> int:
    """Read the loop, build (or reuse) the model, check the loop against it (exit 2), run, report."""
    out = Path(args.output)
    spec = read_loop_file(args.loop) if args.loop else read_structure_loop(args.structure)  # LoopError: exit 2
    model, lib = model_for(args.structure, model_folder(out), progress=not args.quiet)
    req = request_of(args)
    sense_design(model, spec, req)  # the loop checked against the model before any output (exit 2)
    inside = lib_folder(lib, out)
    info = {
        "arguments": {k: v for k, v in vars(args).items() if isinstance(v, (str, int, float, bool, type(None)))},
        "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
    with OutputFolder(out, RESULTS, info, keep_failed=True, shared=SHARED + ((inside,) if inside else ())) as folder:
        staged = folder.stage / inside / Path(lib).name if inside else lib
        try:
            s = run(model, staged, folder.stage, spec, req)
        except SimulationError as exc:
            raise SimulationError(folder.failed_path(str(exc))) from None
        folder.commit()
    if not args.quiet:
        report(s, out)
    return 0


def report(s: dict, out: Path) -> None:
    """One line per rate, and the sweep's figures."""
    deg = 3.141592653589793 / 180
    for r in s["runs"]:
        print(
            f"rate {r['rate_applied_rad_s'] / deg:+.4g} deg/s: read {r['rate_rad_s'] / deg:+.5g} deg/s, quadrature "
            f"{r['quadrature_rad_s'] / deg:+.5g} deg/s, drive {r['drive_hz']:.2f} Hz at {r['drive_amplitude_m'] * 1e6:.4f} um, "
            f"rate noise {r['rate_noise_deg_s_rthz']:.3g} deg/s/rtHz"
        )
    if "sweep" in s:
        sw = s["sweep"]
        print(
            f"scale factor / design {sw['slope']:.5f}, offset {sw['offset_rad_s'] / deg:+.4g} deg/s, "
            f"nonlinearity {sw['nonlinearity_of_full_scale']:.2e} of the sweep's extent"
        )
    print(f"full scale {s['full_scale_rate_deg_s']:.5g} deg/s; wrote {out / 'summary.json'}", file=sys.stderr)


def add_parser(sub) -> None:
    """The `gyro` subcommand's arguments."""
    p = sub.add_parser("gyro", help="run a vibratory gyroscope: drive loop, sigma-delta sense loop, demodulation")
    p.add_argument("structure", help="structure description (TOML; its [loop] table closes the sense loop on y)")
    p.add_argument(
        "--loop",
        type=existing_file("loop description"),
        help="loop description LOOP.toml (replaces the structure's [loop])",
    )
    p.add_argument("-o", "--output", required=True, type=output_folder, help="output folder (summary.json, PNGs)")
    for name in ("ts", "cycles", "rate", "rate_points", "rate_span", "drive_amplitude", "agc_gain", "simulator"):
        add_option(p, OPTIONS[name])
    p.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or summary output")
    p.set_defaults(func=cli)
