"""The sigma-delta force-feedback loop (the paper's section 3, Fig. 3, for any device) around an
emitted macromodel.

loopfile: the loop description ([loop] table, --loop); loop: the design derived from the model
and the description (FILTERS: the loop-filter kinds); ngspice / vacask / osdi: the back ends
(netlists, runs); runner: a run from model to summary.json (BACKENDS: the --simulator choices);
analysis: bitstreams to spectra and figures; plots; cli: `netgen sigma-delta`.
"""

from .analysis import analyse, gravity_balance, levitation, per_clock, psd, thermal_floor
from .loop import FILTERS, Choices, Design, Timing, Tone, design, duty, groups
from .loopfile import LoopSpec, check_input_tone, read_loop_file, read_structure_loop
from .options import OPTIONS, SWEEP, read_tone
from .runner import (
    BACKENDS,
    SIMULATORS,
    BuildOptions,
    RunRequest,
    model_for,
    run,
    simulator_problem,
    with_damping,
)

# the levitated disk's channels (its default loop: loop.channel_names), for the disk's scripts;
# a run's channels are its Design.names and summary["channels"]
CHANNELS = ("z", "tilt_x", "tilt_y")

__all__ = [
    "BACKENDS",
    "CHANNELS",
    "FILTERS",
    "OPTIONS",
    "SWEEP",
    "BuildOptions",
    "Choices",
    "RunRequest",
    "SIMULATORS",
    "Design",
    "LoopSpec",
    "Timing",
    "Tone",
    "analyse",
    "check_input_tone",
    "simulator_problem",
    "design",
    "duty",
    "gravity_balance",
    "groups",
    "levitation",
    "model_for",
    "per_clock",
    "psd",
    "read_loop_file",
    "read_structure_loop",
    "read_tone",
    "run",
    "thermal_floor",
    "with_damping",
]
