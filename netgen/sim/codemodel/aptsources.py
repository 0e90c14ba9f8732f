"""apt source lines built from the mirrors this machine's apt is already configured with: every
`deb` entry of sources.list, sources.list.d/*.list and sources.list.d/*.sources (deb822) whose
suite is exactly RELEASE and whose components include main, with its Signed-By keyring. The
code-model build fetches ngspice's source package through them (netgen.sim.codemodel.source) and
.ci/setup ngspice 46 from RELEASE-backports, each with apt-get against only these lines, so
netgen names no archive host and a machine behind its own mirror uses that mirror.

`python3 netgen/sim/codemodel/aptsources.py KIND RELEASE SUITE...` (standard library only) prints the lines (KIND deb or
deb-src), e.g. `deb bookworm bookworm-backports`; exit 1 with the fix when no source serves RELEASE.
"""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

ETC = Path("/etc/apt")


def one_line_entries(text: str) -> list[dict]:
    """The `deb` lines of a one-line-style list: uri, suite, components and signed-by."""
    entries = []
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line.startswith("deb "):
            continue
        words = shlex.split(line)[1:]
        options: dict[str, str] = {}
        if words and words[0].startswith("["):
            opts = []
            while words:
                w = words.pop(0)
                opts.append(w.strip("[]"))
                if w.endswith("]"):
                    break
            options = dict(o.split("=", 1) for o in opts if "=" in o)
        if len(words) >= 3:
            entries.append(
                {
                    "uris": [words[0]],
                    "suites": [words[1]],
                    "components": words[2:],
                    "signed_by": options.get("signed-by", ""),
                }
            )
    return entries


def deb822_entries(text: str) -> list[dict]:
    """The enabled `deb` stanzas of a deb822 .sources file."""
    entries: list[dict] = []
    fields: dict[str, str] = {}
    key: str | None = None
    for raw in [*text.splitlines(), ""]:
        if raw.startswith("#"):
            continue
        if not raw.strip():
            if fields:
                entries.append(fields)
            fields, key = {}, None
        elif raw[0] in " \t" and key:
            fields[key] += "\n" + raw.strip()
        elif ":" in raw:
            key, value = raw.split(":", 1)
            key = key.strip().lower()
            fields[key] = value.strip()
    out = []
    for f in entries:
        if "deb" not in f.get("types", "").split() or f.get("enabled", "yes").lower() == "no":
            continue
        signed = f.get("signed-by", "")
        out.append(
            {
                "uris": f.get("uris", "").split(),
                "suites": f.get("suites", "").split(),
                "components": f.get("components", "").split(),
                # a path; an inline key block is left to apt's default trusted keys
                "signed_by": signed if signed and "\n" not in signed else "",
            }
        )
    return out


def configured(etc: Path) -> list[dict]:
    """Every deb entry apt reads from `etc` (sources.list and sources.list.d)."""
    entries = []
    files = [etc / "sources.list", *sorted((etc / "sources.list.d").glob("*.list"))]
    for f in files:
        if f.is_file():
            entries += one_line_entries(f.read_text(errors="replace"))
    for f in sorted((etc / "sources.list.d").glob("*.sources")):
        entries += deb822_entries(f.read_text(errors="replace"))
    return entries


def source_lines(kind: str, release: str, suites: list[str], etc: Path = ETC) -> list[str]:
    """One-line sources (`kind` deb or deb-src) for each of `suites`, component main, at each
    mirror apt uses for RELEASE main, with its keyring; [] when none serves RELEASE."""
    lines = []
    for e in configured(etc):
        if release in e["suites"] and "main" in e["components"]:
            opt = f"[signed-by={e['signed_by']}] " if e["signed_by"] else ""
            lines += [f"{kind} {opt}{uri} {suite} main" for uri in e["uris"] for suite in suites]
    return list(dict.fromkeys(lines))


def missing(release: str, etc: Path = ETC) -> str:
    """The error when no configured apt source serves RELEASE main, with the fix."""
    return (
        f"no apt source in {etc}/sources.list or {etc}/sources.list.d serves Debian {release} main; "
        f"add the {release} archive (or a mirror of it) to apt's sources"
    )


def main(argv: list[str]) -> int:
    if len(argv) < 4 or argv[1] not in ("deb", "deb-src"):
        print("usage: aptsources.py deb|deb-src RELEASE SUITE...", file=sys.stderr)
        return 2
    lines = source_lines(argv[1], argv[2], argv[3:])
    if not lines:
        print(f"aptsources: {missing(argv[2])}", file=sys.stderr)
        return 1
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
