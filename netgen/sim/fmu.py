"""Running a model's FMU (netgen.emit.fmu) from Python through fmpy (pip install fmpy): the FMU
written once per model text into a cache, one co-simulation or model-exchange instance with its
variables by name. fmpy is optional (the test extra); without it SimulatorNotFound says so."""

from __future__ import annotations

import hashlib
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..core.errors import SimulationError, SimulatorNotFound
from ..core.files import write_bytes_atomic
from ..emit import fmu as emit_fmu
from ..model import MacroModel
from .codemodel import cache_dir

INSTALL = "install it with: pip install 'fmpy>=0.3,<0.4'"


def fmpy_modules():
    """fmpy's read_model_description, extract and the FMI 2.0 classes, or SimulatorNotFound."""
    try:
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Model, FMU2Slave
    except ImportError:
        raise SimulatorNotFound(f"fmpy is not installed; {INSTALL}") from None
    return read_model_description, extract, FMU2Model, FMU2Slave


def built(model: MacroModel, cpu: str = "generic") -> Path:
    """The model's .fmu in the cache (cache/fmu/<name>-<hash>.fmu), compiled once per C text."""
    text = emit_fmu.source(model)
    key = hashlib.sha256(text.encode() + cpu.encode()).hexdigest()[:12]
    path = cache_dir().parent / "fmu" / f"{model.name}-{key}.fmu"
    if not path.exists():
        write_bytes_atomic(path, emit_fmu.outputs(model, cpu)[".fmu"])  # type: ignore[arg-type]
    return path


class Instance:
    """One instance of an FMU: `cosim` (FMU2Slave, doStep) or model exchange (FMU2Model)."""

    def __init__(self, path: str | os.PathLike, cosim: bool = True, tolerance: float | None = None, name: str = "x1"):
        read_md, extract, model_cls, slave_cls = fmpy_modules()
        self.md = read_md(str(path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.folder = extract(str(path))
        iface = self.md.coSimulation if cosim else self.md.modelExchange
        cls = slave_cls if cosim else model_cls
        self.fmu = cls(
            guid=self.md.guid, unzipDirectory=self.folder, modelIdentifier=iface.modelIdentifier, instanceName=name
        )
        self.fmu.instantiate()
        self.fmu.setupExperiment(tolerance=tolerance, startTime=0.0)
        self.fmu.enterInitializationMode()
        self.cosim, self.time = cosim, 0.0

    def refs(self, names: Sequence[str]) -> list[int]:
        return [self.vr[n] for n in names]

    def set(self, values: dict[str, float]) -> None:
        """Set variables by name (inputs any time; parameters and start states before start())."""
        if values:
            self.fmu.setReal(self.refs(list(values)), [float(v) for v in values.values()])

    def ramp(self, slopes: dict[str, float]) -> None:
        """Co-simulation: the inputs' slopes (per second) over the next step only."""
        if slopes:
            self.fmu.setRealInputDerivatives(
                self.refs(list(slopes)), [1] * len(slopes), [float(v) for v in slopes.values()]
            )

    def get(self, names: Sequence[str]) -> np.ndarray:
        return np.array(self.fmu.getReal(self.refs(names)))

    def set_states(self, x: np.ndarray) -> None:
        """Model exchange: the continuous states (q, q', film forces, SI)."""
        x = np.ascontiguousarray(x, dtype=float)
        self.fmu.setContinuousStates(np.ctypeslib.as_ctypes(x), len(x))

    def start(self) -> None:
        """Leave initialization (model exchange: into continuous-time mode)."""
        self.fmu.exitInitializationMode()
        if not self.cosim:
            self.fmu.enterContinuousTimeMode()

    def step(self, h: float) -> None:
        """One co-simulation communication step of h seconds, the inputs held."""
        self.fmu.doStep(currentCommunicationPoint=self.time, communicationStepSize=h)
        self.time += h

    def stepper(self, inputs: Sequence[str], outputs: Sequence[str]):
        """A fast co-simulation step for long loops: step(values, slopes, h) sets `inputs` to
        `values` ramping at `slopes` (1/s) over h seconds, steps, and returns `outputs` (an array
        it reuses). It calls the library's FMI functions through ctypes directly (fmpy's wrappers
        cost ~100 us per call); SimulationError names a call that fails."""
        import ctypes

        dll, comp = self.fmu.dll, self.fmu.component
        set_real, set_der, do_step, get_real = (
            dll.fmi2SetReal,
            dll.fmi2SetRealInputDerivatives,
            dll.fmi2DoStep,
            dll.fmi2GetReal,
        )
        for f in (set_real, set_der, do_step, get_real):
            f.restype = ctypes.c_int
        do_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
        n_in, n_out = len(inputs), len(outputs)
        vr_in = (ctypes.c_uint * n_in)(*self.refs(inputs))
        vr_out = (ctypes.c_uint * n_out)(*self.refs(outputs))
        order = (ctypes.c_int * n_in)(*([1] * n_in))
        values, slopes, result = np.zeros(n_in), np.zeros(n_in), np.zeros(n_out)
        to_c = ctypes.POINTER(ctypes.c_double)
        p_values, p_slopes, out = (a.ctypes.data_as(to_c) for a in (values, slopes, result))

        def step(v: Sequence[float], dv: Sequence[float], h: float) -> np.ndarray:
            values[:] = v
            slopes[:] = dv
            status = set_real(comp, vr_in, n_in, p_values) or set_der(comp, vr_in, n_in, order, p_slopes)
            status = status or do_step(comp, self.time, h, 1) or get_real(comp, vr_out, n_out, out)
            if status:
                raise SimulationError(f"the FMU's co-simulation step at t = {self.time!r} s failed (status {status})")
            self.time += h
            return result

        return step

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()
