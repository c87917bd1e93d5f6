"""Closed forms for the bouncing-ball examples, independent of rubcosim and of the FMU.

The ball dropped from rest at ``h0`` flies on parabolas between bounces; each bounce
reverses and scales its speed by ``e``; rebounds slower than ``V_MIN`` come to rest
(as in bouncing_ball.c).  :func:`driven_oscillator` integrates the linear impact
oscillator x'' + k x = A cos(w t) + f(t) forced by the ball's height or velocity with
scipy, one flight at a time (so no step straddles a bounce) and with its own impacts
located by scipy's event finder: a second method for oscillator_and_ball.toml.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

G = 9.81  # m/s2, the FMU's default
V_MIN = 1e-6  # m/s


def flights(h0: float, e: float, t_end: float) -> list[tuple[float, float, float]]:
    """``(start, height, upward speed)`` of each flight, the last one at rest."""
    out = [(0.0, h0, 0.0)]
    t = math.sqrt(2.0 * h0 / G)
    v = e * G * t
    while t < t_end and v > V_MIN:
        out.append((t, 0.0, v))
        t += 2.0 * v / G
        v *= e
    out.append((t, 0.0, 0.0))
    return out


def ball_state(t: float, h0: float, e: float) -> tuple[float, float]:
    """Height (m) and velocity (m/s, up positive) of the ball at ``t``."""
    fl = flights(h0, e, t)
    for k in range(len(fl) - 1, -1, -1):
        t0, h, v = fl[k]
        if t >= t0:
            if k == len(fl) - 1 and k > 0:
                return 0.0, 0.0
            s = t - t0
            return h + v * s - 0.5 * G * s * s, v - G * s
    raise ValueError("t < 0")


def driven_oscillator(
    t_out: np.ndarray,
    field: str = "h",
    h0: float = 1.0,
    e: float = 0.7,
    k: float = 1.0,
    amplitude: float = 1.0,
    w: float = 2.0,
    restitution: float = 0.8,
    x0: float = -1.0,
) -> np.ndarray:
    """Displacement of the oscillator (stop at x = 0) at ``t_out`` (from 0, increasing),
    forced by the ball's ``field`` ("h" or "v"), at rtol 1e-12."""
    fl = flights(h0, e, float(t_out[-1]))
    x = np.full(len(t_out), np.nan)
    y, t = np.array([x0, 0.0]), 0.0
    for i, (t0, h, v) in enumerate(fl):
        resting = i == len(fl) - 1 and i > 0
        t_stop = fl[i + 1][0] if i + 1 < len(fl) else float(t_out[-1])
        t_stop = min(t_stop, float(t_out[-1]))

        def force(tt: float, t0=t0, h=h, v=v, resting=resting) -> float:
            if resting:
                return 0.0
            s = tt - t0
            return h + v * s - 0.5 * G * s * s if field == "h" else v - G * s

        def rhs(tt, yy, force=force):
            return [yy[1], -k * yy[0] + amplitude * math.cos(w * tt) + force(tt)]

        def stop(tt, yy):
            return yy[0]

        stop.terminal, stop.direction = True, 1.0
        while t < t_stop:
            sol = solve_ivp(
                rhs,
                (t, t_stop),
                y,
                "DOP853",
                rtol=1e-12,
                atol=1e-14,
                events=stop,
                dense_output=True,
            )
            inside = (t_out >= t) & (t_out <= sol.t[-1])
            if inside.any() and sol.t[-1] > t:
                x[inside] = sol.sol(t_out[inside])[0]
            t, y = sol.t[-1], sol.y[:, -1].copy()
            if sol.status == 1:  # impact: Newton's law at the stop
                y[0], y[1] = 0.0, -restitution * y[1]
        if t >= t_out[-1]:
            break
    return x
