"""The sigma-delta command's model cache (netgen.testbench.sigma_delta.runner.model_for): a
model is reused when what it was built from has the same content (netgen.build.build_key), not
when its files are newer: editing only the [loop] table reuses it, editing a geometry value
rebuilds it."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from netgen.build import build_key
from netgen.structure import load_structure
from netgen.testbench.sigma_delta import model_for
from tests.fixtures import ROOT

EXAMPLE = ROOT / "examples" / "accelerometer_z.toml"


def built(folder: Path) -> int:
    """The model JSON's modification time (ns): changes exactly when model_for builds."""
    return (folder / "accelerometer_z.json").stat().st_mtime_ns


def later(path: Path) -> None:
    """Move the file's modification time an hour ahead (newer than any cached model)."""
    t = path.stat().st_mtime + 3600
    os.utime(path, (t, t))


@pytest.fixture
def structure(tmp_path: Path) -> Path:
    """A copy of the accelerometer example, free to edit."""
    path = tmp_path / "accelerometer_z.toml"
    path.write_text(EXAMPLE.read_text())
    return path


def test_editing_only_the_loop_table_reuses_the_model(structure, tmp_path):
    folder = tmp_path / "model"
    model_for(structure, folder, progress=False)
    first = built(folder)
    structure.write_text(
        structure.read_text()
        .replace("lead = 0.8", "lead = 0.7")
        .replace('acceleration = "9.81 m/s^2"', 'acceleration = "5 m/s^2"')
    )
    later(structure)  # newer than the model: mtimes would rebuild
    model, _ = model_for(structure, folder, progress=False)
    assert built(folder) == first
    assert model.electrodes[0].gap == pytest.approx(2e-6)


def test_editing_a_geometry_value_rebuilds_the_model(structure, tmp_path):
    folder = tmp_path / "model"
    model_for(structure, folder, progress=False)
    first = built(folder)
    structure.write_text(
        structure.read_text().replace('gap = "2 um"\n\n[[electrodes]]', 'gap = "2.5 um"\n\n[[electrodes]]')
    )
    model, _ = model_for(structure, folder, progress=False)
    assert built(folder) != first
    assert sorted(e.gap for e in model.electrodes) == pytest.approx([2e-6, 2.5e-6])  # the edited file's gaps


def test_an_altered_cached_file_rebuilds(structure, tmp_path):
    folder = tmp_path / "model"
    model_for(structure, folder, progress=False)
    lib = folder / "accelerometer_z.lib"
    lib.write_text(lib.read_text() + "* edited\n")
    model_for(structure, folder, progress=False)
    assert "* edited" not in lib.read_text()  # the manifest's checksum no longer matched


def test_the_key_follows_a_named_data_file(tmp_path):
    source = ROOT / "examples" / "calibrated_disk.toml"
    data = ROOT / "examples" / "calibrated_disk_maxwell.json"
    (tmp_path / data.name).write_text(data.read_text())
    path = tmp_path / source.name
    path.write_text(source.read_text())
    key = build_key(load_structure(path))
    (tmp_path / data.name).write_text(data.read_text().replace("1", "2", 1))
    assert build_key(load_structure(path)) != key
