"""The FMU's process parameters against closed forms and ngspice, shared by
tests/emit/test_fmu_process.py (which states the tolerances) and bench/fmu_process.py (which prints
the figures): the proof mass on four clamped-guided beams over one plate (process_cases.GUIDED, all
five parameters declared, Rayleigh alpha = 2e5 1/s), its closed forms (k = 4 E w t^3 / L^3, m = rho (200 um -
2 etch)^2 t, b = alpha m, the step response from rest, the parallel-plate equilibrium), one co-simulation of
its FMU through fmpy and one ngspice 39 transient of its .lib with the same instance parameters."""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from netgen.build import build_model
from netgen.core.constants import EPS0
from netgen.emit import ngspice as emit_ngspice
from netgen.sim import fmu
from netgen.sim.ngspice import run_ngspice
from netgen.structure import parse_structure

from .process_cases import guided
from .testbench import Bench, states, using_ngspice

ALPHA = 2e5  # 1/s
PROCESS = '[process]\nparameters = ["dg", "tscale", "escale", "temp", "etch"]\netch_range = ["-0.2 um", "0.3 um"]\n'
T0_C = 300.0 - 273.15  # the structure's temperature (no [damping] temperature: 300 K)
TC = -60e-6  # 1/K: the [process] default modulus_tc the structure keeps
E0, RHO, T_UM, W_UM, L, AREA, GAP = 160e9, 2330.0, 5.0, 2.0, 150e-6, (200e-6) ** 2, 2e-6
# three values of each parameter across its valid range (dg: |dg| <= 0.15 um, the fit box's 1/4)
VALUES = {
    "tscale": (0.9, 1.05, 1.1),
    "escale": (0.5, 1.2, 1.5),
    "temp": (-40.0, 60.0, 125.0),
    "etch": (-0.2e-6, 0.1e-6, 0.3e-6),
}
DG = (-1.4e-7, 0.5e-7, 1.4e-7)
ETCH_CAPS = (-1e-7, 0.0, 1e-7)  # m: the etch's capacitance law's cases (within both structures' ranges)
STOP, CAP, RELTOL = 300e-6, 2e-9, 1e-9  # run length, ngspice step cap and reltol
GRID = np.linspace(0.0, STOP, 601)  # the co-simulation's communication points
NG_STOP = 100e-6  # ngspice's run: 3.6..6.2 periods and 10 decay times (its 5e4 steps cost 1.6 s)
NG_GRID = GRID[GRID <= NG_STOP * (1 + 1e-12)]
FORCE = 3e-6  # N: the step load (x ~ 60 nm at the nominal 47 N/m)
ACCEL = 6e3  # m/s^2: the a_in step (-m a_in = -2.8 uN at the nominal mass)
VOLTS = 10.0  # the plate's voltage in the gap-offset cases (static pull-in 16 V at dg = -0.14 um)


def build(folder):
    """(model, its .lib in `folder`, its FMU)."""
    text = guided(process=PROCESS).replace("alpha = 2000", f"alpha = {ALPHA:g}")
    text = text.replace('rigid = ["z"]', 'rigid = ["z"]\ninertial = ["a_z"]')  # the a_in port
    model = build_model(parse_structure(text, "cg.toml"))
    lib = folder / "cg.lib"
    lib.write_text(emit_ngspice.subcircuit(model))
    return model, lib, fmu.built(model)


def closed_form(p: dict[str, float]) -> tuple[float, float, float]:
    """(m, k, b) of the structure at the process point p."""
    t = T_UM * 1e-6 * p.get("tscale", 1.0)
    e = E0 * p.get("escale", 1.0) * (1.0 + TC * (p.get("temp", T0_C) - T0_C))
    w = W_UM * 1e-6 - 2.0 * p.get("etch", 0.0)
    m = RHO * (math.sqrt(AREA) - 2.0 * p.get("etch", 0.0)) ** 2 * t  # the etched outline (netgen.model.process.etched)
    return m, 4.0 * e * w * t**3 / L**3, ALPHA * m


def zeta(m: float, k: float, b: float) -> float:
    return b / (2.0 * math.sqrt(k * m))


