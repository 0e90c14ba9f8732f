"""Checks of what `netgen build` writes: committed netlists current, reproducible builds,
JSON content (against the paper's frequencies and closed forms), all-or-nothing output,
error reporting, packaging and CLI progress.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from netgen import emit
from netgen.cli import commands as cli
from netgen.emit import EMITTERS, osdi, xspice
from netgen.emit.ngspice import subcircuit
from netgen.fit.capacitance import PATCH_GRIDS
from netgen.model import MacroModel
from tests.fixtures import REFERENCE, ROOT
from tests.staleness import (
    FIT_SHARE,
    RTOL,
    coefficient_change,
    compare_functions,
    compare_json,
    compare_text,
    model_problems,
    refit,
    text_problems,
    with_fit,
    with_fits,
)

NETLISTS = ROOT / "netlists"
NAME = "levitated_disk"
REGENERATE = ".venv/bin/netgen build examples/levitated_disk.toml -o netlists --format all,osdi"
# The comparison lives in tests/staleness.py (tests/test_netlists.py uses it too); these names stay.
_compare_text, _compare_json = compare_text, compare_json


def _stale(problems: list[str]) -> str:
    shown = "\n  ".join(problems[:8]) + (f"\n  ... {len(problems) - 8} more" if len(problems) > 8 else "")
    return (
        f"the committed netlists are stale ({len(problems)} differences):\n  {shown}\n"
        f"regenerate them from the repository root with:\n    {REGENERATE}"
    )


# ----------------------------------------------------------------------------- committed netlists


def schematic_forms(model: MacroModel) -> dict[str, str]:
    """The Xschem symbol and testbench and the KiCad library of `model`, by file ending."""
    out = {EMITTERS[f].suffix: EMITTERS[f].render(model) for f in ("xschem", "kicad")}
    return out | {suffix: str(text) for suffix, text in EMITTERS["xschem"].extra(model, "").items()}


def test_committed_netlists_are_current(reference_build):
    """A fresh build of the reference example (the session build, loaded from the repository
    root with the same relative path) computes what the committed netlists/ compute: words and
    layout identical, every number but the fit coefficients within rounding, the fitted C and
    dC/dq within a hundredth of the fit's own held-out error (tests/staleness.py derives both)."""
    model = reference_build.model
    assert model.source == REFERENCE
    x = np.vstack([reference_build.grid.x, reference_build.holdout.x])  # the samples and check points
    json_old = (NETLISTS / f"{NAME}.json").read_text(encoding="utf-8")
    problems = model_problems(model, json_old, x, f"{NAME}.json")
    hybrid = with_fits(model, MacroModel.load_json(NETLISTS / f"{NAME}.json"))
    # the _osdi.lib (its .osdi is not committed: a platform binary that differs between compiles)
    for suffix, render in ((".lib", subcircuit), ("_xspice.lib", xspice.subcircuit), ("_osdi.lib", osdi.subcircuit)):
        old = (NETLISTS / f"{NAME}{suffix}").read_text(encoding="utf-8")
        problems += text_problems(render(model), old, render(hybrid), f"{NAME}{suffix}")
    # the schematic forms (netgen.emit.xschem, netgen.emit.kicad), judged the same way
    new, mixed = schematic_forms(model), schematic_forms(hybrid)
    for suffix, text in new.items():
        old = (NETLISTS / f"{NAME}{suffix}").read_text(encoding="utf-8")
        problems += text_problems(text, old, mixed[suffix], f"{NAME}{suffix}")
    assert not problems, _stale(problems)


