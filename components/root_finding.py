"""The one event locator: Brent's safeguarded three-point interpolation, as data.

Feng & Yang locate switching events by quadratic interpolation through three
states, which converges faster than bisection.  Brent's method is that
interpolation (inverse quadratic through the last three points, secant when
only two are distinct) made safe: a trial that would not shrink the bracket
fast enough is replaced by bisection, so it never does worse than bisection.

It is written in reverse-communication form, so one implementation serves
callers that evaluate the function in very different ways: the compiled
engines evaluate an event function on a step's dense output, the
co-simulation master re-runs every unit onto the trial time.  The caller
owns the loop::

    s = bracket(ta, fa, tb, fb, xtol)      # fa > 0 >= fb
    while not advance(s):
        s[F_CUR] = f(s[X_CUR])             # evaluate at the trial point
    t = crossed_end(s)                     # the end with f <= 0

The sign convention: ``f > 0`` before the event, ``f <= 0`` once it has
happened; :func:`crossed_end` returns the bracket end on the crossed side, so
the event is known to have happened there.
"""

from __future__ import annotations

import math

import numpy as np

from .jit import njit

# slots of the locator's state array
X_PRE, X_CUR, F_PRE, F_CUR, X_BLK, F_BLK, S_PRE, S_CUR, X_TOL = range(9)
STATE_SIZE = 9
MAX_TRIALS = 200


@njit(inline="always")
def bracket(ta: float, fa: float, tb: float, fb: float, xtol: float) -> np.ndarray:
    """The locator's state for a bracket ``[ta, tb]`` with ``fa > 0 >= fb``; ``xtol`` is
    the width (same unit as t) below which the bracket counts as located."""
    s = np.empty(STATE_SIZE)
    start(s, ta, fa, tb, fb, xtol)
    return s


@njit(inline="always")
def start(s: np.ndarray, ta: float, fa: float, tb: float, fb: float, xtol: float) -> None:
    """:func:`bracket` into the caller's array ``s`` (``STATE_SIZE`` long)."""
    s[X_PRE], s[X_CUR], s[F_PRE], s[F_CUR] = ta, tb, fa, fb
    s[X_BLK], s[F_BLK] = ta, fa
    s[S_PRE] = s[S_CUR] = tb - ta
    s[X_TOL] = xtol


@njit(inline="always")
def advance(s: np.ndarray) -> bool:
    """Take the value at the current point into account and propose the next trial
    point ``s[X_CUR]``; True when the bracket is located (no trial needed)."""
    xpre, xcur, fpre, fcur = s[X_PRE], s[X_CUR], s[F_PRE], s[F_CUR]
    xblk, fblk, spre, scur = s[X_BLK], s[F_BLK], s[S_PRE], s[S_CUR]
    if fpre != 0.0 and fcur != 0.0 and (fpre < 0.0) != (fcur < 0.0):
        xblk, fblk = xpre, fpre
        spre = scur = xcur - xpre
    if abs(fblk) < abs(fcur):
        xpre, xcur, xblk = xcur, xblk, xcur
        fpre, fcur, fblk = fcur, fblk, fcur
    delta = 0.5 * s[X_TOL]
    sbis = 0.5 * (xblk - xcur)
    done = fcur == 0.0 or abs(sbis) < delta
    if not done:
        if abs(spre) > delta and abs(fcur) < abs(fpre):
            # a zero denominator (equal values at two points) makes the trial infinite,
            # which the test below turns into bisection, as IEEE arithmetic would
            stry = math.inf
            if xpre == xblk:
                if fcur != fpre:
                    stry = -fcur * (xcur - xpre) / (fcur - fpre)  # secant
            elif xpre != xcur and xblk != xcur:
                # inverse quadratic interpolation through the three points
                dpre = (fpre - fcur) / (xpre - xcur)
                dblk = (fblk - fcur) / (xblk - xcur)
                den = dblk * dpre * (fblk - fpre)
                if den != 0.0:
                    stry = -fcur * (fblk * dblk - fpre * dpre) / den
            if 2.0 * abs(stry) < min(abs(spre), 3.0 * abs(sbis) - delta):
                spre = scur
                scur = stry
            else:
                spre = scur = sbis
        else:
            spre = scur = sbis
        xpre, fpre = xcur, fcur
        if abs(scur) > delta:
            xcur += scur
        else:
            xcur += delta if sbis > 0.0 else -delta
    s[X_PRE], s[X_CUR], s[F_PRE], s[F_CUR] = xpre, xcur, fpre, fcur
    s[X_BLK], s[F_BLK], s[S_PRE], s[S_CUR] = xblk, fblk, spre, scur
    return done


