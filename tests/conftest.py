"""The suite's fixtures live in tests/fixtures.py (with the helpers the test modules import).

One BLAS and OpenMP thread per process, set before numpy loads (pytest-xdist's workers and every
subprocess a test starts inherit it; an explicit setting in the environment wins): the suite runs two
workers on two cores, and more OpenBLAS threads per worker spin against each other (tests/emit took
21 min with the default count against 15 min with one, on the shared machine). OpenBLAS splits its
work by the thread count, so one thread also keeps a machine with more cores from rounding the fits
differently; the tolerances do not rely on it (tests/emit passes with either count, bench/stop_newton.py)."""

import os

for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

from tests.fixtures import ngspice_version, reference_build, reference_model  # noqa: E402, F401  (registers the fixtures)


def pytest_collection_modifyitems(config, items):
    """The modules holding a test marked slow run first, each kept whole: pytest-xdist hands tests
    out in collection order, so a minute-long test collected last runs alone while the other worker
    idles; a module kept whole builds its module-scoped fixtures once per worker, as before."""
    slow = {item.nodeid.split("::")[0] for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: item.nodeid.split("::")[0] not in slow)
