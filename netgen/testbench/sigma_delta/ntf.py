"""Noise-transfer-function synthesis for the higher-order sigma-delta loops, in the manner of
Schreier's delta-sigma toolbox (synthesizeNTF, lowpass): zeros at DC or at the optimised
in-band frequencies (the roots of the Legendre polynomial, ds_optzeros), poles on the
maximally flat path that makes the out-of-band gain |NTF(-1)| equal H_inf (Lee's rule: 1.5 for a
stable 1-bit loop).

Written here because the maintained packages do not run on this numpy: python-deltasigma 0.2.2
stops on `np.float` under numpy 2 and pydsm 0.15.2 does not build. `synthesize_ntf` also takes
given zeros (an electromechanical loop's mechanics fix two of them), and then places the poles
for those zeros by the same rule. NTFs are scipy.signal.ZerosPolesGain objects (dt = 1, gain 1:
monic, NTF(inf) = 1 as a causal loop needs).
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import legendre
from scipy import optimize, signal

ITERATIONS = 100


def optimal_zeros(order: int, fixed_dc: int = 0) -> np.ndarray:
    """NTF zero frequencies normalised to the band edge (-1..1) that minimise the in-band noise
    integral of prod |x^2 - a_i^2|: the Legendre roots (ds_optzeros, opt = 1) when all are free;
    with `fixed_dc` zeros held at DC (the mechanics' double integration) the remaining ones by a
    numerical minimisation of  integral_0^1 x^(2 fixed_dc) prod (x^2 - a_i^2)^2 dx."""
    free = order - fixed_dc
    if free <= 0:
        return np.zeros(order)
    if fixed_dc == 0:
        return np.sort(legendre.legroots([0] * order + [1]).real)
    pairs, single = divmod(free, 2)
    x = np.linspace(0.0, 1.0, 2001)

    def noise(a: np.ndarray) -> float:
        poly = x ** (2 * (fixed_dc + single)) * np.prod([(x**2 - ai**2) ** 2 for ai in a], axis=0)
        return float(np.trapezoid(poly, x))

    start = np.linspace(0.5, 0.9, pairs) if pairs else np.array([])
    a = (
        optimize.minimize(noise, start, method="Nelder-Mead", options={"xatol": 1e-10, "fatol": 1e-16}).x
        if pairs
        else start
    )
    return np.sort(np.concatenate([np.zeros(fixed_dc + single), np.abs(a), -np.abs(a)]))


def zeros_for(order: int, osr: float, opt: int) -> np.ndarray:
    """The NTF zeros on the unit circle: all at z = 1 (opt 0) or at the optimised in-band
    frequencies omega = x pi / OSR (opt 1)."""
    if opt not in (0, 1):
        raise ValueError(f"opt must be 0 (zeros at DC) or 1 (optimised zeros), not {opt!r}")
    x = np.zeros(order) if opt == 0 else optimal_zeros(order)
    return np.exp(1j * np.pi * x / osr)


def evaluate(ntf: signal.ZerosPolesGain, z: complex | np.ndarray) -> np.ndarray:
    """NTF(z) of a zeros/poles/gain NTF."""
    z = np.asarray(z, dtype=complex)
    num = np.prod([z - q for q in ntf.zeros], axis=0) if len(ntf.zeros) else np.ones_like(z)
    den = np.prod([z - p for p in ntf.poles], axis=0) if len(ntf.poles) else np.ones_like(z)
    return ntf.gain * num / den


def flat_poles(order: int, x: float) -> np.ndarray:
    """Schreier's maximally flat lowpass pole set for the parameter x (> 0): the roots p of
    (p + 1/p)/2 = 1 - x^(2/order) e^{i w_k} / 2, w_k = (2k - 1) pi / order, inside the circle."""
    me2 = -0.5 * x ** (2.0 / order)
    w = (2 * np.arange(1, order + 1) - 1) * np.pi / order
    mb2 = 1 + me2 * np.exp(1j * w)
    p = mb2 - np.sqrt(mb2**2 - 1)
    out = np.abs(p) > 1
    p[out] = 1 / p[out]
    return pair(p)


def pair(p: np.ndarray) -> np.ndarray:
    """Complex roots as exact conjugate pairs (real ones real), sorted: a real polynomial."""
    p = np.asarray(p, dtype=complex)
    real = np.sort(p[np.abs(p.imag) < 1e-12].real).astype(complex)
    upper = p[p.imag >= 1e-12]
    upper = upper[np.argsort(upper.real)]
    return np.concatenate([real, *[[q, np.conj(q)] for q in upper]])


def synthesize_ntf(
    order: int, osr: float = 64, opt: int = 0, h_inf: float = 1.5, zeros: np.ndarray | None = None
) -> signal.ZerosPolesGain:
    """A lowpass NTF of `order` (synthesizeNTF(order, OSR, opt, H_inf, 0)): the zeros of
    `zeros_for` (or the given ones), the poles iterated (secant on x) until NTF(-1) = h_inf.
    If h_inf is not reachable (at or above the FIR limit prod |-1 - z_i|) the poles are all at
    0, as in the toolbox."""
    if order < 1:
        raise ValueError(f"NTF order must be >= 1, not {order}")
    if h_inf <= 1:
        raise ValueError(f"h_inf must exceed 1 (the NTF is monic), not {h_inf}")
    z = zeros_for(order, osr, opt) if zeros is None else np.asarray(zeros, dtype=complex)
    if len(z) != order:
        raise ValueError(f"{len(z)} zeros given for an NTF of order {order}")
    x, dx, fprev = 0.3 ** (order - 1), 0.0, 0.0
    for it in range(ITERATIONS):
        p = flat_poles(order, x)
        f = float(evaluate(signal.ZerosPolesGain(z, p, 1.0, dt=1), -1.0).real) - h_inf
        dx = -f / 100 if it == 0 else -f * dx / (f - fprev)
        fprev = f
        x = x + dx if x + dx > 0 else 0.1 * x
        if abs(f) < 1e-10 or abs(dx) < 1e-10:
            break
        if x > 1e6:
            p = np.zeros(order, dtype=complex)
            break
    return signal.ZerosPolesGain(z, p, 1.0, dt=1)


def polynomials(ntf: signal.ZerosPolesGain) -> tuple[np.ndarray, np.ndarray]:
    """Real numerator and denominator coefficients (descending powers of z) of the NTF."""
    return np.real(np.poly(ntf.zeros)) * ntf.gain, np.real(np.poly(ntf.poles))


def impulse(num: np.ndarray, den: np.ndarray, n: int) -> np.ndarray:
    """The first n samples of the impulse response of num(z)/den(z) (descending powers, deg num
    <= deg den), h[0] at the impulse."""
    num = np.concatenate([np.zeros(len(den) - len(num)), num])
    x = np.zeros(n)
    x[0] = 1.0
    return signal.lfilter(num, den, x)


def loop_filter(ntf: signal.ZerosPolesGain) -> tuple[np.ndarray, np.ndarray]:
    """L(z) = 1/NTF(z) - 1 = (D - N)/N as (numerator, denominator): the linearised loop gain
    from the quantizer output back to its input that realises the NTF (strictly proper: the
    NTF is monic)."""
    num, den = polynomials(ntf)
    return np.polysub(den, num)[1:], num
