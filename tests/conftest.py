"""The suite's fixtures live in tests/fixtures.py (with the helpers the test modules import).

One BLAS and OpenMP thread per process, set before numpy loads (pytest-xdist's workers and every
subprocess a test starts inherit it; an explicit setting in the environment wins): the suite runs three
workers on two cores (.ci/run), and more OpenBLAS threads per worker spin against each other (tests/emit took
21 min with the default count against 15 min with one, on the shared machine). OpenBLAS splits its
work by the thread count, so one thread also keeps a machine with more cores from rounding the fits
differently; the tolerances do not rely on it (tests/emit passes with either count, bench/stop_newton.py)."""

import os
import shutil
import tempfile
from collections import Counter

import pytest

for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

from tests.fixtures import (  # noqa: E402, F401  (registers the fixtures)
    MODEL_CACHE_ENV,  # noqa: E402
    ngspice_version,
    reference_build,
    reference_model,
)


def pytest_configure(config):
    """The controller makes the folder tests.fixtures.shared_model keeps built models in; the xdist
    workers it starts inherit its environment, so they share it."""
    if not hasattr(config, "workerinput") and MODEL_CACHE_ENV not in os.environ:
        os.environ[MODEL_CACHE_ENV] = tempfile.mkdtemp(prefix="netgen-test-models-")
        config.netgen_model_cache = os.environ[MODEL_CACHE_ENV]


def pytest_unconfigure(config):
    """The controller removes the folder it made."""
    folder = getattr(config, "netgen_model_cache", None)
    if folder:
        shutil.rmtree(folder, ignore_errors=True)
        os.environ.pop(MODEL_CACHE_ENV, None)


def pytest_collection_modifyitems(config, items):
    """Modules in the order pytest-xdist hands them out (pytest_xdist_make_scheduler): those holding a
    test marked slow first, then the rest, each group's larger modules first. A module collected
    last runs while the other worker idles, so the long ones must start early."""
    slow = {item.nodeid.split("::")[0] for item in items if item.get_closest_marker("slow")}
    count = Counter(item.nodeid.split("::")[0] for item in items)
    items.sort(key=lambda item: (item.nodeid.split("::")[0] not in slow, -count[item.nodeid.split("::")[0]]))


# the modules that solve with bempp-cl in the test process: its numba kernels compile on first use
# in every process (about 55 s of CPU, and numba's on-disk cache misses them: they take kernels as
# arguments), so these run on one worker and pay it once
BEMPP_MODULES = frozenset(
    f"tests/electrostatics/{name}.py"
    for name in (
        "test_bem",
        "test_bem_sampling",
        "test_bem_settings",
        "test_bem_symmetry",
        "test_fastcap",
        "test_fastcap_modes",
    )
)


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """Each module whole to one worker (xdist's loadfile), in the collection order above: under plain
    load scheduling both workers ran tests of one module, so each built its module-scoped fixtures
    (a model build, a re-run of the process laws) once more. The BEMPP_MODULES go together."""
    from xdist.scheduler import LoadFileScheduling

    class ModuleScheduling(LoadFileScheduling):
        def _split_scope(self, nodeid: str) -> str:  # xdist's documented point of extension
            module = super()._split_scope(nodeid)
            return "bempp-cl" if module in BEMPP_MODULES else module

    config.option.loadscopereorder = False  # keep the order above, not xdist's by test count
    return ModuleScheduling(config, log)
