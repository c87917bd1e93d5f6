"""The DOP853 Runge-Kutta pair: scipy's tableau, error norm and step-size rule.

Shared by the reference's ``fast`` engine and the units' compiled steps, so
every compiled integrator in rubcosim takes the steps scipy's ``DOP853``
would (same coefficients, same error norm, same controller constants).
"""

from __future__ import annotations

import math

import numpy as np

from . import dop853_tableau as _dop
from .dop853_sums import dense_sums, error_sums, solution_sum
from .dop853_sums import stage_point as stage_point  # the engines' stage, from here
from .jit import njit

N_STAGES = _dop.N_STAGES
N_EXT = _dop.N_STAGES_EXTENDED
N_DENSE = 7  # rows of the dense-output coefficients F (dense_from_stages, dense_poly)
B = np.ascontiguousarray(_dop.B)  # the tangent's trace weights; the sums: dop853_sums
C = np.ascontiguousarray(_dop.C)
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
_EPS = 2.0**-52  # an ulp of a number in [1, 2)
_NORMAL = 2.0**-1022  # the smallest normal number: an ulp below it is _NORMAL * _EPS


@njit(inline="always")
def error_norm(K, h, y, y_new, rtol, atol):
    """scipy's DOP853 error norm of a step from ``y`` to ``y_new`` with stages ``K``;
    ``atol`` is a per-component array."""
    n = y.shape[0]
    e5 = 0.0
    e3 = 0.0
    for i in range(n):
        sc = atol[i] + max(abs(y[i]), abs(y_new[i])) * rtol
        a5, a3 = error_sums(K, i)
        e5 += (a5 / sc) ** 2
        e3 += (a3 / sc) ** 2
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * n)


@njit(inline="always")
def _err_power(err):
    """scipy's ``err ** (-1 / 8)`` (-1 over the error estimator's order plus one) as
    three square roots: a libm ``pow`` costs about as much as a right-hand side of a
    small system, once per step; the two agree to a few ulps."""
    return 1.0 / math.sqrt(math.sqrt(math.sqrt(err)))


@njit(inline="always")
def step_factor(err, rejected):
    """Factor on the step after an error norm ``err``; below 1 the step is accepted.
    Inlined: the next step waits for its chain of square roots, and a call of its own
    added a few nanoseconds a step to that wait (as numba returns through memory)."""
    if err < 1.0:
        factor = MAX_FACTOR if err == 0.0 else min(MAX_FACTOR, SAFETY * _err_power(err))
        return min(1.0, factor) if rejected else factor
    return max(MIN_FACTOR, SAFETY * _err_power(err))


@njit(inline="always")
def solution_point(K, y, h, y_new):
    """The step's 8th-order solution ``y_new = y + h * sum_j B[j] K[j]``."""
    for i in range(y.shape[0]):
        y_new[i] = y[i] + h * solution_sum(K, i)


@njit(inline="always")
def rk_stages(evaluate, ctx, t, y, f, h, K, y_new, f_new, ytmp):
    """One DOP853 step of size ``h`` from ``(t, y)`` with ``f`` the slope there: the
    stages into ``K`` (rows written in place), the solution into ``y_new`` and its slope
    into ``f_new``.  ``evaluate(ctx, t, y, dy)`` (a compiled function, inlined with this
    one) writes the right-hand side at ``(t, y)`` into ``dy``."""
    n = y.shape[0]
    for i in range(n):
        K[0, i] = f[i]
    # The slope at the solution is the loop's last pass: one copy of the inlined
    # right-hand side for all of them (each copy costs seconds of a cold compile)
    for s in range(1, N_STAGES + 1):
        if s < N_STAGES:
            stage_point(K, s, y, h, ytmp)
            ts, point = t + C[s] * h, ytmp
        else:
            solution_point(K, y, h, y_new)
            ts, point = t + h, y_new
        evaluate(ctx, ts, point, K[s])  # straight into K's row
    for i in range(n):
        f_new[i] = K[N_STAGES, i]


