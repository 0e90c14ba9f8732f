"""Closed forms of capacitances: the independent references of the extractors and their tests."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike
from scipy import special
from scipy.integrate import quad
from scipy.optimize import brentq

from netgen.geometry.shapes import Array, corner_radius


def parallel_plate(eps: float, area: float, gap: ArrayLike) -> Array:
    """Ideal parallel-plate capacitance eps*A/g (no fringe): the zeroth-order reference."""
    return eps * area / np.asarray(gap, dtype=float)


def palmer_rectangle(eps: float, a: float, b: float, g: float) -> float:
    """Palmer (1937) capacitance of two equal, aligned, thin a-by-b rectangles at distance g."""
    fa = 1.0 + g / (math.pi * a) * (1.0 + math.log(2.0 * math.pi * a / g))
    fb = 1.0 + g / (math.pi * b) * (1.0 + math.log(2.0 * math.pi * b / g))
    return eps * a * b / g * fa * fb


def kirchhoff_disk(eps: float, radius: float, g: float) -> float:
    """Kirchhoff's capacitance of two thin coaxial disks of radius R at distance g << R."""
    return eps * math.pi * radius**2 / g + eps * radius * (math.log(16.0 * math.pi * radius / g) - 1.0)


def cos_antiderivative(x: float, a: float, b: float) -> float:
    """Continuous antiderivative of 1/(a + b cos x) for a > |b| (Poisson-kernel form)."""
    c = math.sqrt(a * a - b * b)
    rho = b / (a + c)
    return (x - 2.0 * math.atan2(rho * math.sin(x), 1.0 + rho * math.cos(x))) / c


def tilted_sector_exact(
    eps: float,
    r_in: float,
    r_out: float,
    theta_start: float,
    theta_end: float,
    slot: float,
    gap: float,
    tilt: float,
    radius: float = math.inf,
) -> float:
    """Reference value of eps * integral dA / (gap - tilt*y) over a slotted annular sector.

    The angular integral is done in closed form, the radial one by adaptive scipy quad; the
    sector is clipped to r <= radius (plate rim).  Independent of the Gauss rules in this module.
    """
    h = slot / 2.0
    span = theta_end - theta_start
    lo = max(r_in, corner_radius(slot, span))
    hi = min(r_out, radius)
    if hi <= lo:
        return 0.0
    if abs(tilt) * hi >= gap:
        raise ValueError("need |tilt| * min(r_out, radius) < gap (plate must not touch)")

    def ring(r: float) -> float:
        d = math.asin(min(1.0, h / r)) if h > 0 else 0.0
        b = -tilt * r  # gap - tilt r sin(phi) = gap + b cos(phi - pi/2)
        x0, x1 = theta_start + d - math.pi / 2, theta_end - d - math.pi / 2
        return r * (cos_antiderivative(x1, gap, b) - cos_antiderivative(x0, gap, b))

    value, _ = quad(ring, lo, hi, epsabs=0.0, epsrel=1e-13, limit=200)
    return eps * value


def love_disks(kappa: float, same_potential: bool = False, panels: int | None = None, order: int = 16) -> float:
    """Charge of one of two coaxial equal thin disks (radius a, distance d = kappa a) in units
    of eps*a, at potential 1 with the other at -1 (the capacitor; C = Q/2 per unit of a) or +1.

    Love's integral equation (1949), f(x) -+ (1/pi) int_-1^1 kappa f(t) / (kappa^2 + (x-t)^2) dt = 1,
    the charge 4 int_-1^1 f: solved by Nystrom on composite Gauss-Legendre panels about kappa
    wide (the kernel's width), so the quadrature is spectrally accurate (a 1-D Fredholm equation
    of the second kind).
    """
    n = panels or max(8, math.ceil(4.0 / kappa))
    g, w = np.polynomial.legendre.leggauss(order)
    edges = np.linspace(-1.0, 1.0, n + 1)
    half = 0.5 * np.diff(edges)
    x = (edges[:-1, None] + half[:, None] * (g[None, :] + 1.0)).ravel()
    wx = (half[:, None] * w[None, :]).ravel()
    K = kappa / (kappa * kappa + (x[:, None] - x[None, :]) ** 2) / math.pi
    sign = 1.0 if same_potential else -1.0
    f = np.linalg.solve(np.eye(x.size) + sign * K * wx[None, :], np.ones(x.size))
    return float(4.0 * wx @ f)


# ----------------------------------------------------------------------------- 2-D, per unit length


def coplanar_strips(eps: float, width: float, gap: float) -> float:
    """C' (F/m) between two coplanar zero-thickness strips of width w, inner edges `gap` apart, in a
    homogeneous medium (both half-spaces): eps K(k')/K(k), k = s/(s + 2w) (conformal map)."""
    k = gap / (gap + 2.0 * width)
    return eps * float(special.ellipk(1.0 - k * k) / special.ellipk(k * k))


def wire_over_plane(eps: float, radius: float, height: float) -> float:
    """C' (F/m) of a round wire of radius r with its centre at height h over a ground plane:
    2 pi eps / acosh(h/r) (method of images, exact)."""
    return 2.0 * math.pi * eps / math.acosh(height / radius)


def palmer_strips(eps: float, width: float, gap: float) -> float:
    """Maxwell's (Palmer's) asymptotic C' of two parallel thin strips of width W at distance g:
    eps (W/g + (1 + ln(2 pi W/g)) / pi), the first two terms in g/W."""
    r = width / gap
    return eps * (r + (1.0 + math.log(2.0 * math.pi * r)) / math.pi)


def parallel_strips(eps: float, width: float, gap: float) -> float:
    """Exact C' (F/m) of two parallel zero-thickness strips of width W, `gap` apart, face to face
    (Palmer 1927's conformal map, W/g <= 100).

    By symmetry a quarter of the plane maps (Schwarz-Christoffel, prevertices 0 < beta < c < 1,
    dz/dt ~ (t - c) / sqrt(t (t - beta) (t - 1))) to the upper half plane; closure of the strip's
    two faces gives c = E(1-beta)/K(1-beta), the mid-plane-to-strip height
    g/2 ~ 2cK(beta) - 2(K(beta) - E(beta)), the half-width W/2 ~ int_beta^c (beta = e^-s, solved
    for W/g), and C' = eps K(k')/(2K(k)) with k = (1 - sqrt(1-beta)) / (1 + sqrt(1-beta)).
    """
    ratio = width / gap
    if not 0.0 < ratio <= 100.0:
        raise ValueError("parallel_strips: need 0 < W/g <= 100 (beyond, use palmer_strips)")

    def shape(beta: float) -> float:
        c = special.ellipe(1.0 - beta) / special.ellipkm1(beta)
        h = 2.0 * c * special.ellipk(beta) - 2.0 * (special.ellipk(beta) - special.ellipe(beta))
        top = math.acosh(math.sqrt(c / beta))
        a, _ = quad(
            lambda u: 2.0 * (c - beta * math.cosh(u) ** 2) / math.sqrt(1.0 - beta * math.cosh(u) ** 2),
            0.0,
            top,
            limit=400,
            epsabs=1e-12 * c,
            epsrel=1e-9,
        )
        return a / h - ratio

    s = brentq(lambda s: shape(math.exp(-s)), 1e-9, 700.0, xtol=1e-14)
    q = -math.expm1(0.5 * math.log1p(-math.exp(-s)))
    k = q / (2.0 - q)
    return eps * float(special.ellipkm1(k * k) / (2.0 * special.ellipk(k * k)))
