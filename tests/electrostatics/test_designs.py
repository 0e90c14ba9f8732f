"""Checks of the sample designs (netgen.electrostatics.designs).

References: the published point counts of Smolyak grids on nested Clenshaw-Curtis nodes
(Gerstner and Griebel 1998, table 1; Novak and Ritter 1996: 2d + 1, 2d^2 + 2d + 1,
(4d^3 + 6d^2 + 14d + 3)/3 at levels 1-3), exact integrals of monomials over the cube, and the
defining stratification of Latin hypercubes and of Sobol (0, m, s)-nets.
"""

from __future__ import annotations

import numpy as np
import pytest

from netgen.electrostatics import designs
from netgen.electrostatics.sampling import design_points
from netgen.structure import StructureError, parse_structure
from tests.fixtures import ROOT

# Gerstner and Griebel (1998), Numerical integration using sparse grids, table 1 (CC, levels 0..4)
PUBLISHED = {2: [1, 5, 13, 29, 65], 3: [1, 7, 25, 69, 177], 10: [1, 21, 221, 1581, 8801]}


@pytest.mark.parametrize("d", sorted(PUBLISHED))
def test_smolyak_counts_match_the_published_table(d):
    assert [designs.smolyak_count(d, level) for level in range(5)] == PUBLISHED[d]
    assert [len(designs.smolyak_points(d, level)) for level in range(4)] == PUBLISHED[d][:4]


@pytest.mark.parametrize("d", [1, 4, 7, 11, 12])
def test_smolyak_counts_match_the_closed_forms(d):
    assert designs.smolyak_count(d, 1) == 2 * d + 1
    assert designs.smolyak_count(d, 2) == 2 * d * d + 2 * d + 1
    assert 3 * designs.smolyak_count(d, 3) == 4 * d**3 + 6 * d**2 + 14 * d + 3
    pts = designs.smolyak_points(d, 3 if d < 12 else 2)
    assert len(np.unique(pts, axis=0)) == len(pts), "the disjoint union has no repeated point"
    assert np.abs(pts).max() == 1.0


def _mean_of_monomial(e: np.ndarray) -> float:
    """Exact mean of prod x_v^e_v over [-1, 1]^d: prod 1/(e_v + 1) for even e_v, else 0."""
    return 0.0 if np.any(e % 2) else float(np.prod(1.0 / (e + 1.0)))


@pytest.mark.parametrize("d,level", [(2, 1), (2, 3), (3, 2), (5, 2), (4, 3)])
def test_smolyak_quadrature_is_exact_to_total_degree_2l_plus_1(d, level):
    """Exact for every monomial of total degree <= 2 level + 1; x_1^2 x_2^(2 level), of total
    degree 2 level + 2 and outside the exactness space, is not integrated exactly."""
    pts, w = designs.smolyak_quadrature(d, level)
    rng = np.random.default_rng(d * 10 + level)
    for _ in range(60):
        e = np.zeros(d, dtype=int)
        for _ in range(rng.integers(0, 2 * level + 2)):
            e[rng.integers(d)] += 1
        assert np.sum(w * np.prod(pts**e, axis=1)) == pytest.approx(_mean_of_monomial(e), abs=1e-12), e
    e = np.zeros(d, dtype=int)
    e[0], e[1] = 2, 2 * level
    assert abs(np.sum(w * np.prod(pts**e, axis=1)) - _mean_of_monomial(e)) > 1e-4


def test_latin_hypercube_has_one_point_per_slice_and_is_seeded():
    x = designs.latin_hypercube(7, 64, 0.2, seed=3)
    assert np.abs(x).max() <= 0.2
    slices = np.floor((x / 0.2 + 1.0) / 2.0 * 64).astype(int)
    for v in range(7):
        assert sorted(slices[:, v]) == list(range(64)), f"coordinate {v}"
    assert np.array_equal(x, designs.latin_hypercube(7, 64, 0.2, seed=3))
    assert not np.array_equal(x, designs.latin_hypercube(7, 64, 0.2, seed=4))


def test_sobol_points_form_a_net():
    """2^m scrambled Sobol points: one in each of the 2^m slices of every coordinate, and one in
    each elementary box 2^-j x 2^-(m-j) of the first two coordinates (a (0, m, 2)-net)."""
    m = 7
    u = (designs.sobol(5, 2**m, 1.0, seed=11) + 1.0) / 2.0
    for v in range(5):
        assert sorted(np.floor(u[:, v] * 2**m).astype(int)) == list(range(2**m))
    for j in range(m + 1):
        cells = np.floor(u[:, 0] * 2**j).astype(int) * 2 ** (m - j) + np.floor(u[:, 1] * 2 ** (m - j)).astype(int)
        assert len(set(cells)) == 2**m, f"box 2^-{j} x 2^-{m - j}"
    assert np.array_equal(u, (designs.sobol(5, 2**m, 1.0, seed=11) + 1.0) / 2.0)


def _structure(sampling: str, modes: str = '["2,0c", "2,0s", "3,0c", "3,0s"]'):
    text = (ROOT / "examples/levitated_disk.toml").read_text()
    text = text.replace("levels = 3        # 3^7 = 2187 samples, as in the paper\n", sampling + "\n")
    text = text.replace('modes = ["2,0c", "2,0s", "3,0c", "3,0s"]', f"modes = {modes}")
    return parse_structure(text, "designs.toml")


def test_the_default_design_is_the_grid_up_to_seven_coordinates_and_sparse_above():
    grid = _structure("")
    assert grid.sampling.design == "grid" and len(design_points(grid.sampling, 7)) == 3**7
    sparse = _structure("", modes="8")
    assert sparse.sampling.design == "sparse" and sparse.sampling.level == 2
    assert len(design_points(sparse.sampling, 11)) == 2 * 11**2 + 2 * 11 + 1


@pytest.mark.parametrize(
    "sampling,key,words",
    [
        ('design = "random"', "sampling.design", "grid"),
        ('design = "sparse"\nlevels = 5', "sampling.levels", 'set design = "grid"'),
        ('design = "grid"\nlevel = 3', "sampling.level", 'set design = "sparse"'),
        ('design = "lhs"\nlevel = 3', "sampling.level", "does not apply"),
        ('design = "sobol"\npoints = 300', "sampling.points", "points = 256 or 512"),
        ('design = "sparse"\nlevel = 6', "sampling.level", "2098753 points"),
        ('design = "adaptive"\npoints = 3', "sampling.points", "8.."),
    ],
)
def test_bad_sampling_keys_name_the_key_and_the_fix(sampling, key, words):
    with pytest.raises(StructureError) as info:
        _structure(sampling, modes="13")
    text = str(info.value)
    assert "designs.toml" in text and key in text and words in text, text
