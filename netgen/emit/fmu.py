"""The FMU emitter (--format fmu): the MacroModel as an FMI 2.0 Functional Mock-up Unit for model
exchange and co-simulation in one archive, <name>.fmu, compiled from generated C (<name>_fmu.c,
written beside it: templates/fmu/model.c.j2 with the numbers, runtime.c.j2 with the equations).

Everything in the C is data read from the MacroModel (coordinates, fits, clamps, stops, couplings,
strain energy, inertial tables); the runtime evaluates the equations netgen.model.MacroModel
states, in SI: states q (m or rad), q' and the squeeze-film branch forces; inputs the electrode
and plate voltages, the generalized forces f_<q> and the inertial inputs the model has (a_in,
a_x, a_y, w_x, w_y, w_z); outputs the displacements x_<q> and the electrode and plate charges
Q_<e>; parameters the nominal mass, stiffness and damping and, with [process], the process
instance parameters (netgen.emit.fmu_process: min/max the valid range, applied through the
model's laws, refused out of range at initialization). No currents: FMI 2.0 model exchange
cannot pass input derivatives, so the importer takes dQ/dt (or reads the charge directly, as a
charge amplifier does). Co-simulation takes first input derivatives (canInterpolateInputs): an
input ramps linearly over the next doStep, so a piecewise-linear drive (a PULSE's edges) is
integrated exactly. The thermal force noise of an ngspice .lib (its TRNOISE sources) is not in
the FMU: it is deterministic.

Co-simulation integrates with Dormand-Prince 5(4) under error control (tolerance: the
experiment's, else DEFAULT_TOL, relative, times each state's nominal absolute). Explicit is the
choice because the models are not stiff where they are accurate: the fastest rate is the contact
penalty at netgen.model.contact.RATIO times the model time scale, reached only in contact, and the
oscillation accuracy at 1e-9 already needs steps of ~1/20 of the fastest mode's period, inside
DP45's stability region (|h lambda| < 3.3); a stiff importer can use the model-exchange interface
with its own BDF. Names in the modelDescription are validated identifiers with fixed prefixes;
text from input files appears only XML-escaped in description attributes and in C comments.
"""

from __future__ import annotations

import hashlib
import io
import os
import platform
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path
from xml.sax.saxutils import escape as xml_escape

import numpy as np

from ..core.errors import SimulationError
from ..core.templating import render
from ..core.text import escape
from ..fit.polynomial import Polynomial
from ..model import MacroModel
from . import fmu_process
from .common import check_fits, check_names, num, stop_constants, time_scale

