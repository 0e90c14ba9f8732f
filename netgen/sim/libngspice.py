"""Where the libngspice of the selected ngspice lives ($NETGEN_LIBNGSPICE, else beside
netgen.sim.ngspice.ngspice_path()), with the code-model folder and spinit it must read, so a
private-prefix ngspice never loads another version's code models (netgen.sim.pyspice loads it)."""

from __future__ import annotations

import os
import sysconfig
from dataclasses import dataclass
from pathlib import Path

from ..core.errors import SimulatorNotFound
from . import ngspice

ENV = "NETGEN_LIBNGSPICE"
INSTALL_HINT = (
    "install it with: apt-get install -y libngspice0   (Debian/Ubuntu, as root), or set "
    f"{ENV} to the libngspice.so of your ngspice"
)
NAMES = ("libngspice.so.0", "libngspice.so")


@dataclass(frozen=True)
class Library:
    """One libngspice and the folders it must read: its code models and its spinit."""

    path: str
    lib_dir: str | None  # SPICE_LIB_DIR (its folder of code models, *.cm)
    scripts: str | None  # SPICE_SCRIPTS (holds spinit)
    binary: str | None  # the ngspice it was found beside (None: given by NETGEN_LIBNGSPICE)


def library() -> Library:
    """The libngspice to load: $NETGEN_LIBNGSPICE, else the one of the selected ngspice binary
    (its prefix's lib folders); SimulatorNotFound with the fix when there is none."""
    chosen = os.environ.get(ENV, "").strip()
    if chosen:
        path = Path(os.path.expanduser(chosen))
        if not path.is_file():
            raise SimulatorNotFound(
                f"{ENV}={chosen!r} is not a file; point it at a libngspice.so "
                f"(e.g. /usr/lib/x86_64-linux-gnu/libngspice.so.0) or unset it"
            )
        return Library(str(path), *support_folders(path), None)
    binary = ngspice.ngspice_path()
    folders = library_folders(binary)
    for folder in folders:
        for name in NAMES:
            if (folder / name).is_file():
                return Library(str(folder / name), *support_folders(folder / name), binary)
    raise SimulatorNotFound(
        f"libngspice (ngspice's shared library, which PySpice runs) not found beside "
        f"{binary} (looked in {', '.join(map(str, folders))}); {INSTALL_HINT}"
    )


def library_folders(binary: str) -> list[Path]:
    """Where the libngspice of an ngspice at <prefix>/bin/ngspice lives: <prefix>/lib (with the
    multiarch and lib64 variants), and <prefix>/usr/lib for a wrapper over an unpacked package."""
    prefix = Path(binary).absolute().parent.parent
    arch = sysconfig.get_config_var("MULTIARCH") or "x86_64-linux-gnu"
    return [prefix / sub for sub in (f"lib/{arch}", "lib64", "lib", f"usr/lib/{arch}", "usr/lib64", "usr/lib")]


def support_folders(lib: Path) -> tuple[str | None, str | None]:
    """(SPICE_LIB_DIR, SPICE_SCRIPTS) of a libngspice: <libdir>/ngspice and <root>/share/ngspice/
    scripts where <root> holds the lib folder; None where a folder is missing."""
    folder = lib.absolute().parent
    root = next((p.parent for p in (folder, *folder.parents) if p.name in ("lib", "lib64")), folder.parent)
    codemodels, scripts = folder / "ngspice", root / "share" / "ngspice" / "scripts"
    return (str(codemodels) if codemodels.is_dir() else None, str(scripts) if (scripts / "spinit").is_file() else None)
