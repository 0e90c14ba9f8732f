"""The documentation cannot drift: its commands run, its site builds.

Every fenced `bash` block of README.md and docs/*.md is marked on the line before it:
`<!-- tested -->` (the block runs here, each line in bash from a scratch folder that sees the
repository's examples/, netlists/, bench/ and .venv/) or `<!-- not tested: why -->` (the
set-up, the suite itself, runs of minutes). A tested block followed by `<!-- output -->` and a
`text` block must print those lines, in order (numbers within 1 %, times in seconds not
compared); with `<!-- output: text -->` only the text around the numbers is compared. And
`mkdocs build --strict` builds the site without a broken link or a missing page.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.fixtures import ROOT

PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SHARED = ("examples", "netlists", "bench", ".venv")  # what a command may read from the repository
NUMBER = re.compile(r"(?<![\w.])[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?(?![\w.])")
SECONDS = re.compile(r"(?<![\w.])[-+]?\d+(?:\.\d*)?(?= s\b)")


@dataclass
class Block:
    page: Path
    line: int
    mark: str  # the comment before the fence ("" if none)
    lang: str
    text: str
    output: tuple[str, str] | None = None  # (mode "numbers" or "text", expected text)

    @property
    def name(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"


def blocks(page: Path) -> list[Block]:
    """The fenced blocks of a page, each with the comment line before it and, for a command, the
    output block that follows it."""
    lines = page.read_text(encoding="utf-8").splitlines()
    out, k = [], 0
    while k < len(lines):
        m = re.match(r"^```(\w*)\s*$", lines[k])
        if not m:
            k += 1
            continue
        start, end = k, k + 1
        while end < len(lines) and lines[end] != "```":
            end += 1
        prev = next((lines[j].strip() for j in range(start - 1, -1, -1) if lines[j].strip()), "")
        out.append(
            Block(
                page, start + 1, prev if prev.startswith("<!--") else "", m.group(1), "\n".join(lines[start + 1 : end])
            )
        )
        k = end + 1
    for cmd, nxt in zip(out, out[1:]):
        if cmd.lang == "bash" and nxt.mark in ("<!-- output -->", "<!-- output: text -->"):
            cmd.output = ("text" if "text" in nxt.mark else "numbers", nxt.text)
    return out


def commands() -> list[Block]:
    return [b for p in PAGES for b in blocks(p) if b.lang == "bash"]


TESTED = [b for b in commands() if b.mark == "<!-- tested -->"]


def matches(expected: str, actual: str, mode: str) -> str | None:
    """None if the expected lines appear in order among the actual ones, else the first miss."""
    got = [ln.rstrip() for ln in actual.splitlines()]
    k = 0
    for want in (ln.rstrip() for ln in expected.splitlines() if ln.strip()):
        while k < len(got) and not same_line(want, got[k], mode):
            k += 1
        if k == len(got):
            return want
        k += 1
    return None


def same_line(want: str, got: str, mode: str) -> bool:
    """The text around the numbers equal; in "numbers" mode also the numbers within 1 % (but
    the seconds a run took)."""
    if NUMBER.sub("#", want) != NUMBER.sub("#", got):
        return False
    if mode == "text":
        return True
    times = {m.start() for m in SECONDS.finditer(want)}
    for a, b in zip(NUMBER.finditer(want), NUMBER.finditer(got)):
        if a.start() in times:
            continue
        x, y = float(a.group()), float(b.group())
        if abs(x - y) > 0.01 * max(abs(x), abs(y)):
            return False
    return True


def test_every_command_block_is_marked():
    """A command shown in the documentation is either run here or says why it is not."""
    unmarked = [b.name for b in commands() if b.mark != "<!-- tested -->" and not b.mark.startswith("<!-- not tested:")]
    assert unmarked == []
    assert len(TESTED) >= 6


def test_output_comparison_sees_changes():
    """The comparison itself: a changed number or word fails, a changed duration passes."""
    assert matches("a = 1.962e-03", "noise\na = 1.9621e-03\n", "numbers") is None
    assert matches("a = 1.962e-03", "a = 1.99e-03", "numbers") == "a = 1.962e-03"
    assert matches("x, 14.1 s", "x, 9.9 s", "numbers") is None
    assert matches("b 1\nc 2", "c 2\nb 1", "text") == "c 2"
    assert matches("in-band floor -93.6 dB/Hz", "in-band floor -80.0 dB/Hz", "text") is None
    assert matches("in-band floor -93.6 dB/Hz", "in-band floor n/a", "text") is not None


@pytest.mark.parametrize("block", TESTED, ids=[b.name for b in TESTED])
def test_documented_command_runs(block, tmp_path):
    for name in SHARED:
        (tmp_path / name).symlink_to(ROOT / name)
    proc = subprocess.run(
        ["bash", "-e", "-o", "pipefail", "-c", block.text], cwd=tmp_path, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, f"{block.name}: exit {proc.returncode}\n{proc.stderr[-3000:]}"
    if block.output:
        mode, expected = block.output
        assert matches(expected, proc.stdout, mode) is None, (
            f"{block.name}: missing {matches(expected, proc.stdout, mode)!r} in\n{proc.stdout[-3000:]}"
        )


def test_site_builds_without_broken_links(tmp_path):
    """mkdocs build --strict: every page in the nav, every link found."""
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert (tmp_path / "site" / "index.html").read_text().count("Five-minute tutorial") >= 1  # the README


def test_site_build_fails_on_a_broken_link(tmp_path):
    """The same build on a copy of the documentation with one link to a page that is not there."""
    for name in ("docs", "mkdocs.yml", "README.md", "CHANGELOG.md"):
        (shutil.copytree if (ROOT / name).is_dir() else shutil.copy2)(ROOT / name, tmp_path / name)
    with open(tmp_path / "docs" / "contact.md", "a", encoding="utf-8") as fh:
        fh.write("\nSee [the missing page](missing.md).\n")
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(tmp_path / "site")],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode != 0 and "missing.md" in proc.stderr