@njit(inline="always")
def dense_from_stages(h, y_old, y_new, f_new, K, F):
    """scipy's DOP853 dense-output coefficients ``F`` (``N_DENSE`` x n) from all ``N_EXT``
    stages."""
    for i in range(y_old.shape[0]):
        delta = y_new[i] - y_old[i]
        F[0, i] = delta
        F[1, i] = h * K[0, i] - delta
        F[2, i] = 2.0 * delta - h * (f_new[i] + K[0, i])
        d0, d1, d2, d3 = dense_sums(K, i)
        F[3, i] = h * d0
        F[4, i] = h * d1
        F[5, i] = h * d2
        F[6, i] = h * d3


@njit(inline="always")
def dense_stages(evaluate, ctx, t_old, h, y_old, y_new, f_new, K, F, ytmp):
    """The dense output's extra stages of the step just taken into ``K`` and its
    coefficients ``F`` (:func:`dense_from_stages`); ``evaluate`` as in :func:`rk_stages`."""
    for s in range(N_STAGES + 1, N_EXT):
        stage_point(K, s, y_old, h, ytmp)
        evaluate(ctx, t_old + C[s] * h, ytmp, K[s])
    dense_from_stages(h, y_old, y_new, f_new, K, F)


@njit(inline="always")
def min_step(t):
    """The shortest step from time ``t``, s: 10 ulps of t (scipy's rule)."""
    return 10.0 * abs(np.nextafter(t, np.inf) - t)


@njit(inline="always")
def below_min_step(h, t):
    """Whether a step of ``h`` >= 0 s from time ``t`` is shorter than :func:`min_step`.

    ``10 max(|t|, 2**-1022) 2**-52`` is at least :func:`min_step` for every finite t
    below the largest double, and a step is far longer at almost every step: that test
    decides first.  ``nextafter`` is a libm call, which makes a compiled step loop
    spill every register it keeps live across it.  (The bound takes no subnormal
    operand: one costs a microcode assist.)
    """
    return h < 10.0 * (max(abs(t), _NORMAL) * _EPS) and h < min_step(t)


@njit(inline="always")
def next_step(err, h, rejected):
    """The step controller: ``(accepted, next step size)`` after a trial step of size
    ``h`` (s) with error norm ``err``; a non-finite error (a stage left the model's
    domain) rejects and shrinks as scipy does."""
    if not math.isfinite(err):
        return False, h * MIN_FACTOR
    return err < 1.0, h * step_factor(err, rejected)


@njit(inline="always")
def dense_poly(x, F, c):
    """The polynomial part of scipy's DOP853 dense output of component ``c`` at the
    step fraction ``x = (t - t_old) / h`` (the output is ``y_old[c]`` plus this); ``F``
    holds scipy's seven rows (:func:`dense_from_stages`), evaluated as scipy's loop
    does, in the same order, written out (event location evaluates it a dozen times per
    event)."""
    y = 1.0 - x
    acc = (0.0 + F[6, c]) * x
    acc = (acc + F[5, c]) * y
    acc = (acc + F[4, c]) * x
    acc = (acc + F[3, c]) * y
    acc = (acc + F[2, c]) * x
    acc = (acc + F[1, c]) * y
    return (acc + F[0, c]) * x


@njit(inline="always")
def dense_eval(t_old, h, y_old, F, t, out, ncomp):
    """scipy's DOP853 dense output of the step ``[t_old, t_old + h]`` (coefficients
    ``F`` from :func:`dense_from_stages`) at time ``t``, first ``ncomp`` components."""
    x = (t - t_old) / h
    for c in range(ncomp):
        out[c] = dense_poly(x, F, c) + y_old[c]


@njit
def workspace(n):
    """Scratch arrays of a DOP853 driver for ``n`` states: ``(K, F, f, f_new, y_new,
    ytmp, dy)``: all stages, dense-output coefficients, the derivative at the step's
    start and end, the trial solution, a stage point and a derivative buffer."""
    return (
        np.empty((N_EXT, n)),
        np.empty((N_DENSE, n)),
        np.empty(n),
        np.empty(n),
        np.empty(n),
        np.empty(n),
        np.empty(n),
    )