def step_response(m: float, k: float, b: float, t: np.ndarray) -> np.ndarray:
    """x(t) of m x'' + b x' + k x = FORCE from rest (underdamped)."""
    wn, z = math.sqrt(k / m), zeta(m, k, b)
    wd = wn * math.sqrt(1.0 - z**2)
    decay = np.exp(-z * wn * t)
    return FORCE / k * (1.0 - decay * (np.cos(wd * t) + z / math.sqrt(1.0 - z**2) * np.sin(wd * t)))


def equilibrium(dg: float, etch: float = 0.0) -> float:
    """z (m) where the beams hold the plate's pull at VOLTS across the gap g + dg (the stable root),
    at the lateral etch `etch`: k(etch) and the etched facing area (200 um - 2 etch)^2."""
    _, k, _ = closed_form({"etch": etch})
    gap, area = GAP + dg, etched_area(etch)
    return brentq(lambda z: k * z + 0.5 * EPS0 * area * VOLTS**2 / (gap + z) ** 2, -gap / 3.0, 0.0, xtol=1e-22)


def etched_area(etch: float) -> float:
    """The plate's facing area: the mass's etched outline (the plate below is wider than the mass)."""
    return (math.sqrt(AREA) - 2.0 * etch) ** 2


def fmu_run(path, params: dict[str, float], inputs: dict[str, float], tolerance: float) -> np.ndarray:
    """x_z and Q_bot of a co-simulation from rest on GRID."""
    inst = fmu.Instance(path, tolerance=tolerance)
    inst.set(params | inputs)
    inst.start()
    got = [inst.get(["x_z", "Q_bot"])]
    for h in np.diff(GRID):
        inst.step(h)
        got.append(inst.get(["x_z", "Q_bot"]))
    inst.close()
    return np.array(got)


def ngspice_run(model, lib, params: dict[str, float], sources: dict[str, str], folder, op: bool = False):
    """x_z of ngspice 39's transient of the .lib with the instance parameters, from rest, on NG_GRID;
    with `op`, x_z of its .op (the static deflection)."""
    ics = [] if op else [" ".join([".ic"] + [f"v(x1.xs_{c.name})=0 v(x1.u_{c.name})=0" for c in model.coordinates])]
    bench = Bench(model, lib, sources=sources | {model.plate: "DC 0"}, extra=ics,
                  options=f"reltol={RELTOL!r} vntol=1e-14 abstol=1e-17")  # fmt: skip
    args = " ".join(f"{k}={v!r}" for k, v in params.items())
    lines = bench.netlist(".op" if op else f".tran {CAP!r} {NG_STOP!r} 0 {CAP!r} uic").split("\n")
    net = "\n".join(f"{ln} {args}" if ln.startswith("X1 ") else ln for ln in lines)
    with using_ngspice("39"):
        plot = run_ngspice(net, folder / ("op" if op else "tran"))[0]
    x = states(plot, model)[0][:, 0] * model.coordinates[0].scale
    return float(np.real(x[0])) if op else np.interp(NG_GRID, np.asarray(plot["time"]), x)


def phase_bound(model, h: float, stop: float, moving: list[bool]) -> float:
    """The trapezoidal rule's phase error after `stop` at steps <= h, relative to the amplitude:
    (w h)^2 w T / 12 for the fastest frequency w of the coordinates that move (rigid ones: 0, the
    rule is exact for constant acceleration)."""
    w = max([2 * math.pi * c.frequency_hz for c, m in zip(model.coordinates, moving) if m] + [0.0])
    return (w * h) ** 2 * w * stop / 12.0


def ngspice_budget(model) -> float:
    """The FMU-ngspice budget relative to the peak (tests/emit/test_fmu.py): the trapezoidal phase
    error at the step cap, Newton's reltol accumulated over the steps, interpolation and the FMU."""
    return phase_bound(model, CAP, NG_STOP, [True]) + RELTOL * math.sqrt(NG_STOP / CAP) + 2e-7


