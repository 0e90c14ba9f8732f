"""The sweep stage: parameter sweeps and Monte Carlo of the sigma-delta testbench. spec: the
sweep file; plan: its runs; run: running and gathering them; plots: the figure; cli."""

from .plan import RunSpec, plan, to_toml
from .run import run_one, run_sweep, write_csv
from .spec import FIGURES, TESTBENCH, Parameter, Sweep, load_sweep, parse_sweep

__all__ = [
    "FIGURES",
    "TESTBENCH",
    "Parameter",
    "RunSpec",
    "Sweep",
    "load_sweep",
    "parse_sweep",
    "plan",
    "run_one",
    "run_sweep",
    "to_toml",
    "write_csv",
]
