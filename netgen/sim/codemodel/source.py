"""The ngspice source tree a code model is built from: only one of the target ngspice's own
release (netgen.sim.codemodel). NETGEN_NGSPICE_SOURCE (an unpacked tree whose configure.ac names
the target's release), else the Debian source package of the Debian package that installed the
target binary; no other (a code model built from another release crashes ngspice)."""

from __future__ import annotations

import hashlib
import os
import re
import subprocess
import tarfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ...core.errors import CodeModelError
from . import aptsources

ENV = "NETGEN_NGSPICE_SOURCE"
# Members of the ngspice source tarball the build reads (configure.ac: the release it is).
NEEDED = ("configure.ac", "src/include/", "src/xspice/cmpp/", "src/xspice/icm/dlmain.c", "src/misc/dstring.c")


@dataclass(frozen=True)
class Source:
    """label: what the build record names and the cache key hashes; tree: an unpacked tree
    (NETGEN_NGSPICE_SOURCE), or debian: the Debian source version to fetch."""

    label: str
    tree: Path | None = None
    debian: str | None = None


def tree_release(root: Path) -> str:
    """The release an ngspice source tree is (configure.ac's ngspice_major/minor_version;
    a development tree reads e.g. ngspice-46+)."""
    try:
        text = (root / "configure.ac").read_text(errors="replace")
    except OSError as exc:
        raise CodeModelError(f"{root} has no configure.ac: cannot tell which ngspice release it is") from exc
    major = re.search(r"m4_define\(\[ngspice_major_version\],\s*\[([^\]]+)\]", text)
    minor = re.search(r"m4_define\(\[ngspice_minor_version\],\s*\[([^\]]+)\]", text)
    if not major:
        raise CodeModelError(f"{root}/configure.ac names no ngspice_major_version")
    m = minor.group(1).strip() if minor else "0"
    return "ngspice-" + major.group(1).strip() + ("" if m == "0" else f".{m}")


def fast_path(target: dict) -> str:
    """The alternative to a code model on the target ngspice, as a sentence."""
    if target.get("osdi"):
        return (
            f"On {target['version']} the compiled path is OSDI: netgen build --format osdi (the _osdi.lib; "
            f"netgen sigma-delta --simulator ngspice-osdi)."
        )
    return f"On {target['version']} use the B-source .lib (netgen build --format ngspice)."


def find(target: dict) -> Source:
    """The source to build for `target` (netgen.sim.ngspice.identity()); a CodeModelError that
    says why and what to do instead when there is none of its release."""
    want = target["version"]
    given = os.environ.get(ENV)
    if given:
        root = Path(given).expanduser()
        if not (root / "src/xspice/cmpp/main.c").exists():
            raise CodeModelError(f"{ENV}={given} is not an ngspice source tree (no src/xspice/cmpp/main.c)")
        have = tree_release(root)
        if have != want:
            raise CodeModelError(
                f"{ENV}={given} is the source of {have} and the target ngspice ({target['path']}) "
                f"is {want}: a code model built from another release crashes ngspice (its device "
                f"tables differ), so none is built. Point {ENV} at an unpacked {want} source tree, "
                f"or unset it. {fast_path(target)}"
            )
        return Source(f"{ENV} {root.resolve()} ({have}, headers {headers_digest(root)})", tree=root)
    package = debian_package(target["path"])
    if package is None:
        raise CodeModelError(
            f"no source of {want} ({target['path']}) is reachable: netgen builds a code model from "
            f"the Debian source package of the ngspice it will run in, and this one is not a "
            f"Debian package; a code model built from another release's source crashes it. "
            f"{fast_path(target)} Or set {ENV} to an unpacked {want} source tree; the code "
            f"model itself runs on Debian's packaged ngspice (--ngspice /usr/bin/ngspice)."
        )
    return Source(f"Debian source package ngspice {package}", debian=package)


def debian_package(path: str) -> str | None:
    """The Debian source version of the package that installed `path` (e.g. 39.3+ds-1), or None."""
    try:
        owner = subprocess.run(["dpkg", "-S", os.path.realpath(path)], capture_output=True, text=True)
        if owner.returncode != 0:
            return None
        pkg = owner.stdout.split(":", 1)[0].strip()
        out = subprocess.run(
            ["dpkg-query", "-W", "-f=${source:Package} ${source:Version}", pkg], capture_output=True, text=True
        )
    except FileNotFoundError:
        return None
    name, _, ver = out.stdout.strip().partition(" ")
    return ver if out.returncode == 0 and name == "ngspice" and ver else None


