"""XSPICE code-model libraries: build one for the ngspice it will be loaded into, say where it is,
and record that ngspice beside it.

Debian's ngspice 39 cannot load compiled Verilog-A (no OSDI), but it loads XSPICE code models
(`.cm` shared libraries, `codemodel` / `pre_codemodel`). A Library is a folder of model sources
(modpath.lst, udnpath.lst and one sub-folder per model with its ifspec.ifs and cfunc.mod) built
into one `.cm`. MODEL is the macromodel's: netgen_es (netgen/sim/codemodel/netgen_es) evaluates
all plate terms, forces and contact stops of a macromodel in one compiled instance, which
replaces ~220 behavioural sources of the `.lib` (netgen.emit.xspice). The sigma-delta testbench
builds its own library the same way (netgen.testbench.sigma_delta.ngspice.LOOP_LIBRARY).

A code model is not portable across ngspice releases or build switches (ngspice checks nothing
when it loads one, and a mismatched one crashes it: the device tables differ), so the target is
the ngspice netgen runs (netgen.sim.ngspice.ngspice_path(): NETGEN_NGSPICE / --ngspice), and
everything is keyed on that binary's own release and switches (KLU, OSDI; identity()). Building
needs that release's source (cmpp, the code-model preprocessor, and the headers), flex, bison and
gcc. The source is NETGEN_NGSPICE_SOURCE (an unpacked tree, refused unless its configure.ac is
the target's release), or Debian's source package of the Debian package that installed the
target binary (`apt-get source`, with a deb-src list kept in the cache). There is no other:
without a matching source the build exits 3 (for ngspice 44 and later, with OSDI as the fast
path). The compile defines the target's KLU and OSDI where the source's headers test them. The
result is cached per (library sources, target build, source); the build record beside the .cm
(netgen.sim.ngspice.build_record) names the target, and netgen.sim.ngspice refuses to load the
.cm into another ngspice.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import re
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

from ... import __version__
from ...core import process
from ...core.errors import CodeModelError, SimulationError
from ...core.files import cache_root
from ...core.paths import spice_command
from ..ngspice import build_record, identity
from . import source


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
# --enable-pss) that change the layout of the device tables a code model hands to ngspice; the
# target's KLU and OSDI are added where its headers test them (defines()).
BASE_DEFINES = ("XSPICE", "CIDER", "WITH_PSS", "SIMULATOR")
# -march/-mtune spelled out: the x86-64 baseline whatever the compiler's default (no -march=native),
# so a code model built on one machine loads on another; the build record names these flags
CFLAGS = [
    "-O3",
    "-march=x86-64",
    "-mtune=generic",
    "-fPIC",
    "-fvisibility=hidden",
    "-fno-math-errno",
    "-fno-trapping-math",
    "-fassociative-math",
    "-fno-signed-zeros",
]


def cache_dir() -> Path:
    """Where built code models and the ngspice source live (NETGEN_CACHE, else XDG cache)."""
    return cache_root() / "codemodel"


def target() -> dict:
    """The ngspice the code model will be loaded into (the one netgen runs) and its build switches."""
    return identity()


def sources_digest(tgt: dict, src: source.Source, library: Library = MODEL) -> str:
    """Cache key: the library's sources, the target ngspice's release and switches, the source
    it is built from and the compile flags."""
    build = {k: tgt[k] for k in ("major", "minor", "klu", "osdi")}
    h = hashlib.sha256(json.dumps([build, src.label, BASE_DEFINES, CFLAGS], sort_keys=True).encode())
    for f in sorted(library.sources.rglob("*")):
        if f.is_file() and f.suffix in (".ifs", ".mod", ".lst"):
            h.update(f.relative_to(library.sources).as_posix().encode() + f.read_bytes())
    return h.hexdigest()[:16]


def path(library: Library = MODEL) -> Path:
    """Where the library for the target ngspice is (or will be) cached; a CodeModelError when
    no source of the target's release is reachable."""
    tgt = target()
    return cache_dir() / f"{library.name}-{sources_digest(tgt, source.find(tgt), library)}.cm"


def defines(tree: Path, tgt: dict) -> list[str]:
    """The preprocessor switches of the compile: Debian's configure switches, and the target's KLU
    and OSDI where the source's headers test them (they add members to IFdevice and SPICEdev)."""
    headers = [*(tree / "src/include/ngspice").glob("*.h"), tree / "src/xspice/icm/dlmain.c"]
    text = "\n".join(f.read_text(errors="replace") for f in headers if f.is_file())
    extra = [
        name
        for name in ("KLU", "OSDI")
        if tgt.get(name.lower()) and re.search(rf"^\s*#\s*if(?:def\s+{name}\b|.*defined\s*\(?\s*{name}\b)", text, re.M)
    ]
    return [*BASE_DEFINES, *extra]


def ifs_problems(ifs_text: str) -> list[str]:
    """Parameters of an .ifs that some cmpp from 39 on rejects: a default value with
    `Null_Allowed: no` (cmpp 43 and later: "Default value given for parameter ... but the user
    must set instance value"; 39 accepts it). Empty when every cmpp takes the file."""
    bad = []
    for table in ifs_text.split("PARAMETER_TABLE:")[1:]:
        rows = {m.group(1): m.group(2).split() for m in re.finditer(r"^(\w+):\s*(.*)$", table, re.M)}
        names = rows.get("Parameter_Name", [])
        bad += [
            n
            for n, d, null in zip(names, rows.get("Default_Value", []), rows.get("Null_Allowed", []))
            if d != "-" and null == "no"
        ]
    return bad