def step_case(model, lib, path, name: str, value: float, folder, load: str = "f_z") -> dict[str, float]:
    """A step load on z at the process point {name: value}, FORCE through f_z or the acceleration
    ACCEL through a_in (the load -m a_in of the rigid plate): the FMU (tolerance 1e-10) against the
    closed form (err), its own integration error against 1e-13 (integ), the final value against
    F / k (static), the transient's decay left at STOP (tail), all relative to the peak (static:
    to F / k); and against ngspice's transient (ngspice) and the final value against its .op (op)."""
    params = {name: value}
    m, k, b = closed_form(params)
    inputs = {"f_z": FORCE} if load == "f_z" else {"a_in": ACCEL}
    force = FORCE if load == "f_z" else -m * ACCEL
    x = fmu_run(path, params, inputs, 1e-10)[:, 0]
    fine = fmu_run(path, params, inputs, 1e-13)[:, 0]
    ref = step_response(m, k, b, GRID) * force / FORCE
    peak = float(np.max(np.abs(ref)))
    z = zeta(m, k, b)
    port = FORCE / model.coordinates[0].port_units[3]  # the .lib's force port in its display units
    sources = {"f_z": f"DC {port!r}"} if load == "f_z" else {"a_in": f"DC {ACCEL!r}"}  # a_in in m/s^2
    ng = ngspice_run(model, lib, params, sources, folder)
    x_op = ngspice_run(model, lib, params, sources, folder, op=True)
    return {
        "zeta": z,
        "f_hz": math.sqrt(k / m) / (2 * math.pi),
        "err": float(np.max(np.abs(x - ref))) / peak,
        "integ": float(np.max(np.abs(x - fine))) / peak,
        "static": float(abs(x[-1] - force / k) / abs(force / k)),
        "tail": math.exp(-z * math.sqrt(k / m) * STOP) / math.sqrt(1 - z**2),
        "ngspice": float(np.max(np.abs(x[: len(NG_GRID)] - ng))) / float(np.max(np.abs(ng))),
        "op": float(abs(x[-1] - x_op) / abs(x_op)),
    }


def gap_case(model, lib, path, dg: float, folder) -> dict[str, float]:
    """VOLTS stepped onto the plate below at gap offset dg: the static deflection (z) and the charge
    (q) at STOP against the parallel-plate equilibrium, relative; the FMU's own integration error of
    each (z_integ, q_integ); the transient against ngspice relative to its peak (ngspice), the static
    deflection against its .op (op)."""
    params = {"dg_bot": dg}
    run = fmu_run(path, params, {"V_bot": VOLTS}, 1e-10)
    fine = fmu_run(path, params, {"V_bot": VOLTS}, 1e-13)
    z = equilibrium(dg)
    charge = EPS0 * AREA * VOLTS / (GAP + dg + z)
    ng = ngspice_run(model, lib, params, {"bot": f"DC {VOLTS!r}"}, folder)
    z_op = ngspice_run(model, lib, params, {"bot": f"DC {VOLTS!r}"}, folder, op=True)
    m, k, b = closed_form({})
    k_eff = k * (1.0 - 2.0 * abs(z) / (GAP + dg + z))  # the electrostatic spring: d(eps A V^2 / 2 P^2)/dz
    return {
        "z_m": z,
        "tail": math.exp(-b / (2 * m) * STOP) / math.sqrt(1 - zeta(m, k_eff, b) ** 2),
        "z": float(abs(run[-1, 0] - z) / abs(z)),
        "z_integ": float(abs(run[-1, 0] - fine[-1, 0]) / abs(z)),
        "q": float(abs(run[-1, 1] - charge) / charge),
        "q_integ": float(abs(run[-1, 1] - fine[-1, 1]) / charge),
        "ngspice": float(np.max(np.abs(run[: len(NG_GRID), 0] - ng))) / float(np.max(np.abs(ng))),
        "op": float(abs(run[-1, 0] - z_op) / abs(z_op)),
    }