@njit(inline="always")
def crossed_end(s: np.ndarray) -> float:
    """The located end of the bracket on the crossed side (``f <= 0`` there)."""
    if s[F_CUR] <= 0.0:
        return s[X_CUR]
    return s[X_BLK]


# --- with rates: cubic Hermite interpolation, then Newton ----------------------------------
# When the caller also knows the function's derivative (the stator's gap and its exact
# rate), the cubic Hermite interpolant through both ends of the bracket is exact for a
# quadratic and third-order accurate otherwise, where Brent's method, seeing values
# only, crawls when the root sits near one end (a grazing contact: a gap of 1e-14 m
# closing from rest, tens of trials).  Same reverse-communication contract:
#
#     s = bracket_with_rates(ta, fa, da, tb, fb, db, xtol)   # fa > 0 >= fb
#     while not advance_with_rates(s):
#         s[R_F], s[R_D] = f(s[R_X]), f'(s[R_X])
#     t = s[R_B]                                              # f <= 0 there
#
# The first trial is the interpolant's first root in the bracket.  Every later trial is
# Newton's step from the trial before (the value and the derivative there are known:
# quadratic convergence, where a new interpolant over the shrunken bracket would be no
# more accurate than the first), as long as it stays in the bracket and at most half
# as long as the Newton step before it; else the interpolant's root again, or the
# middle when the last two trials did not halve the bracket.  Trials are kept half a
# tolerance inside the bracket (so a root known exactly is bracketed by the next
# trial), and a Newton trial aims a quarter of the tolerance past its root estimate,
# so that once the estimate is that close it lands on the crossed side.  A trial on
# the crossed side whose Newton step back to the root is within the tolerance ends the
# search there (as the masters' test at the end of a step does), so the search usually
# ends on the crossed side and the caller need not re-run onto it.
R_A, R_FA, R_DA, R_B, R_FB, R_DB, R_X, R_F, R_D, R_TOL, R_W1, R_W2, R_PENDING, R_NEWTON = range(14)
RATE_STATE_SIZE = 14


@njit(inline="always")
def hermite_cubic(fa: float, da: float, fb: float, db: float, h: float):
    """``(c3, c2, c1)``: the cubic Hermite interpolant with values ``fa``, ``fb`` and
    derivatives ``da``, ``db`` at 0 and ``h`` is ``((c3 th + c2) th + c1) th + fa``
    in ``th = t / h``, th in [0, 1]."""
    return 2.0 * (fa - fb) + h * (da + db), 3.0 * (fb - fa) - h * (2.0 * da + db), h * da


@njit(inline="always")
def hermite_critical_points(c3: float, c2: float, c1: float):
    """``(count, th0, th1)``: the zeros of the derivative of the cubic of
    :func:`hermite_cubic` (count 0, 1 or 2; th1 unset below 2)."""
    if abs(c3) > 1e-300:
        disc = c2 * c2 - 3.0 * c3 * c1
        if disc >= 0.0:
            sq = math.sqrt(disc)
            return 2, (-c2 - sq) / (3.0 * c3), (-c2 + sq) / (3.0 * c3)
        return 0, 0.0, 0.0
    if abs(c2) > 1e-300:
        return 1, -c1 / (2.0 * c2), 0.0
    return 0, 0.0, 0.0


