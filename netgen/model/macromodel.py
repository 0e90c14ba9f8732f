"""The MacroModel: the one data object between the physics and the emitters.

It holds everything an emitter or a simulation check needs (coordinates with their
scaling, mass, stiffness, damping, fitted capacitances, constant couplings, ports) and
evaluates the model equations in Python for independent checks. Saved as JSON next
to the netlist so later steps never recompute physics.

Units: x_v = q_v / scale_v is the scaled coordinate (1 = touching an electrode).
Generalized forces are in SI (N for lengths, N*m for angles).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from .. import __version__
from ..core.errors import ModelError
from ..core.files import json_document, read_text, write_atomic
from ..fit.capacitance import CapacitanceFit
from ..fit.polynomial import Polynomial, monomial_exponents, monomials
from . import contact, schema, validate
from .inertial import Inertial

# port units: coordinate unit -> (display unit of displacement, factor SI per display unit,
#                                  display unit of generalized force, factor SI per display unit)
PORT_UNITS = {
    "m": ("um", 1e-6, "uN", 1e-6),
    "rad": ("mrad", 1e-3, "nN*m", 1e-9),
}


# what to change when a capacitance fit misses [fit] tolerance (MacroModel.fit_problem)
FIT_FIX = (
    "allow more plate terms ([fit] max_terms), more samples ([sampling] levels, or the level / points "
    "of its design), a higher [fit] degree "
    "or a narrower [sampling] range, or accept the error with a larger [fit] tolerance"
)

ACCEL_PORT = "a_in"  # the inertial-load port (MacroModel.acceleration)


@dataclass(frozen=True)
class Coordinate:
    """One generalized coordinate and its mechanics (diagonal: mass-orthogonal basis)."""

    name: str
    kind: str  # "translation", "rotation" or "mode"
    unit: str  # "m" or "rad": SI unit of q
    scale: float  # SI units of q per unit of the scaled state x (touching amplitude)
    mass: float  # kg (translation, mode) or kg*m^2 (rotation)
    stiffness: float  # N/m or N*m/rad (0 for rigid-body motions)
    damping: float = 0.0  # N*s/m or N*m*s/rad (placeholder until damping models land)
    frequency_hz: float = 0.0
    label: str = ""  # (n,s) label of an eigenmode
    # compressible squeeze film: Maxwell branches (damping N*s/m, corner rad/s), each a damper in
    # series with a gas spring damping*corner, in parallel with `damping` (netgen.mechanics.squeeze_film)
    film: tuple[tuple[float, float], ...] = ()

    @property
    def port_units(self) -> tuple[str, float, str, float]:
        return PORT_UNITS[self.unit]

    def admittance(self, omega: float | np.ndarray) -> np.ndarray | complex:
        """Complex damping B(omega) = damping + sum r / (1 + i omega / corner): the force per
        unit velocity; Re B is the damping, -omega Im B the gas-spring stiffness (a number for a
        scalar omega, and the float damping itself without a film)."""
        w = np.asarray(omega, dtype=float)
        return self.damping + sum(r / (1.0 + 1j * w / c) for r, c in self.film)


@dataclass(frozen=True)
class Electrode:
    """One fixed electrode facing the moving conductor."""

    name: str
    group: str
    side: str
    gap: float
    area: float


@dataclass
class MacroModel:
    """Coordinates, mechanics, fitted capacitances and ports of one structure."""

    name: str
    description: str
    source: str
    coordinates: list[Coordinate]
    electrodes: list[Electrode]
    capacitances: list[CapacitanceFit]  # plate-electrode, one per electrode, same order
    coupling: np.ndarray  # F, constant electrode-electrode capacitances (symmetric)
    sampling: dict  # levels, range, samples, grid point count
    report: dict = field(default_factory=dict)  # mechanics/electrostatics facts for humans
    plate: str = "plate"
    generator: str = f"netgen {__version__}"
    contact: dict = field(default_factory=dict)  # pull-in/contact model (netgen.model.contact), {} = none
    # nonlinear stiffness (netgen.mechanics.beam): {"energy_J": {"exponents", "coeffs"}, ...}, the strain
    # energy beyond 1/2 K q^2 as a polynomial U(xs) of the scaled coordinates; {} = linear springs only
    nonlinear: dict = field(default_factory=dict)
    # inertial load: participation factors G_v = int rho h phi_v dA (kg, or kg*m for rotations);
    # non-empty = the model has the port a_in (frame acceleration along +z, 1 V = 1 m/s^2)
    # and each coordinate feels -G_v a_in
    acceleration: list[float] = field(default_factory=list)
    # electrostatic calibration (netgen.electrostatics.calibration): its source and point count, the
    # per-electrode fringe coefficients {"electrode", "a", "b", "length"} of the term a + b ln(L/g) per
    # unit edge length, and the spread of each coupling over the points; {} = the analytic defaults
    calibration: dict = field(default_factory=dict)
    # the layout drawn to scale by the build report (netgen.geometry.layout.drawing): the conductor's
    # outline and each electrode's overlap pieces as polylines in m; {} = not known (an old JSON)
    layout: dict = field(default_factory=dict)
    # frame acceleration along x, y and rotation rates (ports a_x, a_y, w_x, w_y, w_z; netgen.model.inertial)
    inertial: Inertial = field(default_factory=Inertial)
    # process laws (netgen.model.process): tscale/escale/temp polynomials per coordinate, the
    # squeeze film's viscosity law, the gap-offset sets; {} = no process instance parameters
    process: dict = field(default_factory=dict)

    # ------------------------------------------------------------ evaluation
    @property
    def ncoords(self) -> int:
        return len(self.coordinates)

    @property
    def scales(self) -> np.ndarray:
        return np.array([c.scale for c in self.coordinates])

    def capacitance(self, x: np.ndarray) -> np.ndarray:
        """Plate-electrode capacitances (npoints, nelectrodes) in F at scaled coordinates x."""
        x = np.atleast_2d(x)
        if self._stacked() is None:
            return np.stack([f.value(x) for f in self.capacitances], axis=-1)
        exps, coef, _, owner = self._stacked()
        p, _ = self._clamped(monomials(x, exps) @ coef.T)
        c = (1.0 / p) @ owner.T
        return np.stack([f.factored(x, c[:, e]) for e, f in enumerate(self.capacitances)], axis=-1)

    def capacitance_gradient(self, x: np.ndarray) -> np.ndarray:
        """dC_i/dq_v in F per SI unit of q, shape (npoints, nelectrodes, ncoords); a fit's factor
        (CapacitanceFit.factor) by the product rule."""
        x = np.atleast_2d(x)
        if self._stacked() is None:
            g = np.stack([f.gradient(x) for f in self.capacitances], axis=1)
        else:
            exps, coef, dcoef, owner = self._stacked()
            mono = monomials(x, exps)
            p, slope = self._clamped(mono @ coef.T)  # (npts, nterms)
            dp = np.einsum("pm,vtm->ptv", mono, dcoef) * slope[:, :, None]  # (npts, nterms, ncoords)
            g = np.einsum("et,ptv->pev", owner, -dp / (p * p)[:, :, None])
            c = (1.0 / p) @ owner.T
            g = np.stack([f.factored_gradient(x, c[:, e], g[:, e]) for e, f in enumerate(self.capacitances)], axis=1)
        return g / self.scales[None, None, :]

    def term_clamps(self) -> list[list[tuple[float, float]]]:
        """(knee, floor) of every 1/P term, per electrode (netgen.model.contact): fractions of the term at
        rest, P(0), or of contact["term_rest"] where a process point's copy keeps its nominal model's
        (netgen.sweep.point.at_point: a shifted fit's P(0) is another number, the forms clamp at the
        nominal one); [] without a contact model."""
        if not self.contact or any(f.target == "direct" for f in self.capacitances):
            return []
        knee, floor = self.contact["knee"], self.contact["floor"]
        return [[(knee * r, floor * r) for r in row] for row in self.term_rest()]

    def term_rest(self) -> list[list[float]]:
        """Every 1/P term's value at rest per electrode, the clamps' reference (term_clamps)."""
        zero = np.zeros((1, self.ncoords))
        return self.contact.get("term_rest") or [[float(p(zero)[0]) for p in f.polys] for f in self.capacitances]

    def _clamped(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Clamped plate terms and dP_eff/dP (netgen.model.contact); unchanged without a contact model."""
        if "_clamp" not in self.__dict__:
            clamps = self.term_clamps()
            self.__dict__["_clamp"] = np.array([c for row in clamps for c in row]).T if clamps else None
        if self.__dict__["_clamp"] is None:
            return p, np.ones_like(p)
        return contact.clamp(p, *self.__dict__["_clamp"])

    def contact_force(self, x: np.ndarray, xdot: np.ndarray) -> np.ndarray:
        """Generalized penalty forces of the stop points (SI), x and xdot (1/s) scaled, 1-D."""
        if not self.contact.get("points"):
            return np.zeros(self.ncoords)
        a = np.array([pt["a"] for pt in self.contact["points"]])
        gap = np.array([pt["gap"] for pt in self.contact["points"]])
        pen, w = contact.penetration(a @ np.ravel(x) - 1.0, self.contact["smoothing"])
        f = gap * (self.contact["stiffness"] * pen + self.contact["damping"] * w * (a @ np.ravel(xdot)))
        return -(f * gap) @ a / self.scales

    def _stacked(self):
        """All 1/P terms in one coefficient matrix over a shared monomial basis (fast evaluation);
        None for 'direct' fits. owner[e, t] = c_ref of electrode e for its terms t."""
        if "_stack" not in self.__dict__:
            fits = self.capacitances
            if any(f.target == "direct" for f in fits):
                self.__dict__["_stack"] = None
            else:
                exps = monomial_exponents(self.ncoords, max(f.degree for f in fits))
                index = {tuple(e): i for i, e in enumerate(exps)}
                terms = [(e, p) for e, f in enumerate(fits) for p in f.polys]
                coef = np.zeros((len(terms), len(exps)))
                dcoef = np.zeros((self.ncoords, len(terms), len(exps)))
                owner = np.zeros((len(fits), len(terms)))
                for t, (e, p) in enumerate(terms):
                    owner[e, t] = fits[e].c_ref
                    for ex, c in zip(p.exponents, p.coeffs):
                        coef[t, index[tuple(ex)]] += c
                    for v in range(self.ncoords):
                        d = p.derivative(v)
                        for ex, c in zip(d.exponents, d.coeffs):
                            dcoef[v, t, index[tuple(ex)]] += c
                self.__dict__["_stack"] = (exps, coef, dcoef, owner)
        return self.__dict__["_stack"]

    def electrostatic_force(self, x: np.ndarray, v_el: np.ndarray, v_plate: float | np.ndarray = 0.0) -> np.ndarray:
        """Generalized forces 1/2 sum_i dC_i/dq_v (V_i - V_p)^2, shape (npoints, ncoords), SI."""
        dv = np.atleast_2d(v_el) - np.reshape(v_plate, (-1, 1))
        return 0.5 * np.einsum("pi,piv->pv", dv * dv, self.capacitance_gradient(x))

    def plate_charge(self, x: np.ndarray, v_el: np.ndarray, v_plate: float | np.ndarray) -> np.ndarray:
        """Charge on the moving conductor, -sum_i C_i (V_i - V_p), per point."""
        dv = np.atleast_2d(v_el) - np.reshape(v_plate, (-1, 1))
        return -np.sum(self.capacitance(x) * dv, axis=1)

    def electrode_charges(self, x: np.ndarray, v_el: np.ndarray, v_plate: float | np.ndarray) -> np.ndarray:
        """Charges on the electrodes (plate coupling plus constant couplings), (npoints, nel)."""
        v = np.atleast_2d(v_el)
        dv = v - np.reshape(v_plate, (-1, 1))
        mutual = v * self.coupling.sum(axis=1)[None, :] - v @ self.coupling.T
        return self.capacitance(x) * dv + mutual

    def accelerations(
        self,
        x: np.ndarray,
        xdot: np.ndarray,
        v_el: np.ndarray,
        v_plate: float,
        f_ext: np.ndarray | None = None,
        a_frame: float = 0.0,
        inertial: dict[str, float] | None = None,
    ) -> np.ndarray:
        """Scaled accelerations x'' from M q'' + D q' + K q = F_el + F_ext - G a_frame + F_inertial
        (diagonal M, D, K; F_inertial: the inputs {a_x, a_y, w_x, w_y, w_z: value} through
        netgen.model.inertial.Inertial.force)."""
        c = self.coordinates
        m = np.array([k.mass for k in c])
        d = np.array([k.damping for k in c])
        k = np.array([k.stiffness for k in c])
        s = self.scales
        force = self.electrostatic_force(x, v_el, v_plate)[0] + self.contact_force(x, xdot)
        if self.nonlinear:
            force = force + self.nonlinear_force(x)[0]
        if f_ext is not None:
            force = force + f_ext
        if self.acceleration and a_frame:
            force = force - np.array(self.acceleration) * a_frame
        if self.inertial and inertial:
            force = force + self.inertial.force(s * np.ravel(x), s * np.ravel(xdot), inertial)
        return (force - d * s * np.ravel(xdot) - k * s * np.ravel(x)) / (m * s)

    def nonlinear_energy_polynomial(self) -> Polynomial | None:
        """The nonlinear strain energy U(xs) in J (None without a nonlinear stiffness)."""
        if not self.nonlinear:
            return None
        e = self.nonlinear["energy_J"]
        return Polynomial(
            np.array(e["exponents"], dtype=int).reshape(-1, self.ncoords), np.array(e["coeffs"], dtype=float)
        )

    def nonlinear_force(self, x: np.ndarray) -> np.ndarray:
        """Nonlinear restoring forces -dU/dq (SI), shape (npoints, ncoords), at scaled coordinates x."""
        x = np.atleast_2d(x)
        poly = self.nonlinear_energy_polynomial()
        if poly is None:
            return np.zeros_like(x)
        return -np.stack([poly.derivative(v)(x) for v in range(self.ncoords)], axis=-1) / self.scales

    # ------------------------------------------------------------ JSON
    def to_dict(self) -> dict:
        """Plain, JSON-ready dict; floats are kept at full precision."""
        out = self._to_dict()
        if self.nonlinear:
            out["nonlinear_stiffness"] = self.nonlinear
        if self.acceleration:
            out["acceleration_port"] = {
                "port": ACCEL_PORT,
                "unit": "m/s^2",
                "meaning": "frame acceleration along "
                "+z; coordinate v feels -participation_v * a_in (a_in = 9.81: gravity)",
                "participation": list(self.acceleration),
            }
        if self.inertial:
            out["inertial_inputs"] = self.inertial.to_dict()
        if self.calibration:
            out["calibration"] = self.calibration
        if self.layout:
            out["layout"] = self.layout
        if self.process:
            out["process"] = self.process
        return out

    def fit_misses(self) -> list[dict]:
        """The capacitance fits whose held-out max relative error exceeds the structure's
        fit.tolerance (sampling["tolerance"]): electrode, error, tolerance; [] when all meet it."""
        tol = self.sampling.get("tolerance")
        if tol is None:
            return []
        return [
            {"electrode": f.electrode, "max_rel_error": f.max_rel_error, "tolerance": tol}
            for f in self.capacitances
            if f.max_rel_error > tol
        ]

    def fit_problem(self) -> str:
        """What a fit that misses fit.tolerance means, in one sentence of names and numbers; "" when
        every fit meets it (the warning on stderr, in the JSON and in every netlist header)."""
        misses = self.fit_misses()
        if not misses:
            return ""
        worst = max(misses, key=lambda m: m["max_rel_error"])
        others = f" (and {len(misses) - 1} more electrode(s))" if len(misses) > 1 else ""
        return (
            f"the capacitance fit of electrode {worst['electrode']} misses fit.tolerance: held-out max "
            f"relative error {worst['max_rel_error']:.3e} > {worst['tolerance']:.3e}{others}; charges and "
            "forces are only that accurate"
        )

    def fit_warning(self) -> str:
        """fit_problem with its fix (FIT_FIX); "" when every fit meets fit.tolerance."""
        problem = self.fit_problem()
        return f"{problem}. Fix: {FIT_FIX}" if problem else ""

    def _to_dict(self) -> dict:
        return {
            "generator": self.generator,
            "name": self.name,
            "description": self.description,
            "source": self.source,
            "plate": self.plate,
            "coordinates": [_coordinate_dict(c) for c in self.coordinates],
            "modes": [
                {
                    "name": c.name,
                    "label": c.label,
                    "frequency_hz": c.frequency_hz,
                    "modal_mass": c.mass,
                    "modal_stiffness": c.stiffness,
                }
                for c in self.coordinates
                if c.kind == "mode"
            ],
            "electrodes": [asdict(e) for e in self.electrodes],
            "capacitances": [_fit_dict(f, self.plate) for f in self.capacitances],
            "coupling": [
                {"pair": [self.electrodes[i].name, self.electrodes[j].name], "capacitance": float(self.coupling[i, j])}
                for i in range(len(self.electrodes))
                for j in range(i + 1, len(self.electrodes))
                if self.coupling[i, j] != 0.0
            ],
            "ports": self.ports(),
            "sampling": self.sampling,
            "validity": {
                "warning": f"the capacitance fits are accurate only inside the sampled box |xs| <= "
                f"{self.sampling.get('range')} (xs = q / touching amplitude); outside it "
                "they extrapolate, and near contact the clamped terms and stop points of "
                "'contact' take over"
            }
            | self._fit_validity(),
            "contact": self.contact,
            "report": self.report,
        }

    def _fit_validity(self) -> dict:
        """The JSON's fit-tolerance entries (only when a fit misses it)."""
        if not self.fit_misses():
            return {}
        return {"fit_warning": self.fit_warning(), "fit_tolerance_missed": self.fit_misses()}

    def ports(self) -> list[dict]:
        """Subcircuit port list in order, with meaning and units."""
        ports = [{"name": e.name, "kind": "electrode", "unit": "V"} for e in self.electrodes]
        ports.append({"name": self.plate, "kind": "conductor", "unit": "V"})
        for c in self.coordinates:
            xu, _, fu, _ = c.port_units
            ports.append({"name": f"f_{c.name}", "kind": "force_in", "unit": fu, "coordinate": c.name})
            ports.append({"name": f"x_{c.name}", "kind": "displacement_out", "unit": xu, "coordinate": c.name})
        ports += self.inertial.ports()
        if self.acceleration:
            ports.append({"name": ACCEL_PORT, "kind": "acceleration_in", "unit": "m/s^2"})
        return ports + self.inertial.rate_ports()

    def json_text(self) -> str:
        """The model JSON text, byte-reproducible (full-precision floats, no NaN)."""
        return json.dumps(self.to_dict(), indent=1, sort_keys=False, allow_nan=False) + "\n"

    def save_json(self, path: str | Path) -> None:
        """Write the model JSON atomically (temp file + rename), byte-reproducibly."""
        write_atomic(path, self.json_text())

    @classmethod
    def from_dict(cls, d: dict, path: str = "<model>") -> MacroModel:
        """Rebuild a model from its JSON dict (the emitters' input), validated first
        (netgen.model.validate: names, text, choices); ModelError names `path` and the entry."""
        validate.check(d, path, tuple(PORT_UNITS))
        schema.check(validate.Checker(path, tuple(PORT_UNITS)), d)  # ranges and shapes
        try:
            return cls._from_dict(d)
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise ModelError(
                path,
                "(document)",
                f"the model JSON is incomplete or malformed ({type(exc).__name__}: {exc})",
                validate.FIX,
            ) from None

    @classmethod
    def _from_dict(cls, d: dict) -> MacroModel:
        coords = [
            Coordinate(
                **{k: v for k, v in c.items() if k not in ("port_units", "film")},
                film=tuple(tuple(b) for b in c.get("film", ())),
            )
            for c in d["coordinates"]
        ]
        electrodes = [Electrode(**e) for e in d["electrodes"]]
        fits = [
            CapacitanceFit(
                f["electrode"],
                f["c_ref"],
                f["target"],
                tuple(_polynomial(t, len(coords)) for t in f["terms"]),
                f["max_rel_error"],
                f["rms_rel_error"],
                f["grid_max_rel_error"],
                _polynomial(f["factor"], len(coords)) if "factor" in f else None,
            )
            for f in d["capacitances"]
        ]
        names = [e.name for e in electrodes]
        coupling = np.zeros((len(names), len(names)))
        for c in d["coupling"]:
            i, j = names.index(c["pair"][0]), names.index(c["pair"][1])
            coupling[i, j] = coupling[j, i] = c["capacitance"]
        return cls(
            d["name"],
            d["description"],
            d["source"],
            coords,
            electrodes,
            fits,
            coupling,
            d["sampling"],
            d["report"],
            d["plate"],
            d["generator"],
            d.get("contact", {}),
            d.get("nonlinear_stiffness", {}),
            d.get("acceleration_port", {}).get("participation", []),
            d.get("calibration", {}),
            d.get("layout", {}),
            Inertial.from_dict(d.get("inertial_inputs", {})),
            d.get("process", {}),
        )

    @classmethod
    def load_json(cls, path: str | Path) -> MacroModel:
        """Read and validate a model JSON file; unreadable or invalid files are ModelError (exit 2)."""
        where = validate.escape(str(path))
        text = read_text(path, "file", "a model .json", ModelError, "json")  # regular file, size cap
        doc = json_document(text, where, ModelError, "give the .json a build wrote")
        if not isinstance(doc, dict):
            raise ModelError(where, "file", "the file holds no JSON object", "give the .json a build wrote")
        return cls.from_dict(doc, where)


