"""The BEM's meshes keep the reference disk's symmetry (netgen.electrostatics.bem_mesh: sectors
meshed by halves and reflected, a disk plate dihedral through dihedral_order): sectors equal by
symmetry get congruent meshes, and in a small dense solve the four inner sectors' capacitances
agree to the solve's rounding (docs/bem.md, 'Symmetric meshes').
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from netgen.electrostatics import bem
from netgen.electrostatics.bem_mesh import Surface, dihedral_order, electrode_sheet, plate_face
from netgen.geometry.shapes import AnnularSector, Electrode, Rectangle
from tests.oracles.small_disk import reference_layout

R = 100e-6
EPS = np.finfo(float).eps
# Vertex positions are r cos(theta), r sin(theta) with theta a sum of two angles below 2 pi (4 pi eps
# of rounding), cos and sin within an ulp each, and the test's rotation adds two more ulps: images
# of one node agree within (4 pi + 4) eps R = 3.7e-15 R; 1e-14 R leaves a factor 2.7.
TOL = 1e-14 * R


def moved(s: Surface, angle: float = 0.0, mirror: bool = False) -> np.ndarray:
    """The surface's vertices mirrored (y -> -y, if asked) then rotated by angle about z."""
    v = s.vertices.copy()
    if mirror:
        v[:, 1] = -v[:, 1]
    c, sn = math.cos(angle), math.sin(angle)
    return np.column_stack([c * v[:, 0] - sn * v[:, 1], sn * v[:, 0] + c * v[:, 1], v[:, 2]])


def congruent(a: Surface, vertices: np.ndarray, triangles: np.ndarray) -> bool:
    """The triangles over `vertices` are a's triangles: a node-to-node map within TOL, one to one,
    that carries the triangle sets onto each other (each triangle as a set of nodes)."""
    if len(vertices) != len(a.vertices) or len(triangles) != len(a.triangles):
        return False
    dist, idx = cKDTree(a.vertices).query(vertices)
    if dist.max() > TOL or len(np.unique(idx)) != len(idx):
        return False
    mine = {frozenset(t) for t in idx[triangles].tolist()}
    return mine == {frozenset(t) for t in a.triangles.tolist()}


def levels(gap: float) -> list:
    """The element sizes of the bench's two mesh levels at g/R = 0.02 (edge 0.5, element 3 gaps)."""
    st = bem.BemSettings(edge_to_gap=0.5, element_to_gap=3.0)
    return [st.sizes(gap, k, R) for k in range(2)]


@pytest.mark.parametrize("level", [0, 1])
def test_sectors_equal_by_symmetry_have_congruent_meshes(level):
    """Each ring's four sectors: sector k rotated back by k pi / 2 is sector 0 (nodes within TOL,
    the same triangles), each sector is its own mirror image about its bisector, and the plate face
    is carried onto itself by the quarter turn and by y -> -y (the layout's dihedral group D4)."""
    gap = 0.02 * R
    plate, els = reference_layout(gap, R)
    sizes = levels(gap)[level]
    assert dihedral_order(tuple(els)) == 4
    for ring in (0, 1):
        sheets = [electrode_sheet(e, sizes, gap) for e in els[4 * ring : 4 * ring + 4]]
        for k, s in enumerate(sheets):
            assert congruent(sheets[0], moved(s, -k * math.pi / 2), s.triangles), (ring, k)
            shape = els[4 * ring + k].shape
            bisector = 0.5 * (shape.theta_start + shape.theta_end)
            assert congruent(s, moved(s, 2 * bisector, mirror=True), s.triangles), (ring, k, "mirror")
    face = plate_face(plate, sizes, dihedral_order(tuple(els)))
    assert congruent(face, moved(face, math.pi / 2), face.triangles)
    assert congruent(face, moved(face, mirror=True), face.triangles)