def test_staleness_check_tolerates_refits_and_sees_real_changes(reference_build):
    """The model comparison on planted changes of the reference build. Tolerated: each fit redone
    from samples perturbed by 1e-7 relative (a change near RTOL: the coefficients move along
    their ill-determined directions by far more than RTOL, so a coefficient-by-coefficient check
    fails). Flagged: a mass 1e-6 relative (10 RTOL) in the JSON and the netlist, one plate
    term's constant coefficient 1e-3 relative (C moves by ~1e-3 / K ~ 2.5e-4, 100 times the
    disk's tolerance FIT_SHARE * e ~ 2e-6), and another fit (the next patch grid), which differs
    by about the fits' own error."""
    b, model = reference_build, reference_build.model
    x = np.vstack([b.grid.x, b.holdout.x])
    committed = model.json_text()
    moved = model
    for i in range(len(model.capacitances)):
        moved = with_fit(moved, i, refit(b, i, 1e-7, seed=i))
    assert coefficient_change(moved, model) > 100 * RTOL  # the old coefficient check fails ...
    assert compare_json(json.loads(moved.json_text()), json.loads(committed))
    assert not model_problems(moved, committed, x, "t")  # ... this one does not
    lib = subcircuit(model)
    assert not text_problems(subcircuit(moved), lib, subcircuit(with_fits(moved, model)), "t.lib")

    heavier = dataclasses.replace(model.coordinates[0], mass=model.coordinates[0].mass * (1 + 1e-6))
    changed = dataclasses.replace(model, coordinates=[heavier, *model.coordinates[1:]])
    assert model_problems(changed, committed, x, "t")
    assert text_problems(subcircuit(changed), lib, subcircuit(with_fits(changed, model)), "t.lib")

    f = model.capacitances[1]
    first = f.polys[0]
    bumped = type(first)(first.exponents, first.coeffs * np.r_[1 + 1e-3, np.ones(len(first.coeffs) - 1)])
    assert any(
        "C of" in p
        for p in model_problems(
            with_fit(model, 1, dataclasses.replace(f, polys=(bumped, *f.polys[1:]))), committed, x, "t"
        )
    )
    k = next(k for k, g in enumerate(PATCH_GRIDS) if g[0] * g[1] == len(f.polys))
    other = refit(b, 1, 0.0, grid=k + 1)
    assert model_problems(with_fit(model, 1, other), committed, x, "t")  # other terms, and another C:
    assert any("C of" in p for p in compare_functions(with_fit(model, 1, other), model, x))
    assert FIT_SHARE * f.max_rel_error < 1e-5  # the disk's fits: tolerances of a few 1e-6


def test_staleness_check_sees_small_changes_and_tolerates_rounding():
    """The comparison above: a changed digit at 1e-7 fails, a 1e-12 change passes, a rounded
    comment number may flip its last digit but not change by more."""
    line = "Gf_z_1 0 u_z y_top_r1s1_1 0 9.074329961580687e-07"
    assert not _compare_text(line, line.replace("9.074329961580687e-07", "9.074329961590687e-07"), "t")
    assert _compare_text(line, line.replace("9.074329961580687e-07", "9.074330961580687e-07"), "t")
    assert _compare_text(line, line.replace("y_top_r1s1_1", "y_top_r1s1_2"), "t")
    assert not _compare_text("* top_r1s1  2  1.669e-03", "* top_r1s1  2  1.670e-03", "t", rounded_lines="*")
    assert _compare_text("* top_r1s1  2  1.669e-03", "* top_r1s1  2  1.671e-03", "t", rounded_lines="*")
    assert _compare_text("* z  3e-06 m", "* z  4e-06 m", "t", rounded_lines="*")
    wrapped = ".model m x (\n+ p=[1.25 2.5\n+ 3.75])"  # a vector wrapped at another value
    assert not _compare_text(wrapped, ".model m x (\n+ p=[1.25\n+ 2.5 3.75])", "t")
    assert _compare_text(wrapped, ".model m x (\n+ p=[1.25\n+ 2.5 3.76])", "t")
    assert _compare_json({"a": [1.0, 2]}, {"a": [1.0 + 1e-6, 2]})
    assert not _compare_json(
        {"report": {"mechanics": {"side_conditions": {"phi": 3e-12}}}},
        {"report": {"mechanics": {"side_conditions": {"phi": 8e-13}}}},
    )
    assert "regenerate" in _stale(["x"]) and REGENERATE in _stale(["x"])


# ----------------------------------------------------------------------------- fresh processes


# Fresh `netgen build` processes. Their outputs must equal each other's and, byte for byte, the
# in-process session build: that is a separate process too, one that has already run other
# eigensolves (an unseeded ARPACK start vector differs both between fresh processes and between
# calls in one process), so one fresh run already compares two processes. Each run is a full
# 10-15 s build; raise to 2 to also compare two fresh processes with each other.
FRESH_RUNS = 1