def _check_ifs(library: Library) -> None:
    """Refuse a library whose .ifs a newer cmpp would reject, whatever cmpp this build uses."""
    for name in library.models:
        ifs = library.sources / name / "ifspec.ifs"
        bad = ifs_problems(ifs.read_text())
        if bad:
            raise CodeModelError(
                f"{ifs}: parameters {', '.join(bad)} have a Default_Value and Null_Allowed: no, "
                f"which cmpp 43 and later reject; give them Default_Value: - (or allow null)"
            )


def _run(argv: list[str], cwd: Path, env: dict | None = None, timeout: float = 900.0) -> None:
    """One build step (netgen.core.process: with a wall-clock limit); a failure is a CodeModelError."""
    try:
        done = process.run(argv, cwd, timeout, f"cd {cwd} && {' '.join(argv)}", env=env)
    except FileNotFoundError as exc:
        raise CodeModelError(f"{argv[0]} not found; fix: apt-get install flex bison gcc") from exc
    except SimulationError as exc:
        raise CodeModelError(str(exc)) from None
    if done.returncode != 0:
        raise CodeModelError(f"{' '.join(argv)} failed in {cwd}:\n{done.output[-2000:]}")


def _cmpp(tree: Path, work: Path) -> Path:
    """Build ngspice's code-model preprocessor from its sources."""
    src, out = tree / "src/xspice/cmpp", work / "cmpp"
    out.mkdir()
    for f in src.iterdir():
        shutil.copy(f, out / f.name)
    for name in ("ifs", "mod"):
        _run(["flex", "-o", f"{name}_lex.c", f"{name}_lex.l"], out)
        _run(["bison", "-d", "-o", f"{name}_yacc.c", f"{name}_yacc.y"], out)
    files = [
        "main.c",
        "file_buffer.c",
        "pp_ifs.c",
        "pp_lst.c",
        "pp_mod.c",
        "read_ifs.c",
        "writ_ifs.c",
        "util.c",
        "ifs_lex.c",
        "ifs_yacc.c",
        "mod_lex.c",
        "mod_yacc.c",
    ]
    _run(["gcc", "-O2", "-I.", "-o", "cmpp", *files], out)
    return out / "cmpp"


def build(library: Library = MODEL, force: bool = False, progress=print) -> Path:
    """Build (or find in the cache) a code-model library for the target ngspice; its path. The
    source is chosen (and a mismatched one refused) before the cache is looked at."""
    tgt = target()
    src = source.find(tgt)
    cm = cache_dir() / f"{library.name}-{sources_digest(tgt, src, library)}.cm"
    if _complete(cm) and not force:
        return cm
    cm.parent.mkdir(parents=True, exist_ok=True)
    with open(cm.parent / "build.lock", "w") as lock:  # parallel test workers build it once
        fcntl.flock(lock, fcntl.LOCK_EX)
        if _complete(cm) and not force:
            return cm
        return _build(cm, library, tgt, src, progress)


def _complete(cm: Path) -> bool:
    """A cached build: the .cm and its build record."""
    return cm.exists() and build_record(cm).exists()


def _build(cm: Path, library: Library, tgt: dict, src: source.Source, progress) -> Path:
    """Fetch, preprocess and compile into `cm` (atomically), its build record beside it."""
    _check_ifs(library)
    with tempfile.TemporaryDirectory(prefix="netgen-cm-") as tmp:
        work = Path(tmp)
        progress(f"codemodel: building {', '.join(library.models)} for {tgt['version']} ({tgt['path']}) in {work}")
        tree = source.unpack(src, tgt, work, cache_dir(), _run)
        cmpp = _cmpp(tree, work)
        gen = work / "gen"
        switches = defines(tree, tgt)
        (work / "cfg/ngspice").mkdir(parents=True)
        (work / "cfg/ngspice/config.h").write_text("".join(f"#define {d} 1\n" for d in switches))
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
        for c in sources:
            obj = gen / f"{c.parent.name}_{c.stem}.o"
            _run(["gcc", *CFLAGS, *inc, "-I", str(c.parent), "-c", str(c), "-o", str(obj)], gen)
            objs.append(str(obj))
        tmp_cm = cm.with_suffix(f".{os.getpid()}.tmp")
        _run(["gcc", "-shared", *CFLAGS, *objs, "-lm", "-o", str(tmp_cm)], gen)
        record = {
            "library": library.name,
            "models": list(library.models),
            "ngspice": tgt,
            "source": src.label,
            "defines": switches,
            "cflags": CFLAGS,
            "netgen": __version__,
        }
        tmp_record = build_record(cm).with_suffix(f".{os.getpid()}.json.tmp")
        tmp_record.write_text(json.dumps(record, indent=1) + "\n")
        os.replace(tmp_record, build_record(cm))  # the record first: a .cm never stands without one
        os.replace(tmp_cm, cm)
    progress(f"codemodel: {cm} (built for {tgt['version']}, {' '.join(switches)})")
    return cm


def built_for(library: Library = MODEL) -> list[dict]:
    """The ngspice builds (identity() records) the cache holds a build of `library` for."""
    found = []
    for rec in sorted(cache_dir().glob(f"{library.name}-*.json")):
        try:
            who = json.loads(rec.read_text())["ngspice"]
        except (OSError, ValueError, KeyError):
            continue
        if rec.with_suffix(".cm").exists() and who not in found:
            found.append(who)
    return found


def record(cm: Path) -> dict:
    """The build record of a code-model library (what it was built for and from)."""
    return json.loads(build_record(cm).read_text())


def control_lines(*cms: Path) -> list[str]:
    """The .control lines a netlist using code-model libraries needs: load them before the
    circuit is parsed, and keep ngspice's trtol (an XSPICE 'A' device otherwise lowers it to 1
    for the whole circuit: several times the time points)."""
    return [f"pre_codemodel {spice_command(cm)}" for cm in cms] + ["pre_set xtrtol=7"]