def etch_case(model, lib, path, etch: float, folder) -> dict[str, float]:
    """VOLTS stepped onto the plate below at the lateral etch `etch`: the static deflection (z) and the
    charge (q) at STOP against the parallel-plate equilibrium with k(etch) and the etched area, relative;
    the FMU's own integration error of each (z_integ, q_integ); the static deflection against
    ngspice's .op of the .lib at the same etch (op)."""
    params = {"etch": etch}
    run = fmu_run(path, params, {"V_bot": VOLTS}, 1e-10)
    fine = fmu_run(path, params, {"V_bot": VOLTS}, 1e-13)
    z = equilibrium(0.0, etch)
    charge = EPS0 * etched_area(etch) * VOLTS / (GAP + z)
    z_op = ngspice_run(model, lib, params, {"bot": f"DC {VOLTS!r}"}, folder, op=True)
    m, k, b = closed_form(params)
    k_eff = k * (1.0 - 2.0 * abs(z) / (GAP + z))  # the electrostatic spring
    return {
        "tail": math.exp(-b / (2 * m) * STOP) / math.sqrt(1 - zeta(m, k_eff, b) ** 2),
        "z": float(abs(run[-1, 0] - z) / abs(z)),
        "z_integ": float(abs(run[-1, 0] - fine[-1, 0]) / abs(z)),
        "q": float(abs(run[-1, 1] - charge) / charge),
        "q_integ": float(abs(run[-1, 1] - fine[-1, 1]) / charge),
        "op": float(abs(run[-1, 0] - z_op) / abs(z_op)),
    }


# ----------------------------------------------------------------------------- the squeeze film's temperature


FILM_PROCESS = '[process]\nparameters = ["temp"]\ntemp_range = [-40, 125]\n'
FILM_TEMPS = (-40.0, 25.0, 125.0)  # degC
SUTHERLAND_AIR = 111.0  # K: White, Viscous Fluid Flow (3rd ed.), table 1-2
MEAN_FREE_PATH = 68e-9  # m: air at 1 atm and 300 K


def film_build(folder):
    """(model, its .lib in `folder`, its FMU) of the guided mass damped by the squeeze film alone."""
    text = guided(process=FILM_PROCESS).replace("rayleigh = { alpha = 2000 }", "squeeze_film = true")
    model = build_model(parse_structure(text.replace('name = "cg"', 'name = "cgf"'), "cgf.toml"))
    lib = folder / "cgf.lib"
    lib.write_text(emit_ngspice.subcircuit(model))
    return model, lib, fmu.built(model)


def viscosity_ratio(temp_c: float, t0_k: float = 300.0, gap: float = GAP) -> float:
    """mu_eff(T) / mu_eff(T0) of air in the film at 1 atm: Sutherland's mu ~ T^1.5 / (T + S), the
    mean free path ~ mu sqrt(T) / p, Veijola's rarefied-gas viscosity mu / (1 + 9.638 Kn^1.159)."""
    t = temp_c + 273.15
    mu = (t / t0_k) ** 1.5 * (t0_k + SUTHERLAND_AIR) / (t + SUTHERLAND_AIR)
    kn0 = MEAN_FREE_PATH / gap
    kn = kn0 * mu * math.sqrt(t / t0_k)
    return mu * (1.0 + 9.638 * kn0**1.159) / (1.0 + 9.638 * kn**1.159)


def film_case(model, lib, path, temp_c: float, folder) -> dict[str, float]:
    """The damping at die temperature temp_c: the FMU's (model exchange: q'' at q = 0, q' = 1 m/s
    is -b / m) over the model's nominal, against viscosity_ratio (ratio); and the .lib's from an
    ngspice 39 .ac (1/H = k - m w^2 + i w b) against the FMU's (ngspice)."""
    from .process_forms import ac_fit

    c = model.coordinates[0]
    inst = fmu.Instance(path, cosim=False)
    inst.set({"temp": temp_c})
    inst.start()
    inst.set_states(np.array([0.0, 1.0]))
    b_fmu = -c.mass * float(inst.get(["qdd_z"])[0])
    inst.close()
    net = f"""* ac
.include {lib}
Vf fz 0 DC 0 AC 1
X1 0 0 fz xz {model.name} temp={temp_c!r}
.ac lin 3 5k 30k
.end
"""
    with using_ngspice("39"):
        _, _, b_lib = ac_fit(run_ngspice(net, folder)[0])
    ratio = viscosity_ratio(temp_c)
    return {
        "b": b_fmu,
        "ratio": abs(b_fmu / c.damping / ratio - 1.0),
        "ngspice": abs(b_lib / b_fmu - 1.0),
    }


# ----------------------------------------------------------------------------- the combs' etch shifts

COMB, COMB_VOLTS = "xp_t", 5.0  # examples/accelerometer_xyz's comb pulling +x, and its voltage


