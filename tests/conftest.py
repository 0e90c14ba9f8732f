"""The suite's fixtures live in tests/fixtures.py (with the helpers the test modules import).

One BLAS and OpenMP thread per process, set before numpy loads (pytest-xdist's workers and every
subprocess a test starts inherit it): the suite runs two workers on two cores, and two more
OpenBLAS threads per worker spin against each other (tests/fit and tests/mechanics took 1.8x the
wall time with the default thread count on the shared machine). Results that must agree bit for
bit (a build in-process and in a subprocess, parallel and serial samples) see the same count."""

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
