"""The installed environment is reproducible: requirements.lock (pip-compile, docs/environment.md)
pins every requirement of pyproject.toml, hashes every artifact, and the repository names no
package-archive host (.ci/setup reaches Debian through the mirrors apt is configured with,
netgen.sim.codemodel.aptsources).

- every dependency and every extra's requirement, and the build-system requirements an
  editable install needs, has an exact `==` pin in the lock whose version satisfies its
  specifier (packaging's own matching, pre-releases allowed where the specifier names one);
- every pinned entry carries at least one `--hash=sha256:` (pip's --require-hashes refuses the
  whole file otherwise);
- no tracked file names a Debian or Ubuntu archive host, and no file in .ci/ an http(s) URL;
- aptsources reads one-line and deb822 sources, the release's own suite only.
"""

from __future__ import annotations

import re
import subprocess
import tomllib

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

from netgen.sim.codemodel import aptsources
from tests.fixtures import ROOT

LOCK = ROOT / "requirements.lock"
PYPROJECT = ROOT / "pyproject.toml"
HOSTS = ("deb.debian.org", "ftp.debian.org", "snapshot.debian.org", "archive.ubuntu.com")
URL = re.compile(r"https?://")


def lock_entries() -> dict[str, tuple[str, list[str]]]:
    """name -> (pinned version, its sha256 hashes) from requirements.lock's entries."""
    text = LOCK.read_text(encoding="utf-8").replace("\\\n", " ")
    entries = {}
    for line in text.splitlines():
        line = line.split(" #", 1)[0].strip()
        if not line or line.startswith(("#", "-")):
            continue
        spec, *rest = line.split()
        name, sep, version = spec.partition("==")
        assert sep, f"requirements.lock: {spec!r} is not an exact == pin"
        hashes = [w.split(":", 1)[1] for w in rest if w.startswith("--hash=sha256:")]
        entries[canonicalize_name(name)] = (version, hashes)
    return entries


def project_requirements() -> list[tuple[str, Requirement]]:
    """(where, requirement) for every dependency, extra and build requirement of pyproject.toml."""
    doc = tomllib.loads(PYPROJECT.read_text(encoding="utf-8"))
    found = [("dependencies", Requirement(r)) for r in doc["project"]["dependencies"]]
    for extra, reqs in doc["project"]["optional-dependencies"].items():
        found += [(f"optional-dependencies.{extra}", Requirement(r)) for r in reqs]
    found += [("build-system.requires", Requirement(r)) for r in doc["build-system"]["requires"]]
    return found


def test_every_requirement_is_pinned_within_its_range():
    """pyproject's ranges stay the users'; the lock's pins must lie inside every one of them."""
    locked = lock_entries()
    assert locked, "requirements.lock has no entries"
    for where, req in project_requirements():
        name = canonicalize_name(req.name)
        assert name in locked, f"{where}: {req} is not in requirements.lock; refresh it (docs/environment.md)"
        version = locked[name][0]
        assert req.specifier.contains(version, prereleases=True), (
            f"{where}: {req} is not satisfied by the locked {name}=={version}; refresh requirements.lock"
        )


def test_every_lock_entry_is_hashed():
    """pip install --require-hashes needs a hash on every line; 64 hex digits each."""
    for name, (version, hashes) in lock_entries().items():
        assert hashes, f"requirements.lock: {name}=={version} has no --hash=sha256:"
        assert all(re.fullmatch(r"[0-9a-f]{64}", h) for h in hashes), name


def test_the_linters_are_pinned_exactly():
    """CI's ruff and mypy come from the venv at these exact versions (the lint extra)."""
    locked = lock_entries()
    assert locked["ruff"][0] == "0.17.6" and locked["mypy"][0] == "2.4.1"


def tracked() -> list[str]:
    """The repository's tracked files (git ls-files)."""
    out = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
    return [p for p in out.decode().split("\0") if p]


def test_no_tracked_file_names_an_archive_host():
    """apt's configured sources are the only way to Debian; .ci/ fetches nothing by URL."""
    files = tracked()
    assert ".ci/setup" in files
    bad = []
    for rel in files:
        path = ROOT / rel
        if rel == "tests/test_environment.py" or not path.is_file():
            continue
        text = path.read_bytes().decode("utf-8", errors="replace")
        bad += [f"{rel}: {h}" for h in HOSTS if h in text]
        if rel.startswith(".ci/") and URL.search(text):
            bad.append(f"{rel}: an http(s) URL")
    assert not bad, "archive hosts or URLs in tracked files:\n" + "\n".join(bad)


@pytest.fixture
def etc(tmp_path):
    """An apt configuration with one-line and deb822 sources, disabled and foreign entries."""
    (tmp_path / "sources.list.d").mkdir()
    (tmp_path / "sources.list").write_text(
        "# a comment\ndeb [arch=amd64 signed-by=/k/one.gpg] file:/m1 bookworm main contrib\n"
        "deb file:/m2 bookworm-updates main\ndeb-src file:/m3 bookworm main\n"
    )
    (tmp_path / "sources.list.d" / "a.sources").write_text(
        "Types: deb\n# file:/commented\nURIs: file:/m4 file:/m5\nSuites: bookworm bookworm-updates\n"
        "Components: main\nSigned-By: /k/two.gpg\n\nTypes: deb\nURIs: file:/m6\nSuites: bookworm\n"
        "Components: main\nEnabled: no\n\nTypes: deb\nURIs: file:/m7\nSuites: bookworm-security\nComponents: main\n"
    )
    (tmp_path / "sources.list.d" / "off.list.disabled").write_text("deb file:/m8 bookworm main\n")
    return tmp_path


def test_aptsources_takes_the_release_s_mirrors_only(etc):
    """Suite exactly `bookworm` with main, enabled, type deb, in .list/.sources files only."""
    lines = aptsources.source_lines("deb", "bookworm", ["bookworm-backports"], etc)
    assert lines == [
        "deb [signed-by=/k/one.gpg] file:/m1 bookworm-backports main",
        "deb [signed-by=/k/two.gpg] file:/m4 bookworm-backports main",
        "deb [signed-by=/k/two.gpg] file:/m5 bookworm-backports main",
    ]
    assert aptsources.source_lines("deb", "trixie", ["trixie-backports"], etc) == []
    assert "trixie" in aptsources.missing("trixie", etc)
