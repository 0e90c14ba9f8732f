"""PySpice: netlists and built macromodels run through ngspice's shared library (libngspice) in
this process, results as numpy arrays.

`library()` finds the libngspice of the selected ngspice ($NETGEN_LIBNGSPICE, else the one
beside netgen.sim.ngspice.ngspice_path(), i.e. $NETGEN_NGSPICE or the ngspice on PATH) with its
code-model folder and spinit (SPICE_LIB_DIR, SPICE_SCRIPTS), so a private-prefix ngspice never
loads another version's code models. PySpice loads one libngspice per process (`shared()`).
`run_netlist` is the `netgen simulate --simulator pyspice` runner; `ModelCircuit` puts a built
MacroModel's .lib into a PySpice Circuit (instance with the user's node names, every input port
driven or tied to ground) and its `transient`, `operating_point` and `ac` return a `Result` in
the model's units: coordinates in m and rad (the x_ ports read back with the scaling the model
JSON states), velocities, node voltages, port currents.

PySpice 1.5 raises on any output line with the word "error" (a title, a node name) and on every
stderr line, and logs "Unsupported Ngspice version" for ngspice after 34: here its logger is
quiet, its exceptions are caught, and the failure is decided from ngspice's own output with
netgen.sim.ngspice's rules (the same as for a batch run).
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
import tempfile
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.errors import InputError, SimulationError, SimulatorNotFound
from ..core.paths import spice_card, spice_command
from ..core.text import comment_text
from ..emit import ngspice as emit_ngspice
from ..emit.common import time_scale
from ..model import MacroModel
from . import ngspice
from .libngspice import ENV, INSTALL_HINT, Library, library
from .rawfile import Plot

POLL = 0.01  # s between checks of a background run


# ----------------------------------------------------------------------------- the shared library

LOADED: dict = {}  # "library": the Library of this process, "shared": its NgSpiceShared


@contextlib.contextmanager
def quiet() -> Iterator[None]:
    """PySpice's logger silenced: it prints ngspice's stderr lines as errors and "Unsupported Ngspice
    version" (PySpice 1.5 lists ngspice up to 34; later ones work with its newest table), while
    netgen reports ngspice's output itself."""
    logger = logging.getLogger("PySpice")
    level = logger.level
    logger.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        logger.setLevel(level)


def shared():
    """The process's one PySpice NgSpiceShared on `library()`, loaded on first use; SimulatorNotFound
    if another libngspice is already loaded (PySpice and ngspice keep one per process) or the
    library is not the selected ngspice's release."""
    lib = library()
    if not LOADED:
        LOADED.update(library=lib, shared=load_library(lib))
    elif LOADED["library"].path != lib.path:
        raise SimulatorNotFound(
            f"this process already runs {LOADED['library'].path}; PySpice loads one "
            f"libngspice per process: run {lib.path} in a separate process"
        )
    check_release(lib, LOADED["shared"].ngspice_version)
    return LOADED["shared"]


def load_library(lib: Library):
    """Load `lib` through PySpice with its SPICE_LIB_DIR/SPICE_SCRIPTS, which ngspice reads while it
    starts (spinit, code models); the environment is restored after, so a later `ngspice -b` of
    another release does not inherit them."""
    from PySpice.Spice.NgSpice.Shared import NgSpiceShared

    class Recorder(NgSpiceShared):
        """NgSpiceShared keeping every output line ((stream, text)) for netgen's own diagnosis, and
        the end of each background run (PySpice 1.5's own callback returns no int)."""

        lines: list[tuple[str, str]] = []
        ended = threading.Event()

        def send_char(self, message: str, ngspice_id: int) -> int:
            stream, _, text = message.partition(" ")
            self.lines.append((stream, text))
            return 0

        @staticmethod
        def _background_thread_running(not_running: bool, ngspice_id: int, user_data) -> int:
            if not_running:
                Recorder.ended.set()
            return 0

    saved = {var: os.environ.get(var) for var in ("SPICE_LIB_DIR", "SPICE_SCRIPTS")}
    os.environ.update(
        {var: value for var, value in (("SPICE_LIB_DIR", lib.lib_dir), ("SPICE_SCRIPTS", lib.scripts)) if value}
    )
    NgSpiceShared.LIBRARY_PATH = lib.path
    try:
        with quiet():
            return Recorder.new_instance()
    except OSError as exc:
        raise SimulatorNotFound(f"{lib.path} could not be loaded ({exc}); {INSTALL_HINT}") from exc
    finally:
        for var, value in saved.items():
            if value is None:
                os.environ.pop(var, None)
            else:
                os.environ[var] = value


