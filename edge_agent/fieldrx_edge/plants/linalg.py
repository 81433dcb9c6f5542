"""Small dense linear algebra for discretising plants without scipy.

The edge agent must not depend on scipy, so the matrix exponential (Padé
approximant with scaling and squaring, Higham 2005 / Golub & Van Loan
alg. 11.3.1) and the zero-order-hold discretisation live here. The matrices
are tiny (<= 4 states), so clarity beats speed. Tests check both against
``scipy.linalg.expm`` and ``scipy.signal.cont2discrete``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

# Padé (6, 6) coefficients c_k = (2q-k)! q! / ((2q)! k! (q-k)!), q = 6.
_Q = 6
_PADE = [
    math.factorial(2 * _Q - k)
    * math.factorial(_Q)
    / (math.factorial(2 * _Q) * math.factorial(k) * math.factorial(_Q - k))
    for k in range(_Q + 1)
]


def expm(a: ArrayLike) -> NDArray[np.float64]:
    """Matrix exponential by scaling and squaring with a (6, 6) Padé approximant.

    The matrix is scaled by 2**-s so its infinity norm is <= 0.5, where the
    (6, 6) Padé error is below 1e-16 relative; then squared s times.
    """
    m = np.array(a, dtype=float)
    if m.ndim != 2 or m.shape[0] != m.shape[1]:
        raise ValueError("expm needs a square matrix")
    n = m.shape[0]
    norm = float(np.linalg.norm(m, np.inf)) if n else 0.0
    s = max(0, int(math.ceil(math.log2(norm / 0.5)))) if norm > 0.5 else 0
    x = m / (2.0**s)
    ident = np.eye(n)
    num = _PADE[0] * ident
    den = _PADE[0] * ident
    power = ident
    for k in range(1, _Q + 1):
        power = power @ x
        term = _PADE[k] * power
        num = num + term
        den = den + term if k % 2 == 0 else den - term
    r = np.linalg.solve(den, num)
    for _ in range(s):
        r = r @ r
    return np.asarray(r, dtype=np.float64)


def zoh(a: ArrayLike, b: ArrayLike, dt: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Exact zero-order-hold discretisation: Phi = e^(A dt), Gamma = int_0^dt e^(A s) ds B.

    Uses the augmented-matrix identity expm([[A, B], [0, 0]] dt) = [[Phi, Gamma], [0, I]],
    which also handles singular A (integrators) without inverting it.
    """
    if dt <= 0.0:
        raise ValueError("dt must be positive")
    am = np.atleast_2d(np.array(a, dtype=float))
    bm = np.array(b, dtype=float).reshape(am.shape[0], -1)
    n, m = bm.shape
    aug = np.zeros((n + m, n + m))
    aug[:n, :n] = am
    aug[:n, n:] = bm
    e = expm(aug * dt)
    return e[:n, :n], e[:n, n:]


def tf2ss(
    num: ArrayLike, den: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Controllable canonical realisation of a proper SISO transfer function.

    Coefficients are in descending powers of s, as in MATLAB/scipy.
    """
    d = np.trim_zeros(np.array(den, dtype=float), "f")
    nu = np.trim_zeros(np.array(num, dtype=float), "f")
    if d.size == 0:
        raise ValueError("denominator is zero")
    if nu.size > d.size:
        raise ValueError("transfer function must be proper")
    nu = nu / d[0]
    d = d / d[0]
    n = d.size - 1
    nu = np.concatenate([np.zeros(d.size - nu.size), nu])
    dd = np.array([[nu[0]]])
    if n == 0:
        return np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), dd
    a = np.zeros((n, n))
    a[0, :] = -d[1:]
    a[1:, :-1] = np.eye(n - 1)
    b = np.zeros((n, 1))
    b[0, 0] = 1.0
    c = (nu[1:] - nu[0] * d[1:]).reshape(1, n)
    return a, b, c, dd
