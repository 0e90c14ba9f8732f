"""The repository stands alone: no tracked file cites the developers' notes or paper by a path
outside the repository, so a user who clones it follows no dangling reference.

Every file `git ls-files` lists (the tree walked, without .git, .venv and build output, where
git is unavailable) is searched for the forbidden mentions, and each hit is named by file and
line. The facts such a citation pointed at live in docs/ (simulators.md, performance.md, bem.md,
structure-files.md); the paper is cited by its bibliographic reference, not a file name.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

from tests.fixtures import ROOT

# Built from pieces so that this file does not contain the strings it forbids (it is scanned
# like any other tracked file, and excluding it would hide a mention added here later).
FORBIDDEN = (
    "design" + ".md",
    ".." + "/shared",
    "shared" + "/reference",
    "/" + "work/",
    "macromodel-paper" + ".txt",
)
PATTERN = re.compile("|".join(re.escape(s) for s in FORBIDDEN))
SKIP_DIRS = {".git", ".venv", "site", "out", "__pycache__", ".pytest_cache", ".ruff_cache", "build", "dist"}


def tracked_files(root: Path) -> list[Path]:
    """The files git tracks under root; without git (or outside a checkout) every file of the
    tree except version-control, environment and build folders."""
    try:
        proc = subprocess.run(["git", "ls-files", "-z"], cwd=root, capture_output=True, check=True, timeout=60)
        names = [n for n in proc.stdout.decode("utf-8", "surrogateescape").split("\0") if n]
        if names:
            return [root / n for n in names]
    except (OSError, subprocess.SubprocessError):
        pass
    return [
        p
        for p in root.rglob("*")
        if p.is_file()
        and not any(part in SKIP_DIRS or part.endswith(".egg-info") for part in p.relative_to(root).parts)
    ]


def mentions(root: Path, files: list[Path]) -> list[str]:
    """'path:line: text' for every line of a text file that holds a forbidden mention."""
    hits = []
    for path in files:
        try:
            text = path.read_bytes().decode("utf-8", "replace")
        except OSError:  # a tracked file deleted in the work tree
            continue
        for number, line in enumerate(text.splitlines(), 1):
            if PATTERN.search(line):
                hits.append(f"{path.relative_to(root)}:{number}: {line.strip()[:160]}")
    return hits


def test_no_tracked_file_cites_a_path_outside_the_repository():
    """Each hit names the file and line; move the fact into docs/ and cite the page instead."""
    files = tracked_files(ROOT)
    assert len(files) > 100  # the scan saw the repository, not an empty listing
    hits = mentions(ROOT, files)
    assert hits == [], "references outside the repository (cite a docs/ page instead):\n" + "\n".join(hits)


def test_scanner_finds_each_forbidden_mention(tmp_path):
    """The scan itself: a planted mention of each pattern is found with its file and line, clean
    text is not, and the tree walk (no git checkout here) sees the files and skips .venv."""
    (tmp_path / "clean.md").write_text("see docs/bem.md, 'Two 1 mm squares'\n")
    for k, s in enumerate(FORBIDDEN):
        (tmp_path / f"f{k}.py").write_text(f"x = 1\n# see {s}\n")
    (tmp_path / ".venv").mkdir()
    (tmp_path / ".venv" / "lib.py").write_text(f"# {FORBIDDEN[0]}\n")
    files = tracked_files(tmp_path)
    assert sorted(p.name for p in files) == sorted(["clean.md", *(f"f{k}.py" for k in range(len(FORBIDDEN)))])
    hits = mentions(tmp_path, files)
    assert sorted(h.split(": ", 1)[0] for h in hits) == sorted(f"f{k}.py:2" for k in range(len(FORBIDDEN)))
