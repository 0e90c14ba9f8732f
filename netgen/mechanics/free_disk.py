"""Mechanics of a free thin disk: rigid-body inertia and Kirchhoff plate eigenmodes.

Implements the mechanical half of the macromodel paper (sections 2-3): the generalized
coordinates of a floating plate are the rigid-body motions about the centre of mass plus
the amplitudes of selected free-plate eigenmodes.  The eigenmodes come from scikit-fem's
Morley plate element on a unit disk and are scaled to the physical radius.

Conventions
-----------
* Mode labels ``"n,s"`` + ``c``/``s``: n nodal diameters, s nodal circles, angular factor
  cos(n theta) (``c``) or sin(n theta) (``s``); n = 0 modes carry no suffix.  The rigid
  motions are (0,0) (translation) and (1,0) (tilts), so elastic modes with n < 2 have s >= 1.
* Every shape is scaled to max |w| = 1 over the plate (a modal coordinate is the peak
  deflection in metres) with a positive angular Fourier coefficient at the rim: a "c" mode
  is positive at theta = 0, an "s" mode at theta = 90 deg / n, an n = 0 mode on the rim.
* Shapes are vertical displacements only (thin plate), as in the paper.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from dataclasses import field as dataclass_field

import numpy as np
from scipy.sparse.linalg import eigsh
from skfem import BilinearForm, CellBasis, Functional, LinearForm, MeshTri
from skfem.element import ElementTriMorley
from skfem.helpers import dd, ddot, trace

from ..structure import Structure, mode_name
from .base import RIGID, Mechanics, rigid_field
from .fields import P2Field, p2_field
from .kirchhoff import free_edge_roots, free_plate_lambda2_exact

_LABEL = re.compile(r"^([0-9]+),([0-9]+)([cs]?)\Z")
_RIM_SAMPLES = 256  # angular samples on circles used to classify and align modes
_RADIAL_SAMPLES = 200  # radial samples used to count nodal circles
_OUTSIDE_TOL = 1e-6  # relative distance beyond the rim still accepted by shape()
_MAX_EIGENPAIRS = 240  # refuse requests that would need more eigenpairs than this


# ----------------------------------------------------------------------------- rigid body


@dataclass(frozen=True)
class RigidBody:
    """Mass (kg) and inertia tensor (kg m^2, about the centre of mass, principal axes)."""

    mass: float
    inertia: np.ndarray


def rigid_disk(radius: float, thickness: float, density: float) -> RigidBody:
    """Mass and inertia of a solid disk: the rigid part of the paper's kinetic energy."""
    mass = density * np.pi * radius**2 * thickness
    i_xx = mass * (radius**2 / 4 + thickness**2 / 12)
    inertia = np.diag([i_xx, i_xx, mass * radius**2 / 2])
    inertia.flags.writeable = False
    return RigidBody(mass=float(mass), inertia=inertia)


# --------------------------------------------------------------------- unit-disk FEM model


@dataclass(frozen=True)
class UnitDisk:
    """Morley discretisation of the unit disk: D = 1 stiffness, rho h = 1 mass, moments."""

    basis: CellBasis
    stiffness: object
    mass: object
    moments: np.ndarray  # (3, ndofs): integral of v, x v, y v over the disk
    rigid_norms: np.ndarray  # (3,): M-norms of the rigid fields 1, x, y


def bending_form(nu: float) -> BilinearForm:
    """Kirchhoff bending energy per unit D; the free edge is the natural condition."""

    @BilinearForm
    def form(u, v, _):
        return (1 - nu) * ddot(dd(u), dd(v)) + nu * trace(dd(u)) * trace(dd(v))

    return form


@BilinearForm
def mass_form(u, v, _):
    """Mass per unit rho h."""
    return u * v