@pytest.fixture(scope="module")
def fresh_builds(tmp_path_factory):
    """`netgen build` of the reference example in fresh processes (run concurrently), from the
    repository root, with progress (not quiet): (folder, exit code, stdout, stderr) each."""
    runs = []
    for k in range(FRESH_RUNS):
        out = tmp_path_factory.mktemp(f"build{k}")
        proc = subprocess.Popen(
            [sys.executable, "-m", "netgen.cli.commands", "build", REFERENCE, "-o", str(out)],
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        runs.append((out, proc))
    results = []
    for out, proc in runs:
        stdout, stderr = proc.communicate(timeout=300)
        results.append((out, proc.returncode, stdout, stderr))
    return results


def test_builds_in_separate_processes_are_byte_identical(fresh_builds, reference_model):
    for out, rc, _, err in fresh_builds:
        assert rc == 0, err[-2000:]
        _assert_clean_outputs(out)
        assert (out / f"{NAME}.json").read_bytes() == reference_model.json_text().encode("utf-8")
        assert (out / f"{NAME}.lib").read_bytes() == subcircuit(reference_model).encode("utf-8")
    first = fresh_builds[0][0]
    for out, *_ in fresh_builds[1:]:
        for ext in (".lib", ".json"):
            assert (out / f"{NAME}{ext}").read_bytes() == (first / f"{NAME}{ext}").read_bytes(), ext


def test_cli_shows_progress_and_files_written(fresh_builds):
    out, rc, stdout, stderr = fresh_builds[0]
    assert rc == 0
    # tqdm bars on stderr for the sampling and fit stages
    for desc in ("capacitance samples", "held-out samples", "fits"):
        assert re.search(rf"{desc}:\s+\d+%\|", stderr), f"no progress bar for {desc!r}"
    assert "eigenmodes" in stderr
    # stdout: the files written (netlist and JSON first, each of them exists), then a summary line
    lines = stdout.splitlines()
    assert lines[:2] == [f"wrote {out / (NAME + '.lib')}", f"wrote {out / (NAME + '.json')}"]
    for line in lines[:-1]:
        assert line.startswith("wrote ") and Path(line[len("wrote ") :]).is_file(), line
    worst = max(f["max_rel_error"] for f in json.loads((out / f"{NAME}.json").read_text())["capacitances"])
    assert re.fullmatch(
        rf"{NAME}: 7 coordinates, 16 electrodes, held-out max capacitance error "
        rf"{worst:.2e}, \d+\.\d s",
        lines[-1],
    ), lines[-1]
    assert "%|" not in stdout  # progress stays off stdout


# ----------------------------------------------------------------------------- JSON content


@pytest.fixture(scope="module")
def committed():
    return json.loads((NETLISTS / f"{NAME}.json").read_text(encoding="utf-8"))


def test_json_has_coordinates_modes_capacitances_ports(committed):
    d = committed
    coords = d["coordinates"]
    assert [c["name"] for c in coords] == ["z", "tilt_x", "tilt_y", "m2_0c", "m2_0s", "m3_0c", "m3_0s"]
    assert [c["kind"] for c in coords] == ["translation", "rotation", "rotation"] + ["mode"] * 4
    gap, radius = 3e-6, 473e-6  # examples/levitated_disk.toml
    scale = {c["name"]: c["scale"] for c in coords}
    assert scale["z"] == pytest.approx(gap, rel=1e-9, abs=0)  # a rigid lift touches at z = g
    for tilt in ("tilt_x", "tilt_y"):  # the rim touches at R * angle = g
        assert scale[tilt] == pytest.approx(gap / radius, rel=1e-6)
    for m in ("m2_0c", "m2_0s", "m3_0c", "m3_0s"):  # peak deflection 1: touches at >= g
        assert gap * (1 - 1e-9) <= scale[m] <= 1.01 * gap

    modes = d["modes"]
    assert [m["label"] for m in modes] == ["2,0c", "2,0s", "3,0c", "3,0s"]
    mass = math.pi * radius**2 * 10e-6 * 2330
    for m in modes:
        paper, tol = (97.6e3, 0.01) if m["label"].startswith("2,0") else (225.3e3, 0.015)
        assert m["frequency_hz"] == pytest.approx(paper, rel=tol), m["label"]
        assert 0 < m["modal_mass"] < mass
        assert m["frequency_hz"] == pytest.approx(
            math.sqrt(m["modal_stiffness"] / m["modal_mass"]) / (2 * math.pi), rel=1e-9
        )

    electrodes = {e["name"]: e for e in d["electrodes"]}
    assert len(electrodes) == 16
    for f in d["capacitances"]:
        assert f["pair"] == [d["plate"], f["electrode"]]
        assert 0 < f["rms_rel_error"] <= f["max_rel_error"] < 5e-3
        e = electrodes[f["electrode"]]
        # c_ref is the parallel plate eps0 A / g (eps0 of CODATA 2022) plus the edge fringe (a few % at g/R ~ 1/160)
        assert 1.0 < f["c_ref"] / (8.8541878188e-12 * e["area"] / e["gap"]) < 1.06, f["electrode"]
    # electrode areas: annular quadrants minus two half-slots (5 um wide) along the radial edges
    for ring, (r0, r1) in {"r1": (20e-6, 230e-6), "r2": (240e-6, 473e-6)}.items():
        area = math.pi * (r1**2 - r0**2) / 4 - 2 * 5e-6 * (r1 - r0)
        for name, e in electrodes.items():
            if f"_{ring}s" in name:
                assert e["area"] == pytest.approx(area, rel=2e-3), name

    ports = d["ports"]
    names = [p["name"] for p in ports]
    assert names[:17] == list(electrodes) + [d["plate"]]
    assert names[17:] == [f"{io}_{c['name']}" for c in coords for io in ("f", "x")]
    units = {p["name"]: p["unit"] for p in ports}
    assert units["x_z"] == "um" and units["f_z"] == "uN" and units["x_tilt_x"] == "mrad" and units["f_tilt_x"] == "nN*m"


def test_model_round_trips_through_json(reference_model):
    back = MacroModel.from_dict(json.loads(reference_model.json_text()))
    rng = np.random.default_rng(7)
    x = rng.uniform(-0.2, 0.2, size=(50, reference_model.ncoords))
    v = rng.uniform(-5, 5, size=(50, len(reference_model.electrodes)))
    np.testing.assert_array_equal(back.capacitance(x), reference_model.capacitance(x))
    np.testing.assert_array_equal(back.capacitance_gradient(x), reference_model.capacitance_gradient(x))
    np.testing.assert_array_equal(back.electrostatic_force(x, v, 1.0), reference_model.electrostatic_force(x, v, 1.0))
    np.testing.assert_array_equal(back.coupling, reference_model.coupling)
    assert back.coordinates == reference_model.coordinates and back.electrodes == reference_model.electrodes
    assert back.json_text() == reference_model.json_text()


# ----------------------------------------------------------------------------- no partial output


@pytest.fixture
def cli_with_model(reference_build, monkeypatch):
    """`netgen build` on the reference file, with the 10 s pipeline run replaced by the session's."""
    monkeypatch.setattr("netgen.cli.commands.build", lambda s, *args, **kwargs: reference_build)
    return lambda out: cli.main(["build", str(ROOT / REFERENCE), "-o", str(out), "-q"])


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir()) if folder.exists() else []


