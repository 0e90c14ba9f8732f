"""The checks of a planned sweep that need the structure file or the drawn values: every run is
checked here, before any runs, so that nothing a sweep file says fails only at run time. The
Monte Carlo draws (seeded, so known now) must lie in their parameter's range, a tone must name a
coordinate of the model and lie below the Nyquist frequency (the structure's [loop.input] tone
too), every run's structure (with its overrides) must be a valid structure file, and every
simulator a run names must be installed here in a version that runs it."""

from __future__ import annotations

from pathlib import Path

from ..core.errors import LoopError, StructureError, SweepError
from ..core.options import OptionError
from ..core.reader import Reader
from ..emit.process import SLACK
from ..structure import Structure, mode_name, parse_structure
from ..testbench import sigma_delta as sd
from ..testbench.sigma_delta import read_tone
from .plan import RunSpec
from .point import gap_bound, problem
from .spec import Sweep, check_value


def coordinates(s: Structure, rigid_only: bool) -> tuple[list[str], bool]:
    """The model's coordinate names known from the structure file, and whether that list is
    complete (modes given as a count are named only after the FEM)."""
    names = list(s.coordinates.rigid)
    modes = s.coordinates.modes
    if rigid_only or not modes:
        return names, True
    if isinstance(modes, int):
        return names, False
    return names + [mode_name(m) for m in modes], True


def check_runs(sweep: Sweep, structure: Structure, structure_path: str, runs: list[RunSpec]) -> None:
    """Refuse (SweepError: sweep file, key, run, fix) any run that could only fail once started."""
    rd = _reader(sweep.path)
    _check_simulators(rd, sweep, runs)
    loop = sd.read_structure_loop(structure_path)  # LoopError: exit 2
    drawn = [p for p in sweep.parameters if p.distribution]
    parsed: dict[str, Structure] = {}
    for run in runs:
        for p in drawn:
            k = sweep.parameters.index(p)
            value = run.params[p.name]
            try:
                check_value(rd, f"parameters[{k}]", p.name, value)
            except SweepError as exc:
                raise SweepError(
                    sweep.path,
                    f"parameters[{k}]",
                    f"{run.name} draws {p.name} = {value:.4g}, out of range: {exc.problem}",
                    'narrow the distribution (a smaller std, or distribution = "uniform" within the range)',
                    exc.line,
                ) from None
        s = structure
        if run.structure_text is not None:
            if run.structure_text not in parsed:
                parsed[run.structure_text] = _run_structure(sweep, run, structure_path)
            s = parsed[run.structure_text]
        _check_tone(rd, sweep, run, s)
        _check_loop_tone(rd, sweep, run, loop)
        _check_process(rd, sweep, run, s)


def _check_process(rd: Reader, sweep: Sweep, run: RunSpec, s: Structure) -> None:
    """A run on the shared model at a process point: the structure's [process] declares each swept
    parameter and its range holds the value (netgen.sweep.point.problem); every back end passes the
    point as instance parameters of its own form (.lib and _xspice.lib params:, the _osdi.lib's
    .model card, VACASK's model card)."""
    for name, value in run.process.items():
        refused = problem(s, name, value, rebuild=False)
        if refused:
            k = next((k for k, p in enumerate(sweep.parameters) if p.name == f"process.{name}"), None)
            if k is not None and sweep.parameters[k].distribution:  # a Monte Carlo draw
                where, fix = f"parameters[{k}]", f"narrow the distribution, or {refused[1]}"
            else:
                where, fix = _where(sweep, f"process.{name}") or f"process.{name}", refused[1]
            raise rd.fail(where, f"{run.name}: {refused[0]}", fix)


def _check_simulators(rd: Reader, sweep: Sweep, runs: list[RunSpec]) -> None:
    """Each simulator the runs name runs here (the installed ngspice's version, VACASK present)."""
    for name in sorted({run.testbench.get("simulator", "ngspice") for run in runs}):
        problem = sd.simulator_problem(name)
        if problem:
            where = _where(sweep, "simulator") or "simulator"
            raise rd.fail(where, f"simulator = {name!r}: {problem}", "sweep a simulator installed here")


def _check_loop_tone(rd: Reader, sweep: Sweep, run: RunSpec, loop) -> None:
    """The structure's [loop.input] tone lies below f_s/2 at the run's ts (a tone of the sweep replaces it)."""
    if run.testbench.get("tone") or loop.input.tone is None:
        return
    try:
        sd.check_input_tone(loop, run.testbench["ts"])
    except LoopError as exc:
        raise rd.fail(
            _where(sweep, "ts") or "ts",
            f"{run.name}: ts = {run.testbench['ts']:g} s puts the structure's {exc.where} above f_s/2: {exc.problem}",
            "give a shorter ts, or a lower tone frequency in the structure's [loop.input]",
        ) from None


