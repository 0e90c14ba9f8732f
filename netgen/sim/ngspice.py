"""ngspice in batch mode: find it, run a netlist (sim.process), read its raw file (sim.rawfile)
and turn a failure into a SimulationError with the cause, the node and time ngspice names, the
log and the saved netlist to reproduce the run."""

from __future__ import annotations

import json
import os
import re
import shutil
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from ..core import process
from ..core.errors import CodeModelError, SimulationError, SimulatorNotFound
from .rawfile import Plot, first_plot, read_raw

INSTALL_HINT = "install it with: apt-get install -y ngspice libngspice0   (Debian/Ubuntu, as root)"

FAILURES = [
    (
        re.compile(
            r"timestep too small.*?(?:time\s*=\s*([0-9.eE+-]+))?.*?(?:timestep\s*=\s*[0-9.eE+-]+)?"
            r"(?:.*?trouble with node\s*\"?([\w.#:]+)\"?)?",
            re.I | re.S,
        ),
        "timestep too small",
    ),
    (re.compile(r"singular matrix:?\s*check nodes?\s*([\w.#:]+)?", re.I), "singular matrix"),
    (re.compile(r"no convergence in dc|gmin stepping failed|source stepping failed", re.I), "no DC convergence"),
]
# a batch analysis that failed (the raw file may still exist); a .control run that aborted
FAILED = re.compile(
    r"simulation\(s\) aborted|analysis .*failed|no convergence|no such command available|"
    r"circuit not parsed|simulation interrupted due to error|fatal error in ngspice",
    re.I,
)
ABORTED = re.compile(r"simulation\(s\) aborted|timestep too small", re.I)


ENV = "NETGEN_NGSPICE"


def ngspice_path() -> str:
    """The ngspice netgen runs: $NETGEN_NGSPICE (a path, or a name on PATH) when set, else the
    `ngspice` on PATH; a clear error with the fix when neither is an executable."""
    chosen = os.environ.get(ENV, "").strip()
    if chosen:
        path = shutil.which(os.path.expanduser(chosen))
        if not path:
            raise SimulatorNotFound(
                f"{ENV}={chosen!r} (or --ngspice) is not an executable ngspice; point it at one "
                f"(e.g. ~/.cache/netgen/ngspice-46/bin/ngspice) or unset it to use "
                f"the ngspice on PATH"
            )
        return path
    path = shutil.which("ngspice")
    if not path:
        raise SimulatorNotFound(f"ngspice is not installed (not found on PATH); {INSTALL_HINT}")
    return path


@dataclass(frozen=True)
class Version:
    """What one ngspice binary is: its release and the build options netgen's outputs depend on."""

    path: str
    major: int
    minor: int
    klu: bool

    @property
    def label(self) -> str:
        return f"ngspice-{self.major}" + (f".{self.minor}" if self.minor else "")

    @property
    def osdi(self) -> bool:
        """Loads OpenVAF-reloaded's OSDI 0.4/0.5 (openvaf-r's output): ngspice 44 and later."""
        return self.major >= 44

    @property
    def osdi_node_limit(self) -> int | None:
        """ngspice 44 caps an OSDI instance at 20 nodes; the cap is gone from 45 on."""
        return 20 if self.major == 44 else None


def version(path: str | None = None) -> Version:
    """The version of `path` (default: ngspice_path()), from `ngspice --version`."""
    path = path or ngspice_path()
    return _version(path, os.stat(path).st_mtime_ns)


PROBE_TIMEOUT: ContextVar[float] = ContextVar("PROBE_TIMEOUT", default=30.0)


@contextmanager
def probe_timeout(seconds: float) -> Iterator[None]:
    """Within this block the ngspice probes (version(), has_osdi()) get the command's time limit
    (at most the default 30 s): a hanging ngspice is killed with its children by sim.process."""
    token = PROBE_TIMEOUT.set(min(seconds, PROBE_TIMEOUT.get()))
    try:
        yield
    finally:
        PROBE_TIMEOUT.reset(token)