def check_release(lib: Library, major: int | None) -> None:
    """A libngspice found beside an ngspice must be that ngspice's release (batch and shared runs
    then agree); one named by NETGEN_LIBNGSPICE is taken as it is."""
    if lib.binary is None:
        return
    want = ngspice.version(lib.binary)
    if major != want.major:
        raise SimulatorNotFound(
            f"{lib.path} is ngspice-{major}, but the selected ngspice {lib.binary} is "
            f"{want.label}; set {ENV} to the libngspice of {want.label}"
        )


def release() -> str:
    """The loaded library's release as ngspice names it, e.g. "ngspice-46"."""
    return f"ngspice-{shared().ngspice_version}"


# ----------------------------------------------------------------------------- running a netlist


def command(ng, text: str) -> None:
    """One ngspice command; PySpice's exception for a line with "error" or any stderr line is
    dropped here, as the recorded output decides what failed (`check`)."""
    from PySpice.Spice.NgSpice.Shared import NgSpiceCommandError

    with quiet():
        try:
            ng.exec_command(text)
        except NgSpiceCommandError:
            pass


def output(lines: list[tuple[str, str]], start: int = 0) -> str:
    """The recorded output from line `start` on, as one text."""
    return "\n".join(text for _, text in lines[start:])


def run_text(
    netlist: str, workdir: str | Path | None = None, name: str = "circuit", timeout: float = 3600.0
) -> list[Plot]:
    """Load `netlist` into the shared ngspice, run its analyses (a .control block runs as it loads),
    and return the new plots, oldest first, named as in a raw file (v(node), i(source)). With
    `workdir` the netlist is saved there as name.cir and sourced (.include paths resolve from it,
    as for `ngspice -b`) and the output is kept as name.log, also when the run fails."""
    ng = shared()
    command(ng, "destroy all")
    start = len(ng.lines)
    cir = save(netlist, Path(workdir), name) if workdir is not None else None
    log = cir.with_suffix(".log") if cir is not None else None
    where = str(log) if log is not None else "(pass workdir to keep it)"
    try:
        if cir is not None:
            command(ng, f"source {spice_command(cir)}")
        else:
            load(ng, netlist)
        check_load(ng.lines[start:], cir, where)
        if not re.search(r"^\s*\.control\b", netlist, re.M | re.I):
            background_run(ng, timeout, cir)
        plots = [plot(ng, p) for p in reversed(ng.plot_names) if p != "const"]
        check(output(ng.lines, start), plots, cir, where)
        return plots
    finally:
        if log is not None:
            log.write_text(output(ng.lines, start) + "\n")
        command(ng, "destroy all")
        command(ng, "remcirc")


def save(netlist: str, workdir: Path, name: str) -> Path:
    """workdir/name.cir with the netlist, for ngspice's `source` (a path netgen.core.paths.spice_command
    writes, under 1000 characters)."""
    cir = workdir / f"{name}.cir"
    spice_command(cir)  # refused (exit 2) before anything is written
    if len(str(cir)) > 1000:
        raise SimulationError(
            f"{cir}: ngspice's source command takes a path of under 1000 characters; use another run folder"
        )
    workdir.mkdir(parents=True, exist_ok=True)
    cir.write_text(netlist)
    return cir


def load(ng, netlist: str) -> None:
    """ngSpice_Circ of the netlist's lines (PySpice's load_circuit), its "error" exception dropped."""
    from PySpice.Spice.NgSpice.Shared import NgSpiceCircuitError

    with quiet():
        try:
            ng.load_circuit(netlist)
        except NgSpiceCircuitError:
            pass


def check_load(lines: list[tuple[str, str]], cir: Path | None, log: str) -> None:
    """A netlist ngspice refused (an unknown subcircuit or model, a bad line): its stderr "Error" line."""
    refused = [text for stream, text in lines if stream == "stderr" and re.match(r"\s*error\b", text, re.I)]
    if refused:
        raise SimulationError(
            f"ngspice (libngspice via PySpice) refused the netlist: {refused[0].strip()}; log {log}{reproduce(cir)}"
        )


def background_run(ng, timeout: float, cir: Path | None) -> None:
    """`bg_run` and wait for its thread to end: past `timeout` s, or on an interrupt, the run is halted."""
    ng.ended.clear()
    began = time.perf_counter()
    with quiet():  # the run's stderr lines arrive from ngspice's thread
        command(ng, "bg_run")
        wait(ng, began, timeout, cir)