def _assert_clean_outputs(folder: Path) -> None:
    """Both outputs written, no temp or hidden files left next to them."""
    names = _leftovers(folder)
    assert {f"{NAME}.json", f"{NAME}.lib"} <= set(names), names
    assert not [n for n in names if n.startswith(".") or n.endswith(".tmp")], names


def _assert_internal_error(capsys, cwd: Path, text: str) -> None:
    """Exit 70's one line on stderr, the traceback in the crash log in `cwd` (no output folder)."""
    err = capsys.readouterr().err
    assert "internal error" in err and text in err and "Traceback" not in err and len(err.splitlines()) == 1
    assert text in (cwd / "netgen-crash.log").read_text() and "Traceback" in (cwd / "netgen-crash.log").read_text()


def test_failing_emitter_leaves_nothing(cli_with_model, monkeypatch, tmp_path, capsys):
    def broken(model):
        raise RuntimeError("emitter failed")

    monkeypatch.setitem(emit.EMITTERS, "ngspice", dataclasses.replace(emit.EMITTERS["ngspice"], render=broken))
    monkeypatch.chdir(tmp_path)
    assert cli_with_model(tmp_path / "out") == 70
    assert _leftovers(tmp_path / "out") == []
    _assert_internal_error(capsys, tmp_path, "emitter failed")


