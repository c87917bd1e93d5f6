"""Exact steps of linear units: the matrix exponential of an augmented system.

A rotor unit's ODE (:func:`.unit_odes.unit_rhs`) is affine in its state and inputs,
with harmonic unbalance forcing at the spin speed ``w`` and constant gravity::

    y' = A y + Bu u(s) + a + b cos(w t) + c sin(w t)

and over a macro step each input is a polynomial ``u(s) = u0 + u1 s + u2 s^2 / 2``
(s = t - t0).  With sigma = s / h, the state together with the basis
``(1, sigma, sigma^2 / 2, cos(w t), sin(w t))`` solves a linear, autonomous system
``z' = M z`` on sigma in [0, 1], so the step is ``z(1) = expm(M) z(0)``: exact up to
round-off, whatever the step size, the stiffness or the damping (resonance included).

The affine model is read off the unit's own right-hand side (:func:`affine_model`),
so the equations stay written once; ``tests/test_linear_propagation.py`` checks that
the model reproduces the right-hand side at random states, inputs and times, and the
step against the closed-form whirl of a Jeffcott rotor.  The same source runs under
numba and, inside an FMU, as plain numpy.
"""

from __future__ import annotations

import math

import numpy as np

from .jit import USE_NUMBA, njit
from .unit_odes import unit_rhs

# Higham (2005), "The scaling and squaring method for the matrix exponential revisited":
# the [m/m] Pade coefficients, m = 3, 5, 7, 9, 13, and the 1-norm up to which each is
# accurate to round-off (the cheapest that is accurate is used).
PADE = (
    np.array([120.0, 60.0, 12.0, 1.0]),
    np.array([30240.0, 15120.0, 3360.0, 420.0, 30.0, 1.0]),
    np.array([17297280.0, 8648640.0, 1995840.0, 277200.0, 25200.0, 1512.0, 56.0, 1.0]),
    np.array(
        [
            17643225600.0,
            8821612800.0,
            2075673600.0,
            302702400.0,
            30270240.0,
            2162160.0,
            110880.0,
            3960.0,
            90.0,
            1.0,
        ]
    ),  # fmt: skip
    np.array(
        [
            64764752532480000.0,
            32382376266240000.0,
            7771770303897600.0,
            1187353796428800.0,
            129060195264000.0,
            10559470521600.0,
            670442572800.0,
            33522128640.0,
            1323241920.0,
            40840800.0,
            960960.0,
            16380.0,
            182.0,
            1.0,
        ]
    ),  # fmt: skip
)
THETA = (1.495585217958292e-2, 2.539398330063230e-1, 9.504178996162932e-1, 2.097847961257068)
THETA13 = 5.371920351148152
N_BASIS = 5  # 1, sigma, sigma^2 / 2, cos(w t), sin(w t)


# The largest scale factor balancing gives a state (and 1 / it the smallest): far past
# any real ratio of scales, well inside the doubles, so that a matrix with a row or column
# of (almost) zeros never drives a factor to infinity.
MAX_SCALE = 2.0**300


@njit
def balance(M: np.ndarray, sweeps: int = 3) -> np.ndarray:
    """Scale factors ``d`` (powers of 2, so exact) such that ``M[i, j] d[j] / d[i]`` has
    rows and columns of similar norms (Parlett & Reinsch's balancing, one index at a
    time, each factor within [1 / MAX_SCALE, MAX_SCALE]):
    a state in metres beside one in m/s would otherwise let the larger entries set the
    exponential's round-off.  Plain loops when compiled (no temporaries); an FMU's
    plain-numpy copy takes each index's sums as products of a row and a column, the
    same steps (scaling all indices at once, as it did, could overflow)."""
    n = M.shape[0]
    d = np.ones(n)
    inv = np.ones(n)  # 1 / d, exact (powers of 2): products where divisions would be slow
    if not USE_NUMBA:
        off = np.abs(M)
        np.fill_diagonal(off, 0.0)
    for _ in range(sweeps):
        for i in range(n):  # one index at a time, with the others' current scaling
            if not USE_NUMBA:  # Python floats: a ratio past the doubles is inf, silently
                ci = float(off[:, i] @ inv) * float(d[i])
                ri = float(off[i, :] @ d) * float(inv[i])
            else:
                ci, ri = 0.0, 0.0
                for j in range(n):
                    if j != i:
                        ci += abs(M[j, i]) * inv[j]
                        ri += abs(M[i, j]) * d[j]
                ci *= d[i]
                ri *= inv[i]
            ratio = ri / ci if ci > 0.0 else 0.0
            if 0.0 < ratio < math.inf:  # (a ratio past the doubles: left as it is)
                f = 2.0 ** math.floor(0.5 * math.log2(ratio) + 0.5)
                if 1.0 / MAX_SCALE <= d[i] * f <= MAX_SCALE:
                    d[i] *= f
                    inv[i] /= f
    return d


