"""A small 3-D frame solver: Euler-Bernoulli beam elements (axial, torsion, bending about both
cross-section axes; 12 DOF per element: u, v, w, rx, ry, rz at each end) in numpy, for the
stiffness of flexures (netgen.mechanics.flexures) independently of their closed forms.

A frame is a list of straight members between nodes; nodes are clamped (anchors), free, or
tied rigidly to one master body (the proof mass). `body_stiffness` condenses the frame onto
the master's six rigid-body DOF (x, y, z, rx, ry, rz about a reference point): the 6x6
stiffness the suspended body feels. Shear deformation is neglected (slender beams).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def torsion_constant(a: float, b: float) -> float:
    """Saint-Venant torsion constant J of an a x b rectangle (Roark's series fit, within ~0.5 %
    for any aspect ratio): J = A B^3 (1/3 - 0.21 (B/A) (1 - B^4 / (12 A^4))), A >= B."""
    big, small = max(a, b), min(a, b)
    return big * small**3 * (1.0 / 3.0 - 0.21 * small / big * (1.0 - small**4 / (12.0 * big**4)))


@dataclass(frozen=True)
class Section:
    """A rectangular cross-section: in-plane width w (along the local y axis) and thickness t
    (along global z), Young's modulus E and shear modulus G."""

    width: float
    thickness: float
    youngs_modulus: float
    shear_modulus: float

    @property
    def area(self) -> float:
        return self.width * self.thickness

    @property
    def i_inplane(self) -> float:
        """Second moment for in-plane bending (about the local z axis): t w^3 / 12."""
        return self.thickness * self.width**3 / 12.0

    @property
    def i_vertical(self) -> float:
        """Second moment for out-of-plane bending (about the local y axis): w t^3 / 12."""
        return self.width * self.thickness**3 / 12.0

    @property
    def torsion(self) -> float:
        return torsion_constant(self.width, self.thickness)


def local_stiffness(s: Section, length: float) -> np.ndarray:
    """The 12x12 element stiffness in local axes (x along the member, z vertical)."""
    e, g, L = s.youngs_modulus, s.shear_modulus, length
    k = np.zeros((12, 12))
    ea, gj = e * s.area / L, g * s.torsion / L
    for a, v in ((0, ea), (3, gj)):  # axial u, torsion rx
        k[a, a] = k[a + 6, a + 6] = v
        k[a, a + 6] = k[a + 6, a] = -v
    for w, r, ei, sign in ((1, 5, e * s.i_inplane, 1.0), (2, 4, e * s.i_vertical, -1.0)):
        a = np.array(
            [
                [12, 6 * L * sign, -12, 6 * L * sign],
                [6 * L * sign, 4 * L * L, -6 * L * sign, 2 * L * L],
                [-12, -6 * L * sign, 12, -6 * L * sign],
                [6 * L * sign, 2 * L * L, -6 * L * sign, 4 * L * L],
            ]
        )
        dofs = [w, r, w + 6, r + 6]
        k[np.ix_(dofs, dofs)] += ei / L**3 * a
    return k


def rotation(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """3x3 direction cosines (rows: local x, y, z in global axes) of an in-plane member."""
    ex = (p1 - p0) / np.linalg.norm(p1 - p0)
    ez = np.array([0.0, 0.0, 1.0])
    ey = np.cross(ez, ex)
    return np.stack([ex, ey, ez])


@dataclass
class Frame:
    """Nodes (m), members (node pairs, sections, subdivisions), clamped and body-tied nodes."""

    nodes: list[np.ndarray] = field(default_factory=list)
    members: list[tuple[int, int, Section]] = field(default_factory=list)
    clamped: set[int] = field(default_factory=set)
    tied: set[int] = field(default_factory=set)

    def node(self, x: float, y: float, z: float = 0.0) -> int:
        """The index of the node at (x, y, z), added if new (within 1e-12 m)."""
        p = np.array([x, y, z], dtype=float)
        for i, q in enumerate(self.nodes):
            if np.allclose(p, q, rtol=0.0, atol=1e-12):
                return i
        self.nodes.append(p)
        return len(self.nodes) - 1

    def member(self, a: tuple[float, float], b: tuple[float, float], section: Section, elements: int = 8) -> None:
        """A straight member from a to b (in the plane), split into `elements` beam elements."""
        pa, pb = np.array([*a, 0.0]), np.array([*b, 0.0])
        ids = [self.node(*(pa + (pb - pa) * k / elements)) for k in range(elements + 1)]
        for i, j in zip(ids[:-1], ids[1:]):
            self.members.append((i, j, section))

    def stiffness(self) -> np.ndarray:
        """The assembled global stiffness (6 DOF per node)."""
        n = len(self.nodes)
        k = np.zeros((6 * n, 6 * n))
        for i, j, s in self.members:
            r = rotation(self.nodes[i], self.nodes[j])
            t = np.kron(np.eye(4), r)
            ke = t.T @ local_stiffness(s, float(np.linalg.norm(self.nodes[j] - self.nodes[i]))) @ t
            dofs = np.r_[6 * i : 6 * i + 6, 6 * j : 6 * j + 6]
            k[np.ix_(dofs, dofs)] += ke
        return k

    def body_stiffness(self, centre: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
        """6x6 stiffness (x, y, z, rx, ry, rz) of a rigid body tied to the `tied` nodes, the
        `clamped` nodes fixed, every other node condensed out (static condensation)."""
        n = len(self.nodes)
        free = [i for i in range(n) if i not in self.clamped and i not in self.tied]
        cols = 6 + 6 * len(free)
        p = np.zeros((6 * n, cols))
        c = np.asarray(centre, dtype=float)
        for i in self.tied:
            r = self.nodes[i] - c
            link = np.eye(6)
            link[:3, 3:] = -np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])  # u = u0 + theta x r
            p[6 * i : 6 * i + 6, :6] = link
        for k, i in enumerate(free):
            p[6 * i : 6 * i + 6, 6 + 6 * k : 12 + 6 * k] = np.eye(6)
        kr = p.T @ self.stiffness() @ p
        kmm, kmf, kff = kr[:6, :6], kr[:6, 6:], kr[6:, 6:]
        return kmm - kmf @ np.linalg.solve(kff, kmf.T) if kff.size else kmm
