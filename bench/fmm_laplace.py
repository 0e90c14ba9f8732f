"""fmm3dpy against FastCap2 on the same panels: two coaxial unit disks at d/a (0.05, 0.02) against
Love's equation (closed_forms.love_disks), the Maxwell matrix from each solver on the extractor's
two default mesh levels (fastcap_mesh.polar_panels), C00 - C01 per level and Richardson-extrapolated
(order 2, as fastcap.converged), with CPU seconds and peak RSS per solver (each in its own process).

The fmm3dpy side is this file's collocation BEM: a constant charge density per flat panel,
collocated at the panel centroids; the far field is `points` Gauss points per panel (1: the
centroid; 4: 2 x 2 on the bilinear map) summed by fmm3dpy.lfmm3d, and every pair closer than `near`
source-panel diameters is replaced by the exact integral of 1/(4 pi r) over the flat panel
(panel_potential, Wilton et al. 1984); scipy's GMRES, Jacobi-preconditioned (the self term), solves
each column. fmm3dpy is not a project dependency (docs/fastcap.md, 'Why FastCap2 and not fmm3dpy'):

    .venv/bin/python -m pip install --target /tmp/fmmlib --no-deps fmm3dpy
    PYTHONPATH=/tmp/fmmlib nice -n 10 env OMP_NUM_THREADS=1 .venv/bin/python bench/fmm_laplace.py
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.linalg import LinearOperator, gmres
from scipy.spatial import cKDTree
from support import closed_forms

from netgen.core.constants import EPS0
from netgen.electrostatics import fastcap
from netgen.electrostatics.fastcap_mesh import Panels, polar_panels

FMM_MISSING = (
    "bench/fmm_laplace.py needs fmm3dpy, which is not a project dependency (not in the lock); install it "
    "outside the venv: .venv/bin/python -m pip install --target /tmp/fmmlib --no-deps fmm3dpy, then run "
    "with PYTHONPATH=/tmp/fmmlib"
)


def _fmm():
    """The fmm3dpy module, or exit naming the missing package and how to get it."""
    try:
        import fmm3dpy
    except ImportError:
        sys.exit(FMM_MISSING)
    return fmm3dpy


def disk_levels(kappa: float) -> list[list[Panels]]:
    """The extractor's two default mesh levels of two coaxial unit disks kappa apart (as fastcap_love.py)."""
    st = fastcap.FastcapSettings()
    out = []
    for k in range(2):
        s = st.sizes(kappa, k, 1.0)
        out.append([polar_panels(0.0, 1.0, 0.0, 2 * math.pi, 0.0, s, z) for z in (0.0, kappa)])
    return out


def centroids(c: np.ndarray) -> np.ndarray:
    """Centroid of every flat panel (n, 4, 3): the area-weighted centroids of its two triangles."""
    a1 = 0.5 * np.linalg.norm(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]), axis=1)
    a2 = 0.5 * np.linalg.norm(np.cross(c[:, 2] - c[:, 0], c[:, 3] - c[:, 0]), axis=1)
    g1, g2 = (c[:, 0] + c[:, 1] + c[:, 2]) / 3.0, (c[:, 0] + c[:, 2] + c[:, 3]) / 3.0
    return (a1[:, None] * g1 + a2[:, None] * g2) / (a1 + a2)[:, None]


def gauss_points(c: np.ndarray, points: int) -> tuple[np.ndarray, np.ndarray]:
    """Far-field sources (n * points, 3) and their weights (areas): the centroid with the panel's
    area (points = 1), or 2 x 2 Gauss-Legendre on the bilinear map of the corners (points = 4)."""
    if points == 1:
        return centroids(c), Panels(c).areas()
    g = 0.5 * (1.0 + np.array([-1.0, 1.0]) / math.sqrt(3.0))
    xs, ws = [], []
    for u in g:
        for v in g:
            shape = np.array([(1 - u) * (1 - v), u * (1 - v), u * v, (1 - u) * v])
            du = np.array([-(1 - v), 1 - v, v, -v])
            dv = np.array([-(1 - u), -u, u, 1 - u])
            xs.append(np.einsum("k,nkd->nd", shape, c))
            jac = np.cross(np.einsum("k,nkd->nd", du, c), np.einsum("k,nkd->nd", dv, c))
            ws.append(0.25 * np.linalg.norm(jac, axis=1))
    return np.stack(xs, axis=1).reshape(-1, 3), np.stack(ws, axis=1).reshape(-1)