def wait(ng, began: float, timeout: float, cir: Path | None) -> None:
    """Until the background run has ended; halted past `timeout` s or on an interrupt."""
    try:
        while not ng.ended.wait(POLL):
            if time.perf_counter() - began > timeout:
                halt(ng)
                raise SimulationError(
                    f"ngspice (libngspice via PySpice) did not finish within {timeout:.0f} s{reproduce(cir)}"
                )
    except KeyboardInterrupt:
        halt(ng)
        raise


def halt(ng) -> None:
    """Stop a background run and wait until its thread has ended."""
    command(ng, "bg_halt")
    ng.ended.wait(60)


def check(text: str, plots: list[Plot], cir: Path | None, log: str) -> None:
    """A failed run (the batch runner's rules, netgen.sim.ngspice): an aborted or failed analysis,
    or none that produced a plot."""
    problem = ngspice.diagnose(text)
    if not plots or ngspice.FAILED.search(text) or (problem and ngspice.fatal(problem)):
        raise SimulationError(
            f"ngspice (libngspice via PySpice) failed: {problem or 'no analysis ran'}; log {log}{reproduce(cir)}"
        )


def reproduce(cir: Path | None) -> str:
    """The command that reruns a saved netlist in batch mode."""
    return f"; reproduce with: ngspice -b {cir}" if cir is not None else ""


def plot(ng, name: str) -> Plot:
    """One of the shared ngspice's plots as a netgen Plot: node voltages as v(node), source
    currents as i(source), the abscissa (time, frequency, v-sweep) as it is; complex where ngspice's is."""
    with quiet():
        vectors = ng.plot(None, name)
        out = {}
        for key, vec in vectors.items():
            data = np.array(vec.to_waveform())
            if vec.is_voltage_node and key.lower() not in ("v-sweep",):
                out[f"v({vec.simplified_name.lower()})"] = data
            elif vec.is_branch_current:
                out[f"i({vec.simplified_name.lower()})"] = data
            else:
                out[key.lower()] = data
    return Plot(name, name, out)


def run_netlist(netlist: str, workdir: Path, name: str, timeout: float) -> list[Plot]:
    """The `netgen simulate --simulator pyspice` runner: run_text with the run folder."""
    return run_text(netlist, workdir, name, timeout)


# ----------------------------------------------------------------------------- a macromodel in a Circuit

INPUTS = ("electrode", "conductor", "force_in", "acceleration_in", "rate_in")  # port kinds a source drives or ties
ELECTRICAL = ("electrode", "conductor")
NODE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*$")
SOURCE_WORDS = {"dc", "ac", "pulse", "sin", "pwl", "exp", "sffm", "am"}
SOURCE_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?[a-z]*$", re.I)
OPTIONS = {"chgtol": 1e-18}  # the model header's advice for fF*mV charges


def load_model(lib: str | Path) -> MacroModel:
    """The MacroModel of a .lib written by `netgen build` (its .json beside it)."""
    lib = Path(lib)
    if not lib.is_file():
        raise InputError(str(lib), "library", "no such file", "give the .lib that `netgen build` wrote")
    found = lib.with_suffix(".json")
    for form in ("_xspice", "_osdi"):
        if lib.stem.endswith(form):
            raise InputError(
                str(lib),
                "library",
                f"the {form}.lib form loads a code model or OSDI device "
                "in .control lines, which this runner does not give",
                f"give the B-source {lib.stem[: -len(form)]}.lib (`netgen build --format ngspice`)",
            )
    if not found.is_file():
        raise InputError(
            str(lib),
            "model JSON",
            f"{found.name} is not beside it (it holds the ports and the scaling of every state)",
            "build with `netgen build STRUCTURE -o DIR`, which writes both, or pass the MacroModel with its .lib",
        )
    return MacroModel.load_json(found)


def port_volts(model: MacroModel, port: str, value: float) -> float:
    """A port's source voltage for a value in SI units: electrodes and the conductor in V, f_<q>
    in N (or N*m), a_in in m/s^2; the scaling is the model JSON's force_si_per_volt."""
    for c in model.coordinates:
        if port == f"f_{c.name}":
            return float(value) / c.port_units[3]
    return float(value)


