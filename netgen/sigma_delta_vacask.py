"""The sigma-delta levitation loop in VACASK: the fast path for spectra-length runs.

The same circuit, loop design and timing as the ngspice bench (netgen.sigma_delta.design(),
templates/sigma_delta_tb.cir.j2), with the macromodel as its compiled Verilog-A module
(netgen.emit_veriloga) and the loop circuitry as the small Verilog-A modules of
templates/sigma_delta_blocks.va (VACASK has no behavioural sources): electrode drivers that also
feed their currents into the charge amplifiers, integrators with reset, samplers, the lead
filter + comparator + clocked latch, and the smooth sampler/latch/reset clock windows. The
electrode phases are vsource pulses, as in the ngspice bench.

simulate() returns a Plot with the ngspice bench's vector names (time, v(b_<channel>),
v(y_<channel>), v(x_<coordinate>)), so netgen.sigma_delta.per_clock()/analyse() and everything
after them are the same code for both simulators. The raw file is read through a memory map
(a 2^16-cycle run writes ~1 GB) and deleted by the caller after the per-clock sampling.
"""

from __future__ import annotations

import hashlib
import re
import subprocess
import sys
import time
from importlib import resources
from pathlib import Path

import numpy as np

from . import __version__
from .model import MacroModel
from .sigma_delta import CHANNELS, Design, Tone, _coord_index, mechanical_inputs
from .simulate import Plot, SimulationError, _read_header
from .templating import render
from .vacask import ANSI, compile_va, tools

BLOCKS = "sigma_delta_blocks.va"
# VACASK options: the ngspice bench's reltol and chgtol (maxstep is given on the analysis, design.md).
# tran_fbr=0.1: after every pulse corner VACASK restarts with a backward-Euler step, by default up
# to 0.25 of the distance to the next corner; at the bench's reltol and maxstep that made every
# feedback impulse 0.45 % short (a pulse drive of the model alone against solve_ivp); 0.1 leaves
# 0.09 % (ngspice, which restarts at 0.1 of the previous step: 0.05 % long), which brings the
# mechanics to the ngspice bench's accuracy against an independent integration
# (tests/test_sigma_delta_vacask.py). It costs time points (110 -> 171 per period);
# tran_lteratio=10 took 15 % of them back without a measurable loss (the steps are set by the
# corners, the clock windows and maxstep, not by the LTE of the smooth parts).
OPTIONS = "reltol={reltol!r} chgtol=1e-18 tran_fbr=0.1 tran_lteratio=10"
# Appended to OPTIONS in every bench (later settings win), e.g. "tran_fbr=0.25" for VACASK's
# default corner steps: 35 % fewer time points, feedback impulses 0.45 % short (spectra unchanged).
EXTRA_OPTIONS = ""


def blocks_source() -> str:
    """Text of templates/sigma_delta_blocks.va (the loop circuitry modules)."""
    return resources.files("netgen.templates").joinpath(BLOCKS).read_text(encoding="utf-8")


def _compiled(text: str, stem: str, cache: Path) -> Path:
    """Compile Verilog-A text with openvaf-r into cache/<stem>-<hash>.osdi, once per distinct text."""
    cache.mkdir(parents=True, exist_ok=True)
    key = hashlib.sha256(text.encode()).hexdigest()[:12]
    osdi = cache / f"{stem}-{key}.osdi"
    if not osdi.exists():
        va = cache / f"{stem}-{key}.va"
        va.write_text(text, encoding="utf-8")
        tmp = cache / f"{stem}-{key}.tmp.osdi"
        compile_va(va, tmp, deny_warnings=True)
        tmp.replace(osdi)                              # atomic: parallel runs never load a partial file
    return osdi


def compile_model(model: MacroModel, cache: Path, va: Path | None = None) -> Path:
    """OSDI of the macromodel: the given .va, or the module netgen.emit_veriloga renders from the
    model (the same text the build writes; tests/test_veriloga.py keeps the two identical)."""
    if va is not None and Path(va).exists():
        text = Path(va).read_text(encoding="utf-8")
    else:
        from .emit_veriloga import module
        text = module(model)
    return _compiled(text, model.name, cache)


def compile_blocks(cache: Path) -> Path:
    """OSDI of the loop-circuitry modules."""
    return _compiled(blocks_source(), "sigma_delta_blocks", cache)


def force_sources(model: MacroModel, d: Design, tone: Tone | None) -> list[dict]:
    """VACASK vsource parameters per input port (netgen.sigma_delta.mechanical_inputs)."""
    return [{"port": port, "source": (f'type="sine" sinedc={dc!r} ampl={t.amplitude!r} freq={t.freq!r}' if t
                                      else f"dc={dc!r}")}
            for port, dc, t in mechanical_inputs(model, d, tone)]


def merge_options(*texts: str) -> str:
    """key=value option lists merged left to right (VACASK refuses a repeated option)."""
    merged: dict[str, str] = {}
    for text in texts:
        for item in text.split():
            key, sep, value = item.partition("=")
            if not sep:
                raise ValueError(f"VACASK option {item!r} is not key=value")
            merged[key] = value
    return " ".join(f"{k}={v}" for k, v in merged.items())


def saves(model: MacroModel) -> list[str]:
    """Node voltages per_clock() and the comparisons need: bits, lead-filter outputs, coordinates."""
    names = [f"b_{c}" for c in CHANNELS] + [f"y_{c}" for c in CHANNELS] + [f"x_{c.name}" for c in model.coordinates]
    return [f"v({n})" for n in names]               # bare node names would be ignored (all nodes saved)