DEFAULT_TOL = 1e-8  # relative tolerance of the co-simulation integrator when the importer sets none
CFLAGS = ["-O2", "-std=c99", "-fPIC", "-shared", "-fvisibility=hidden", "-ffp-contract=off", "-Wall"]
ARCH = {"generic": ["-march=x86-64", "-mtune=generic"], "native": ["-march=native"]}
PAIRS = fmu_process.PAIRS  # the runtime's order of the centrifugal products
# FMI unit name -> SI base-unit exponents
UNITS: dict[str, dict[str, float]] = {
    "m": {"m": 1},
    "rad": {"rad": 1},
    "m/s": {"m": 1, "s": -1},
    "rad/s": {"rad": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "rad/s2": {"rad": 1, "s": -2},
    "N": {"kg": 1, "m": 1, "s": -2},
    "N.m": {"kg": 1, "m": 2, "s": -2},
    "N/s": {"kg": 1, "m": 1, "s": -3},
    "N.m/s": {"kg": 1, "m": 2, "s": -3},
    "V": {"kg": 1, "m": 2, "s": -3, "A": -1},
    "C": {"s": 1, "A": 1},
    "kg": {"kg": 1},
    "kg.m2": {"kg": 1, "m": 2},
    "N/m": {"kg": 1, "s": -2},
    "N.m/rad": {"kg": 1, "m": 2, "s": -2, "rad": -1},
    "N.s/m": {"kg": 1, "s": -1},
    "N.m.s/rad": {"kg": 1, "m": 2, "s": -1, "rad": -1},
    "degC": {"K": 1, "offset": 273.15},
}


def platform_folder() -> str | None:
    """The FMI 2.0 binaries/ folder of this machine (linux64, darwin64, win64), None if FMI names none."""
    bits = "64" if sys.maxsize > 2**32 else "32"
    name = {"linux": "linux", "darwin": "darwin", "win32": "win"}.get(sys.platform)
    return f"{name}{bits}" if name else None


def library_suffix() -> str:
    return {"darwin": ".dylib", "win32": ".dll"}.get(sys.platform, ".so")


def compiler() -> list[str] | None:
    """The C compiler command: $CC (split like a shell word list) if set, else cc, gcc or clang on PATH."""
    cc = os.environ.get("CC")
    if cc is not None:
        words = shlex.split(cc)
        return words if words and shutil.which(words[0]) else None
    found = next((p for p in (shutil.which(c) for c in ("cc", "gcc", "clang")) if p), None)
    return [found] if found else None


def refusal(model: MacroModel) -> str | None:
    """Why there is no FMU of this model here: no C compiler or a platform FMI 2.0 names no folder for."""
    if platform_folder() is None:
        return f"FMI 2.0 has no binaries folder for platform {sys.platform!r}"
    if compiler() is None:
        cc = os.environ.get("CC")
        return (
            f"no C compiler found (CC={escape(cc)!r} is not an executable)"
            if cc is not None
            else "no C compiler found (CC is unset and none of cc, gcc, clang is on PATH)"
        )
    return None


FIX = "install a C compiler (Debian: apt-get install gcc) or set CC to one, e.g. CC=gcc"


def attr(text: object) -> str:
    """Text for an XML attribute value: control characters escaped (netgen.core.text.escape), then XML-escaped."""
    return xml_escape(escape(str(text)), {'"': "&quot;", "\n": "&#10;"})


def variables(model: MacroModel) -> list[dict]:
    """Every FMI variable in value-reference order (vr = index - 1): states q, q', film forces;
    the derivatives q'' and film rates; inputs; outputs; parameters."""
    out: list[dict] = []
    ws = time_scale(model)

    def add(name, unit, causality, variability, description, **kw):
        out.append(
            {
                "name": name,
                "vr": len(out),
                "unit": unit,
                "causality": causality,
                "variability": variability,
                "description": attr(description),
                "initial": kw.get("initial"),
                "start": kw.get("start"),
                "derivative": kw.get("derivative"),
                "nominal": kw.get("nominal"),
                "group": kw.get("group", name),
                "min": kw.get("min"),
                "max": kw.get("max"),
            }
        )

    cs = model.coordinates
    force = {c.name: "N" if c.unit == "m" else "N.m" for c in cs}
    for c in cs:
        add(f"q_{c.name}", c.unit, "local", "continuous", f"coordinate {c.name} ({c.kind}), state",
            initial="exact", start="0", nominal=num(c.scale), group="pos")  # fmt: skip
    for k, c in enumerate(cs):
        add(f"qd_{c.name}", f"{c.unit}/s", "local", "continuous", f"d q_{c.name}/dt, state",
            initial="exact", start="0", derivative=k + 1, nominal=num(c.scale * ws), group="vel")  # fmt: skip
    for c in cs:
        for j, (r, _) in enumerate(c.film):
            add(f"film_{c.name}_{j + 1}", force[c.name], "local", "continuous",
                f"force of squeeze-film branch {j + 1} on {c.name}, state", initial="exact", start="0",
                nominal=num(r * c.scale * ws), group="film")  # fmt: skip
    nq = len(cs)
    for k, c in enumerate(cs):
        add(f"qdd_{c.name}", f"{c.unit}/s2", "local", "continuous", f"d qd_{c.name}/dt",
            derivative=nq + k + 1, group="acc")  # fmt: skip
    f = 2 * nq
    for c in cs:
        for j, _ in enumerate(c.film):
            f += 1
            add(f"der_film_{c.name}_{j + 1}", f"{force[c.name]}/s", "local", "continuous",
                f"d film_{c.name}_{j + 1}/dt", derivative=f, group="dfilm")  # fmt: skip
    for e in model.electrodes:
        add(f"V_{e.name}", "V", "input", "continuous", f"voltage of electrode {e.name}", start="0", group="V")
    add(f"V_{model.plate}", "V", "input", "continuous", f"voltage of the moving conductor {model.plate}",
        start="0", group="VP")  # fmt: skip
    for c in cs:
        add(f"f_{c.name}", force[c.name], "input", "continuous", f"external generalized force on {c.name}",
            start="0", group="F")  # fmt: skip
    for p in model.ports():
        if p["kind"] in ("acceleration_in", "rate_in"):
            unit = "m/s2" if p["kind"] == "acceleration_in" else "rad/s"
            what = "frame acceleration" if unit == "m/s2" else "frame rotation rate"
            add(p["name"], unit, "input", "continuous", f"{what} {p['name']} (a_in: along +z)", start="0")
    for c in cs:
        add(f"x_{c.name}", c.unit, "output", "continuous", f"displacement {c.name} (= q_{c.name})", group="X")
    for e in model.electrodes:
        add(f"Q_{e.name}", "C", "output", "continuous", f"charge on electrode {e.name}", group="Q")
    add(f"Q_{model.plate}", "C", "output", "continuous", f"charge on the moving conductor {model.plate}",
        group="QP")  # fmt: skip
    for kind, units in (
        ("mass", ("kg", "kg.m2")),
        ("stiffness", ("N/m", "N.m/rad")),
        ("damping", ("N.s/m", "N.m.s/rad")),
    ):
        for c in cs:
            add(f"{kind}_{c.name}", units[c.unit == "rad"], "parameter", "fixed", f"{kind} of {c.name}",
                initial="exact", start=num(getattr(c, kind)), group=kind.upper())  # fmt: skip
    for pr in fmu_process.rows(model):  # process instance parameters (netgen.emit.fmu_process)
        add(pr["name"], pr["unit"], "parameter", "fixed", pr["description"], initial="exact", start=pr["start"],
            min=pr["min"], max=pr["max"], group="PROC")  # fmt: skip
    names = [v["name"] for v in out]
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise ValueError(f"FMU variable names collide: {', '.join(dup)}; rename the coordinates or electrodes")
    return out


def first(vs: list[dict], group: str) -> int:
    """The value reference of a group's first variable (-1 if the model has none)."""
    return next((v["vr"] for v in vs if v["group"] == group), -1)


def references(model: MacroModel, vs: list[dict]) -> list[tuple[str, int]]:
    """The runtime's #defines of the value references (-1: the model has no such input)."""
    groups = {"ACC": "acc", "DFILM": "dfilm", "V": "V", "VP": "VP", "F": "F", "X": "X", "Q": "Q", "QP": "QP"}
    groups |= {"MASS": "MASS", "STIFF": "STIFFNESS", "DAMP": "DAMPING", "AIN": "a_in", "AX": "a_x", "AY": "a_y"}
    groups |= {"WX": "w_x", "WY": "w_y", "WZ": "w_z"}
    return [(f"VR_{k}", first(vs, g)) for k, g in groups.items()]


def array(ctype: str, name: str, values) -> dict:
    """One C array of the data part (one zero when empty: C has no empty arrays)."""
    vals = [float(v) if ctype == "double" else int(v) for v in np.ravel(np.asarray(values, dtype=float))]
    text = ", ".join(num(v) if ctype == "double" else str(v) for v in vals) if vals else "0"
    return {"type": ctype, "name": name, "size": max(len(vals), 1), "data": text}


def term_arrays(model: MacroModel) -> list[dict]:
    """The capacitance terms: owner electrode, direct or 1/P, clamp, and their monomials."""
    clamps = model.term_clamps()
    elec: list[int] = []
    direct: list[bool] = []
    knee: list[float] = []
    floor: list[float] = []
    mt: list[int] = []
    mc: list[float] = []
    me: list[list[int]] = []
    for i, f in enumerate(model.capacitances):
        for k, poly in enumerate(f.polys):
            t = len(elec)
            elec.append(i)
            direct.append(f.target == "direct")
            kf = clamps[i][k] if clamps and clamps[i][k] else (0.0, 0.0)
            knee.append(kf[0])
            floor.append(kf[1])
            for e, c in zip(poly.exponents, poly.coeffs):
                if c != 0.0:
                    mt.append(t)
                    mc.append(c)
                    me.append(list(e))
    return [
        array("int", "TERM_ELEC", elec),
        array("int", "TERM_DIRECT", direct),
        array("double", "KNEE", knee),
        array("double", "FLOOR_", floor),
        array("double", "CREF", [f.c_ref for f in model.capacitances]),
        array("int", "MONO_TERM", mt),
        array("double", "MONO_COEF", mc),
        array("int", "MONO_EXP", me),
    ]


def rotary_shares(model: MacroModel) -> dict[str, list]:
    """Per inertial kind the tables' rotary shares f (netgen.model.process_loads.inertial_law) in the
    runtime's order (rates x, y, z; PAIRS; a_x, a_y), None where an entry has no law (a constant)."""
    law = (model.process.get("inertial") or {}).get("t3_fraction", {})
    keys = {"gyroscopic": "xyz", "centrifugal": PAIRS, "centrifugal_force": PAIRS, "participation": ("a_x", "a_y")}
    return {kind: [law.get(kind, {}).get(k) for k in order] for kind, order in keys.items()}


def split(tables: list, shares: list) -> tuple[np.ndarray, np.ndarray]:
    """Tables X as their t and t^3 parts X (1 - f), X f (the runtime's force is tscale X1 + tscale^3
    X3); without a law (f None) X and zeros."""
    x = np.array([np.asarray(t, dtype=float) for t in tables])
    f = np.array([np.zeros_like(t) if s is None else np.asarray(s, dtype=float) for t, s in zip(x, shares)])
    return x * (1.0 - f), x * f


def mechanics_arrays(model: MacroModel) -> tuple[list[dict], dict]:
    """Stops, strain energy, inertial tables, film branches and couplings, and the contact scalars."""
    n = model.ncoords
    stops = stop_constants(model)
    pts = model.contact.get("points", []) if stops else []
    poly = model.nonlinear_energy_polynomial() or Polynomial(np.zeros((0, n), dtype=int), np.zeros(0))
    keep = [i for i, c in enumerate(poly.coeffs) if c != 0.0]
    ine, share = model.inertial, rotary_shares(model)
    gyro, gyro3 = split([ine.gyroscopic.get(k, np.zeros((n, n))) for k in "xyz"], share["gyroscopic"])
    cent, cent3 = split([ine.centrifugal.get(p, np.zeros((n, n))) for p in PAIRS], share["centrifugal"])
    centf, centf3 = split([ine.centrifugal_force.get(p, np.zeros(n)) for p in PAIRS], share["centrifugal_force"])
    p_ax, p_ax3 = split([ine.participation.get("a_x", np.zeros(n))], share["participation"][:1])
    p_ay, p_ay3 = split([ine.participation.get("a_y", np.zeros(n))], share["participation"][1:])
    film = [(v, r, w) for v, c in enumerate(model.coordinates) for r, w in c.film]
    arrays = [
        array("double", "SCALE", model.scales),
        array("double", "STOP_A", [p["a"] for p in pts]),
        array("double", "STOP_GAP", [p["gap"] for p in pts]),
        array("double", "NL_COEF", poly.coeffs[keep]),
        array("int", "NL_EXP", poly.exponents[keep]),
        array("double", "G_AIN", model.acceleration or np.zeros(n)),
        array("double", "P_AX", p_ax),
        array("double", "P_AY", p_ay),
        array("double", "GYRO", gyro),
        array("double", "CENT", cent),
        array("double", "CENTF", centf),
        array("double", "P_AX3", p_ax3),
        array("double", "P_AY3", p_ay3),
        array("double", "GYRO3", gyro3),
        array("double", "CENT3", cent3),
        array("double", "CENTF3", centf3),
        array("int", "FILM_COORD", [b[0] for b in film]),
        array("double", "FILM_R", [b[1] for b in film]),
        array("double", "FILM_CORNER", [b[2] for b in film]),
        array("double", "COUPLING", model.coupling),
    ]
    ct = model.contact
    scalars = {
        "smooth": num(ct["smoothing"]) if pts else "1.0",
        "contact_k": num(ct["stiffness"]) if pts else "0.0",
        "contact_c": num(ct["damping"]) if pts else "0.0",
        "ns": len(pts),
        "nu": len(keep),
        "nf": len(film),
    }
    return arrays, scalars


def fastest_rate(model: MacroModel) -> float:
    """rad/s: the largest of the modal frequencies, the model time scale, the film corners and
    the contact penalty's frequency (the first co-simulation step is 1/10 of its inverse)."""
    ws = time_scale(model)
    rates = [
        ws,
        *(2 * np.pi * c.frequency_hz for c in model.coordinates),
        *(w for c in model.coordinates for _, w in c.film),
    ]
    if model.contact.get("points"):
        m = min(c.mass for c in model.coordinates)
        rates.append(float(np.sqrt(model.contact["stiffness"] / m)))
    return float(max(rates))


def context(model: MacroModel) -> dict:
    """Everything the C and the modelDescription templates need, the GUID last (a hash of the rest)."""
    check_names(model)
    check_fits(model)
    vs = variables(model)
    arrays = term_arrays(model) + mechanics_arrays(model)[0]
    scalars = mechanics_arrays(model)[1]
    nq, nf = model.ncoords, scalars["nf"]
    nx = 2 * nq + nf
    settable = [v["causality"] in ("input", "parameter") or v["initial"] == "exact" for v in vs]
    nominal = [float(v["nominal"]) for v in vs[:nx]]
    start = [float(v["start"]) if v["start"] is not None else 0.0 for v in vs]
    inputs = [v["causality"] == "input" for v in vs]
    arrays += [array("int", "SETTABLE", settable), array("int", "INPUT", inputs)]
    arrays += [array("double", "NOMINAL", nominal), array("double", "START", start)]
    proc, defines, proc_names = fmu_process.arrays(model, {v["name"]: v["vr"] for v in vs}, array)
    ctx = {
        "m": model,
        "nq": nq,
        "ne": len(model.electrodes),
        "nx": nx,
        "nk": sum(len(f.polys) for f in model.capacitances),
        "nm": sum(int(np.count_nonzero(p.coeffs)) for f in model.capacitances for p in f.polys),
        "nv": len(vs),
        "refs": references(model, vs),
        "arrays": arrays + proc,
        "process": defines,
        "proc_names": proc_names,
        "tolerance": num(DEFAULT_TOL),
        "first_step": num(0.1 / fastest_rate(model)),
        "variables": vs,
        **scalars,
    }
    ctx["guid"] = guid(render("fmu/model.c.j2", **ctx, guid=""))
    return ctx


def guid(text: str) -> str:
    """A GUID from the hash of the model's C code without its comments (one model, one GUID; the
    free text a structure file carries into the comments never reaches the code, not even as a hash)."""
    code = re.sub(r"//[^\n]*", "", re.sub(r"/\*.*?\*/", "", text, flags=re.S))
    lines = "\n".join(ln.rstrip() for ln in code.split("\n") if ln.strip())
    h = hashlib.sha256(lines.encode()).hexdigest()
    return f"{{{h[:8]}-{h[8:12]}-{h[12:16]}-{h[16:20]}-{h[20:32]}}}"


def source(model: MacroModel) -> str:
    """The <name>_fmu.c text: the model's data and the FMI 2.0 runtime."""
    return render("fmu/model.c.j2", **context(model))


def description(model: MacroModel, ctx: dict | None = None) -> str:
    """The modelDescription.xml text."""
    ctx = ctx or context(model)
    vs = ctx["variables"]
    nx = ctx["nx"]
    used = sorted({v["unit"] for v in vs if v["unit"]})  # "": a ratio, no unit attribute
    units = [{"name": u, "base": sorted(UNITS[u].items())} for u in used]
    index = {v["vr"]: v["vr"] + 1 for v in vs}
    derivs = [v for v in vs if v["derivative"]]
    derivs.sort(key=lambda v: v["derivative"])  # the state order: q, q', film
    outputs = [index[v["vr"]] for v in vs if v["causality"] == "output"]
    return render(
        "fmu/modelDescription.xml.j2",
        model=model.name,
        guid=ctx["guid"],
        description=attr(
            f"netgen macromodel {model.name} of {model.source}: {model.description} "
            "(deterministic: the thermal force noise of the .lib is not included)"
        ),
        tool=attr(model.generator),
        units=units,
        stop_time=num(20.0 * 2 * np.pi / time_scale(model)),
        tolerance=ctx["tolerance"],
        variables=vs,
        outputs=outputs,
        derivatives=[index[v["vr"]] for v in derivs[:nx]],
        initial_unknowns=sorted(outputs + [index[v["vr"]] for v in derivs if v["vr"] >= nx]),
    )


def compile_library(text: str, name: str, folder: Path, cpu: str) -> Path:
    """Compile the C text into folder/<name><suffix>; SimulationError with the compiler's output."""
    cc = compiler()
    if cc is None:
        raise SimulationError(f"no C compiler found; {FIX}")
    src = folder / f"{name}.c"
    src.write_text(text, encoding="utf-8")
    lib = folder / f"{name}{library_suffix()}"
    arch = ARCH.get(cpu, []) if platform.machine() in ("x86_64", "AMD64") else []
    cmd = [*cc, *CFLAGS, *arch, "-o", str(lib), str(src), "-lm"]
    try:
        done = subprocess.run(
            cmd, capture_output=True, text=True, errors="replace", timeout=300, stdin=subprocess.DEVNULL
        )
    except subprocess.TimeoutExpired:
        raise SimulationError(f"the C compiler did not finish within 300 s: {' '.join(cmd)}") from None
    if done.returncode != 0 or not lib.is_file():
        raise SimulationError(
            f"compiling the FMU failed (exit {done.returncode}): {' '.join(cmd)}\n{done.stderr.strip()}"
        )
    return lib


def archive(files: dict[str, bytes]) -> bytes:
    """A zip of `files` (name -> content) with fixed timestamps and order: reproducible bytes."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for name in sorted(files):
            info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            z.writestr(info, files[name])
    return buf.getvalue()


def outputs(model: MacroModel, cpu: str = "generic") -> dict[str, str | bytes]:
    """Beside <name>_fmu.c: <name>.fmu, the archive of modelDescription.xml, the compiled library
    for this platform (`cpu`: netgen.emit.osdi.GENERIC or NATIVE, the -march of the compile) and
    the source."""
    problem = refusal(model)
    if problem:
        raise SimulationError(f"{problem}; {FIX}")
    ctx = context(model)
    text = render("fmu/model.c.j2", **ctx)
    with tempfile.TemporaryDirectory(prefix="netgen-fmu-") as tmp:
        lib = compile_library(text, model.name, Path(tmp), cpu)
        files = {
            "modelDescription.xml": description(model, ctx).encode(),
            f"binaries/{platform_folder()}/{lib.name}": lib.read_bytes(),
            f"sources/{model.name}.c": text.encode(),
        }
    return {".fmu": archive(files)}
