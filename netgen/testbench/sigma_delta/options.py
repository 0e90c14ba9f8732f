"""The sigma-delta loop's options, each declared once (netgen.core.options.Option): the `netgen
sigma-delta` flags, the [loop] keys and the sweep parameters of the same setting share one range
and one check. The command line (cli.add_parser: every option with a flag), the loop reader
(loopfile: every top-level [loop] key, LOOP_SETTINGS), the loop filter's reader
(kinds.read_lead2), the design's choices (loop.Choices: the options of role "design"), the sweep
file (netgen.sweep.spec: every option with a sweep parameter) and the docs' option tables
(tests/test_options.py) are derived from OPTIONS: a new option is its declaration and its use."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace
from pathlib import Path

from ...core.options import Option, OptionError, by_name, markdown_table, number, with_table

# ngspice runs go in segments of this much simulated time, restarted at t = 0 (ngspice.run_segments)
SEGMENT_S = 5e-4
MIN_SEGMENT = 16
SIMULATORS = ("ngspice", "ngspice-xspice", "vacask", "ngspice-osdi")  # runner.BACKENDS' names
MAX_CYCLES = 1 << 24  # periods per run: 2^24 periods write ~250 GB of raw file
# the sampling period: below 1 ns ngspice's time steps reach its resolution; above 1 s a period
# is longer than any mechanics the models describe
TS_RANGE = (1e-9, 1.0)
MAX_TONE = 1e12  # a force tone's amplitude (f_ port unit) and any tone's frequency (Hz)
MAX_ACCELERATION = 1e7  # m/s^2 (a_in: DC and tone)
TIMEOUT = 36000.0  # s: the default wall-clock limit of one simulator run (netgen.core.process)


def below_nyquist(freq: float, context: dict) -> str | None:
    """A tone frequency below f_s/2 = 1/(2 ts) (context "ts"; unknown ts: not checked here)."""
    ts = context.get("ts")
    if ts is None or freq < 0.5 / ts:
        return None
    return f"the tone frequency is not below f_s/2 = 1/(2 T_s) = {0.5 / ts:g} Hz (T_s = {ts:g} s)"


def simulator_available(name: str, context: dict) -> str | None:
    """The simulator can run here (context "installed": its check, which names what is missing)."""
    check = context.get("installed")
    return check(name) if check else None


def damping_accepted(value: object, context: dict) -> str | None:
    """The structure accepts the setting in its [damping] table (context "damping": the
    structure's own check of the table with this setting, -> its problem or None)."""
    check = context.get("damping")
    return check(value) if check else None


def design_ratio(name: str, text: str, high: float, default: float) -> Option:
    """A design option in (0, high], set as the [loop] key and the sweep parameter of its own name."""
    return Option(
        name,
        text,
        role="design",
        low=0.0,
        high=high,
        open_low=True,
        default=default,
        example=repr(default),
        loop_key=name,
        sweep=name,
    )


_options = [
    Option(
        "ts",
        "the sampling period T_s",
        quantity="time",
        low=TS_RANGE[0],
        high=TS_RANGE[1],
        default=1e-6,
        example="1e-6",
        flag="--ts",
        sweep="ts",
    ),
    Option(
        "cycles",
        "the number of sampling periods",
        type="int",
        low=64,
        high=MAX_CYCLES,
        default=4096,
        example="4096",
        flag="--cycles",
        sweep="cycles",
    ),
    Option(
        "skip",
        "the periods left out at the start of the spectra (at most half of cycles)",
        type="int",
        low=0,
        high=MAX_CYCLES // 2,
        default_text="cycles / 8",
        example="512",
        sweep="skip",
    ),
    Option(
        "lead",
        "the lead-compensator coefficient a in y = a*prev - cur",
        role="design",
        low=-10.0,
        high=10.0,
        default=0.8,
        example="0.8",
        flag="--lead",
        loop_key="filter.lead",
        sweep="lead",
    ),
    Option(
        "density",
        "the mean bit the DC input needs when V_fb is derived",
        role="design",
        low=0.0,
        high=1.0,
        open_low=True,
        open_high=True,
        default=0.5,
        example="0.5",
        loop_key="density",
        sweep="density",
    ),
    design_ratio("sense_ratio", "the sense voltage over the feedback voltage, V_s / V_fb", 10.0, 0.25),
    design_ratio("full_scale", "the readout's full scale, a fraction of the touch amplitude that reads 1 V", 1.0, 0.01),
    Option(
        "dither",
        "the comparator dither, a fraction of the one-period feedback displacement a_fb*T_s^2 (0: none)",
        role="design",
        low=0.0,
        high=1.0,
        default=0.2,
        example="0.2",
        flag="--dither",
        loop_key="dither",
        sweep="dither",
    ),
    Option(
        "reltol",
        "the simulator's relative tolerance (1e-4 for spectra you quote: docs/sigma-delta.md)",
        role="design",
        low=1e-7,
        high=1e-2,
        default=1e-3,
        example="1e-3",
        flag="--reltol",
        loop_key="reltol",
        sweep="reltol",
    ),
    Option(
        "ramp_steps",
        "ngspice-xspice only: cross every feedback edge in this many equal steps (0: ngspice's own step "
        "control, which misses an edge's impulse by up to 2e-3; 20 with reltol 1e-6 converges: docs/fmu.md)",
        type="int",
        role="design",
        low=0,
        high=1000,
        default=0,
        example="20",
        flag="--ramp-steps",
        loop_key="ramp_steps",
        sweep="ramp_steps",
    ),
    Option(
        "feedback_voltage",
        "the feedback voltage V_fb",
        quantity="voltage",
        low=0.0,
        high=1e4,
        open_low=True,
        default_text="the DC input needs a mean bit of `density`",
        example='"3 V"',
        loop_key="feedback_voltage",
        sweep="feedback_voltage",
    ),
    Option(
        "acceleration",
        "the DC frame acceleration through a_in",
        quantity="acceleration",
        low=-MAX_ACCELERATION,
        high=MAX_ACCELERATION,
        default_text="gravity",
        example='"9.81 m/s^2"',
        loop_key="input.acceleration",
        sweep="acceleration",
    ),
    Option(
        "tone",
        "a sinusoidal input COORD:AMPLITUDE:FREQ (amplitude in the f_ port unit, uN or nN*m; a_in: m/s^2)",
        type="text",
        example="z:0.02:1000",
        flag="--tone",
        sweep="tone",
    ),
    Option(
        "tone_amplitude",
        "the amplitude of a force tone (its f_ port unit)",
        low=0.0,
        high=MAX_TONE,
        open_low=True,
        example="0.02",
        loop_key="input.force.amplitude",
        sweep="tone_amplitude",
    ),
    Option(
        "tone_acceleration",
        "the amplitude of an acceleration tone on a_in",
        quantity="acceleration",
        low=0.0,
        high=MAX_ACCELERATION,
        open_low=True,
        example='"2 m/s^2"',
        loop_key="input.tone.amplitude",
    ),
    Option(
        "tone_freq",
        "the tone frequency (below f_s/2)",
        quantity="frequency",
        low=0.0,
        high=MAX_TONE,
        open_low=True,
        example="1000",
        loop_key="input.tone.frequency",
        sweep="tone_freq",
        cross=below_nyquist,
    ),
    Option(
        "segment",
        "the ngspice periods per segment",
        type="int",
        low=MIN_SEGMENT,
        high=MAX_CYCLES,
        zero="one run",
        default_text=f"{SEGMENT_S * 1e3:g} ms of simulated time",
        example=str(MIN_SEGMENT * 64),
        flag="--segment",
    ),
    Option(
        "timeout",
        "the wall-clock limit of each simulator call",
        quantity="time",
        low=0.0,
        high=1e7,
        open_low=True,
        default=TIMEOUT,
        default_text="36000 s (a sweep: 10 min + 1 s per period)",
        example="3600",
        flag="--timeout",
    ),
    Option(
        "simulator",
        "the circuit simulator",
        type="choice",
        choices=SIMULATORS,
        default="ngspice",
        example="ngspice",
        flag="--simulator",
        sweep="simulator",
        usage="; ngspice with the .lib; ngspice-xspice: ngspice with the model's plate terms in the compiled "
        "XSPICE code model (netgen codemodel; about 4x faster); or VACASK with the compiled Verilog-A module: "
        "the same loop, for spectra-length runs",
        cross=simulator_available,
    ),
    Option(
        "pressure",
        "the gas pressure of the squeeze film (turns squeeze-film damping on)",
        quantity="pressure",
        low=0.0,
        open_low=True,
        default_text="none: the structure's [damping]",
        example='"100 Pa"',
        flag="--pressure",
        cross=damping_accepted,
    ),
    Option(
        "film",
        "the squeeze-film model",
        type="choice",
        choices=("incompressible", "compressible"),
        default_text="the structure's [damping] film_model",
        example="incompressible",
        flag="--film",
        cross=damping_accepted,
    ),
    Option(
        "rigid_only",
        "drop the eigenmodes (the model built with modes = 0)",
        type="bool",
        flag="--rigid-only",
        sweep="rigid_only",
    ),
    # the command's other arguments: what it reads and writes, and how it runs
    Option(
        "structure",
        "the structure description (TOML; its [loop] table describes the loop)",
        type="text",
        example="examples/levitated_disk.toml",
        flag="structure",
    ),
    Option(
        "loop",
        "the loop description LOOP.toml (a [loop] table, as in a structure file; replaces the structure's): "
        "channels, electrodes, feedback voltage, loop filter, timing, input",
        type="file",
        default_text="the structure's [loop]",
        example="loop.toml",
        flag="--loop",
    ),
    Option(
        "output",
        "the output folder (bitstreams.npz, spectra, summary.json)",
        type="folder",
        example="out/sd",
        flag="--output",
        short="-o",
        required=True,
    ),
    Option(
        "model",
        "the model .json to use (with the .lib, and for VACASK the .va, next to it) instead of building",
        type="file",
        default_text="built in DIR/model",
        example="netlists/levitated_disk.json",
        flag="--model",
    ),
    Option("rebuild", "rebuild the model even if DIR/model is up to date", type="bool", flag="--rebuild"),
    Option(
        "noise",
        "thermal force noise of the damping (ngspice trnoise); summary.json gives the resulting Brownian "
        "floor per channel",
        type="bool",
        flag="--noise",
    ),
    Option(
        "native",
        "compile the Verilog-A (vacask, ngspice-osdi) for this machine's CPU (openvaf-r --target_cpu native: "
        "faster on long runs); default: the x86-64 baseline (summary.json names the target)",
        type="bool",
        flag="--native",
    ),
    Option("no_plots", "skip the PNG figures", type="bool", flag="--no-plots"),
    Option("quiet", "no progress or summary output", type="bool", flag="--quiet", short="-q"),
]


def loop_settings(options: Iterable[Option]) -> dict[str, Option]:
    """The options written as top-level [loop] keys (loopfile.LoopSettings; a dotted key is read in its table)."""
    return {o.name: o for o in options if o.loop_key and "." not in o.loop_key}


def sweep_parameters(options: Iterable[Option]) -> dict[str, Option]:
    """The options that are sweep parameters, by parameter name (netgen.sweep.spec.TESTBENCH)."""
    return {o.sweep: o for o in options if o.sweep}


OPTIONS = by_name(_options)
# where the settings are written: the sigma-delta command's arguments, the [loop] keys, the sweep's parameters
FLAGS = {o.flag: o for o in _options if o.flag}
LOOP_KEYS = {o.loop_key: o for o in _options if o.loop_key}
LOOP_SETTINGS = loop_settings(_options)
SWEEP = sweep_parameters(_options)


def read_tone(text: object, named: str, ts: float | None = None, amplitude: Option | None = None):
    """COORD:AMPLITUDE:FREQ as a (coordinate, amplitude, frequency): the numbers strictly (no
    underscores), the amplitude in its option's range (tone_acceleration on a_in, else
    tone_amplitude), the frequency in tone_freq's and below f_s/2 when `ts` is known."""
    fix = OPTIONS["tone"].fix(named)
    if not isinstance(text, str) or not text.strip():
        raise OptionError(f"{named} = {text!r} is not COORD:AMPLITUDE:FREQ", fix)
    parts = text.split(":")
    if len(parts) != 3 or not parts[0]:
        raise OptionError(f"{named} = {text!r} is not COORD:AMPLITUDE:FREQ", fix)
    coord, amp, freq = parts
    amp_option = amplitude or OPTIONS["tone_acceleration" if coord == "a_in" else "tone_amplitude"]
    # the numbers plain, as on the command line (a unit belongs to the [loop.input] tables)
    checks: tuple[tuple[str, str, Option, dict], ...] = (
        ("amplitude", amp, replace(amp_option, quantity="dimensionless"), {}),
        # plain numbers only (number() below), checked against the key's own physical range too
        ("frequency", freq, OPTIONS["tone_freq"], {"ts": ts}),
    )
    out = []
    for what, value, option, context in checks:
        try:
            if number(value) is None:
                raise OptionError(f"{what} {value!r} is not a plain number", "")
            out.append(option.read(value, what, context))
        except OptionError as exc:
            raise OptionError(
                f"{named} = {text!r}: {exc.problem}",
                f"give {option.help} in {option.range_text()}, e.g. {OPTIONS['tone'].example_as(named)}",
            ) from None
    return coord, out[0], out[1]


def markdown_tables(options: Iterable[Option] = OPTIONS.values()) -> dict[str, str]:
    """The docs' option tables by page, each below its line MARK.format("sigma-delta") (write them:
    write_docs("docs"); tests/test_options.py checks the pages hold
    them): every option of `netgen sigma-delta` and the [loop] table, and the sweep's testbench parameters."""
    options = list(options)
    return {
        "sigma-delta.md": markdown_table(o for o in options if o.flag or o.loop_key),
        "sweeps.md": markdown_table((o for o in options if o.sweep), ("sweep",)),
    }


def write_docs(folder: str) -> None:
    """Rewrite the option tables of the docs pages in `folder` from the declarations."""
    for page, table in markdown_tables().items():
        path = Path(folder) / page
        path.write_text(with_table(path.read_text(encoding="utf-8"), "sigma-delta", table), encoding="utf-8")
