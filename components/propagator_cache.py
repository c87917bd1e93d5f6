"""Exact steps of linear units from propagators cached per step size: the FMU's path.

The exact step of :mod:`.linear_propagation` exponentiates a matrix holding the
step's inputs, so nothing of it can be reused from one step to the next.  Split
the other way, the step of ``y' = A y + Bu u(s) + a + b cos(w t) + c sin(w t)``
with ``u(s) = u0 + u1 s + u2 s^2 / 2`` over ``[t0, t0 + h]`` is (sigma = s / h)::

    y(t0 + h) = E y0 + P1 h (a + Bu u0) + P2 h^2 Bu u1 + P3 h^3 Bu u2
                + Wc h (cos b + sin c) + Ws h (cos c - sin b)     (cos, sin of w t0)

with ``E = exp(A h)``, ``Pk`` the integral over sigma in [0, 1] of
``exp(A h (1 - sigma)) sigma^(k-1) / (k-1)!`` and ``Wc``, ``Ws`` that of
``exp(A h (1 - sigma))`` times ``cos(w h sigma)``, ``sin(w h sigma)``: functions of
``h`` alone.  One exponential of a ``6n x 6n`` block matrix gives all six (Van Loan
1978, "Computing integrals involving the matrix exponential"), after which a step is
one ``n x 6n`` matrix-vector product.

Inside an FMU (plain numpy, where every numpy call costs about a microsecond) the
rotor units take this path when a step has the length of the one before (a tool at
a fixed communication step: one exponential for the whole run), and modal
coordinates otherwise (:mod:`.modal_propagation`; a master that changes the step
would pay a 6n x 6n exponential for nothing).  The last step's
length is part of the unit's state, so a step replayed from a restored state takes
the same path and repeats bit for bit.  Compiled, the per-step 9 x 9 exponential in
plain loops costs less than a miss here, so the installed package always takes it.
The two agree to round-off (``tests/test_linear_propagation.py``).
"""

from __future__ import annotations

import math
from collections import OrderedDict

import numpy as np

from .linear_propagation import balance, expm

N_BLOCKS = 6  # E, P1, P2, P3, Wc, Ws


def propagators(A: np.ndarray, d: np.ndarray, h: float, w: float) -> np.ndarray:
    """``[E, P1, P2, P3, Wc, Ws]`` side by side (``n x 6n``) for the step ``h`` (s);
    ``d``: the diagonal scaling that balances ``A`` (:func:`.linear_propagation.balance`),
    ``w`` (rad/s): the forcing frequency."""
    n = A.shape[0]
    eye = np.eye(n)
    X = np.zeros((N_BLOCKS * n, N_BLOCKS * n))
    X[:n, :n] = (A * (d.reshape(1, n) / d.reshape(n, 1))) * h  # D^-1 A D h
    # the state is driven by the first and fourth basis functions ...
    X[:n, n : 2 * n] = eye
    X[:n, 4 * n : 5 * n] = eye
    # ... whose exponential's first rows are 1, sigma, sigma^2 / 2 (a nilpotent chain)
    # and cos, -sin of w h sigma (a rotation): the top block row of exp(X) is then
    # [E, P1, P2, P3, Wc, -Ws], each scaled by D
    X[n : 2 * n, 2 * n : 3 * n] = eye
    X[2 * n : 3 * n, 3 * n : 4 * n] = eye
    X[4 * n : 5 * n, 5 * n :] = -w * h * eye
    X[5 * n :, 4 * n : 5 * n] = w * h * eye
    top = expm(X)[:n]
    top[:, 5 * n :] *= -1.0
    # undo the scaling: block = D block' D^-1
    dd = np.tile(d, N_BLOCKS)
    return top * (d.reshape(n, 1) / dd.reshape(1, N_BLOCKS * n))


class PropagatorCache:
    """Exact steps of one linear unit, with the propagators of the step sizes that come
    back.  ``model``: ``(A, Bu, a, b, c)`` of :func:`.linear_propagation.affine_model`;
    ``w`` (rad/s): its forcing frequency.

    Kept per step size as one ``n x (n + 3 n_in + 3)`` matrix ``[E, h P1 Bu, h^2 P2 Bu,
    h^3 P3 Bu, h (Wc b + Ws c), h (Wc c - Ws b), h P1 a]`` that multiplies
    ``(y, u0, u1, u2, cos w t0, sin w t0, 1)``.
    """

    def __init__(self, model: tuple[np.ndarray, ...], w: float, size: int = 8) -> None:
        self.model = model
        self.w = w
        self.d = balance(model[0])
        self.size = size
        self.kept: OrderedDict[float, np.ndarray] = OrderedDict()
        self.computed = 0  # propagators computed (one 6n x 6n exponential each)

    def _propagator(self, h: float) -> np.ndarray:
        A, Bu, a, b, c = self.model
        n = A.shape[0]
        top = propagators(A, self.d, h, self.w)
        E, P1, P2, P3, Wc, Ws = (top[:, k * n : (k + 1) * n] for k in range(N_BLOCKS))
        self.computed += 1
        return np.hstack(
            (
                E,
                h * (P1 @ Bu),
                (h * h) * (P2 @ Bu),
                (h * h * h) * (P3 @ Bu),
                (h * (Wc @ b + Ws @ c)).reshape(n, 1),
                (h * (Wc @ c - Ws @ b)).reshape(n, 1),
                (h * (P1 @ a)).reshape(n, 1),
            )
        )

    def step(self, t0: float, h: float, y: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The state ``h`` seconds after ``t0`` from ``y``, inputs ``u`` as rows
        (value, d1, d2) at ``t0``."""
        Q = self.kept.get(h)
        if Q is None:
            Q = self._propagator(h)
            self.kept[h] = Q
            if len(self.kept) > self.size:
                self.kept.popitem(last=False)
        else:
            self.kept.move_to_end(h)
        wt = self.w * t0
        v = np.concatenate((y, u.T.ravel(), (math.cos(wt), math.sin(wt), 1.0)))
        return Q @ v
