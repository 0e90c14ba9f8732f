"""The paper's sigma-delta levitation loop (section 3, Fig. 3) around an emitted macromodel.

loop: the loop design derived from the model; ngspice / vacask: the back ends (netlists, runs); runner:
a run from model to summary.json (BACKENDS: the --simulator choices); analysis: bitstreams to
spectra and figures; plots; cli: `netgen sigma-delta`.
"""

from .analysis import analyse, gravity_balance, levitation, per_clock, psd, thermal_floor
from .loop import CHANNELS, RELTOL_RANGE, RELTOL_TEXT, Design, Timing, Tone, design, duty, groups
from .runner import BACKENDS, SIMULATORS, model_for, run, with_damping

__all__ = ["BACKENDS", "CHANNELS", "RELTOL_RANGE", "RELTOL_TEXT", "SIMULATORS", "Design", "Timing", "Tone",
           "analyse", "design", "duty", "gravity_balance", "groups", "levitation", "model_for", "per_clock", "psd",
           "run", "thermal_floor", "with_damping"]