def _reader(path: str) -> Reader:
    """A Reader over the sweep file (for line numbers), empty if it cannot be read."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        text = ""
    return Reader(path, text, SweepError)


def _run_structure(sweep: Sweep, run: RunSpec, structure_path: str) -> Structure:
    """Parse a run's structure (the file with the run's overrides), as the run would."""
    try:
        return parse_structure(run.structure_text, str(Path(run.dir) / "structure.toml"))
    except StructureError as exc:
        keys = [k for k in run.params if k.startswith("structure.")] + [
            k for k in sweep.fixed if k.startswith("structure.")
        ]
        settings = ", ".join(f"{k} = {run.params.get(k, sweep.fixed.get(k))!r}" for k in keys)
        where = " / ".join(f"{_where(sweep, k)} ({k})" for k in keys) or "structure"
        raise SweepError(
            sweep.path,
            where,
            f"{run.name} ({settings}) makes {structure_path} invalid: {exc.where}: {exc.problem}",
            f"give {' / '.join(keys)} values the structure file accepts ({exc.fix})",
            _reader(sweep.path).line_of(_where(sweep, keys[0])) if keys else None,
        ) from None


def _check_tone(rd: Reader, sweep: Sweep, run: RunSpec, s: Structure) -> None:
    """The run's tone names a coordinate of its model and lies below f_s / 2."""
    text = run.testbench.get("tone")
    if not text:
        return
    coord, _, freq = text.split(":")
    where = _where(sweep, "tone")
    names, complete = coordinates(s, run.rigid_only)
    if coord != "a_in" and coord not in names and (complete or not coord.startswith("m")):
        raise rd.fail(
            where,
            f"{run.name}: the tone's coordinate {coord!r} is not one of the model's {names}"
            f"{' (rigid_only = true drops the modes)' if run.rigid_only else ''}",
            f"name one of {', '.join(names)} in the tone (COORD:AMPLITUDE:FREQ)",
        )
    key = "tone_freq" if _where(sweep, "tone_freq") else "tone"
    try:
        read_tone(text, key, run.testbench["ts"])  # the amplitude as the run reads it, and f_s/2
    except OptionError as exc:
        raise rd.fail(
            _where(sweep, key), f"{run.name}: {exc.problem}", f"{exc.fix} (in band: below 1/(128 ts))"
        ) from None


def _where(sweep: Sweep, name: str) -> str:
    """The key that sets `name`: parameters[k].values if swept, fixed.<name> if fixed, else ''."""
    for k, p in enumerate(sweep.parameters):
        if p.name == name:
            return f"parameters[{k}].values"
    return f"fixed.{name}" if name in sweep.fixed else ""


def check_model_tones(sweep: Sweep, runs: list[RunSpec], names: dict[bool, list[str]]) -> None:
    """After the shared models are built (before any run): a tone on a mode named only by the
    FEM must be one of the built model's coordinates."""
    rd = _reader(sweep.path)
    for run in runs:
        text = run.testbench.get("tone")
        if text and run.structure_text is None and run.rigid_only in names:
            coord = text.split(":")[0]
            if coord != "a_in" and coord not in names[run.rigid_only]:
                raise rd.fail(
                    "tone",
                    f"{run.name}: the tone's coordinate {coord!r} is not one of the model's {names[run.rigid_only]}",
                    f"name one of {', '.join(names[run.rigid_only])}",
                )


def check_model_process(sweep: Sweep, runs: list[RunSpec], models: dict) -> None:
    """After the shared models are built (before any run): each dg_<set> of a run on instance
    parameters within the bound the model states (its process record's max_m, widened by the .va's
    own SLACK: the printed bound itself passes; the check before the build used range x gap / 4)."""
    rd = _reader(sweep.path)
    for run in runs:
        if run.structure_text is not None or run.rigid_only not in models:
            continue
        model = models[run.rigid_only][0]
        for name, value in run.process.items():
            bound = gap_bound(model, name)
            if name.startswith("dg_") and (bound is None or abs(value) > bound * (1 + SLACK)):
                raise rd.fail(
                    _where(sweep, f"process.{name}") or f"process.{name}",
                    f"{run.name}: process.{name} = {value:g} m is outside the model's valid range |dg| <= "
                    f"{bound or 0:.3g} m (the fit's box moves by dg)",
                    f'keep |dg| <= {bound or 0:.3g} m, widen [sampling] range, or write [sweep] process = "rebuild"',
                )