def panel_potential(c: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Exact integral of 1/(4 pi |x - y|) over each flat polygon c[k] (4 corners, a repeated one for
    a triangle) at the point x[k]: the edge sum of Wilton et al. (1984), asinh form."""
    n = np.cross(c[:, 2] - c[:, 0], c[:, 3] - c[:, 1])
    n /= np.linalg.norm(n, axis=1)[:, None]
    h = np.einsum("kd,kd->k", x - c[:, 0], n)
    total = np.zeros(len(c))
    for i in range(4):
        a, b = c[:, i], c[:, (i + 1) % 4]
        length = np.linalg.norm(b - a, axis=1)
        ok = length > 0.0
        t = (b - a) / np.where(ok, length, 1.0)[:, None]
        u = np.cross(t, n)  # outward in-plane normal of the edge (corners counter-clockwise about n)
        s = np.einsum("kd,kd->k", a - x, u)
        lm, lp = np.einsum("kd,kd->k", a - x, t), np.einsum("kd,kd->k", b - x, t)
        r0sq = s * s + h * h
        r0 = np.sqrt(np.maximum(r0sq, 1e-300))
        rm, rp = np.sqrt(r0sq + lm * lm), np.sqrt(r0sq + lp * lp)
        term = s * (np.arcsinh(lp / r0) - np.arcsinh(lm / r0))
        ah = np.abs(h)
        term -= ah * (np.arctan2(s * lp, r0sq + ah * rp) - np.arctan2(s * lm, r0sq + ah * rm))
        total += np.where(ok, term, 0.0)
    return total / (4.0 * math.pi)


def near_correction(c: np.ndarray, xc: np.ndarray, src: np.ndarray, w: np.ndarray, near: float) -> csr_matrix:
    """The sparse correction (targets x panels): the exact panel integral minus the far-field
    point sum, for every panel within `near` of its own diameters of a collocation point."""
    n, per = len(c), len(w) // len(c)
    diam = np.max(np.linalg.norm(c[:, [2, 3]] - c[:, [0, 1]], axis=2), axis=1)
    tree = cKDTree(xc)
    rows, cols = [], []
    for j, hits in enumerate(tree.query_ball_point(centroids(c), near * diam)):
        rows.append(np.asarray(hits, dtype=np.int64))
        cols.append(np.full(len(hits), j, dtype=np.int64))
    ti, pj = np.concatenate(rows), np.concatenate(cols)
    vals = np.empty(len(ti))
    for lo in range(0, len(ti), 200_000):
        i, j = ti[lo : lo + 200_000], pj[lo : lo + 200_000]
        exact = panel_potential(c[j], xc[i])
        s, ws = src.reshape(n, per, 3)[j], w.reshape(n, per)[j]
        dist = np.linalg.norm(s - xc[i][:, None, :], axis=2)  # 0 only for a centroid source on its own target,
        inv = np.divide(1.0, dist, out=np.zeros_like(dist), where=dist > 0.0)  # which lfmm3d leaves out too
        point = np.sum(ws * inv, axis=1) / (4.0 * math.pi)
        vals[lo : lo + 200_000] = exact - point
    return csr_matrix((vals, (ti, pj)), shape=(n, n))


def fmm_solve(conductors: list[Panels], points: int, near: float, eps: float, rtol: float) -> tuple[np.ndarray, dict]:
    """Maxwell matrix (units of eps0 and the lengths) by the collocation BEM above, and its record."""
    fmm = _fmm()
    c = np.concatenate([p.corners for p in conductors])
    owner = np.concatenate([np.full(len(p), k) for k, p in enumerate(conductors)])
    xc = centroids(c)
    src, w = gauss_points(c, points)
    t0 = time.process_time()
    corr = near_correction(c, xc, src, w, near)
    t_near = time.process_time() - t0
    self_term = panel_potential(c, xc)
    calls = [0]

    def matvec(sigma: np.ndarray) -> np.ndarray:
        """Potential at the centroids of the panel densities sigma."""
        calls[0] += 1
        q = np.repeat(sigma, points) * w
        out = fmm.lfmm3d(eps=eps, sources=src.T.copy(), charges=q, targets=xc.T.copy(), pgt=1)
        return out.pottarg + corr @ sigma  # lfmm3d sums q / (4 pi r)

    a = LinearOperator((len(c), len(c)), matvec=matvec, dtype=float)
    m = LinearOperator((len(c), len(c)), matvec=lambda v: v / self_term, dtype=float)
    areas = Panels(c).areas()
    cmat = np.zeros((len(conductors), len(conductors)))
    iters = []
    for k in range(len(conductors)):
        before = calls[0]
        sigma, info = gmres(a, (owner == k).astype(float), rtol=rtol, restart=200, maxiter=50, M=m)
        if info != 0:
            raise RuntimeError(f"GMRES did not converge (info {info})")
        iters.append(calls[0] - before)
        cmat[:, k] = np.bincount(owner, weights=sigma * areas, minlength=len(conductors))
    seconds = time.process_time() - t0
    record = {"panels": len(c), "seconds": seconds, "near_seconds": t_near, "near_pairs": corr.nnz, "matvecs": iters}
    return 0.5 * (cmat + cmat.T), record


def fastcap_solve(conductors: list[Panels], order: int, iter_tol: float) -> tuple[np.ndarray, dict]:
    """Maxwell matrix in units of eps0 from FastCap2 (fastcap.solve_panels), and its record."""
    t0 = time.process_time()
    cmat, record = fastcap.solve_panels(conductors, 1.0, order, iter_tol)
    record["seconds"] = time.process_time() - t0
    return cmat / EPS0, record


def peak_rss_mb() -> float:
    """This process's peak resident set (VmHWM, MB): unlike ru_maxrss it starts afresh at exec,
    so the parent's peak (Love's dense Nystrom matrix) does not show in a child's figure."""
    with open("/proc/self/status") as f:
        line = next(x for x in f if x.startswith("VmHWM:"))
    return float(line.split()[1]) / 1e3


