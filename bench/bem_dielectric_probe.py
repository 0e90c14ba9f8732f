"""Why the dense BEM (bempp-cl) refuses a dielectric layer: the polarisation-charge formulation
FastCap uses, tried on bempp's Galerkin P0 operators, on the guarded layered electrode.

    .venv/bin/python bench/bem_dielectric_probe.py --eps-r 7.5 --layer 0.2 --sense 20
    .venv/bin/python bench/bem_dielectric_probe.py --eps-r 7.5 --layer 0.2 --sense 20 --order 12
    .venv/bin/python bench/bem_dielectric_probe.py --eps-r 7.5 --layer 1.0 --sense 8 --element-to-gap 1

The formulation: total (free + polarisation) charge sigma on every surface in vacuum; on a
conductor the single layer S sigma = eps0 V; on a dielectric interface (normal n towards eps+)
the normal D continuous, eps+ E+ = eps- E-, which with E+- = (+-sigma / 2 - K' sigma) / eps0
(K': bempp's adjoint double layer) is (eps+ + eps-) / 2 sigma - (eps+ - eps-) K' sigma = 0; the
same operator on a conductor sheet (eps+ on its face in the layer, eps- behind) gives its free
charge, so the electrode under the layer can stay a sheet. The guarded electrode (a plate of
sense + 2 guard over an electrode split into the sense square and its guard ring, the layer's
face and walls an interface) has the closed form eps0 sense^2 / (g - t_d + t_d / eps_r).
Printed per mesh level: unknowns, C_sense over the closed form - 1, the Maxwell matrix's
asymmetry max |C - C^T| / max |C| (0 for a correct free charge), CPU seconds.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.linalg import lu_factor, lu_solve

from netgen.core.constants import EPS0
from netgen.electrostatics import fastcap
from netgen.electrostatics.fastcap_mesh import Panels, layered_panels, rect_panels
from netgen.geometry.shapes import Electrode, Rectangle

UM = 1e-6


def tris(p: Panels) -> np.ndarray:
    """Quads (n, 4, 3) -> triangles (2n, 3, 3), the quads' orientation kept."""
    c = p.corners
    return np.concatenate([c[:, [0, 1, 2]], c[:, [0, 2, 3]]])


def solve(parts: list, order: int) -> tuple[np.ndarray, int]:
    """Maxwell matrix of free charges; parts: (triangles, conductor index or -1, eps+, eps-)."""
    import bempp_cl.api as bempp
    from bempp_cl.api.utils.parameters import DefaultParameters

    t = np.concatenate([p[0] for p in parts])
    v, inv = np.unique(np.round(t.reshape(-1, 3) / 1e-12).astype(np.int64), axis=0, return_inverse=True)
    grid = bempp.Grid((v * 1e-12).T, inv.reshape(-1, 3).T.astype(np.uint32))
    space = bempp.function_space(grid, "DP", 0)
    prm = DefaultParameters()
    prm.quadrature.regular = order
    kw = dict(parameters=prm, assembler="dense", device_interface="numba", precision="double")
    lap = bempp.operators.boundary.laplace
    S = np.asarray(lap.single_layer(space, space, space, **kw).weak_form().to_dense())
    K = np.asarray(lap.adjoint_double_layer(space, space, space, **kw).weak_form().to_dense())
    owner = np.concatenate([np.full(len(p[0]), p[1]) for p in parts])
    ep, em = np.concatenate([p[2] for p in parts]), np.concatenate([p[3] for p in parts])
    a = np.asarray(grid.volumes)
    F = np.diag(a * (ep + em) / 2) - (ep - em)[:, None] * K  # free charge per element
    A = np.where((owner >= 0)[:, None], S, F)
    n = owner.max() + 1
    B = np.zeros((len(a), n))
    idx = np.flatnonzero(owner >= 0)
    B[idx, owner[idx]] = a[idx]
    Q = F @ lu_solve(lu_factor(A), B)
    return np.stack([Q[owner == i].sum(axis=0) for i in range(n)]), len(a)


def level(k: int, a) -> list:
    """Mesh level k of the guarded layered electrode: plate, sense, guard, interface."""
    g, t_d, eps_d = a.gap * UM, a.layer * UM, a.eps_r * EPS0
    st = fastcap.FastcapSettings(edge_to_gap=a.edge_to_gap, element_to_gap=a.element_to_gap)
    sz = st.sizes(g - t_d, k)
    s, c = a.sense * UM / 2, a.sense * UM / 2 + a.guard * UM
    box = layered_panels(Electrode(Rectangle("g", -c, c, -c, c), "below", g, "g", t_d, a.eps_r), sz, 0.0, 1.0)
    sense = tris(rect_panels(-s, s, -s, s, sz, 0.0))
    ring = np.concatenate(
        [tris(rect_panels(*p, sz, 0.0)) for p in [(-c, c, -c, -s), (-c, c, s, c), (-c, -s, -s, s), (s, c, -s, s)]]
    )
    plate = tris(rect_panels(-c, c, -c, c, sz, g))
    parts = [(plate, 0, np.full(len(plate), EPS0), np.full(len(plate), EPS0))]
    for t, i in ((sense, 1), (ring, 2)):
        up = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])[:, 2] > 0
        parts.append((t, i, np.where(up, eps_d, EPS0), np.where(up, EPS0, eps_d)))
    top = np.concatenate([sense, ring])
    top[:, :, 2] += t_d
    n_top = len(rect_panels(-c, c, -c, c, sz, 0.0))
    walls, refs = box.interface.corners[n_top:], box.refs[n_top:]
    it = np.concatenate([top, walls[:, [0, 1, 2]], walls[:, [0, 2, 3]]])
    ref = np.concatenate([top.mean(axis=1) - [0.0, 0.0, t_d / 2], refs, refs])
    n = np.cross(it[:, 1] - it[:, 0], it[:, 2] - it[:, 0])
    into = np.einsum("ij,ij->i", n, ref - it.mean(axis=1)) > 0  # the normal points into the layer
    parts.append((it, -1, np.where(into, eps_d, EPS0), np.where(into, EPS0, eps_d)))
    return parts


def main() -> None:
    """Solve both mesh levels and print the figures (module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--eps-r", type=float, default=7.5)
    ap.add_argument("--layer", type=float, default=0.2, help="um")
    ap.add_argument("--gap", type=float, default=2.0, help="um")
    ap.add_argument("--sense", type=float, default=20.0, help="um")
    ap.add_argument("--guard", type=float, default=8.0, help="um")
    ap.add_argument("--edge-to-gap", type=float, default=0.5)
    ap.add_argument("--element-to-gap", type=float, default=2.0)
    ap.add_argument("--order", type=int, default=4, help="bempp's regular quadrature order")
    a = ap.parse_args()
    ref = EPS0 * (a.sense * UM) ** 2 / ((a.gap - a.layer + a.layer / a.eps_r) * UM)
    for k in range(2):
        t = time.process_time()
        C, n = solve(level(k, a), a.order)
        asym = np.max(np.abs(C - C.T)) / np.max(np.abs(C))
        print(
            f"level {k}: {n} unknowns, C_sense / closed form - 1 = {-C[0, 1] / ref - 1:+.4f}, "
            f"asymmetry {asym:.2e}, {time.process_time() - t:.1f} s CPU",
            flush=True,
        )


if __name__ == "__main__":
    main()
