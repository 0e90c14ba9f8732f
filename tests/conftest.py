"""Shared fixtures: the reference example, built once per test session (per xdist worker)."""

from __future__ import annotations

import contextlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = "examples/levitated_disk.toml"        # relative to ROOT: the path the netlist header names


@pytest.fixture(scope="session")
def reference_build():
    """Every stage output of the reference example (pipeline.build; its .model is what
    build_model returns). Loaded from ROOT with the relative path, as the committed netlists
    were, so the model's `source` matches theirs. About 10-14 s; once per worker."""
    from netgen import pipeline
    from netgen.structure import load_structure

    with contextlib.chdir(ROOT):
        return pipeline.build(load_structure(REFERENCE))


@pytest.fixture(scope="session")
def reference_model(reference_build):
    """The reference MacroModel (treat as read-only: it is shared by the session)."""
    return reference_build.model