@njit
def hermite_first_root(fa: float, da: float, fb: float, db: float, h: float) -> float:
    """The first zero in ``(0, h]`` of the cubic Hermite interpolant with values
    ``fa > 0 >= fb`` and derivatives ``da``, ``db`` at 0 and ``h``."""
    c3, c2, c1 = hermite_cubic(fa, da, fb, db, h)
    lo, hi = 0.0, 1.0
    # the first interval between critical points over which p changes sign
    n, r0, r1 = hermite_critical_points(c3, c2, c1)
    if n == 2 and r0 > r1:
        r0, r1 = r1, r0
    for k in range(n):
        r = r0 if k == 0 else r1
        if lo < r < hi and ((c3 * r + c2) * r + c1) * r + fa <= 0.0:
            hi = r
            break
    # Newton on the monotone piece from its secant point (a few steps from there where
    # the middle took many more), bisection when it leaves it
    # (lo is still 0 here, where p is fa: only hi moved)
    p_hi = ((c3 * hi + c2) * hi + c1) * hi + fa
    th = hi * (fa / (fa - p_hi)) if fa > p_hi else 0.5 * hi
    for _ in range(60):
        p = ((c3 * th + c2) * th + c1) * th + fa
        if p > 0.0:
            lo = th
        else:
            hi = th
        dp = (3.0 * c3 * th + 2.0 * c2) * th + c1
        step = p / dp if dp != 0.0 else math.inf
        if abs(step) <= 1e-15 * th:
            # converged: tested on the step, not on the next point, which round-off
            # may push out of the bracket (a bisection then, for nothing)
            th = min(max(th - step, lo), hi)
            break
        nxt = th - step
        if not lo < nxt < hi:
            nxt = 0.5 * (lo + hi)
        if hi - lo <= 1e-16:
            th = nxt
            break
        th = nxt
    return th * h


@njit
def bracket_with_rates(
    ta: float, fa: float, da: float, tb: float, fb: float, db: float, xtol: float
) -> np.ndarray:
    """The rate-aware locator's state for ``[ta, tb]`` with ``fa > 0 >= fb`` and the
    derivatives ``da``, ``db`` there; ``xtol`` as in :func:`bracket`."""
    s = np.empty(RATE_STATE_SIZE)
    start_with_rates(s, ta, fa, da, tb, fb, db, xtol)
    return s


@njit(inline="always")
def start_with_rates(
    s: np.ndarray, ta: float, fa: float, da: float, tb: float, fb: float, db: float, xtol: float
) -> None:
    """:func:`bracket_with_rates` into the caller's array ``s`` (``RATE_STATE_SIZE`` long)."""
    s[R_A], s[R_FA], s[R_DA] = ta, fa, da
    s[R_B], s[R_FB], s[R_DB] = tb, fb, db
    s[R_X], s[R_F], s[R_D] = ta, fa, da
    s[R_TOL] = xtol
    s[R_W1] = s[R_W2] = s[R_NEWTON] = math.inf
    s[R_PENDING] = 0.0


@njit(inline="always")
def advance_with_rates(s: np.ndarray) -> bool:
    """Take the value and derivative at the trial point into account and propose the
    next trial ``s[R_X]``; True when located (``s[R_B]`` is the crossed end)."""
    newton = math.inf  # Newton's step from the trial just evaluated, if any
    if s[R_PENDING] != 0.0:
        s[R_PENDING] = 0.0
        if s[R_F] > 0.0:
            s[R_A], s[R_FA], s[R_DA] = s[R_X], s[R_F], s[R_D]
        else:
            s[R_B], s[R_FB], s[R_DB] = s[R_X], s[R_F], s[R_D]
            if s[R_D] < 0.0 and -s[R_F] <= -s[R_D] * s[R_TOL]:
                return True  # crossed, and the root is within the tolerance behind
        if s[R_D] < 0.0:  # falling through the crossing, as a root in the bracket needs
            newton = -s[R_F] / s[R_D]
    a, b, tol = s[R_A], s[R_B], s[R_TOL]
    width = b - a
    if width <= tol or s[R_FB] == 0.0:
        return True
    x = s[R_X] + newton
    if a < x < b and abs(newton) <= 0.5 * s[R_NEWTON]:
        s[R_NEWTON] = abs(newton)
        x += 0.25 * tol
    else:
        s[R_NEWTON] = math.inf
        if width > 0.5 * s[R_W2]:  # two trials without halving the bracket: bisect
            x = a + 0.5 * width
        else:
            x = a + hermite_first_root(s[R_FA], s[R_DA], s[R_FB], s[R_DB], width)
    x = min(max(x, a + 0.5 * tol), b - 0.5 * tol)
    s[R_W2], s[R_W1] = s[R_W1], width
    s[R_X] = x
    s[R_PENDING] = 1.0
    return False