def headers_digest(root: Path) -> str:
    """Digest of a tree's headers and cmpp: a changed tree is a new cache entry."""
    h = hashlib.sha256()
    for f in sorted([*(root / "src/include").rglob("*.h"), *(root / "src/xspice/cmpp").iterdir()]):
        if f.is_file():
            h.update(f.relative_to(root).as_posix().encode() + f.read_bytes())
    return h.hexdigest()[:16]


def unpack(source: Source, target: dict, work: Path, cache: Path, run: Callable[..., None]) -> Path:
    """The source tree (given, or Debian's unpacked into `work`), checked to be the target's release."""
    if source.tree is not None:
        return source.tree
    assert source.debian is not None  # find: a Source is a tree or a Debian version
    tarball = fetch(source.debian, cache / "ngspice-source", run, target)
    with tarfile.open(tarball) as tar:
        members = [m for m in tar.getmembers() if _needed(m.name) and ".." not in m.name and not m.issym()]
        tar.extractall(work / "src", members=members, filter="data")
    tops = {Path(m.name).parts[0] for m in members}
    if len(tops) != 1:
        raise CodeModelError(f"unexpected layout of {tarball}")
    root = work / "src" / tops.pop()
    want, have = target["version"], tree_release(root)
    if have != want:
        raise CodeModelError(
            f"{tarball} is the source of {have}, not of the target {want} ({target['path']}). {fast_path(target)}"
        )
    return root


def _needed(name: str) -> bool:
    """A tarball member the build reads (NEEDED, below the tarball's top folder)."""
    rest = name.split("/", 1)[1] if "/" in name else ""
    return any(rest == n or (n.endswith("/") and rest.startswith(n)) for n in NEEDED)


def fetch(version: str, dest: Path, run: Callable[..., None], target: dict) -> Path:
    """Debian's ngspice source package `version` (orig tarball) in dest, downloaded once."""
    upstream = version.split("-")[0]
    have = sorted(dest.glob(f"ngspice_{upstream}.orig.tar.*"))
    if have:
        return have[0]
    suite = (
        subprocess.run(
            ["sh", "-c", ". /etc/os-release && echo $VERSION_CODENAME"], capture_output=True, text=True
        ).stdout.strip()
        or "bookworm"
    )
    suites = [suite] + ([f"{suite}-backports"] if "~bpo" in version else [])
    lists = dest / "apt-lists"
    (lists / "partial").mkdir(parents=True, exist_ok=True)
    src = dest / "deb-src.list"
    # the mirror(s) apt already uses for this release (netgen.sim.codemodel.aptsources)
    release = suite.split("-")[0]
    lines = aptsources.source_lines("deb-src", release, suites)
    if not lines:
        raise CodeModelError(
            f"Debian's source of ngspice {version} is not reachable: {aptsources.missing(release)}; or set "
            f"{ENV} to an unpacked source tree of that release. {fast_path(target)}"
        )
    src.write_text("".join(f"{ln}\n" for ln in lines))
    opts = [
        "-o",
        f"Dir::Etc::sourcelist={src}",
        "-o",
        "Dir::Etc::sourceparts=-",
        "-o",
        f"Dir::State::Lists={lists}",
        "-o",
        "APT::Get::List-Cleanup=0",
        "-qq",
    ]
    try:
        run(["apt-get", *opts, "update"], dest)
        run(["apt-get", *opts, "source", "--download-only", f"ngspice={version}"], dest)
    except CodeModelError as exc:
        raise CodeModelError(
            f"Debian's source of ngspice {version} is not reachable ({str(exc)[-300:].strip()}); "
            f"set {ENV} to an unpacked source tree of that release. {fast_path(target)}"
        ) from None
    have = sorted(dest.glob(f"ngspice_{upstream}.orig.tar.*"))
    if not have:
        raise CodeModelError(
            f"apt-get source ngspice={version} gave no orig tarball in {dest}; fix: set "
            f"{ENV} to an unpacked ngspice source tree of that version"
        )
    return have[0]