def test_failing_json_after_netlist_leaves_nothing(cli_with_model, monkeypatch, tmp_path, capsys):
    """The .lib renders fine, then the model's JSON fails: no .lib may remain on its own."""

    def broken(self):
        raise ValueError("model not serialisable")

    monkeypatch.setattr(MacroModel, "to_dict", broken)
    monkeypatch.chdir(tmp_path)
    assert cli_with_model(tmp_path / "out") == 70
    assert _leftovers(tmp_path / "out") == []
    _assert_internal_error(capsys, tmp_path, "serialisable")


def test_failing_write_leaves_no_temp_files_and_keeps_old_outputs(cli_with_model, monkeypatch, tmp_path, capsys):
    """The disk fills while writing the second file: exit 2 with a message, no temp files,
    and the previous outputs are untouched (not half replaced)."""
    out = tmp_path / "out"
    out.mkdir()
    (out / f"{NAME}.lib").write_text("old lib\n")
    (out / f"{NAME}.json").write_text("old json\n")
    real_fdopen, calls = os.fdopen, []

    def fdopen(fd, *args, **kwargs):
        calls.append(fd)
        fh = real_fdopen(fd, *args, **kwargs)
        if len(calls) == 2:
            fh.close()
            raise OSError(28, "No space left on device")
        return fh

    monkeypatch.setattr("netgen.core.files.os.fdopen", fdopen)
    assert cli_with_model(out) == 2
    assert "the disk is full" in capsys.readouterr().err  # netgen.runtime.folders names the folder and the fix
    assert _leftovers(out) == [f"{NAME}.json", f"{NAME}.lib"]
    assert (out / f"{NAME}.lib").read_text() == "old lib\n" and (out / f"{NAME}.json").read_text() == "old json\n"


def test_successful_write_replaces_outputs_with_normal_permissions(cli_with_model, tmp_path):
    out = tmp_path / "out"
    assert cli_with_model(out) == 0
    _assert_clean_outputs(out)
    umask = os.umask(0)
    os.umask(umask)
    assert (out / f"{NAME}.lib").stat().st_mode & 0o777 == 0o666 & ~umask


def test_invalid_structure_file_exits_2_with_file_key_and_fix(tmp_path):
    text = (ROOT / REFERENCE).read_text(encoding="utf-8")
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('gap = "3 um"', 'gap = "-3 um"', 1), encoding="utf-8")
    line = 1 + bad.read_text().splitlines().index('gap = "-3 um"')
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "netgen.cli.commands", "build", str(bad), "-o", str(out)],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and proc.stdout == ""
    assert f"{bad}:{line}" in proc.stderr  # file and line
    assert "electrodes[0].gap" in proc.stderr  # key
    assert "\n  fix: " in proc.stderr  # and how to fix it
    assert not out.exists()