def source_spec(model: MacroModel, port: str, value: float | str, where: str) -> str:
    """A port's source text: a number is a DC value in SI units (`port_volts`), a string an
    independent-source specification in the port's volts (e.g. "PULSE(0 3 0 10n 10n 0.49u 1u)",
    "DC 0 AC 1"), accepted only as source keywords and numbers: it is data, never netlist code."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return repr(port_volts(model, port, value))
    tokens = re.split(r"[\s(),]+", value) if isinstance(value, str) else [None]
    bad = [t for t in tokens if t and not (t.lower() in SOURCE_WORDS or SOURCE_NUMBER.match(t))]
    if not isinstance(value, str) or bad or re.search(r"[\r\n]", value) or not value.strip():
        raise InputError(
            where,
            f"drive[{port!r}]",
            f"{value!r} is not a number or a source specification (bad part: {bad[0] if bad else value!r})",
            'give a number in SI units or e.g. "PULSE(0 3 0 10n 10n 0.49u 1u)", "SIN(0 1 50k)", '
            '"DC 0 AC 1" (keywords DC AC PULSE SIN PWL EXP SFFM AM and numbers)',
        )
    return value.strip()


@dataclass
class Result:
    """One analysis of a ModelCircuit in the model's units. `axis` is time (s), frequency (Hz) or
    the one point of an operating point; `q` and `velocity` per coordinate in m or rad (and /s);
    `voltage` per node of the plot (the user's nodes and the instance's x1.* states, V);
    `current` per electrical port, A into the model's terminal. AC values are complex."""

    analysis: str
    axis: np.ndarray
    q: dict[str, np.ndarray]
    velocity: dict[str, np.ndarray]
    voltage: dict[str, np.ndarray]
    current: dict[str, np.ndarray]
    units: dict[str, str]
    plot: Plot
    release: str


