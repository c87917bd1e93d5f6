"""Exact steps of linear units in modal coordinates: an FMU's step of a new length.

In plain numpy (inside an FMU, where every numpy call costs about a microsecond)
the exponential of :func:`.linear_propagation.exact_step` costs about 85 us a step.
A master that changes the step every time (an adaptive one) pays it at every step.
The unit's matrix ``A`` never changes, though, so it is diagonalised once,
``A = V diag(lambda) V^-1``, and a step of any length ``h`` is then a handful of
scalar functions per mode.  Over ``[t0, t0 + h]``, with ``z = lambda h``,
``theta = w h`` and the inputs ``u(s) = u0 + u1 s + u2 s^2 / 2``, mode ``k`` goes
from ``q0`` to::

    q1 = e^z q0 + h phi1(z) g(u0 + a) + h^2 phi2(z) g(u1) + h^3 phi3(z) g(u2)
         + h e^{i w t0} e^{i theta} phi1(z - i theta) g((b - i c) / 2)
         + h e^{-i w t0} e^{-i theta} phi1(z + i theta) g((b + i c) / 2)

where ``g(f)`` is the row of ``V^-1 f`` and ``phi_k(z)`` the integral over sigma in
[0, 1] of ``e^{z (1 - sigma)} sigma^(k-1) / (k-1)!`` (``phi_k(z) = sum_j z^j /
(j + k)!``, by its series where ``|z| < 1``, where the closed forms lose digits to
cancellation).  A real ``A`` has its complex modes in conjugate pairs: one mode of
each pair is kept, counted twice (its partner's contribution is the conjugate).

Diagonalising is safe only when the eigenvectors are well conditioned; when they
are not (a defective or nearly defective ``A``: critical damping, a free rigid
body), :meth:`ModalPropagator.build` returns None and the unit keeps the matrix
exponential.  The two agree to round-off times the eigenvectors' condition number
(``tests/test_linear_propagation.py``).
"""

from __future__ import annotations

import cmath
import math

import numpy as np

from .linear_propagation import balance

EPS = 2.0**-53
COND_MAX = 1e4  # eigenvector condition number beyond which the exponential is kept
SAME = 1e-12  # eigenvalues this close (relative to the largest) share their functions
INV_FACT = tuple(1.0 / math.factorial(k) for k in range(64))


def series_terms(r: float, k: int) -> int:
    """Terms after the first of ``phi_k(z) = sum_j z^j / (j + k)!`` for ``|z| <= r <
    1``, beyond which the remainder is below the unit round-off of ``phi_k(0)``."""
    m, term = 0, INV_FACT[k]
    while term > 0.5 * EPS * INV_FACT[k] and m < 60:
        m += 1
        term *= r / (m + k)
    return m