def probe(path: str, args: list[str], files: dict[str, str] | None = None) -> str:
    """The merged output of `path args` run by sim.process in a scratch folder (holding `files`)
    within PROBE_TIMEOUT: SimulatorNotFound when it cannot start or does not finish."""
    limit = PROBE_TIMEOUT.get()
    command = " ".join([path, *args])
    with tempfile.TemporaryDirectory(prefix="netgen-probe-") as tmp:
        for name, text in (files or {}).items():
            Path(tmp, name).write_text(text)
        try:
            return process.run([path, *args], tmp, limit, command, Path(path).name).output
        except OSError as exc:
            raise SimulatorNotFound(f"{command} failed ({exc}); is it an ngspice?") from exc
        except SimulationError:
            raise SimulatorNotFound(
                f"{command} did not finish within {limit:g} s (it was killed with its children); "
                f"is it an ngspice? Point {ENV} (or --ngspice) at a working one, or raise --timeout"
            ) from None


@lru_cache(maxsize=8)
def _version(path: str, mtime: int) -> Version:
    out = probe(path, ["--version"])
    match = re.search(r"ngspice-(\d+)(?:\.(\d+))?", out)
    if not match:
        raise SimulatorNotFound(f"{path} --version printed no ngspice release; point {ENV} at an ngspice")
    return Version(path, int(match.group(1)), int(match.group(2) or 0), "Compiled with KLU" in out)


@contextmanager
def selected(path: str | None) -> Iterator[None]:
    """Run the block with NETGEN_NGSPICE = `path` (the `--ngspice` option; None: unchanged), as
    an environment variable so that worker processes and child tools see the same ngspice."""
    if not path:
        yield
        return
    before = os.environ.get(ENV)
    os.environ[ENV] = path
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(ENV, None)
        else:
            os.environ[ENV] = before


def has_osdi(path: str) -> bool:
    """Was this binary built with OSDI (the `osdi` command)? A build switch that changes the
    device tables an XSPICE code model hands over, so the code model's build must know it."""
    return _has_osdi(path, os.stat(path).st_mtime_ns)


@lru_cache(maxsize=8)
def _has_osdi(path: str, mtime: int) -> bool:
    out = probe(path, ["-b", "probe.cir"], {"probe.cir": "osdi probe\n.control\nosdi\n.endc\n.end\n"})
    return "no such command" not in out


def identity(path: str | None = None) -> dict:
    """What a run used, for the outputs that record it: the ngspice's path, release label and
    the build switches (KLU, OSDI) that a compiled code model depends on."""
    v = version(path)
    return {
        "path": v.path,
        "version": v.label,
        "major": v.major,
        "minor": v.minor,
        "klu": v.klu,
        "osdi": has_osdi(v.path),
    }


def same_build(a: dict, b: dict) -> bool:
    """Two identity() records describe ngspice builds that load the same code models."""
    return all(a.get(k) == b.get(k) for k in ("major", "minor", "klu", "osdi"))


def build_record(cm: str | Path) -> Path:
    """Where netgen.sim.codemodel records the ngspice a code-model library was built for."""
    return Path(cm).with_suffix(".json")


# the path as netgen.core.paths.spice_command writes it ('quoted'), or a bare word
CODEMODEL_LINE = re.compile(r"^\s*(?:pre_)?codemodel\s+(?:'([^']*)'|(\S+))", re.I | re.M)


def check_code_models(netlist: str, workdir: Path) -> None:
    """Refuse, before ngspice starts, a netlist that loads a netgen code model built for another
    ngspice (loading one crashes ngspice: the device tables differ between releases and build
    switches). Code models without netgen's build record beside them are not netgen's to judge,
    except netgen's own library names, whose record a build always writes."""
    here = None
    for quoted, bare in CODEMODEL_LINE.findall(netlist):
        cm = Path(os.path.expanduser(quoted or bare))
        cm = cm if cm.is_absolute() else Path(workdir) / cm
        record = build_record(cm)
        if not record.exists():
            if cm.name.startswith("netgen_"):
                raise CodeModelError(
                    f"{cm} has no build record ({record.name}): netgen cannot tell which "
                    f"ngspice it was built for, and one built for another crashes ngspice; "
                    f"rebuild it with: netgen codemodel"
                )
            continue
        built = json.loads(record.read_text()).get("ngspice", {})
        here = here or identity()
        if not same_build(built, here):
            raise CodeModelError(refusal(cm, built, here))