@njit
def _mm(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """A @ B: plain loops when compiled (a BLAS call costs more than a 13 x 13 product),
    numpy's product in an FMU's plain-Python copy."""
    if not USE_NUMBA:
        return A @ B
    n, k, m = A.shape[0], A.shape[1], B.shape[1]
    C = np.zeros((n, m))
    for i in range(n):
        for q in range(k):
            a = A[i, q]
            if a != 0.0:
                for j in range(m):
                    C[i, j] += a * B[q, j]
    return C


@njit
def _solve(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """A^-1 B: Gaussian elimination with partial pivoting in plain loops when compiled
    (LAPACK's call overhead exceeds the work at these sizes), numpy's solve otherwise."""
    if not USE_NUMBA:
        return np.linalg.solve(A, B)
    n, m = B.shape[0], B.shape[1]
    A = A.copy()
    X = B.copy()
    for k in range(n):
        piv = k
        big = abs(A[k, k])
        for i in range(k + 1, n):
            if abs(A[i, k]) > big:
                piv, big = i, abs(A[i, k])
        if piv != k:
            for j in range(n):
                A[k, j], A[piv, j] = A[piv, j], A[k, j]
            for j in range(m):
                X[k, j], X[piv, j] = X[piv, j], X[k, j]
        inv = 1.0 / A[k, k]
        for i in range(k + 1, n):
            f = A[i, k] * inv
            if f != 0.0:
                for j in range(k + 1, n):
                    A[i, j] -= f * A[k, j]
                for j in range(m):
                    X[i, j] -= f * X[k, j]
    for k in range(n - 1, -1, -1):
        inv = 1.0 / A[k, k]
        for j in range(m):
            acc = X[k, j]
            for i in range(k + 1, n):
                acc -= A[k, i] * X[i, j]
            X[k, j] = acc * inv
    return X


@njit
def _plus(Y: np.ndarray, c: float, X: np.ndarray) -> np.ndarray:
    """``Y + c X`` (a new array).  :func:`expm`'s sums go through this one function: each
    array expression written out there compiled a loop of its own (seconds of a cold
    compile, for a function a run calls once per step size)."""
    return Y + c * X


@njit
def expm(M: np.ndarray) -> np.ndarray:
    """exp(M) of a square float matrix: Pade approximation of the lowest degree that is
    accurate at its norm, with scaling and squaring beyond (Higham 2005)."""
    n = M.shape[0]
    norm = np.abs(M).sum(axis=0).max()
    ident = np.eye(n)
    zero = np.zeros((n, n))
    X = M.copy()  # C-contiguous whatever M's layout: numba's fast matrix product
    X2 = _mm(X, X)
    for k in range(4):
        if norm <= THETA[k]:
            b = PADE[k]
            U = _plus(zero, b[1], ident)
            V = _plus(zero, b[0], ident)
            P = ident
            for q in range(1, k + 2):
                P = _mm(P, X2)
                U = _plus(U, b[2 * q + 1], P)
                V = _plus(V, b[2 * q], P)
            U = _mm(X, U)
            return _solve(_plus(V, -1.0, U), _plus(V, 1.0, U))
    s = 0
    if norm > THETA13:
        s = int(math.ceil(math.log2(norm / THETA13)))
        X = _plus(zero, 1.0 / 2.0**s, X)
        X2 = _mm(X, X)
    b = PADE[4]
    X4 = _mm(X2, X2)
    X6 = _mm(X4, X2)
    inner = _plus(_plus(_plus(zero, b[13], X6), b[11], X4), b[9], X2)
    U = _plus(_plus(_plus(_plus(_mm(X6, inner), b[7], X6), b[5], X4), b[3], X2), b[1], ident)
    U = _mm(X, U)
    inner = _plus(_plus(_plus(zero, b[12], X6), b[10], X4), b[8], X2)
    V = _plus(_plus(_plus(_mm(X6, inner), b[6], X6), b[4], X4), b[2], X2)
    V = _plus(V, b[0], ident)
    R = _solve(_plus(V, -1.0, U), _plus(V, 1.0, U))
    for _ in range(s):
        R = _mm(R, R)
    return R


# up to this 1-norm of the balanced matrix the step sums exp(M) z as a Taylor series
# (matrix-vector products only); beyond, the Pade approximant of exp(M) itself
TAYLOR_MAX_NORM = 8.0
EPS = 2.0**-53


@njit
def taylor_terms(theta: float) -> int:
    """The number of Taylor terms after which the remainder of exp(X) x, with
    ``|X|_1 <= theta <= 1``, is below ``EPS |x|`` (bound ``theta^(m+1) / (m+1)! e``)."""
    bound = math.e
    m = 0
    while m < 30:
        m += 1
        bound *= theta / m
        if bound * theta / (m + 1) <= EPS:
            return m
    return m


@njit
def expm_action(M: np.ndarray, z: np.ndarray, norm: float) -> np.ndarray:
    """exp(M) z for a matrix of 1-norm ``norm``: the Taylor series of exp(M / s) applied
    ``s = ceil(norm)`` times, each truncated where its remainder is bound to be below
    the unit round-off relative to the vector, or earlier once two consecutive terms
    are (Al-Mohy & Higham 2011, "Computing the action of the matrix exponential": the
    chain of the input basis, nilpotent, keeps the 1-norm at 1 where the terms fall
    much faster): a few matrix-vector products where the Pade approximant needs
    matrix products and a solve.  Plain loops, for the compiled step only (in plain
    numpy the Pade approximant takes fewer calls, :func:`exact_step`)."""
    s = max(1, int(math.ceil(norm)))
    m = taylor_terms(norm / s)
    n = z.shape[0]
    x = z.copy()
    term = np.empty(n)
    nxt = np.empty(n)
    for _ in range(s):
        term[:] = x
        small = 0  # consecutive terms below the round-off of the sum: the series is done
        for k in range(1, m + 1):
            f = 1.0 / (s * k)
            t_max, x_max = 0.0, 0.0
            for i in range(n):
                acc = 0.0
                for j in range(n):
                    acc += M[i, j] * term[j]
                nxt[i] = acc * f
            for i in range(n):
                term[i] = nxt[i]
                x[i] += nxt[i]
                t_max = max(t_max, abs(nxt[i]))
                x_max = max(x_max, abs(x[i]))
            small = small + 1 if t_max <= EPS * x_max else 0
            if small == 2:
                break
    return x


@njit
def affine_model(kind: int, p: np.ndarray, n: int, n_in: int, w: float):
    """``(A, Bu, a, b, c)`` of unit ``kind``'s right-hand side (see the module's
    docstring), read off :func:`.unit_odes.unit_rhs` at unit states and inputs; ``w``
    (rad/s) is the frequency of its harmonic forcing (0: none)."""
    y = np.zeros(n)
    u = np.zeros((n_in, 3))
    f0 = np.empty(n)
    dy = np.empty(n)
    unit_rhs(kind, 0.0, y, p, u, 0.0, f0)
    if w > 0.0:
        # f(t) = a + b cos(w t) + c sin(w t) at w t = 0, pi / 2, pi
        fq = np.empty(n)
        fh = np.empty(n)
        unit_rhs(kind, 0.5 * math.pi / w, y, p, u, 0.0, fq)
        unit_rhs(kind, math.pi / w, y, p, u, 0.0, fh)
        a = 0.5 * (f0 + fh)
        b = 0.5 * (f0 - fh)
        c = fq - a
    else:
        a = f0.copy()
        b = np.zeros(n)
        c = np.zeros(n)
    A = np.empty((n, n))
    for j in range(n):
        y[j] = 1.0
        unit_rhs(kind, 0.0, y, p, u, 0.0, dy)
        y[j] = 0.0
        for i in range(n):
            A[i, j] = dy[i] - f0[i]
    Bu = np.empty((n, n_in))
    for k in range(n_in):
        u[k, 0] = 1.0
        unit_rhs(kind, 0.0, y, p, u, 0.0, dy)
        u[k, 0] = 0.0
        for i in range(n):
            Bu[i, k] = dy[i] - f0[i]
    return A, Bu, a, b, c


@njit
def exact_step(t0: float, h: float, y: np.ndarray, model, w: float, u: np.ndarray) -> np.ndarray:
    """The state ``h`` seconds after ``t0`` from ``y`` (exact), ``model`` from
    :func:`affine_model`, inputs ``u`` as rows (value, d1, d2) at ``t0``."""
    A, Bu, a, b, c = model
    n = y.shape[0]
    m = n + N_BASIS
    M = np.zeros((m, m))
    if USE_NUMBA:  # plain loops: no temporaries, no BLAS call for a 4 x 2 product
        for i in range(n):
            g0, g1, g2 = 0.0, 0.0, 0.0
            for k in range(Bu.shape[1]):
                g0 += Bu[i, k] * u[k, 0]
                g1 += Bu[i, k] * u[k, 1]
                g2 += Bu[i, k] * u[k, 2]
            for j in range(n):
                M[i, j] = h * A[i, j]
            M[i, n] = h * (a[i] + g0)
            M[i, n + 1] = h * h * g1
            M[i, n + 2] = h * h * h * g2
            M[i, n + 3] = h * b[i]
            M[i, n + 4] = h * c[i]
    else:
        G = Bu @ np.ascontiguousarray(u)  # n x 3: the inputs' value, d1, d2 as forces
        M[:n, :n] = h * A
        M[:n, n] = h * (a + G[:, 0])
        M[:n, n + 1] = h * h * G[:, 1]
        M[:n, n + 2] = h * h * h * G[:, 2]
        M[:n, n + 3] = h * b
        M[:n, n + 4] = h * c
    M[n + 1, n] = 1.0  # d sigma / d sigma = 1
    M[n + 2, n + 1] = 1.0  # d (sigma^2 / 2) / d sigma = sigma
    M[n + 3, n + 4] = -w * h  # d cos(w t) / d sigma = -w h sin(w t)
    M[n + 4, n + 3] = w * h
    d = balance(M)
    z = np.zeros(m)
    z[:n] = y
    z[n] = 1.0
    z[n + 3] = math.cos(w * t0)
    z[n + 4] = math.sin(w * t0)
    if not USE_NUMBA:  # numpy: a Pade approximant is a dozen calls, a series more
        E = expm(M * (d.reshape(1, m) / d.reshape(m, 1)))  # exp(M) = D E D^-1
        return d[:n] * (E[:n] @ (z / d))
    inv = 1.0 / d  # exact: powers of 2
    norm = 0.0
    for j in range(m):  # the balanced matrix, in place, and its 1-norm
        col = 0.0
        for i in range(m):
            M[i, j] *= d[j] * inv[i]
            col += abs(M[i, j])
        norm = max(norm, col)
    zs = z * inv
    out = np.zeros(n)
    if norm <= TAYLOR_MAX_NORM:
        x = expm_action(M, zs, norm)
        for i in range(n):
            out[i] = d[i] * x[i]
        return out
    E = expm(M)
    for i in range(n):
        acc = 0.0
        for j in range(m):
            acc += E[i, j] * zs[j]
        out[i] = d[i] * acc
    return out
