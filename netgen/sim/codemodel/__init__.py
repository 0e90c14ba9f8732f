"""XSPICE code-model libraries: build one for the installed ngspice and say where it is.

Debian's ngspice 39 cannot load compiled Verilog-A (no OSDI), but it loads XSPICE code models
(`.cm` shared libraries, `codemodel` / `pre_codemodel`). A Library is a folder of model sources
(modpath.lst, udnpath.lst and one sub-folder per model with its ifspec.ifs and cfunc.mod) built
into one `.cm`. MODEL is the macromodel's: netgen_es (netgen/sim/codemodel/netgen_es) evaluates
all plate terms, forces and contact stops of a macromodel in one compiled instance, which
replaces ~220 behavioural sources of the `.lib` (netgen.emit.xspice). The sigma-delta testbench
builds its own library the same way (netgen.testbench.sigma_delta.ngspice.LOOP_LIBRARY).

Building needs what ngspice's own build of its code models needs: the ngspice source of the
installed version (for cmpp, the code-model preprocessor, and the headers), flex, bison and gcc.
The source comes from Debian's source package (`apt-get source`, with a deb-src list kept in the
cache), unless NETGEN_NGSPICE_SOURCE names an unpacked tree. The result is cached per
(library sources, ngspice version): `build()` is a no-op after the first call.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import shutil
import subprocess
import tarfile
import tempfile
from dataclasses import dataclass
from pathlib import Path

from ...errors import CodeModelError, SimulationError
from .. import process


@dataclass(frozen=True)
class Library:
    """A code-model library: `sources` holds modpath.lst (the models, one per line),
    udnpath.lst and one folder per model; `name` is the stem of the built .cm."""
    name: str
    sources: Path

    @property
    def models(self) -> tuple[str, ...]:
        return tuple(ln.strip() for ln in (self.sources / "modpath.lst").read_text().splitlines() if ln.strip())


MODEL = Library("netgen_es", Path(__file__).resolve().parent)
# The configure switches of Debian's ngspice build (debian/rules: --enable-xspice --enable-cider
# --enable-pss) that change the layout of the device tables a code model hands to ngspice.
CONFIG_H = "#define XSPICE 1\n#define CIDER 1\n#define WITH_PSS 1\n#define SIMULATOR 1\n"
# Members of the ngspice source tarball the build reads.
NEEDED = ("src/include/", "src/xspice/cmpp/", "src/xspice/icm/dlmain.c", "src/misc/dstring.c")
CFLAGS = ["-O3", "-fPIC", "-fvisibility=hidden", "-fno-math-errno", "-fno-trapping-math",
          "-fassociative-math", "-fno-signed-zeros"]


def cache_dir() -> Path:
    """Where built code models and the ngspice source live (NETGEN_CACHE, else XDG cache)."""
    base = os.environ.get("NETGEN_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "netgen")
    return Path(base) / "codemodel"


def ngspice_version() -> str:
    """The installed Debian ngspice package version (e.g. 39.3+ds-1)."""
    try:
        out = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "ngspice"], capture_output=True, text=True)
    except FileNotFoundError as exc:
        raise CodeModelError("dpkg-query not found: the code model is built against Debian's ngspice package") from exc
    if out.returncode != 0 or not out.stdout.strip():
        raise CodeModelError("ngspice is not installed as a Debian package; fix: apt-get install ngspice")
    return out.stdout.strip()


def sources_digest(version: str, library: Library = MODEL) -> str:
    """Cache key: the library's sources, the config and the ngspice version."""
    h = hashlib.sha256(version.encode() + CONFIG_H.encode() + " ".join(CFLAGS).encode())
    for f in sorted(library.sources.rglob("*")):
        if f.is_file() and f.suffix in (".ifs", ".mod", ".lst"):
            h.update(f.relative_to(library.sources).as_posix().encode() + f.read_bytes())
    return h.hexdigest()[:16]


def path(library: Library = MODEL) -> Path:
    """Where the library for the installed ngspice is (or will be) cached."""
    version = ngspice_version()
    return cache_dir() / f"{library.name}-{sources_digest(version, library)}.cm"


def _run(argv: list[str], cwd: Path, env: dict | None = None, timeout: float = 900.0) -> None:
    """One build step (netgen.sim.process: with a wall-clock limit); a failure is a CodeModelError."""
    try:
        done = process.run(argv, cwd, timeout, f"cd {cwd} && {' '.join(argv)}", env=env)
    except FileNotFoundError as exc:
        raise CodeModelError(f"{argv[0]} not found; fix: apt-get install flex bison gcc") from exc
    except SimulationError as exc:
        raise CodeModelError(str(exc)) from None
    if done.returncode != 0:
        raise CodeModelError(f"{' '.join(argv)} failed in {cwd}:\n{done.output[-2000:]}")