def refusal(cm: Path, built: dict, here: dict) -> str:
    """Why a code model built for `built` is not loaded into `here`, and the alternatives."""

    def name(r: dict) -> str:
        return (
            f"{r.get('version')} ({r.get('path')}"
            + (", KLU" if r.get("klu") else "")
            + (", OSDI" if r.get("osdi") else "")
            + ")"
        )

    fast = (
        "on it the compiled path is OSDI: netgen build --format osdi (the _osdi.lib)"
        if here.get("osdi")
        else "on it use the B-source .lib"
    )
    return (
        f"{cm.name} was built for {name(built)} and this run uses {name(here)}: a code model built for "
        f"another ngspice crashes it, so it is not loaded. Run it on the ngspice it was built for "
        f"(--ngspice {built.get('path')} or NETGEN_NGSPICE), or rebuild it for this one with netgen codemodel "
        f"where its sources are reachable; {fast}"
    )


def diagnose(log: str) -> str | None:
    """Summarise an ngspice failure from its log: cause, node and time when present."""
    for pattern, what in FAILURES:
        match = pattern.search(log)
        if match:
            details = []
            node = re.search(r"trouble with node\s*\"?([\w.#:]+)", log, re.I) or re.search(
                r"check node[s]?\s*([\w.#:]+)", log, re.I
            )
            when = re.search(r"time\s*=\s*([0-9.eE+-]+)", log[match.start() :], re.I)
            if node:
                details.append(f"node {node.group(1)}")
            if when and what == "timestep too small":
                details.append(f"at t = {when.group(1)} s")
            return what + (f" ({', '.join(details)})" if details else "")
    lines = [ln.strip() for ln in log.splitlines()]
    for i, line in enumerate(lines):
        if (
            re.search(r"\berror\b|fatal|unknown (?:subckt|model|device)|no such command|can't find model", line, re.I)
            and "no error" not in line.lower()
        ):
            # "Error on line 4 or its substitute:" says what in the lines after it
            after = [ln for ln in lines[i + 1 : i + 3] if ln and not ln.lower().startswith("simulation interrupted")]
            return " ".join([line] + after[:2]) if line.endswith(":") else line
    return None


def fatal(problem: str) -> bool:
    """Warnings ngspice recovers from (a singular first Newton step fixed by gmin stepping)
    are not failures; an aborted analysis is, even when a partial raw file exists."""
    return problem.startswith("timestep too small")


def run_ngspice(netlist: str, workdir: str | Path, name: str = "circuit", timeout: float = 3600.0) -> list[Plot]:
    """Write `netlist` to workdir/name.cir, run ngspice -b, return the plots of name.raw."""
    exe = ngspice_path()
    workdir = Path(workdir)
    with probe_timeout(timeout):
        check_code_models(netlist, workdir)
        cir, raw, log = _files(workdir, name, netlist, f"{name}.raw")
        reproduce = f"{exe} -b {cir}"
        # names relative to workdir, ngspice's working folder (a relative workdir would resolve twice)
        done = process.run([exe, "-b", "-r", raw.name, cir.name], workdir, timeout, reproduce, "ngspice")
        return checked(done, raw, log, reproduce)


def run_file(netlist: str | Path, workdir: str | Path, timeout: float = 3600.0) -> list[Plot]:
    """Run a user's netlist file where it is, so its relative .include/.lib paths resolve
    against its own folder as ngspice resolves them; the raw file and log go to the run folder
    `workdir` (also the working folder: what its .control block writes lands there)."""
    exe = ngspice_path()
    source, workdir = Path(netlist).resolve(), Path(workdir).resolve()
    with probe_timeout(timeout):
        check_code_models(source.read_bytes().decode("latin-1"), workdir)  # before any folder is made
        workdir.mkdir(parents=True, exist_ok=True)
        raw, log = workdir / f"{source.stem}.raw", workdir / f"{source.stem}.log"
        raw.unlink(missing_ok=True)
        reproduce = f"cd {workdir} && {exe} -b -r {raw.name} {source}"
        done = process.run([exe, "-b", "-r", str(raw), str(source)], workdir, timeout, reproduce, "ngspice")
        return checked(done, raw, log, reproduce)