def unit_disk(nu: float, refine: int) -> UnitDisk:
    """Assemble the unit-disk plate model at mesh refinement ``refine``."""
    basis = CellBasis(MeshTri.init_circle(refine), ElementTriMorley())
    weights = (lambda w: 1.0 + 0 * w.x[0], lambda w: w.x[0], lambda w: w.x[1])
    moments = np.stack([LinearForm(lambda v, w, f=f: f(w) * v).assemble(basis) for f in weights])
    norms = np.sqrt([Functional(lambda w, f=f: f(w) ** 2).assemble(basis) for f in weights])
    return UnitDisk(basis, bending_form(nu).assemble(basis), mass_form.assemble(basis), moments, norms)


def _eigenpairs(disk: UnitDisk, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Lowest ``count`` elastic eigenpairs (mu = lambda^4, M-orthonormal vectors)."""
    # a fixed start vector: ARPACK's default is random, which makes builds non-reproducible
    v0 = np.random.default_rng(0).standard_normal(disk.stiffness.shape[0])
    mu, vec = eigsh(disk.stiffness, k=count + 3, M=disk.mass, sigma=-1.0, which="LM", v0=v0)
    order = np.argsort(mu)
    mu, vec = mu[order], vec[:, order]
    if not np.all(np.abs(mu[:3]) < 1e-6 * mu[3]):
        raise RuntimeError(f"expected 3 zero-frequency rigid modes, got eigenvalues {mu[:4]}")
    return mu[3:], vec[:, 3:]


# ------------------------------------------------------------ classification and alignment


def _circle(radius: float, samples: int = _RIM_SAMPLES) -> tuple[np.ndarray, np.ndarray]:
    """Equally spaced angles and points on a circle of the unit disk."""
    theta = 2 * np.pi * np.arange(samples) / samples
    return theta, radius * np.stack([np.cos(theta), np.sin(theta)])


def _fourier(values: np.ndarray) -> np.ndarray:
    """Complex angular Fourier coefficients (..., samples) -> (..., samples // 2 + 1)."""
    return np.fft.rfft(values, axis=-1) / values.shape[-1]


def _cos_sin(coeffs: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Amplitudes of cos(n theta) and sin(n theta) from rfft coefficients."""
    c = coeffs[..., n]
    return (c.real, 0 * c.real) if n == 0 else (2 * c.real, -2 * c.imag)


def _classify(field: P2Field) -> list[tuple[int, int]]:
    """(n, s) of each column: dominant rim harmonic and sign changes along a radius."""
    _, rim = _circle(1.0)
    rim_coeffs = _fourier(field(*rim).T)  # (ncols, nh)
    radii = np.linspace(0.0, 1.0, _RADIAL_SAMPLES + 1)[1:]
    pts = np.concatenate([_circle(r)[1] for r in radii], axis=1)
    coeffs = _fourier(field(*pts).T.reshape(-1, len(radii), _RIM_SAMPLES))  # (ncols, nr, nh)
    labels = []
    for col, rc in enumerate(rim_coeffs):
        n = int(np.argmax(np.abs(rc)))
        a, b = _cos_sin(rc, n)
        ra, rb = _cos_sin(coeffs[col], n)
        labels.append((n, _sign_changes((a * ra + b * rb) / np.hypot(a, b))))
    return labels


def _sign_changes(profile: np.ndarray, floor: float = 0.02) -> int:
    """Zero crossings of a radial profile, ignoring samples near zero (noise, r -> 0)."""
    big = profile[np.abs(profile) > floor * np.max(np.abs(profile))]
    return int(np.count_nonzero(np.diff(np.sign(big))))


def _label(n: int, s: int, suffix: str) -> str:
    """Canonical label, e.g. '2,0c', '0,1'."""
    return f"{n},{s}{suffix if n else ''}"


def _align(field: P2Field, n: int, cols: list[int]) -> tuple[np.ndarray, list[str]]:
    """Rotation (ncols, len(cols)) turning a mode group into cos/sin members, and labels."""
    _, rim = _circle(1.0)
    a, b = _cos_sin(_fourier(field(*rim)[:, cols].T), n)
    q = np.zeros((field.nodes.shape[-1], len(cols)))
    if n == 0:
        q[cols[0], 0] = np.sign(a[0])
        return q, [""]
    if len(cols) == 1:
        suffix = "c" if abs(a[0]) >= abs(b[0]) else "s"
        q[cols[0], 0] = np.sign(a[0] if suffix == "c" else b[0])
        return q, [suffix]
    qc = np.array([b[1], -b[0]]) / np.hypot(*b)
    qc *= np.sign(a @ qc)
    qs = np.array([-qc[1], qc[0]])
    qs *= np.sign(b @ qs)
    q[cols, 0], q[cols, 1] = qc, qs
    return q, ["c", "s"]


def _organise(field: P2Field, mu: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """Group, align (c/s), sign and max-normalise raw eigenvectors, in frequency order.

    Returns the coefficient matrix (nraw, nmodes) onto the raw vectors and the labels; a
    lone member of a degenerate pair at the top of the computed range is dropped.
    """
    groups: dict[tuple[int, int], list[int]] = {}
    for col, key in enumerate(_classify(field)):
        groups.setdefault(key, []).append(col)
    blocks, labels = [], []
    for (n, s), cols in sorted(groups.items(), key=lambda kv: mu[kv[1]].mean()):
        if len(cols) > (2 if n else 1):
            raise RuntimeError(f"mode identification failed: {len(cols)} modes look like ({n},{s}); refine the mesh")
        if n and len(cols) == 1 and cols[0] == len(mu) - 1:
            continue
        q, suffixes = _align(field, n, cols)
        blocks.append(q)
        labels += [_label(n, s, sfx) for sfx in suffixes]
    coeffs = np.hstack(blocks)
    peak = np.max(np.abs(field.nodes @ coeffs), axis=(0, 1))
    return coeffs / peak, labels


# --------------------------------------------------------------------------- mode requests


def _parse_labels(modes: list[str] | tuple[str, ...]) -> list[tuple[str, int, int]]:
    """Validate labels; return (canonical label, n, s) for each, in request order."""
    parsed = []
    for raw in modes:
        match = _LABEL.match(str(raw).replace(" ", ""))
        if not match:
            raise ValueError(
                f"bad mode label {raw!r}: expected 'n,s' + 'c'/'s' "
                "(e.g. '2,0c', '3,0s') or 'n,s' for n = 0 (e.g. '0,1')"
            )
        n, s, suffix = int(match[1]), int(match[2]), match[3]
        if n < 2 and s == 0:
            raise ValueError(
                f"mode {raw!r} is a rigid-body motion (translation/tilt) of "
                "the free disk, not an eigenmode: use the rigid coordinates"
            )
        if (n == 0) != (suffix == ""):
            hint = f"'{n},{s}'" if n == 0 else f"'{n},{s}c' or '{n},{s}s'"
            raise ValueError(f"mode {raw!r}: write {hint} (c/s orientation only for n > 0)")
        parsed.append((_label(n, s, suffix), n, s))
    names = [p[0] for p in parsed]
    if len(set(names)) != len(names):
        raise ValueError(f"duplicate mode labels in {list(modes)}")
    return parsed


def _eigenpairs_needed(parsed: list[tuple[str, int, int]], nu: float) -> int:
    """Elastic eigenpairs to compute so all requested modes (and their partners) appear."""
    stop = np.sqrt(1.03 * max(free_plate_lambda2_exact(n, s, nu) for _, n, s in parsed))
    count, n = 0, 0
    while n < 2 or free_edge_roots(n, nu, count=1)[0] <= stop:
        count += len(free_edge_roots(n, nu, stop=stop)) * (2 if n else 1)
        n += 1
    return count + 2


# --------------------------------------------------------------------------- public result


@dataclass(frozen=True)
class PlateModes:
    """Selected free-disk eigenmodes: labels, modal mass/stiffness, shapes, side conditions.

    ``orthogonality``: cosines (M-inner product) of each mode with the rigid fields
    ``phi`` (translation), ``x_phi`` and ``y_phi`` (tilts), max over modes, plus the largest
    relative off-diagonal modal mass/stiffness between selected modes.
    ``coupling``: the paper's rotation-mode coupling A and inertia-tensor correction, as
    relative sizes (see ``free_disk_modes``).
    """

    labels: tuple[str, ...]
    frequencies_hz: np.ndarray
    modal_mass: np.ndarray
    modal_stiffness: np.ndarray
    lambda2: np.ndarray
    orthogonality: dict[str, float]
    coupling: dict[str, float]
    radius: float
    field: P2Field = dataclass_field(repr=False, compare=False)

    def shape(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Normalised vertical displacement (npts, nmodes) at points (m, centre at origin).

        Points up to the rim are accepted (those between the mesh polygon and the circle are
        projected radially onto the polygon); points farther out raise ValueError.
        """
        x = np.ravel(np.asarray(x, dtype=float)) / self.radius
        y = np.ravel(np.asarray(y, dtype=float)) / self.radius
        if x.shape != y.shape:
            raise ValueError(f"x and y must have the same size, got {x.size} and {y.size}")
        r = np.hypot(x, y)
        if x.size and r.max() > 1 + _OUTSIDE_TOL:
            raise ValueError(f"points outside the disk: max radius {r.max() * self.radius:.6g} m > {self.radius:.6g} m")
        return self.field(x, y)


def free_disk_modes(
    radius: float,
    thickness: float,
    youngs_modulus: float,
    poisson_ratio: float,
    density: float,
    modes: int | list[str],
    refine: int = 6,
    reference_amplitude: float | None = None,
) -> PlateModes:
    """Eigenmodes of the free Kirchhoff disk (Morley FEM), as the paper's modal coordinates.

    ``modes``: an int (the first N elastic modes in frequency order) or labels such as
    ``["2,0c", "2,0s", "3,0c", "3,0s"]`` (returned in the requested order).
    ``reference_amplitude`` (m, default: the thickness) is the amplitude given to every
    selected mode when sizing the inertia-tensor correction in ``coupling``.
    """
    nu = poisson_ratio
    if isinstance(modes, str):
        modes = [modes]
    if isinstance(modes, (int, np.integer)):
        if modes < 1:
            raise ValueError(f"modes must be >= 1, got {modes}")
        parsed, count = None, int(modes) + 2
    else:
        parsed = _parse_labels(list(modes))
        if not parsed:
            raise ValueError("no modes requested")
        count = _eigenpairs_needed(parsed, nu)
    if count + 3 > _MAX_EIGENPAIRS:
        raise ValueError(f"request needs {count} eigenpairs (limit {_MAX_EIGENPAIRS - 3})")
    disk = unit_disk(nu, refine)
    mu, vectors = _eigenpairs(disk, count)
    raw = p2_field(disk.basis, vectors)
    coeffs, labels = _organise(raw, mu)
    pick = _select(labels, modes if parsed is None else [p[0] for p in parsed])
    coeffs, labels = coeffs[:, pick], [labels[i] for i in pick]
    plate = _Plate(radius, thickness, youngs_modulus, nu, density)
    amplitude = thickness if reference_amplitude is None else reference_amplitude
    return _plate_modes(plate, disk, vectors @ coeffs, raw.combine(coeffs), labels, amplitude)


def _select(labels: list[str], wanted: int | list[str]) -> list[int]:
    """Column indices of the wanted modes (first N, or by label with a helpful error)."""
    if isinstance(wanted, (int, np.integer)):
        if len(labels) < wanted:
            raise RuntimeError(f"only {len(labels)} modes identified, {wanted} requested")
        return list(range(int(wanted)))
    missing = [w for w in wanted if w not in labels]
    if missing:
        raise ValueError(f"modes {missing} not among the computed modes {labels}")
    return [labels.index(w) for w in wanted]


# ------------------------------------------------------------------- physical quantities


@dataclass(frozen=True)
class _Plate:
    """Physical plate data."""

    radius: float
    thickness: float
    youngs_modulus: float
    nu: float
    density: float

    @property
    def bending_stiffness(self) -> float:
        """D = E h^3 / (12 (1 - nu^2))."""
        return self.youngs_modulus * self.thickness**3 / (12 * (1 - self.nu**2))

    @property
    def areal_density(self) -> float:
        """rho h."""
        return self.density * self.thickness


def _plate_modes(
    plate: _Plate, disk: UnitDisk, phi: np.ndarray, shapes: P2Field, labels: list[str], amplitude: float
) -> PlateModes:
    """Scale unit-disk shapes to the plate and collect modal data and side conditions."""
    r, rho_h = plate.radius, plate.areal_density
    mass = rho_h * r**2 * (phi.T @ (disk.mass @ phi))
    stiff = plate.bending_stiffness / r**2 * (phi.T @ (disk.stiffness @ phi))
    m, k = np.diag(mass).copy(), np.diag(stiff).copy()
    omega = np.sqrt(k / m)
    lambda2 = omega * r**2 * np.sqrt(rho_h / plate.bending_stiffness)
    arrays = [omega / (2 * np.pi), m, k, lambda2]
    for a in arrays:
        a.flags.writeable = False
    return PlateModes(
        labels=tuple(labels),
        frequencies_hz=arrays[0],
        modal_mass=arrays[1],
        modal_stiffness=arrays[2],
        lambda2=arrays[3],
        orthogonality=_orthogonality(disk, phi, mass, stiff),
        coupling=_coupling(plate, disk, phi, mass, amplitude),
        radius=float(r),
        field=shapes,
    )


def _orthogonality(disk: UnitDisk, phi: np.ndarray, mass: np.ndarray, stiff: np.ndarray) -> dict[str, float]:
    """Side conditions (M-cosines with rigid fields) and modal cross terms, max over modes."""
    norms = np.sqrt(np.einsum("dm,dm->m", phi, disk.mass @ phi))
    cos = np.abs(disk.moments @ phi) / np.outer(disk.rigid_norms, norms)
    return {
        "phi": float(cos[0].max()),
        "x_phi": float(cos[1].max()),
        "y_phi": float(cos[2].max()),
        "mass_offdiag": _offdiag(mass),
        "stiffness_offdiag": _offdiag(stiff),
    }


def _offdiag(matrix: np.ndarray) -> float:
    """Largest |M_ij| / sqrt(M_ii M_jj) for i != j (0 for a single mode)."""
    d = np.sqrt(np.diag(matrix))
    rel = np.abs(matrix) / np.outer(d, d) - np.eye(len(d))
    return float(np.abs(rel).max())


def _coupling(plate: _Plate, disk: UnitDisk, phi: np.ndarray, mass: np.ndarray, amplitude: float) -> dict[str, float]:
    """Paper's A = rho int x x G dV and Theta(m) - Theta_undef, relative to rigid inertia.

    Thin plate, vertical-only G = (0, 0, phi): A_i = rho h int (y phi, -x phi, 0) dA (the
    (x + G m) x G term adds G m x G = 0).  The inertia correction is the exact change of
    rho int (|r|^2 I - r r^T) dV for r = x + u, u = (0, 0, w), w = amplitude * sum phi_i:
    rho h [[W2, 0, -Xw], [0, W2, -Yw], [-Xw, -Yw, 0]] with W2 = int w^2, Xw = int x w,
    Yw = int y w (the z-linear terms integrate to zero over the thickness).  Its first-order
    part (Xw, Yw) is what the side conditions remove; the second-order part W2 remains.
    The paper's printed first-order terms (I3 x.u without the factor 2, and -2 x u^T
    instead of -(x u^T + u x^T)) differ from this, but vanish here all the same.
    """
    r, rho_h = plate.radius, plate.areal_density
    i_xx = rigid_disk(r, plate.thickness, plate.density).inertia[0, 0]
    first = rho_h * r**3 * (disk.moments[1:] @ phi)  # (2, nmodes): x, y
    a_matrix = np.stack([first[1], -first[0], np.zeros(phi.shape[1])])
    a_rel = np.linalg.norm(a_matrix, axis=0) / np.sqrt(i_xx * np.diag(mass))
    xw, yw = amplitude * first.sum(axis=1)
    w2 = amplitude**2 * mass.sum()
    delta = np.array([[w2, 0.0, -xw], [0.0, w2, -yw], [-xw, -yw, 0.0]])
    return {
        "A_rel_max": float(a_rel.max()),
        "inertia_correction_rel_max": float(np.abs(delta).max() / i_xx),
        "inertia_correction_linear_rel_max": float(max(abs(xw), abs(yw)) / i_xx),
        "reference_amplitude_m": float(amplitude),
    }


# ------------------------------------------------------------------- the stage


def floats(d: dict) -> dict:
    """A report dict with numpy scalars as plain floats (JSON)."""
    return {k: (float(v) if isinstance(v, (int, float, np.floating)) else v) for k, v in d.items()}


def mechanics(s: Structure) -> Mechanics:
    """Rigid-body masses and FEM eigenmodes of a free disk, as generalized coordinates."""
    d = s.conductor
    body = rigid_disk(d.radius, d.thickness, d.density)
    rigid_mass = {"z": body.mass, "tilt_x": body.inertia[0, 0], "tilt_y": body.inertia[1, 1]}
    modes = None
    if s.coordinates.modes:
        modes = free_disk_modes(
            d.radius,
            d.thickness,
            d.youngs_modulus,
            d.poisson_ratio,
            d.density,
            list(s.coordinates.modes) if not isinstance(s.coordinates.modes, int) else s.coordinates.modes,
            refine=s.fem.refine,
            reference_amplitude=s.sampling.range * min(e.gap for e in s.electrode_sets),
        )
    rigid = list(s.coordinates.rigid)
    labels = list(modes.labels) if modes else []
    names = rigid + [mode_name(lab) for lab in labels]
    kinds = [RIGID[r][0] for r in rigid] + ["mode"] * len(labels)
    units = [RIGID[r][1] for r in rigid] + ["m"] * len(labels)
    masses = np.array([rigid_mass[r] for r in rigid] + (list(modes.modal_mass) if modes else []))
    stiff = np.array([0.0] * len(rigid) + (list(modes.modal_stiffness) if modes else []))
    freqs = np.array([0.0] * len(rigid) + (list(modes.frequencies_hz) if modes else []))

    def basis(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Vertical displacement per unit of each coordinate at points (x, y)."""
        out = [rigid_field(r, x, y) for r in rigid]
        if modes is not None:
            shapes = modes.shape(x, y)
            out += [shapes[:, k] for k in range(shapes.shape[1])]
        return np.stack(out, axis=-1)

    report = {"mass_kg": body.mass, "inertia_kg_m2": np.asarray(body.inertia).tolist()}
    if modes is not None:
        report.update(
            {
                "fem_refine": s.fem.refine,
                "lambda2": [float(v) for v in modes.lambda2],
                "side_conditions": floats(modes.orthogonality),
                "rotation_mode_coupling": floats(modes.coupling),
            }
        )
    return Mechanics(names, kinds, units, [""] * len(rigid) + labels, masses, stiff, freqs, basis, report)


def selected_modes(s: Structure) -> PlateModes:
    """The structure's selected eigenmodes alone (the exporter's per-element node values)."""
    d = s.conductor
    return free_disk_modes(
        d.radius,
        d.thickness,
        d.youngs_modulus,
        d.poisson_ratio,
        d.density,
        list(s.coordinates.modes) if not isinstance(s.coordinates.modes, int) else s.coordinates.modes,
        refine=s.fem.refine,
    )