def comb_build(folder, build=build_model):
    """(model, its .lib in `folder`, its FMU) of examples/accelerometer_xyz with the textbook combs and
    etch declared (process_cases.xyz_text); `build` the structure -> MacroModel step (the suite passes
    its session-wide one, tests.fixtures.shared_model)."""
    from .process_cases import xyz_text

    model = build(parse_structure(xyz_text(process='[process]\nparameters = ["etch"]\n'), "xyz.toml"))
    lib = folder / "xyz.lib"
    lib.write_text(emit_ngspice.subcircuit(model))
    return model, lib, fmu.built(model)


def comb_balance(model, path, etch: float, name: str = "etch") -> tuple[np.ndarray, float, float]:
    """(q (SI) where the FMU's accelerations vanish at rest, its charge of COMB, the condition number
    of the scaled balance's Jacobian there) with COMB_VOLTS on COMB at `etch` (or the parameter `name`
    at that value): model exchange, a
    Newton solve of q''(q) = 0 by scipy's hybrid method in scaled coordinates to 1e-15; the Jacobian
    by central differences of 1e-6 (scaled)."""
    from scipy.optimize import root

    scale = np.array([c.scale for c in model.coordinates])
    inst = fmu.Instance(path, cosim=False)
    inst.set({name: etch, f"V_{COMB}": COMB_VOLTS})
    inst.start()
    names = [f"qdd_{c.name}" for c in model.coordinates]
    norm = np.array([c.mass / (c.stiffness * c.scale) for c in model.coordinates])  # q'' to scaled x

    def residual(xs: np.ndarray) -> np.ndarray:
        x = np.zeros(inst.md.numberOfContinuousStates)  # at rest: q' = 0, film forces 0
        x[: len(xs)] = xs * scale
        inst.set_states(x)
        return inst.get(names) * norm

    sol = root(residual, np.zeros(len(scale)), method="hybr", tol=1e-15)
    eye = np.eye(len(scale)) * 1e-6
    jac = np.stack([(residual(sol.x + d) - residual(sol.x - d)) / 2e-6 for d in eye], axis=1)
    residual(sol.x)
    q = inst.get([f"Q_{COMB}"])[0]
    inst.close()
    return sol.x * scale, float(q), float(np.linalg.cond(jac))


def comb_op(model, lib, etch: float, folder, name: str = "etch") -> np.ndarray:
    """q (SI) of ngspice 39's .op of the .lib at `etch` (or the parameter `name` at that value) with
    COMB_VOLTS on COMB (Newton at reltol
    RELTOL, vntol 1e-12 V: above the velocity nodes' rounding floor at rest, docs/contact.md, and 1e-10 of
    x_x's ~0.01 um, a tenth of RELTOL)."""
    bench = Bench(model, lib, sources={COMB: f"DC {COMB_VOLTS!r}", model.plate: "DC 0"},
                  options=f"reltol={RELTOL!r} vntol=1e-12 abstol=1e-20")  # fmt: skip
    lines = bench.netlist(".op").split("\n")
    net = "\n".join(f"{ln} {name}={etch!r}" if ln.startswith("X1 ") else ln for ln in lines)
    with using_ngspice("39"):
        plot = run_ngspice(net, folder / "op")[0]
    x = np.real(states(plot, model)[0]).reshape(-1, model.ncoords)[0]
    return x * np.array([c.scale for c in model.coordinates])


def comb_stop_onset(model, path, etch: float, gap: float, step: float) -> tuple[float, float]:
    """The FMU's q''_x / x at rest along x alone (no voltage, no force) at x_c - step and x_c + step
    around x_c = gap + 2 etch (the etched finger gap, process_cases.xyz_text), each against its value
    at x = 0.1 um (the springs alone, far from any stop): relative deviations (before, after)."""
    inst = fmu.Instance(path, cosim=False)
    inst.set({"etch": etch})
    inst.start()

    def ratio(x: float) -> float:
        s = np.zeros(inst.md.numberOfContinuousStates)
        s[0] = x
        inst.set_states(s)
        return float(inst.get(["qdd_x"])[0]) / x

    free = ratio(1e-7)
    xc = gap + 2.0 * etch
    before, after = ratio(xc - step) / free - 1.0, ratio(xc + step) / free - 1.0
    inst.close()
    return abs(before), abs(after)