def testbench(model: MacroModel, d: Design, model_osdi: Path, blocks_osdi: Path, cycles: int,
              tone: Tone | None = None, options: str = "") -> str:
    """The VACASK netlist of the loop (templates/sigma_delta_tb.vacask.j2)."""
    if tone:
        tone.unit = model.coordinates[_coord_index(model, tone.coord)].port_units[2]
    ports = ["0" if p["name"] == model.plate else p["name"] for p in model.ports()]
    return render("sigma_delta_tb.vacask.j2", bench="sigma_delta", version=__version__, model=model, d=d,
                  model_osdi=str(Path(model_osdi).resolve()), blocks_osdi=str(Path(blocks_osdi).resolve()),
                  cycles=cycles, ports=ports, forces=force_sources(model, d, tone), tone=tone,
                  saves=saves(model), options=merge_options(OPTIONS.format(reltol=d.reltol), EXTRA_OPTIONS, options))


def _header(path: Path) -> tuple[dict, int]:
    """Header and data offset of a real binary raw file, also while VACASK is still writing it
    (the point count is blank until the end; the rows are counted from the file size)."""
    with open(path, "rb") as fh:
        head = fh.read(1 << 16)
    head = re.sub(rb"(No\. Points:)([ \t]+)\n", lambda m: m.group(1) + b"0".rjust(len(m.group(2))) + b"\n", head)
    header, pos, binary = _read_header(head, 0)
    if header is None or not binary or "complex" in header["flags"]:
        raise SimulationError(f"{path}: expected a real binary raw file")
    rows = (path.stat().st_size - pos) // (8 * len(header["names"]))
    header["points"] = min(header["points"], rows) if header["points"] else rows
    return header, pos


def read_raw_mapped(path: Path) -> Plot:
    """A binary raw file as a Plot of memory-mapped columns, named like the ngspice bench's
    vectors (node n -> v(n)); nothing is loaded until a column is used."""
    header, pos = _header(path)
    names = header["names"]
    data = np.memmap(path, dtype="<f8", mode="r", offset=pos, shape=(header["points"], len(names)))
    vectors = {(n.lower() if n.lower() == "time" else f"v({n.lower()})"): data[:, k] for k, n in enumerate(names)}
    return Plot(header["title"], header["plotname"], vectors)


def _raw_time(raw: Path) -> float:
    """Last simulated time in a raw file VACASK is still writing (0 if none yet): VACASK streams
    the binary rows, so the file size gives the rows written so far."""
    try:
        header, pos = _header(raw)
        if header["points"] < 1:
            return 0.0
        with open(raw, "rb") as fh:
            fh.seek(pos + (header["points"] - 1) * 8 * len(header["names"]))
            return float(np.frombuffer(fh.read(8), dtype="<f8")[0])
    except (OSError, ValueError, SimulationError):
        return 0.0


def simulate(netlist: str, workdir: Path, stop: float, progress: bool = True, timeout: float = 36000.0) -> Plot:
    """Run VACASK on the bench in workdir, report simulated/wall time (from the raw file VACASK
    streams); return the memory-mapped plot of tran1.raw."""
    _, vacask = tools()
    workdir.mkdir(parents=True, exist_ok=True)
    sim, raw, log = workdir / "sigma_delta.sim", workdir / "tran1.raw", workdir / "sigma_delta.vacask.log"
    sim.write_text(netlist)
    raw.unlink(missing_ok=True)
    reproduce = f"cd {workdir} && {vacask} {sim.name}"
    start = time.perf_counter()
    with open(log, "w") as fh:
        proc = subprocess.Popen([vacask, sim.name], cwd=workdir, stdout=fh, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL)
        try:
            while True:
                try:
                    proc.wait(timeout=2.0)
                    break
                except subprocess.TimeoutExpired:
                    pass
                wall = time.perf_counter() - start
                if wall > timeout:
                    raise SimulationError(f"VACASK exceeded {timeout:.0f} s; reproduce with: {reproduce}")
                t = _raw_time(raw) if progress else 0.0
                if t > 0:
                    print(f"sigma-delta (vacask): simulated {t * 1e3:.3f} / {stop * 1e3:.3f} ms, wall {wall:.1f} s, "
                          f"eta {wall * (stop / t - 1):.0f} s", file=sys.stderr, flush=True)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    text = ANSI.sub("", log.read_text(errors="replace"))
    log.write_text(text)
    if proc.returncode != 0 or not raw.exists() or re.search(r"aborted|timestep too small", text, re.I):
        last = [ln for ln in text.splitlines() if ln.strip() and not ln.startswith(" ")][-4:]
        raise SimulationError(f"VACASK failed (exit code {proc.returncode}): {' | '.join(last)}; log {log}; "
                              f"reproduce with: {reproduce}")
    return read_raw_mapped(raw)


def stats(workdir: Path) -> dict:
    """Accepted/rejected time points and NR iterations from VACASK's `print stats` in the log."""
    text = (workdir / "sigma_delta.vacask.log").read_text()
    out = {}
    for key, pat in (("accepted", r"Accepted timepoints:\s+(\d+)"), ("rejected", r"Rejected timepoints:\s+(\d+)"),
                     ("nr_iterations", r"NR solver iterations:\s+(\d+)")):
        m = re.search(pat, text)
        if m:
            out[key] = int(m.group(1))
    return out


def run_bench(model: MacroModel, d: Design, out: Path, cycles: int, tone: Tone | None = None,
              progress: bool = True, va: Path | None = None, cache: Path | None = None, options: str = "") -> Plot:
    """Compile (cached), render and run the VACASK bench in `out`; return its plot."""
    cache = cache or out / "osdi"
    model_osdi = compile_model(model, cache, va)
    blocks_osdi = compile_blocks(cache)
    bench = testbench(model, d, model_osdi, blocks_osdi, cycles, tone, options)
    return simulate(bench, out, d.ts * cycles, progress)
