"""Eigenmodes of a thin rectangular Kirchhoff plate (a proof mass's internal modes): scikit-fem's
Bogner-Fox-Schmit element (C1 bicubic Hermite, conforming) on a tensor mesh of the rectangle,
with the disk's bending and mass forms (netgen.mechanics.free_disk.bending_form, mass_form).

Conventions
-----------
* Edges are free (the natural condition of the bending form), "clamped" (w = dw/dn = 0) or
  "simply_supported" (w = 0); the proof mass uses free edges, and netgen.mechanics.proof_mass adds
  its flexures' vertical springs at the attachment points to each mode's stiffness.
* Modes are labelled "1", "2", ... in frequency order (coordinate names m1, m2, ...), each scaled to
  a peak |w| = 1 over the mesh nodes (the modal coordinate is the peak deflection in metres), with
  its sign fixed by the node of largest |w| (ties: largest x, then y). A degenerate pair (a square
  plate) is turned into members of definite parity under x -> -x (even first), so the same input
  gives the same modes on any machine.
* An etch-hole grid (square holes of side h on a pitch p, f = h / p) enters as an effective plate:
  density rho (1 - f^2) (the mass fraction), bending stiffness D / ((1 - f) + f / (1 - f)) (a strip
  one pitch wide bent along x or y: solid for a length p (1 - f) and a ligament of width p (1 - f)
  for p f, in series, Euler-Bernoulli), Poisson's ratio unchanged. It holds for holes small
  against a mode's wavelength; tests/mechanics/test_rect_plate.py checks it against the plate
  with the holes cut out of the mesh.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from dataclasses import field as dataclass_field

import numpy as np
from scipy.sparse.linalg import eigsh
from skfem import CellBasis, MeshQuad
from skfem.element import ElementQuadBFS

from ..structure import grid_count
from .free_disk import bending_form, mass_form

BOUNDARIES = ("free", "clamped", "simply_supported")
DEGENERATE = 1e-6  # relative eigenvalue spread treated as one degenerate group


@dataclass(frozen=True)
class EffectivePlate:
    """The homogenised perforated plate: factors on rho and on D (1 without holes)."""

    density_factor: float
    stiffness_factor: float

    @classmethod
    def of_holes(cls, hole: float, pitch: float) -> EffectivePlate:
        """Mass fraction and series-strip bending stiffness of a square hole grid (module docstring)."""
        if not hole:
            return cls(1.0, 1.0)
        f = hole / pitch
        return cls(1.0 - f * f, 1.0 / ((1.0 - f) + f / (1.0 - f)))


@dataclass(frozen=True)
class RectPlateModes:
    """The first eigenmodes of a rectangular plate [-a/2, a/2] x [-b/2, b/2]: labels, modal mass
    (kg) and stiffness (N/m) per unit peak deflection, frequencies, lambda^2 = omega a^2
    sqrt(rho h / D) (Leissa's frequency parameter on the side a along x), shapes."""

    labels: tuple[str, ...]
    frequencies_hz: np.ndarray
    modal_mass: np.ndarray
    modal_stiffness: np.ndarray
    lambda2: np.ndarray
    length: float
    width: float
    boundary: str
    orthogonality: dict[str, float]
    basis: CellBasis = dataclass_field(repr=False, compare=False)
    vectors: np.ndarray = dataclass_field(repr=False, compare=False)

    def shape(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Vertical displacement per unit modal amplitude, (npts, nmodes), at points (m; centre at
        the origin); a point beyond the rectangle (on a comb finger: a rigid box clamped to the edge)
        takes the value at the nearest edge point plus the edge's outward slope times its distance
        beyond it (small angles: the finger turns with the edge)."""
        x = np.ravel(np.asarray(x, dtype=float))
        y = np.ravel(np.asarray(y, dtype=float))
        if x.size == 0:
            return np.zeros((0, len(self.labels)))
        inner = np.array([[0.5], [0.5 * self.width / self.length]]) * (1.0 - 1e-12)
        asked = np.stack([x, y]) / self.length
        edge = np.clip(asked, -inner, inner)
        out = self.basis.probes(edge) @ self.vectors
        beyond = asked - edge
        for k in (0, 1):
            far = np.flatnonzero(np.abs(beyond[k]) > 1e-9)
            if far.size:
                out[far] += self.outward_slope(edge[:, far], k, np.sign(beyond[k, far])) * np.abs(beyond[k, far, None])
        return np.asarray(out)

    def outward_slope(self, edge: np.ndarray, axis: int, sign: np.ndarray) -> np.ndarray:
        """d phi / d(axis) per unit `length` at edge points (in units of `length`), outward along
        sign: the one-sided second-order difference (3 f0 - 4 f1 + f2) / 2h inside the last element
        (a cubic along the axis there: off by h^2 / 3 of the third derivative, h = 1e-4)."""
        h = 1e-4
        step = np.zeros_like(edge)
        step[axis] = -sign * h
        f = [self.basis.probes(edge + i * step) @ self.vectors for i in range(3)]
        return (3 * f[0] - 4 * f[1] + f[2]) / (2 * h)


def plate_basis(length: float, width: float, elements: int, holes: tuple[float, float] = (0.0, 0.0)) -> CellBasis:
    """BFS basis on an elements x elements(b/a) tensor mesh of the centred rectangle, in units of
    `length` (the derivative dofs of a micrometre mesh in metres leave M singular to working
    precision); with
    holes = (side, pitch) the square holes of a centred grid are cut out of the mesh (the grid
    lines then fall on the hole edges: `elements` cells on each of a pitch's three segments)."""
    hole, pitch = holes[0] / length, holes[1] / length
    width, length = width / length, 1.0
    if hole:
        per = elements
        nx, ny = grid_count(length, pitch), grid_count(width, pitch)
        xs = _hole_lines(length, nx, pitch, hole, per)
        ys = _hole_lines(width, ny, pitch, hole, per)
        mesh = MeshQuad.init_tensor(xs, ys)
        mid = mesh.p[:, mesh.t].mean(axis=1)
        cut = _in_hole(mid[0], length, nx, pitch, hole) & _in_hole(mid[1], width, ny, pitch, hole)
        mesh = mesh.remove_elements(np.flatnonzero(cut)).remove_unused_nodes()
    else:
        ny = max(2, int(round(elements * width / length)))
        mesh = MeshQuad.init_tensor(
            np.linspace(-length / 2, length / 2, elements + 1), np.linspace(-width / 2, width / 2, ny + 1)
        )
    return CellBasis(mesh, ElementQuadBFS())


def _hole_lines(size: float, count: int, pitch: float, hole: float, per: int) -> np.ndarray:
    """Grid lines along one side: each pitch in three segments (solid, hole, solid), each in
    `per` cells, so every hole edge is a grid line."""
    start = -count * pitch / 2
    seg = np.array([0.0, (pitch - hole) / 2, (pitch + hole) / 2, pitch])
    cell = np.concatenate([np.linspace(seg[i], seg[i + 1], per + 1)[:-1] for i in range(3)])
    lines = (start + pitch * np.arange(count)[:, None] + cell[None, :]).ravel()
    return (
        np.concatenate([[-size / 2], lines[lines > -size / 2], [start + count * pitch], [size / 2]])
        if count * pitch < size
        else np.append(lines, size / 2)
    )


def _in_hole(c: np.ndarray, size: float, count: int, pitch: float, hole: float) -> np.ndarray:
    """Element centres inside a hole along one axis."""
    u = (c + count * pitch / 2) / pitch
    k = np.floor(u)
    frac = (u - k) * pitch
    return (k >= 0) & (k < count) & (np.abs(frac - pitch / 2) < hole / 2)


def constrained_dofs(basis: CellBasis, boundary: str) -> np.ndarray:
    """The BFS dofs a boundary condition fixes: none (free), all boundary dofs (clamped: w and
    every derivative vanish along a clamped edge), or w and its tangential derivative (simply
    supported)."""
    if boundary == "free":
        return np.zeros(0, dtype=int)
    dofs = basis.get_dofs()
    if boundary == "clamped":
        return dofs.all()
    mesh = basis.mesh
    nodes = np.unique(mesh.facets[:, mesh.boundary_facets()])
    xs, ys = mesh.p[0, nodes], mesh.p[1, nodes]
    on = {
        "u_y": np.isclose(np.abs(xs), np.abs(mesh.p[0]).max()),  # edges x = +-a/2: w_y = 0 along them
        "u_x": np.isclose(np.abs(ys), np.abs(mesh.p[1]).max()),
    }  # edges y = +-b/2: w_x = 0
    out = [dofs.nodal["u"]] + [basis.nodal_dofs[basis.elem.dofnames.index(n), nodes[m]] for n, m in on.items()]
    return np.unique(np.concatenate(out))


@dataclass(frozen=True)
class PlateSpec:
    """A rectangular plate's size (m) and material (Pa, kg/m^3), rect_plate_modes' input."""

    length: float
    width: float
    thickness: float
    youngs_modulus: float
    poisson_ratio: float
    density: float


def rect_plate_modes(
    p: PlateSpec,
    count: int,
    elements: int = 24,
    boundary: str = "free",
    effective: EffectivePlate = EffectivePlate(1.0, 1.0),
    holes: tuple[float, float] = (0.0, 0.0),
) -> RectPlateModes:
    """The first `count` elastic eigenmodes (free edges: after the three rigid ones) of the
    rectangular plate, effective density and stiffness applied; `holes` = (side, pitch) cuts the
    holes out of the mesh instead (the check of the effective plate)."""
    length, width, thickness = p.length, p.width, p.thickness
    youngs_modulus, poisson_ratio, density = p.youngs_modulus, p.poisson_ratio, p.density
    if boundary not in BOUNDARIES:
        raise ValueError(f"boundary {boundary!r}: use one of {BOUNDARIES}")
    basis = plate_basis(length, width, elements, holes)
    K = bending_form(poisson_ratio).assemble(basis)
    M = mass_form.assemble(basis)
    fixed = constrained_dofs(basis, boundary)
    free = np.setdiff1d(np.arange(basis.N), fixed)
    rigid = 3 if boundary == "free" else 0
    v0 = np.random.default_rng(0).standard_normal(len(free))  # ARPACK's default start is random
    mu, vec = eigsh(K[free][:, free], k=count + rigid + 2, M=M[free][:, free], sigma=-1.0, which="LM", v0=v0)
    order = np.argsort(mu)
    mu, vec = mu[order][rigid:], vec[:, order][:, rigid:]
    full = np.zeros((basis.N, vec.shape[1]))
    full[free] = vec
    full = _align(basis, mu, full)[:, :count]
    full = _normalise(basis, full)
    rho_h = density * effective.density_factor * thickness
    d = youngs_modulus * effective.stiffness_factor * thickness**3 / (12 * (1 - poisson_ratio**2))
    mass = rho_h * length**2 * (full.T @ (M @ full))  # the mesh is in units of `length`
    stiff = d / length**2 * (full.T @ (K @ full))
    m, k = np.diag(mass).copy(), np.diag(stiff).copy()
    omega = np.sqrt(k / m)
    return RectPlateModes(
        tuple(str(i + 1) for i in range(count)),
        omega / (2 * math.pi),
        m,
        k,
        omega * length**2 * math.sqrt(rho_h / d),
        length,
        width,
        boundary,
        _orthogonality(basis, M, full, mass, stiff),
        basis,
        full,
    )


def _align(basis: CellBasis, mu: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Degenerate groups turned into members of definite x-parity (then y-parity), even first."""
    out = vectors.copy()
    i = 0
    while i < len(mu):
        j = i + 1
        while j < len(mu) and mu[j] - mu[i] < DEGENERATE * abs(mu[i]):
            j += 1
        if j - i > 1:
            out[:, i:j] = _parity_split(basis, vectors[:, i:j])
        i = j
    return out


def _parity_split(basis: CellBasis, group: np.ndarray) -> np.ndarray:
    """A degenerate group rotated onto the eigenvectors of the x-reflection (+1 first), each
    sub-space of one x-parity in turn onto those of the y-reflection (on the nodal values: the
    tensor mesh is symmetric)."""
    w = group[basis.nodal_dofs[basis.elem.dofnames.index("u")]]  # (nnodes, g)
    result = []
    for sign in (1.0, -1.0):
        sub = _reflection_space(w, w[_mirror(basis.mesh.p, 0)], sign)
        if sub.shape[1] > 1:
            sub = sub @ np.hstack(
                [_reflection_space(w @ sub, w[_mirror(basis.mesh.p, 1)] @ sub, s) for s in (1.0, -1.0)]
            )
        result.append(sub)
    return group @ np.hstack(result)


def _mirror(p: np.ndarray, axis: int) -> np.ndarray:
    """Index of each node's mirror image across the axis through the centre (x -> -x for 0)."""
    key = {tuple(np.round(q, 9)): i for i, q in enumerate(p.T)}
    flip = p.copy()
    flip[axis] *= -1
    return np.array([key[tuple(np.round(q, 9))] for q in flip.T])


def _reflection_space(here: np.ndarray, mirrored: np.ndarray, sign: float) -> np.ndarray:
    """Orthonormal coefficients of the group members with w(mirror) = sign * w: the eigenvectors
    of the least-squares reflection matrix with eigenvalue `sign`."""
    t = np.linalg.lstsq(here, mirrored, rcond=None)[0]
    vals, vecs = np.linalg.eigh(0.5 * (t + t.T))
    return vecs[:, np.abs(vals - sign) < 0.5]


def _normalise(basis: CellBasis, vectors: np.ndarray) -> np.ndarray:
    """Peak |w| = 1 over the mesh nodes; sign from the node of largest |w| (ties: largest x, y)."""
    nodal = basis.nodal_dofs[basis.elem.dofnames.index("u")]
    w = vectors[nodal]  # (nnodes, nmodes)
    p = basis.mesh.p
    out = vectors.copy()
    for k in range(w.shape[1]):
        peak = np.abs(w[:, k]).max()
        near = np.flatnonzero(np.abs(w[:, k]) > (1 - 1e-6) * peak)
        pick = near[np.lexsort((np.round(p[1, near], 15), np.round(p[0, near], 15)))[-1]]
        out[:, k] = vectors[:, k] / w[pick, k]
    return out


def _orthogonality(basis: CellBasis, M, phi: np.ndarray, mass: np.ndarray, stiff: np.ndarray) -> dict[str, float]:
    """M-cosines of the modes with the rigid fields 1, x, y (free edges: zero up to round-off) and
    the largest relative modal cross terms."""
    x, y = basis.mesh.p
    nodal = basis.nodal_dofs
    names = basis.elem.dofnames
    rigid = np.zeros((basis.N, 3))
    rigid[nodal[names.index("u")], 0] = 1.0
    rigid[nodal[names.index("u")], 1] = x
    rigid[nodal[names.index("u_x")], 1] = 1.0
    rigid[nodal[names.index("u")], 2] = y
    rigid[nodal[names.index("u_y")], 2] = 1.0
    mr = np.sqrt(np.einsum("dk,dk->k", rigid, M @ rigid))
    mp = np.sqrt(np.einsum("dk,dk->k", phi, M @ phi))
    cos = np.abs(rigid.T @ (M @ phi)) / np.outer(mr, mp)
    return {
        "phi": float(cos[0].max()),
        "x_phi": float(cos[1].max()),
        "y_phi": float(cos[2].max()),
        "mass_offdiag": _offdiag(mass),
        "stiffness_offdiag": _offdiag(stiff),
    }


def _offdiag(matrix: np.ndarray) -> float:
    """Largest |A_ij| / sqrt(A_ii A_jj), i != j (0 for one mode)."""
    d = np.sqrt(np.diag(matrix))
    return float(np.abs(np.abs(matrix) / np.outer(d, d) - np.eye(len(d))).max())


ELEMENTS = 24  # BFS elements along the length of a proof mass (the first 12 free modes to ~1e-5)


def conductor_plate(c) -> EffectivePlate:
    """A proof mass's effective plate: the density factor is its actual solid fraction
    (ProofMass.fill_factor, which its rigid mass and participation use too, also when the hole grid
    does not fill whole pitches), the stiffness factor the hole grid's series strips."""
    return replace(EffectivePlate.of_holes(c.hole, c.hole_pitch), density_factor=c.fill_factor)


def conductor_modes(c, count: int) -> RectPlateModes:
    """The first `count` internal modes of a proof mass (free edges, etch holes as the effective
    plate of the module docstring)."""
    plate = PlateSpec(c.length, c.width, c.thickness, c.youngs_modulus, c.poisson_ratio, c.density)
    return rect_plate_modes(
        plate,
        count,
        ELEMENTS,
        "free",
        conductor_plate(c),
    )