@dataclass
class ModelCircuit:
    """A built macromodel in a PySpice Circuit: `.include` of its .lib, the instance X<instance>
    with the user's node names (`nodes`: port -> node, default the port's name; "0" is ground), and a
    voltage source V<port> on every input port: the `drive` value, else 0 V (mechanical inputs tied,
    electrodes and the conductor grounded) unless the port is in `floating`. Add elements to
    `circuit` before running an analysis."""

    model: MacroModel
    lib: Path
    circuit: object  # PySpice.Spice.Netlist.Circuit
    nodes: dict[str, str]
    sources: dict[str, str]  # port -> voltage source name
    instance: str

    @classmethod
    def build(
        cls,
        model: MacroModel | str | Path,
        lib: str | Path | None = None,
        *,
        nodes: dict[str, str] | None = None,
        drive: dict[str, float | str] | None = None,
        floating: tuple[str, ...] = (),
        instance: str = "1",
        title: str | None = None,
        workdir: str | Path | None = None,
    ) -> ModelCircuit:
        """The circuit of `model` (a MacroModel, or the path of the .lib `netgen build` wrote, its
        JSON beside it). A MacroModel without `lib` is emitted (netgen.emit.ngspice) into `workdir`
        (default: a new temporary folder)."""
        from PySpice.Spice.Netlist import Circuit

        if not isinstance(model, MacroModel):
            lib, model = Path(model), load_model(model)
        elif lib is None:
            folder = Path(workdir) if workdir is not None else Path(tempfile.mkdtemp(prefix="netgen-pyspice-"))
            folder.mkdir(parents=True, exist_ok=True)
            lib = folder / f"{model.name}.lib"
            lib.write_text(emit_ngspice.subcircuit(model))
        lib = Path(lib).absolute()
        where = str(lib)
        include = f".include {spice_card(lib)}"  # the path quoted, or refused (netgen.core.paths)
        node_of = check_nodes(model, nodes or {}, where)
        drive = drive or {}
        known = {p["name"]: p["kind"] for p in model.ports()}
        for port in [*drive, *floating]:
            if known.get(port) not in INPUTS:
                raise InputError(
                    where,
                    f"drive/floating[{port!r}]",
                    "not an input port of the model",
                    f"use one of {[p for p, k in known.items() if k in INPUTS]}",
                )
        if not re.fullmatch(r"\w+", instance) or "error" in instance.lower():
            raise InputError(
                where,
                "instance",
                f"{instance!r} is not a simple name",
                "use letters, digits and _ (not the word 'error')",
            )
        # the title is the deck's first card: one line, its controls escaped (netgen.core.text)
        circuit = Circuit(comment_text(title) if title else f"netgen {model.name} through PySpice")
        circuit.raw_spice = include  # not Circuit.include: it writes the path unquoted
        circuit.X(instance, model.name, *[node_of[p["name"]] for p in model.ports()])
        sources = {}
        for p in model.ports():
            name = p["name"]
            if p["kind"] in INPUTS and name not in floating and node_of[name] != "0":
                circuit.V(name, node_of[name], circuit.gnd, source_spec(model, name, drive.get(name, 0.0), where))
                sources[name] = f"v{name}".lower()
        return cls(model, lib, circuit, node_of, sources, f"x{instance}".lower())

    def simulation(self, options: dict | None = None):
        """A PySpice CircuitSimulation of the circuit (the netlist generator, no simulator), with the
        model's recommended options and `options` (reltol, abstol, ...) on top."""
        from PySpice.Spice.Simulation import CircuitSimulation

        class Deck(CircuitSimulation):
            SIMULATOR = "ngspice"

        deck = Deck(self.circuit)
        deck.options(**(OPTIONS | (options or {})))
        return deck

    def nodeset(self, deck) -> None:
        """Newton starts at the undeflected structure (every state xs_<q> = 0): without it a biased
        .op converges to the pulled-in contact state (docs/embedding.md)."""
        deck.node_set(**{f"{self.instance}.xs_{c.name}": 0 for c in self.model.coordinates})

    def transient(
        self,
        step: float,
        stop: float,
        *,
        max_step: float | None = None,
        start: float = 0.0,
        uic: bool = True,
        options: dict | None = None,
        workdir: str | Path | None = None,
        timeout: float = 3600.0,
    ) -> Result:
        """.tran step stop start max_step [uic]: with uic (default) every state starts at 0, as the
        model header advises for free-floating coordinates."""
        deck = self.simulation(options)
        deck.transient(step, stop, start, max_step, uic)
        return self.run(deck, "tran", workdir, timeout)

    def operating_point(
        self,
        *,
        nodeset: bool = True,
        options: dict | None = None,
        workdir: str | Path | None = None,
        timeout: float = 3600.0,
    ) -> Result:
        """.op, by default from the undeflected structure (`nodeset`)."""
        deck = self.simulation(options)
        if nodeset:
            self.nodeset(deck)
        deck.operating_point()
        return self.run(deck, "op", workdir, timeout)

    def ac(
        self,
        start: float,
        stop: float,
        points: int = 20,
        variation: str = "dec",
        *,
        nodeset: bool = True,
        options: dict | None = None,
        workdir: str | Path | None = None,
        timeout: float = 3600.0,
    ) -> Result:
        """.ac variation points start stop around the operating point; the excitation is the AC part of
        a drive (e.g. drive={"f_z": "DC 0 AC 1"}: 1 port volt, i.e. 1 uN)."""
        deck = self.simulation(options)
        if nodeset:
            self.nodeset(deck)
        deck.ac(variation, points, start, stop)
        return self.run(deck, "ac", workdir, timeout)

    def run(self, deck, analysis: str, workdir: str | Path | None, timeout: float) -> Result:
        """Run a deck through the shared ngspice and read its one plot back in the model's units."""
        plots = run_text(str(deck), workdir, f"{self.model.name}_{analysis}", timeout)
        return self.result(plots[-1], analysis)

    def result(self, plot: Plot, analysis: str) -> Result:
        """A plot in the model's units: x_<q> port volts times the JSON's displacement_si_per_volt,
        velocities from the u_<q> states (scale * w_s), currents into the model's terminals."""
        ws = time_scale(self.model)
        q, velocity, units = {}, {}, {}
        for c in self.model.coordinates:
            q[c.name] = plot[f"v({self.nodes[f'x_{c.name}']})"] * c.port_units[1]
            velocity[c.name] = plot[f"v({self.instance}.u_{c.name})"] * (c.scale * ws)
            units[c.name] = c.unit
        current = {
            p: -plot[f"i({s})"]
            for p, s in self.sources.items()
            if p in {e.name for e in self.model.electrodes} | {self.model.plate}
        }
        axis = {"tran": "time", "ac": "frequency"}.get(analysis)
        x = np.real(plot[axis]) if axis else np.zeros(1)
        voltage = {k[2:-1]: v for k, v in plot.vectors.items() if k.startswith("v(")}
        return Result(analysis, x, q, velocity, voltage, current, units, plot, release())


def check_nodes(model: MacroModel, nodes: dict[str, str], where: str) -> dict[str, str]:
    """port -> node for every port: the user's names (simple names, outputs not on ground, no port
    left out by a typo), the port's own name elsewhere."""
    ports = {p["name"]: p["kind"] for p in model.ports()}
    for port, node in nodes.items():
        if port not in ports:
            raise InputError(where, f"nodes[{port!r}]", "not a port of the model", f"use one of {list(ports)}")
        ok = isinstance(node, str) and (node == "0" or NODE.match(node)) and "error" not in node.lower()
        if not ok or (node == "0" and ports[port] == "displacement_out"):
            raise InputError(
                where,
                f"nodes[{port!r}]",
                f"{node!r} is not a node name for this port",
                "use letters, digits and _ (not the word 'error', which PySpice takes for a "
                'simulator failure); "0" is ground, for input ports only',
            )
    return {p: nodes.get(p, p) for p in ports}
