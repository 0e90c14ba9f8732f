"""The sweep stage: parameter sweeps and Monte Carlo of the sigma-delta testbench. spec: the
sweep file; plan: its runs; point: a run at a process point; tomltext: the TOML writer both use; run:
running and gathering them; plots: the figure; cli."""

from .plan import RunSpec, plan
from .run import run_one, run_sweep, write_csv
from .spec import FIGURES, TESTBENCH, Parameter, Sweep, load_sweep, parse_sweep
from .tomltext import to_toml

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