def _coordinate_dict(c: Coordinate) -> dict:
    """A coordinate's JSON entry (the film branches only when there are any)."""
    out = asdict(c) | {"port_units": _port_dict(c)}
    if not c.film:
        out.pop("film")
    else:
        out["film"] = [list(b) for b in c.film]
    return out


def _port_dict(c: Coordinate) -> dict:
    xu, xf, fu, ff = c.port_units
    return {"displacement": xu, "displacement_si_per_volt": xf, "force": fu, "force_si_per_volt": ff}


def _polynomial(d: dict, ncoords: int) -> Polynomial:
    """A polynomial from its JSON entry {"exponents", "coeffs"}."""
    return Polynomial(np.array(d["exponents"], dtype=int).reshape(-1, ncoords), np.array(d["coeffs"], dtype=float))


def _fit_dict(f: CapacitanceFit, plate: str) -> dict:
    """A fit's JSON entry; its factor (a process point's, CapacitanceFit.factor) only when it has one."""
    factor = {} if f.factor is None else {"factor": _poly_dict(f.factor)}
    return {
        "pair": [plate, f.electrode],
        "electrode": f.electrode,
        "c_ref": f.c_ref,
        "target": f.target,
        "max_rel_error": f.max_rel_error,
        "rms_rel_error": f.rms_rel_error,
        "grid_max_rel_error": f.grid_max_rel_error,
        "terms": [_poly_dict(p) for p in f.polys],
    } | factor


def _poly_dict(p: Polynomial) -> dict:
    return {"exponents": p.exponents.tolist(), "coeffs": [float(c) for c in p.coeffs]}


def finite(value: float) -> float:
    """Guard against NaN/inf reaching a netlist or JSON."""
    if not math.isfinite(value):
        raise ValueError(f"non-finite model value {value}")
    return value
