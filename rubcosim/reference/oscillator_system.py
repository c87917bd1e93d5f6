"""The single-DOF impact oscillator family of an assembled system (state x, v).

Right-hand side, event functions, event maps and outputs, dispatched to by
:mod:`.system`.  Modes: ``MODE_FREE``, ``MODE_STUCK_UPPER`` (resting on the
barrier +D), ``MODE_STUCK_LOWER`` (on -D).  The impact, the end of chattering
and the release are the kernels of :mod:`rubcosim.components.oscillator`,
which the co-simulation unit calls too.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from rubcosim.components.oscillator import (
    STOP_ELASTIC_ONE,
    STOP_ELASTIC_TWO,
    STOP_NONE,
    STOP_RIGID_ONE,
    STOP_RIGID_TWO,
    barrier_gap,
    elastic_stop_force,
    free_acceleration,
    pressing,
    stop_impact,
)
from rubcosim.components.stator import MODE_FREE

from .layout import (
    IP_STOP,
    KIND_CONTACT_OFF,
    KIND_CONTACT_ON,
    KIND_IMPACT,
    KIND_RELEASE,
    MODE_STUCK_LOWER,
    MODE_STUCK_UPPER,
    P_A,
    P_B,
    P_C3,
    P_DB,
    P_F,
    P_KSTOP,
    P_RR,
    P_VCHAT,
    P_WF,
)


@nb.njit(cache=True, inline="always")
def resting_acceleration(t: float, side: int, p: np.ndarray) -> float:
    """Free acceleration (m/s^2) of the mass at rest on the barrier on ``side`` (+1: +D)."""
    return free_acceleration(t, side * p[P_DB], 0.0, p[P_A], p[P_B], p[P_C3], p[P_F], p[P_WF])


@nb.njit(cache=True, inline="always")
def oscillator_rhs(
    t: float, y: np.ndarray, mode: int, p: np.ndarray, ip: np.ndarray, dy: np.ndarray
) -> None:
    """dy/dt = (v, a); at rest while stuck on a barrier."""
    if mode != MODE_FREE:
        dy[0] = 0.0
        dy[1] = 0.0
        return
    acc = free_acceleration(t, y[0], y[1], p[P_A], p[P_B], p[P_C3], p[P_F], p[P_WF])
    acc += elastic_stop_force(y[0], ip[IP_STOP], p[P_DB], p[P_KSTOP])
    dy[0] = y[1]
    dy[1] = acc


@nb.njit(cache=True, inline="always")
def oscillator_events(
    t: float,
    y: np.ndarray,
    mode: int,
    p: np.ndarray,
    ip: np.ndarray,
    g: np.ndarray,
    dirs: np.ndarray,
    rates: np.ndarray,
) -> None:
    """Slot 0: the barrier +D (impact, or a breakpoint of an elastic stop) or, stuck
    there, its release; slot 2: the same for -D; slots 1 and 3: their rates."""
    stop = ip[IP_STOP]
    if stop == STOP_NONE:
        return
    D = p[P_DB]
    if mode == MODE_STUCK_UPPER:
        g[0] = pressing(1, resting_acceleration(t, 1, p))
        dirs[0] = -1
        return
    if mode == MODE_STUCK_LOWER:
        g[2] = pressing(-1, resting_acceleration(t, -1, p))
        dirs[2] = -1
        return
    rigid = stop == STOP_RIGID_ONE or stop == STOP_RIGID_TWO
    g[0] = barrier_gap(y[0], D, 1)
    g[1] = -y[1]
    dirs[0] = -1 if rigid else 2
    rates[0] = 1
    if stop == STOP_RIGID_TWO or stop == STOP_ELASTIC_TWO:
        g[2] = barrier_gap(y[0], D, -1)
        g[3] = y[1]
        dirs[2] = -1 if rigid else 2
        rates[2] = 3


@nb.njit(cache=True)
def oscillator_apply(
    k: int, t: float, y: np.ndarray, mode: int, p: np.ndarray, ip: np.ndarray
) -> tuple[int, int]:
    """Event of slot ``k``: crossing an elastic stop's edge, release from a barrier,
    or an impact (which may end chattering and stick).  Returns ``(mode, kind)``."""
    stop = ip[IP_STOP]
    if stop == STOP_ELASTIC_ONE or stop == STOP_ELASTIC_TWO:
        entering = y[1] > 0.0 if k == 0 else y[1] < 0.0
        return mode, KIND_CONTACT_ON if entering else KIND_CONTACT_OFF
    if mode != MODE_FREE:
        return MODE_FREE, KIND_RELEASE
    side = 1 if k == 0 else -1
    y[0] = side * p[P_DB]
    y[1], stuck = stop_impact(y[1], p[P_RR], p[P_VCHAT], side, resting_acceleration(t, side, p))
    if stuck:
        return (MODE_STUCK_UPPER if k == 0 else MODE_STUCK_LOWER), KIND_IMPACT
    return MODE_FREE, KIND_IMPACT


@nb.njit(cache=True)
def oscillator_outputs(
    y: np.ndarray, mode: int, p: np.ndarray, ip: np.ndarray, out: np.ndarray
) -> None:
    """x, v and contact: 0 free, 1 inside an elastic stop, 2 stuck on a barrier."""
    out[0] = y[0]
    out[1] = y[1]
    out[2] = 0.0 if mode == MODE_FREE else 2.0
    stop = ip[IP_STOP]
    if (stop == STOP_ELASTIC_ONE or stop == STOP_ELASTIC_TWO) and (
        y[0] > p[P_DB] or (stop == STOP_ELASTIC_TWO and y[0] < -p[P_DB])
    ):
        out[2] = 1.0
