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


@njit
def bracket(ta: float, fa: float, tb: float, fb: float, xtol: float) -> np.ndarray:
    """The locator's state for a bracket ``[ta, tb]`` with ``fa > 0 >= fb``; ``xtol`` is
    the width (same unit as t) below which the bracket counts as located."""
    s = np.empty(STATE_SIZE)
    s[X_PRE], s[X_CUR], s[F_PRE], s[F_CUR] = ta, tb, fa, fb
    s[X_BLK], s[F_BLK] = ta, fa
    s[S_PRE] = s[S_CUR] = tb - ta
    s[X_TOL] = xtol
    return s


@njit
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


@njit
def crossed_end(s: np.ndarray) -> float:
    """The located end of the bracket on the crossed side (``f <= 0`` there)."""
    if s[F_CUR] <= 0.0:
        return s[X_CUR]
    return s[X_BLK]