class ModalPropagator:
    """Exact steps of the affine unit ``y' = A y + Bu u(s) + a + b cos(w t) + c sin(w t)``
    (``model = (A, Bu, a, b, c)`` of :func:`.linear_propagation.affine_model`, ``w`` in
    rad/s) in its modal coordinates; build it with :meth:`build`."""

    def __init__(self, model: tuple[np.ndarray, ...], w: float, lam, V, Vinv) -> None:
        A, Bu, a, b, c = model
        self.w = float(w)
        self.lam = [complex(x) for x in lam]
        self.reach = max((abs(x) for x in self.lam), default=0.0)
        # a rotor's axes repeat each eigenvalue (to round-off): the scalar functions
        # are worked out once per distinct one
        self.distinct: list[complex] = []
        self.which: list[int] = []
        for x in self.lam:
            same = [j for j, v in enumerate(self.distinct) if abs(v - x) <= SAME * self.reach]
            if not same:
                self.distinct.append(x)
            self.which.append(same[0] if same else len(self.distinct) - 1)
        self.V = V
        n_in = Bu.shape[1]
        # the six modal drivers as one matrix on (y, u0, u1, u2, 1): rows of V^-1 (y),
        # V^-1 (Bu u0 + a), V^-1 Bu u1, V^-1 Bu u2, V^-1 (b - i c) / 2, V^-1 (b + i c) / 2
        nk, n = Vinv.shape
        G = np.zeros((6, nk, n + 3 * n_in + 1), dtype=complex)
        G[0, :, :n] = Vinv
        GB = Vinv @ Bu
        for r in range(3):
            G[1 + r, :, n + r * n_in : n + (r + 1) * n_in] = GB
        G[1, :, -1] = Vinv @ a
        G[4, :, -1] = Vinv @ (0.5 * (b - 1j * c))
        G[5, :, -1] = Vinv @ (0.5 * (b + 1j * c))
        self.G = G.reshape(6 * nk, -1)
        self.nk = nk

    @classmethod
    def build(cls, model: tuple[np.ndarray, ...], w: float) -> ModalPropagator | None:
        """The propagator of ``model``, or None when ``A``'s eigenvectors are too
        ill-conditioned for modal coordinates (condition number above
        :data:`COND_MAX`, after balancing)."""
        A = model[0]
        n = A.shape[0]
        d = balance(A)
        lam, W = np.linalg.eig(A * (d.reshape(1, n) / d.reshape(n, 1)))  # D^-1 A D
        if not np.all(np.isfinite(lam)) or np.linalg.cond(W) > COND_MAX:
            return None
        Winv = np.linalg.inv(W)
        V, Vinv = W * d.reshape(n, 1), Winv / d.reshape(1, n)
        # LAPACK returns a real matrix's complex eigenvalues as conjugate pairs, one after
        # the other, with conjugate eigenvectors: keep the first of each, counted twice
        keep, weight, k = [], [], 0
        while k < n:
            keep.append(k)
            if lam[k].imag == 0.0:
                weight.append(1.0)
                k += 1
                continue
            if k + 1 >= n or lam[k + 1] != lam[k].conjugate():
                return None
            weight.append(2.0)
            k += 2
        keep_idx = np.array(keep)
        return cls(model, w, lam[keep_idx], V[:, keep_idx] * np.array(weight), Vinv[keep_idx])

    def step(self, t0: float, h: float, y: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The state ``h`` seconds after ``t0`` from ``y``, inputs ``u`` as rows
        (value, d1, d2) at ``t0``."""
        th = self.w * h
        ith = 1j * th
        # series where |z| < 1: as many terms as the largest such |z| needs
        m3 = series_terms(min(self.reach * h, 1.0), 3)
        m1 = series_terms(min(self.reach * h + th, 1.0), 1)
        rot = cmath.exp(1j * (self.w * t0 + th))  # e^{i w (t0 + h)}
        hh = h * h
        coefficients = []
        for lam in self.distinct:
            z = lam * h
            e, p1, p2, p3 = _phi0123(z, m3)
            coefficients.append((e, h * p1, hh * p2, hh * h * p3, h * rot * _phi1(z - ith, m1),
                                 h * _phi1(z + ith, m1) / rot))  # fmt: skip
        rows = np.array([coefficients[j] for j in self.which]).T  # 6 x modes
        x = np.concatenate((y, u.T.ravel(), (1.0,)))
        q1 = (rows * (self.G @ x).reshape(6, self.nk)).sum(axis=0)
        return (self.V @ q1).real


def _phi0123(z: complex, m: int) -> tuple[complex, complex, complex, complex]:
    """``e^z, phi1(z), phi2(z), phi3(z)``: ``phi3`` by ``m + 1`` terms of its series and
    the others from it (``phi_{k-1} = z phi_k + 1 / (k-1)!``, no cancellation) where
    ``|z| < 1``; by the closed forms elsewhere."""
    if abs(z) < 1.0:
        p3 = 0j
        for j in range(m, -1, -1):
            p3 = p3 * z + INV_FACT[j + 3]
        p2 = z * p3 + 0.5
        p1 = z * p2 + 1.0
        return z * p1 + 1.0, p1, p2, p3
    e = cmath.exp(z)
    p1 = (e - 1.0) / z
    p2 = (p1 - 1.0) / z
    return e, p1, p2, (p2 - 0.5) / z


def _phi1(z: complex, m: int) -> complex:
    """``phi1(z) = (e^z - 1) / z``: ``m + 1`` terms of its series where ``|z| < 1``."""
    if abs(z) < 1.0:
        p = 0j
        for j in range(m, -1, -1):
            p = p * z + INV_FACT[j + 1]
        return p
    return (cmath.exp(z) - 1.0) / z