def child(a: argparse.Namespace) -> None:
    """One solver on one level (a process of its own, so its peak RSS is its own): JSON on stdout."""
    conductors = disk_levels(a.kappa)[a.level]
    base = peak_rss_mb()
    if a.solver == "fmm":
        _fmm()
        cmat, record = fmm_solve(conductors, a.points, a.near, a.fmm_eps, a.rtol)
    else:
        cmat, record = fastcap_solve(conductors, a.order, a.iter_tol)
    record["c"] = float(cmat[0, 0] - cmat[0, 1])
    record["rss_mb"] = peak_rss_mb()
    record["rss_before_mb"] = base
    print(json.dumps(record))


def run(a: argparse.Namespace, solver: str, kappa: float, level: int) -> dict:
    """This script as a child process for one solver, d/a and level; its JSON record."""
    args = [sys.executable, __file__, "--child", solver, "--kappa", str(kappa), "--level", str(level)]
    args += ["--points", str(a.points), "--near", str(a.near), "--fmm-eps", str(a.fmm_eps), "--rtol", str(a.rtol)]
    args += ["--order", str(a.order), "--iter-tol", str(a.iter_tol)]
    out = subprocess.run(args, check=True, capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    """For each d/a: both solvers on both levels, C00 - C01 against Love, CPU seconds and peak RSS."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kappa", type=float, nargs="*", default=[0.05, 0.02], help="d/a values")
    ap.add_argument("--points", type=int, choices=(1, 4), default=4, help="far-field points per panel")
    ap.add_argument("--near", type=float, default=2.0, help="exact integrals within this many panel diameters")
    ap.add_argument("--fmm-eps", type=float, default=1e-6, help="lfmm3d's requested precision")
    ap.add_argument("--rtol", type=float, default=1e-6, help="GMRES relative residual")
    ap.add_argument("--order", type=int, default=4, help="FastCap's expansion order")
    ap.add_argument("--iter-tol", type=float, default=1e-4, help="FastCap's GMRES tolerance")
    ap.add_argument("--solvers", nargs="*", default=["fastcap", "fmm"], choices=("fastcap", "fmm"))
    ap.add_argument("--child", choices=("fastcap", "fmm"), help=argparse.SUPPRESS)
    ap.add_argument("--level", type=int, default=0, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        a.solver = a.child
        a.kappa = a.kappa[0]
        return child(a)
    if "fmm" in a.solvers:
        _fmm()
    print(
        f"{'d/a':>5} {'solver':>8} {'panels':>13} {'level 0':>9} {'level 1':>9} {'Richardson':>10} {'CPU s':>20}"
        f" {'peak RSS MB':>16} {'matvecs':>10}"
    )
    for kappa in a.kappa:
        ref = closed_forms.love_disks(kappa)
        for solver in a.solvers:
            recs = [run(a, solver, kappa, level) for level in range(2)]
            c0, c1 = recs[0]["c"], recs[1]["c"]
            best = c1 + (c1 - c0) / (fastcap.FastcapSettings().refinement ** 2 - 1.0)
            devs = " ".join(f"{100 * (v / ref - 1):+8.3f}%" for v in (c0, c1, best))
            cpu = "/".join(f"{r['seconds']:.1f}" for r in recs)
            if solver == "fmm":  # of which the near-field integrals
                cpu += " (" + "/".join(f"{r['near_seconds']:.1f}" for r in recs) + ")"
            rss = "/".join(f"{r['rss_mb']:.0f}({r['rss_before_mb']:.0f})" for r in recs)
            mv = "/".join("+".join(str(m) for m in r.get("matvecs", [])) or "-" for r in recs)
            panels = "/".join(str(r["panels"]) for r in recs)
            print(f"{kappa:5.3f} {solver:>8} {panels:>13} {devs} {cpu:>20} {rss:>16} {mv:>10}", flush=True)


if __name__ == "__main__":
    main()
