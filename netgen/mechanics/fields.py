"""Piecewise-quadratic fields on triangle meshes of the unit disk (the Morley plate modes, and
imported mode shapes on quadratic triangles), evaluated vectorised at arbitrary points."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree
from skfem import CellBasis, MeshTri

P2_NODES = np.array([[0.0, 1.0, 0.0, 0.5, 0.5, 0.0], [0.0, 0.0, 1.0, 0.0, 0.5, 0.5]])


@dataclass(frozen=True)
class P2Field:
    """Piecewise-quadratic (Morley) fields on a triangle mesh of the unit disk, vectorised."""

    origin: np.ndarray  # (ne, 2) first vertex of each triangle
    inverse: np.ndarray  # (ne, 2, 2) inverse affine map physical -> reference
    nodes: np.ndarray  # (ne, 6, ncols) field values at the P2 nodes
    tree: cKDTree  # centroids, to find candidate triangles
    rim_angles: np.ndarray  # sorted boundary-vertex angles, closed (+2 pi)
    rim_points: np.ndarray  # (nb + 1, 2) boundary vertices in that order, closed

    def combine(self, coefficients: np.ndarray) -> P2Field:
        """Field of the linear combinations ``nodes @ coefficients`` (same mesh)."""
        return P2Field(
            self.origin, self.inverse, self.nodes @ coefficients, self.tree, self.rim_angles, self.rim_points
        )

    def inside(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Project points radially onto the mesh polygon if they lie beyond its boundary."""
        r = np.hypot(x, y)
        theta = np.mod(np.arctan2(y, x), 2 * np.pi)
        k = np.clip(np.searchsorted(self.rim_angles, theta, side="right") - 1, 0, len(self.rim_angles) - 2)
        p, q = self.rim_points[k], self.rim_points[k + 1]
        edge = q - p
        u = np.stack([np.cos(theta), np.sin(theta)], axis=1)
        chord = (p[:, 0] * edge[:, 1] - p[:, 1] * edge[:, 0]) / (u[:, 0] * edge[:, 1] - u[:, 1] * edge[:, 0])
        r = np.minimum(r, chord * (1 - 1e-12))
        return r * u[:, 0], r * u[:, 1]

    def __call__(self, x: np.ndarray, y: np.ndarray, chunk: int = 50_000) -> np.ndarray:
        """Values (npts, ncols) at unit-disk points (|r| <= 1 + tolerance), in chunks."""
        x, y = self.inside(np.ravel(x).astype(float), np.ravel(y).astype(float))
        pts = np.stack([x, y], axis=1)
        parts = [self._evaluate(pts[i : i + chunk]) for i in range(0, len(pts), chunk)]
        return np.concatenate(parts) if parts else np.zeros((0, self.nodes.shape[-1]))

    def _evaluate(self, pts: np.ndarray) -> np.ndarray:
        """P2 interpolation at points already inside the mesh polygon."""
        cells, bary = self._locate(pts)
        l0, l1, l2 = bary
        basis = np.stack(
            [l0 * (2 * l0 - 1), l1 * (2 * l1 - 1), l2 * (2 * l2 - 1), 4 * l0 * l1, 4 * l1 * l2, 4 * l0 * l2], axis=1
        )
        return np.einsum("pk,pkm->pm", basis, self.nodes[cells])

    def _locate(self, pts: np.ndarray) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
        """Containing triangle and barycentrics: the best of the nearest centroids."""
        k = min(12, len(self.origin))
        _, cand = self.tree.query(pts, k)
        cand = cand.reshape(len(pts), k)
        ref = np.einsum("pkij,pkj->pki", self.inverse[cand], pts[:, None, :] - self.origin[cand])
        bary = np.stack([1 - ref[..., 0] - ref[..., 1], ref[..., 0], ref[..., 1]], axis=-1)
        best = np.argmax(bary.min(axis=-1), axis=1)
        rows = np.arange(len(pts))
        b = bary[rows, best]
        return cand[rows, best], (b[:, 0], b[:, 1], b[:, 2])


def p2_field(basis: CellBasis, vectors: np.ndarray) -> P2Field:
    """Exact per-element P2 representation of Morley DOF vectors (ndofs, ncols)."""
    mesh = basis.mesh
    nodal = CellBasis(mesh, basis.elem, quadrature=(P2_NODES, np.full(6, 1 / 6)))
    phi = np.stack([np.asarray(nodal.basis[k][0]) for k in range(nodal.Nbfun)])  # (6dof, ne, 6pt)
    dofs = vectors[nodal.element_dofs]  # (6dof, ne, ncols)
    nodes = np.einsum("dep,dem->epm", phi, dofs)
    p, t = mesh.p, mesh.t
    a = np.stack([p[:, t[1]] - p[:, t[0]], p[:, t[2]] - p[:, t[0]]], axis=-1)  # (2, ne, 2)
    inverse = np.linalg.inv(np.moveaxis(a, 0, 1))
    return P2Field(
        origin=p[:, t[0]].T, inverse=inverse, nodes=nodes, tree=cKDTree(p[:, t].mean(axis=1).T), **rim_polygon(mesh)
    )


def rim_polygon(mesh: MeshTri) -> dict[str, np.ndarray]:
    """Boundary vertices of the disk mesh sorted by angle and closed, for projection."""
    b = mesh.boundary_nodes()
    angles = np.mod(np.arctan2(mesh.p[1, b], mesh.p[0, b]), 2 * np.pi)
    order = np.argsort(angles)
    points = mesh.p[:, b[order]].T
    return {
        "rim_angles": np.append(angles[order], angles[order[0]] + 2 * np.pi),
        "rim_points": np.vstack([points, points[:1]]),
    }
