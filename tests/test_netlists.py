"""The committed netlists of every structure example (netlists/<example>/, beside the reference
disk's netlists/ itself, which tests/pipeline/test_outputs.py checks): one build per example from
the repository root, every emitted text form (.lib, _xspice.lib, _osdi.lib, .va, .json, and a
calibrated build's _calibration.json) rendered from it and compared with the committed file,
byte for byte where the build reproduces them exactly (it does on one machine), and otherwise by
what the model computes, as for the disk (tests/staleness.py: words and layout identical, numbers
within rounding except the fit coefficients, whose fitted C and dC/dq agree within a hundredth of
the fit's own held-out error); the committed folder holds exactly those files. No example is
skipped: a new example without netlists fails here until they are committed."""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import json
from pathlib import Path

import numpy as np
import pytest

from netgen.build import Build, build, write_calibration
from netgen.emit import EMITTERS, chosen
from netgen.fit.capacitance import PATCH_GRIDS
from netgen.model import MacroModel
from netgen.structure import load_structure
from tests.fixtures import ROOT
from tests.staleness import (
    RTOL,
    coefficient_change,
    compare_functions,
    compare_json,
    model_problems,
    refit,
    text_problems,
    with_fit,
    with_fits,
)

NETLISTS = ROOT / "netlists"
REFERENCE = "levitated_disk"  # netlists/ itself (tests/pipeline/test_outputs.py)
NOT_STRUCTURES = {"sweep_ts"}  # a sweep file beside the structures
EXAMPLES = sorted(p.stem for p in (ROOT / "examples").glob("*.toml") if p.stem not in NOT_STRUCTURES | {REFERENCE})
REGENERATE = (
    "for n in " + " ".join(EXAMPLES) + "; do .venv/bin/netgen build examples/$n.toml -o netlists/$n "
    "--format all,osdi; done"
)
# text files; PNGs and the build report (its figures inline) are not compared, nor committed
COMMITTED = (".lib", ".json", ".va", "_calibration.json", ".sym", "_tb.sch", ".kicad_sym")


@functools.cache
def built(name: str) -> Build:
    """One in-process build of an example (loaded with the relative path from the repository root,
    as the committed files were); cached for the planted-change test."""
    with contextlib.chdir(ROOT):
        return build(load_structure(f"examples/{name}.toml"))


def rendered(model: MacroModel) -> dict[str, str]:
    """Every committed netlist text form of a model, by file name (the Xschem testbench too)."""
    out = {f"{model.name}{EMITTERS[f].suffix}": EMITTERS[f].render(model) for f in chosen(model, "all,osdi")}
    return out | {f"{model.name}{suffix}": str(text) for suffix, text in EMITTERS["xschem"].extra(model, "").items()}


def problems_of(b: Build, folder: Path, tmp: Path) -> tuple[list[str], list[str]]:
    """The files built and the differences of the committed ones beyond what rounding does
    (tests/staleness.py; none where the bytes are equal)."""
    model = b.model
    new = rendered(model) | {f"{model.name}.json": model.json_text()}
    new |= {p.name: p.read_text(encoding="utf-8") for p in write_calibration(b, tmp, figure=False)}
    committed = lambda f: (folder / f).read_text(encoding="utf-8")  # noqa: E731
    names = {p.name for p in folder.glob("*")}
    problems, hybrid = [], model
    json_file = f"{model.name}.json"
    if json_file in names:
        problems += model_problems(model, committed(json_file), np.vstack([b.grid.x, b.holdout.x]), json_file)
        hybrid = with_fits(model, MacroModel.load_json(folder / json_file))
    hybrid_text = rendered(hybrid)
    for file in sorted(set(new) & names - {json_file}):
        if file.endswith(".json"):  # the calibration report: no fits in it
            found = [f"{file}: {p}" for p in compare_json(json.loads(new[file]), json.loads(committed(file)))]
        else:
            found = text_problems(new[file], committed(file), hybrid_text[file], file)
        problems += [] if new[file] == committed(file) else found
    return sorted(new), problems


@pytest.mark.parametrize("name", EXAMPLES)
def test_example_netlists_are_current(name, tmp_path):
    """netlists/<name>/ holds exactly the example's text forms, each equal to a fresh build's."""
    folder = NETLISTS / name
    built_files, found = problems_of(built(name), folder, tmp_path)
    committed = (
        sorted(p.name for p in folder.glob("*") if p.name.endswith(COMMITTED) and not p.name.endswith(".manifest.json"))
        if folder.is_dir()
        else []
    )  # git ignores the manifest
    problems = [] if committed == built_files else [f"files: {committed} committed, {built_files} built"]
    problems += found
    shown = "\n  ".join(problems[:8])
    assert not problems, (
        f"netlists/{name} is stale ({len(problems)} differences):\n  {shown}\n"
        f"regenerate every example's netlists from the repository root with:\n    {REGENERATE}"
    )


