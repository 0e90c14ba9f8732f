"""What the bench scripts share: the repository root and the test oracles (tests/oracles), loaded
by file path, so that `.venv/bin/python bench/x.py` needs no sys.path edit (a script's own folder
is on sys.path, which makes `import support` find this file; netgen is installed editable).

The oracle modules and the testbench names load on first use (`from support import Bench`,
`support.closed_forms`): a script that takes only ROOT imports no simulator code.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[1]
ORACLES = ROOT / "tests" / "oracles"
PACKAGE = "netgen_test_oracles"  # the name the oracles package gets here (tests import it as tests.oracles)

# the oracle modules this file hands out, and the testbench names it re-exports (tests/fixtures.py
# re-exports the same ones to the tests)
MODULES = (
    "beam_etch",
    "bem_reduced",
    "closed_forms",
    "crab_legs",
    "fastcap_guarded",
    "film_rerun",
    "fmu_process",
    "gyro_reference",
    "lateral_comb",
    "loop_orders",
    "plate_etch",
    "process_balance",
    "process_cases",
    "process_energy",
    "process_forms",
    "process_inertial",
    "process_mc",
    "process_vacask",
    "sc_readout",
    "sigma_delta_reference",
    "sigma_delta_vacask",
    "small_disk",
    "spice_decks",
    "squeeze_film",
    "testbench",
    "va_scan",
)
TESTBENCH = ("NGSPICE", "Bench", "Pulse", "reference_transient", "states", "transient_drive", "using_ngspice")

__all__ = ["ORACLES", "ROOT", "oracle", *MODULES, *TESTBENCH]


def oracle(name: str) -> ModuleType:
    """tests/oracles/<name>.py, imported as a submodule of the oracles package loaded from its folder
    (so the oracles' relative imports of each other resolve)."""
    if PACKAGE not in sys.modules:
        spec = importlib.util.spec_from_file_location(
            PACKAGE, ORACLES / "__init__.py", submodule_search_locations=[str(ORACLES)]
        )
        package = importlib.util.module_from_spec(spec)
        sys.modules[PACKAGE] = package
        spec.loader.exec_module(package)
    return importlib.import_module(f"{PACKAGE}.{name}")


def __getattr__(name: str):
    """An oracle module, or a testbench name, on first use."""
    if name in MODULES:
        return oracle(name)
    if name in TESTBENCH:
        return getattr(oracle("testbench"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