def test_dihedral_plate_face_is_conforming():
    """The plate face built from one wedge: every edge in one or two triangles, the one-triangle
    edges exactly the rim (both ends at radius R), every node used, one orientation, and the area
    of the inscribed polygons (within the chords' loss, at most (pi^2 / 6) (h / R)^2 of the disk)."""
    sizes = levels(0.02 * R)[0]
    for wedges in (1, 3, 4, 8):
        face = plate_face(reference_layout(0.02 * R, R)[0], sizes, wedges)
        t = face.triangles
        edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
        uniq, count = np.unique(edges, axis=0, return_counts=True)
        assert count.max() == 2 and len(np.unique(t)) == len(face.vertices)
        rim = np.hypot(*face.vertices[uniq[count == 1]][:, :, :2].transpose(2, 0, 1))
        assert np.allclose(rim, R, rtol=1e-12)
        p = face.vertices[t]
        assert (np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])[:, 2] > 0).all()
        loss = 1.0 - face.areas().sum() / (math.pi * R * R)
        assert 0.0 < loss < math.pi**2 / 6 * (sizes.h_max / R) ** 2


def test_dihedral_order_of_layouts():
    """The largest dihedral group of a layout: the reference layout's 2 x 4 quadrants D4, eight 45
    degree sectors D8, one sector off its place or a rectangle off the axis 1, a full ring 8 (the cap)."""
    gap = 2e-6
    _, els = reference_layout(gap, R)
    assert dihedral_order(tuple(els)) == 4
    eight = tuple(
        Electrode(AnnularSector(f"s{k}", 20e-6, R, k * math.pi / 4, (k + 1) * math.pi / 4, 2e-6), "above", gap)
        for k in range(8)
    )
    assert dihedral_order(eight) == 8
    shifted = (*els[:-1], Electrode(AnnularSector("x", 50e-6, R, 1.4, 2.9, 1e-6), "above", gap))
    assert dihedral_order(shifted) == 1
    assert dihedral_order((Electrode(AnnularSector("ring", 0.0, R, 0.0, 2 * math.pi), "above", gap),)) == 8
    assert dihedral_order((Electrode(Rectangle("r", 1e-6, 5e-6, -2e-6, 2e-6), "above", gap),)) == 1
    square = Electrode(Rectangle("q", -5e-6, 5e-6, -5e-6, 5e-6), "above", gap)
    assert dihedral_order((square,)) == 4


def test_four_inner_sectors_agree_to_rounding():
    """A small dense solve of the reference layout (g/R = 0.1, 1-4 gap elements, about 1k unknowns):
    the four inner (and outer) sectors' C agree to the solve's rounding. The configuration is
    carried onto itself by the quarter turn up to the node rounding (TOL), so the single-layer
    matrix is permuted onto itself up to entries perturbed by at most TOL / h_edge relative (the
    kernel 1/r at r >= h_edge, the smallest element) and LU's backward error N eps; C's relative
    spread is then below cond(A) (TOL / h_edge + N eps), about 8e-10 here. The meshes before this
    check (592 unknowns then 566) spread by 3.4e-5 (inner) and 3.9e-4 (outer; docs/bem.md)."""
    pytest.importorskip("bempp_cl")
    from netgen.core.constants import EPS0

    gap = 0.1 * R
    plate, els = reference_layout(gap, R)
    st = bem.BemSettings(edge_to_gap=1.0, element_to_gap=4.0, levels=1, max_levels=1)

    def rigid(x, y):
        """The plate's rigid z and tilt_x."""
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        return np.stack([np.ones_like(x), y], axis=1)

    p = bem.BemExtractor(eps=EPS0, settings=st).prepare(els, plate, rigid)
    surfaces = p.surfaces(np.zeros(2), 0)
    A, B = bem.single_layer(surfaces, bem.quadrature_order(st.element_to_gap))
    bound = np.linalg.cond(A) * (TOL / st.sizes(gap, 0, R).h_edge + len(A) * EPS)
    assert bound < 1e-6  # the check can see a mesh asymmetry (1e-4)
    c = -(EPS0 * B.T @ bem.dense_solve(A.copy(), B))[0, 1:]
    for ring in (c[:4], c[4:]):
        assert np.ptp(ring) / ring.mean() < bound