def test_every_structure_example_is_covered():
    """Each example structure has its folder (the reference disk: netlists/ itself)."""
    assert {p.name for p in NETLISTS.iterdir() if p.is_dir()} == set(EXAMPLES)


def test_refits_of_the_cantilever_pass_and_real_changes_fail():
    """The model comparison on the example whose coefficients moved 8e-4 between two machines.
    Its fit (9 plates, held-out max error 0.13) redone from samples perturbed by 1e-7 relative
    moves the coefficients far beyond RTOL (the old number-by-number check fails) and is the same
    model; the next patch grid (another fit: C differs by about the fits' error) and a 1e-6
    relative change of a mass are flagged."""
    b = built("cantilever")
    model, x = b.model, np.vstack([b.grid.x, b.holdout.x])
    committed = model.json_text()
    moved = with_fit(model, 0, refit(b, 0, 1e-7, seed=0))
    assert coefficient_change(moved, model) > 100 * RTOL
    assert compare_json(json.loads(moved.json_text()), json.loads(committed))  # the old check: stale
    assert not model_problems(moved, committed, x, "t")
    old_texts, moved_texts, hybrid = rendered(model), rendered(moved), rendered(with_fits(moved, model))
    assert not [p for f in old_texts for p in text_problems(moved_texts[f], old_texts[f], hybrid[f], f)]
    k = next(k for k, g in enumerate(PATCH_GRIDS) if g[0] * g[1] == len(model.capacitances[0].polys))
    other = with_fit(model, 0, refit(b, 0, 0.0, grid=k - 1))
    assert model_problems(other, committed, x, "t")  # its JSON has other terms, and its function:
    assert any("C of" in p for p in compare_functions(other, model, x))
    c = model.coordinates[1]
    heavier = dataclasses.replace(c, mass=c.mass * (1 + 1e-6))
    changed = dataclasses.replace(model, coordinates=[model.coordinates[0], heavier, *model.coordinates[2:]])
    assert model_problems(changed, committed, x, "t")


def test_refits_of_the_beam_converge_to_one_function():
    """The clamped-clamped beam's fit, which one capped Levenberg-Marquardt run left where rounding
    put it (C moved by twice its own error between 1e-12 changes of the samples), now settles
    (netgen.fit.capacitance.settled): re-fits from samples perturbed by 1e-12 relative (another
    CPU's rounding, with a thousandfold margin) are the same model by the staleness comparison."""
    b = built("cc_beam")
    model, x = b.model, np.vstack([b.grid.x, b.holdout.x])
    for seed in range(3):
        moved = with_fit(model, 0, refit(b, 0, 1e-12, seed=seed))
        assert not model_problems(moved, model.json_text(), x, f"seed {seed}")


BEAM_KINDS = ("cantilever", "clamped_clamped_beam")


def beam_rounding_bound(conductor) -> float:
    """eps lambda_max / (lambda_2 - lambda_1) of a beam's Hermite pencil (the same matrices
    netgen.mechanics.beam.beam_modes solves, read through its eigh): the first-order rounding of its
    mode shapes along the second mode, which the peak normalisation passes to the modal masses."""
    from netgen.mechanics import beam

    seen, original = {}, beam.eigh

    def spy(K, M, **kw):
        seen["w"] = original(K, M, eigvals_only=True)  # the whole spectrum of the same pencil
        return original(K, M, **kw)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(beam, "eigh", spy)
        beam.beam_modes(conductor, 2)
    w = seen["w"]
    return float(np.finfo(float).eps * w[-1] / (w[1] - w[0]))


@pytest.mark.parametrize("name", EXAMPLES)
def test_rtol_covers_the_beams_rounding(name):
    """tests/staleness.RTOL holds the beam examples' mode-shape rounding: 4 eps lambda_max /
    (lambda_2 - lambda_1) (a mode's value at the first one's peak, two builds) below it, so a finer
    beam mesh that outgrows it fails here rather than on another CPU."""
    conductor = load_structure(ROOT / "examples" / f"{name}.toml").conductor
    if getattr(conductor, "kind", "") not in BEAM_KINDS:
        return
    assert 4 * beam_rounding_bound(conductor) <= RTOL