def _fetch_source(version: str, dest: Path) -> Path:
    """Download Debian's ngspice source package (orig tarball) into dest; return the tarball."""
    upstream = version.split("-")[0]
    have = sorted(dest.glob(f"ngspice_{upstream}.orig.tar.*"))
    if have:
        return have[0]
    suites = subprocess.run(["sh", "-c", ". /etc/os-release && echo $VERSION_CODENAME"],
                            capture_output=True, text=True).stdout.strip() or "bookworm"
    lists = dest / "apt-lists"
    (lists / "partial").mkdir(parents=True, exist_ok=True)
    src = dest / "deb-src.list"
    src.write_text(f"deb-src http://deb.debian.org/debian {suites} main\n")
    opts = ["-o", f"Dir::Etc::sourcelist={src}", "-o", "Dir::Etc::sourceparts=-",
            "-o", f"Dir::State::Lists={lists}", "-o", "APT::Get::List-Cleanup=0", "-qq"]
    _run(["apt-get", *opts, "update"], dest)
    _run(["apt-get", *opts, "source", "--download-only", f"ngspice={version}"], dest)
    have = sorted(dest.glob(f"ngspice_{upstream}.orig.tar.*"))
    if not have:
        raise CodeModelError(f"apt-get source ngspice={version} gave no orig tarball in {dest}; fix: set "
                             "NETGEN_NGSPICE_SOURCE to an unpacked ngspice source tree of that version")
    return have[0]


def _source_tree(version: str, work: Path) -> Path:
    """An ngspice source tree holding NEEDED: NETGEN_NGSPICE_SOURCE, or the unpacked Debian source."""
    given = os.environ.get("NETGEN_NGSPICE_SOURCE")
    if given:
        root = Path(given)
        if not (root / "src/xspice/cmpp/main.c").exists():
            raise CodeModelError(f"NETGEN_NGSPICE_SOURCE={given} is not an ngspice source tree "
                                 "(no src/xspice/cmpp/main.c)")
        return root
    tarball = _fetch_source(version, cache_dir() / "ngspice-source")
    with tarfile.open(tarball) as tar:
        members = [m for m in tar.getmembers()
                   if any(part in m.name for part in NEEDED) and ".." not in m.name and not m.issym()]
        tar.extractall(work / "src", members=members, filter="data")
    tops = {Path(m.name).parts[0] for m in members}
    if len(tops) != 1:
        raise CodeModelError(f"unexpected layout of {tarball}")
    return work / "src" / tops.pop()


def _cmpp(tree: Path, work: Path) -> Path:
    """Build ngspice's code-model preprocessor from its sources."""
    src, out = tree / "src/xspice/cmpp", work / "cmpp"
    out.mkdir()
    for f in src.iterdir():
        shutil.copy(f, out / f.name)
    for name in ("ifs", "mod"):
        _run(["flex", "-o", f"{name}_lex.c", f"{name}_lex.l"], out)
        _run(["bison", "-d", "-o", f"{name}_yacc.c", f"{name}_yacc.y"], out)
    files = ["main.c", "file_buffer.c", "pp_ifs.c", "pp_lst.c", "pp_mod.c", "read_ifs.c", "writ_ifs.c", "util.c",
             "ifs_lex.c", "ifs_yacc.c", "mod_lex.c", "mod_yacc.c"]
    _run(["gcc", "-O2", "-I.", "-o", "cmpp", *files], out)
    return out / "cmpp"


def build(library: Library = MODEL, force: bool = False, progress=print) -> Path:
    """Build (or find in the cache) a code-model library for the installed ngspice; its path."""
    target = path(library)
    if target.exists() and not force:
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    with open(target.parent / "build.lock", "w") as lock:   # parallel test workers build it once
        fcntl.flock(lock, fcntl.LOCK_EX)
        if target.exists() and not force:
            return target
        return _build(target, library, progress)


def _build(target: Path, library: Library, progress) -> Path:
    """Fetch, preprocess and compile into `target` (atomically)."""
    version = ngspice_version()
    with tempfile.TemporaryDirectory(prefix="netgen-cm-") as tmp:
        work = Path(tmp)
        progress(f"codemodel: building {', '.join(library.models)} for ngspice {version} in {work}")
        tree = _source_tree(version, work)
        cmpp = _cmpp(tree, work)
        gen = work / "gen"
        (work / "cfg/ngspice").mkdir(parents=True)
        (work / "cfg/ngspice/config.h").write_text(CONFIG_H)
        env = dict(os.environ, CMPP_IDIR=str(library.sources), CMPP_ODIR=str(gen))
        gen.mkdir()
        _run([str(cmpp), "-lst"], gen, env)
        inc = ["-I", str(work / "cfg"), "-I", str(tree / "src/include"), "-I", str(gen)]
        sources = [tree / "src/xspice/icm/dlmain.c", tree / "src/misc/dstring.c"]
        for name in library.models:
            (gen / name).mkdir()
            env.update(CMPP_IDIR=str(library.sources / name), CMPP_ODIR=str(gen / name))
            _run([str(cmpp), "-ifs"], gen, env)
            _run([str(cmpp), "-mod"], gen, env)
            sources += [gen / name / "cfunc.c", gen / name / "ifspec.c"]
        objs = []
        for src in sources:
            obj = gen / f"{src.parent.name}_{src.stem}.o"
            _run(["gcc", *CFLAGS, *inc, "-I", str(src.parent), "-c", str(src), "-o", str(obj)], gen)
            objs.append(str(obj))
        tmp_cm = target.with_suffix(f".{os.getpid()}.tmp")
        _run(["gcc", "-shared", *CFLAGS, *objs, "-lm", "-o", str(tmp_cm)], gen)
        os.replace(tmp_cm, target)
    progress(f"codemodel: {target}")
    return target


def control_lines(*cms: Path) -> list[str]:
    """The .control lines a netlist using code-model libraries needs: load them before the
    circuit is parsed, and keep ngspice's trtol (an XSPICE 'A' device otherwise lowers it to 1
    for the whole circuit: several times the time points)."""
    return [f"pre_codemodel {cm}" for cm in cms] + ["pre_set xtrtol=7"]
