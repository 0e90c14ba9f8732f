"""The committed netlists of every structure example (netlists/<example>/, beside the reference
disk's netlists/ itself, which tests/pipeline/test_outputs.py checks): one build per example from
the repository root, every emitted text form (.lib, _xspice.lib, _osdi.lib, .va, .json, and a
calibrated build's _calibration.json) rendered from it and compared with the committed file,
byte for byte where the build reproduces them exactly (it does on one machine), and otherwise up
to BLAS-level rounding as for the disk; the committed folder holds exactly those files. No example
is skipped: a new example without netlists fails here until they are committed."""

from __future__ import annotations

import contextlib
import json
from pathlib import Path

import pytest

from netgen.build import build, write_calibration
from netgen.emit import EMITTERS, chosen
from netgen.structure import load_structure
from tests.fixtures import ROOT
from tests.pipeline.test_outputs import _compare_json, _compare_text

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


def rendered(name: str, tmp: Path) -> dict[str, str]:
    """Every committed text form of one example, from a fresh in-process build (loaded with the
    relative path from the repository root, as the committed files were)."""
    with contextlib.chdir(ROOT):
        b = build(load_structure(f"examples/{name}.toml"))
    model = b.model
    out = {f"{model.name}{EMITTERS[f].suffix}": EMITTERS[f].render(model) for f in chosen(model, "all,osdi")}
    out |= {f"{model.name}{suffix}": text for suffix, text in EMITTERS["xschem"].extra(model).items()}  # _tb.sch
    out[f"{model.name}.json"] = model.json_text()
    for path in write_calibration(b, tmp, figure=False):
        out[path.name] = path.read_text(encoding="utf-8")
    return out


def problems_of(new: str, old: str, file: str) -> list[str]:
    """Differences beyond BLAS rounding (none when the bytes are equal)."""
    if new == old:
        return []
    if file.endswith(".json"):
        found = _compare_text(new, old, file, numbers=False)
        return found or _compare_json(json.loads(new), json.loads(old), file)
    return _compare_text(new, old, file, rounded_lines="*" if not file.endswith(".va") else "//")


@pytest.mark.parametrize("name", EXAMPLES)
def test_example_netlists_are_current(name, tmp_path):
    """netlists/<name>/ holds exactly the example's text forms, each equal to a fresh build's."""
    folder = NETLISTS / name
    new = rendered(name, tmp_path)
    committed = (
        sorted(p.name for p in folder.glob("*") if p.name.endswith(COMMITTED) and not p.name.endswith(".manifest.json"))
        if folder.is_dir()
        else []
    )  # git ignores the manifest
    problems = [] if committed == sorted(new) else [f"files: {committed} committed, {sorted(new)} built"]
    for file in sorted(set(new) & set(committed)):
        problems += problems_of(new[file], (folder / file).read_text(encoding="utf-8"), file)
    shown = "\n  ".join(problems[:8])
    assert not problems, (
        f"netlists/{name} is stale ({len(problems)} differences):\n  {shown}\n"
        f"regenerate every example's netlists from the repository root with:\n    {REGENERATE}"
    )


def test_every_structure_example_is_covered():
    """Each example structure has its folder (the reference disk: netlists/ itself)."""
    assert {p.name for p in NETLISTS.iterdir() if p.is_dir()} == set(EXAMPLES)
