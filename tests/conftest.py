"""The suite's fixtures live in tests/fixtures.py (with the helpers the test modules import)."""

from tests.fixtures import ngspice_version, reference_build, reference_model  # noqa: F401  (registers the fixtures)


def pytest_collection_modifyitems(config, items):
    """The modules holding a test marked slow run first, each kept whole: pytest-xdist hands tests
    out in collection order, so a minute-long test collected last runs alone while the other worker
    idles; a module kept whole builds its module-scoped fixtures once per worker, as before."""
    slow = {item.nodeid.split("::")[0] for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: item.nodeid.split("::")[0] not in slow)