def checked(done: process.Finished, raw: Path, log: Path, reproduce: str) -> list[Plot]:
    """The plots of a finished batch run, or a SimulationError with ngspice's own message (a
    netlist it rejects, an aborted analysis, no raw file), the log and how to reproduce it."""
    log.write_text(log_header() + done.output)
    problem = diagnose(done.output)
    if done.returncode == 0 and not raw.exists() and not problem:
        problem = (
            "no raw file: the netlist has no analysis outside a .control block (add e.g. .op or .tran; "
            "a .control block writes its own results)"
        )
    if done.returncode != 0 or not raw.exists() or FAILED.search(done.output) or (problem and fatal(problem)):
        raise SimulationError(
            f"ngspice failed: {problem or f'exit code {done.returncode}'}; log {log}; reproduce with: {reproduce}"
        )
    try:
        plots = read_raw(raw)
    except SimulationError as exc:  # garbage in the raw file: name the log and the command too
        raise SimulationError(f"ngspice: {exc}; log {log}; reproduce with: {reproduce}") from None
    if not plots:
        raise SimulationError(
            f"ngspice wrote no results into {raw} (does the netlist have an analysis, "
            f"e.g. .op or .tran?); log {log}; reproduce with: {reproduce}"
        )
    return plots


def run_control(
    netlist: str,
    workdir: str | Path,
    name: str,
    raw_name: str,
    timeout: float = 36000.0,
    on_line: Callable[[str], None] | None = None,
) -> Plot:
    """Run a netlist whose .control block runs its analyses and writes `raw_name` itself (e.g.
    pausing for progress lines, which `on_line` sees as they are printed); return that plot.
    ngspice exits 1 after a paused-and-resumed run: success is a complete raw file."""
    exe, workdir = ngspice_path(), Path(workdir)
    with probe_timeout(timeout):
        return _run_control(exe, netlist, workdir, name, raw_name, timeout, on_line)


def _run_control(
    exe: str,
    netlist: str,
    workdir: Path,
    name: str,
    raw_name: str,
    timeout: float,
    on_line: Callable[[str], None] | None,
) -> Plot:
    """run_control's run, its probes already limited to its timeout."""
    check_code_models(netlist, workdir)
    cir, raw, log = _files(workdir, name, netlist, raw_name)
    reproduce = f"cd {workdir} && {exe} -b {cir.name}"
    done = process.run(
        process.line_buffered([exe, "-b", cir.name]), workdir, timeout, reproduce, "ngspice", process.Watch(on_line)
    )
    log.write_text(log_header() + done.output)
    if not raw.exists() or ABORTED.search(done.output):
        raise SimulationError(
            f"ngspice failed: {diagnose(done.output) or f'exit code {done.returncode}'}; "
            f"log {log}; reproduce with: {reproduce}"
        )
    return first_plot(raw, log=log, reproduce=reproduce)


def log_header() -> str:
    """The first line of every ngspice log netgen writes: which ngspice ran (identity())."""
    who = identity()
    return (
        f"netgen: ran {who['version']} ({who['path']}; KLU {'yes' if who['klu'] else 'no'}, "
        f"OSDI {'yes' if who['osdi'] else 'no'})\n"
    )


def _files(workdir: Path, name: str, netlist: str, raw_name: str) -> tuple[Path, Path, Path]:
    """Write the netlist into workdir, clear a stale raw file; (netlist, raw, log) paths."""
    workdir.mkdir(parents=True, exist_ok=True)
    cir, raw, log = workdir / f"{name}.cir", workdir / raw_name, workdir / f"{name}.log"
    cir.write_text(netlist)
    raw.unlink(missing_ok=True)
    return cir, raw, log