def test_misspelled_key_suggests_the_right_one(tmp_path, capsys):
    bad = tmp_path / "typo.toml"
    bad.write_text((ROOT / REFERENCE).read_text(encoding="utf-8").replace("\nradius = ", "\nradiu = "))
    assert cli.main(["build", str(bad), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "conductor.radiu" in err and "fix:" in err and "'radius'" in err
    assert not (tmp_path / "out").exists()


# ----------------------------------------------------------------------------- packaging


def test_wheel_ships_templates_and_renders_outside_the_repo(tmp_path):
    """Build a wheel from a copy of the sources, unpack it, and render the committed model's
    netlist from it in a process whose cwd is outside the repository."""
    src = tmp_path / "src"
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    for d in ("netgen", "templates"):
        shutil.copytree(ROOT / d, src / d, ignore=ignore)
    for f in ("pyproject.toml", "README.md"):
        shutil.copy2(ROOT / f, src / f)
    dist = tmp_path / "dist"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            str(src),
            "--no-deps",
            "--no-build-isolation",
            "--no-index",
            "-q",
            "-w",
            str(dist),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    (wheel,) = dist.glob("netgen-*.whl")
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
        # every module of every package, the code models' sources (netgen.sim.codemodel builds them
        # on the user's machine), the Verilog-A loop blocks, and every template under netgen/templates
        shipped = {
            f"netgen/{f.relative_to(ROOT / 'netgen').as_posix()}"
            for f in (ROOT / "netgen").rglob("*")
            if f.suffix in (".py", ".lst", ".ifs", ".mod", ".va") and "__pycache__" not in f.parts
        }
        shipped |= {
            f"netgen/templates/{f.relative_to(ROOT / 'templates').as_posix()}"
            for f in (ROOT / "templates").rglob("*.j2")
        }
        assert (
            "netgen/templates/ngspice/subckt.lib.j2" in shipped
            and "netgen/sim/codemodel/netgen_es/cfunc.mod" in shipped
        )
        assert not shipped - names, sorted(shipped - names)
        entry = next(n for n in names if n.endswith(".dist-info/entry_points.txt"))
        assert "netgen = netgen.cli:main" in z.read(entry).decode()
        z.extractall(tmp_path / "site")
    work = tmp_path / "elsewhere"
    work.mkdir()
    script = (
        "import sys, netgen\n"
        "from netgen.model import MacroModel\n"
        "from netgen.emit.ngspice import subcircuit\n"
        "print(netgen.__file__)\n"
        f"sys.stdout.write(subcircuit(MacroModel.load_json({str(NETLISTS / (NAME + '.json'))!r})))\n"
    )
    env = dict(os.environ, PYTHONPATH=str(tmp_path / "site"))
    run = subprocess.run([sys.executable, "-c", script], cwd=work, env=env, capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr[-3000:]
    where, _, text = run.stdout.partition("\n")
    assert Path(where).is_relative_to(tmp_path / "site"), where  # the wheel's copy, not the repo's
    assert text == subcircuit(MacroModel.load_json(NETLISTS / f"{NAME}.json"))
    assert f".subckt {NAME} " in text and ".ends" in text


def test_xspice_emission_names_the_electrode_whose_fit_it_cannot_take(tmp_path, monkeypatch, capsys):
    """The code model evaluates 1/P plate terms only: a 'direct' polynomial fit is refused with
    the electrode and the fix (emitter and `netgen build --format xspice`: exit 2, nothing
    written), and `all` leaves the xspice .lib out for such a model (and writes the rest)."""
    import types

    model = MacroModel.load_json(NETLISTS / f"{NAME}.json")
    fits = [dataclasses.replace(model.capacitances[0], target="direct"), *model.capacitances[1:]]
    bad = dataclasses.replace(model, capacitances=fits)
    with pytest.raises(ValueError, match=r"top_r1s1.*'direct'.*fix: emit the B-source form"):
        xspice.subcircuit(bad)
    monkeypatch.setattr("netgen.cli.commands.build", lambda s, *args, **kwargs: types.SimpleNamespace(model=bad))
    out = tmp_path / "one"
    code = cli.main(["build", str(ROOT / REFERENCE), "-o", str(out), "-q", "--no-plots", "--format", "xspice"])
    err = capsys.readouterr().err
    assert code == 2 and "electrode top_r1s1 has a 'direct' capacitance fit" in err and "; fix: " in err
    assert _leftovers(out) == []
    written = {p.name for p in emit.write_outputs(bad, tmp_path / "all", "all")}
    schematics = {f"{NAME}.sym", f"{NAME}_tb.sch", f"{NAME}.kicad_sym"}  # netgen.emit.xschem, netgen.emit.kicad
    assert written == {f"{NAME}.lib", f"{NAME}.va", f"{NAME}.json"} | schematics
