"""The suite's fixtures live in tests/fixtures.py (with the helpers the test modules import)."""

from tests.fixtures import ngspice_version, reference_build, reference_model  # noqa: F401  (registers the fixtures)
