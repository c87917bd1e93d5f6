"""One assembled system: right-hand side, event functions, event maps, outputs.

A system is described by two arrays built by :mod:`rubcosim.reference.assemble`:
``ip`` (integers: family, which units, state offsets) and ``p`` (reals: every
parameter in SI units), at the slots :mod:`.layout` derives from the unit
declarations (``P_STATOR_CLEARANCE``, ``IP_STATOR``, ``IP_ROTOR_JOURNAL_X``).
The functions here dispatch on them and call the kernels of :mod:`rubcosim.components`;
they are compiled once with numba and shared by both engines, so the ``fast`` and
``accurate`` engines differ only in how they take a Runge-Kutta step.

Families
--------
``FAMILY_ROTOR``: disc (x, y, vx, vy; always ``y[0:4]``: the rotor is the first role
of the registry and declares them first) [+ journal] [+ casing]; stator none,
rigid, elastic or casing; bearing none, linear or oil film (two-mass rotor);
delayed-feedback controller on the disc.
``FAMILY_HYBRID + i``: the hybrid unit type i of the registry, a whole model whose
own kernels hold its physics (the impact oscillators;
:mod:`rubcosim.components.hybrid_dispatch`).

Discrete modes
--------------
Rotor with a stator: ``MODE_FREE`` (no contact), ``MODE_SLIDE_POS`` /
``MODE_SLIDE_NEG`` (in contact, slip speed positive / negative: the friction
direction is fixed by the mode, so the right-hand side is smooth within a
step), ``MODE_STICK`` (in contact without slip: the disc rolls on the
stator, friction holds it).  For the rigid stator "in contact" is sustained
contact (full annular rub) with the normal force from the constraint; for
the elastic stators it is penalty contact.  Slip reversal, sticking and
release are events, so friction is a proper Filippov system, never a sign
that chatters inside a step.  A hybrid unit type numbers its own modes.

Outputs: :mod:`.system_outputs`.

Event slots
-----------
Four slots (layout and slot numbers: :mod:`.layout`).  ``dirs[k]``: 0 not an
event, -1 fires when g goes from > 0 to <= 0, +1 the reverse, 2 either way (a
breakpoint).  ``rates[k] = j`` says slot j holds dg_k/dt, used to find grazing
contacts inside a step.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from rubcosim.components import bearing_law, contact_law
from rubcosim.components.bearing import linear_bearing_force
from rubcosim.components.controller import delay_at, feedback_force
from rubcosim.components.hybrid_dispatch import (
    hybrid_apply,
    hybrid_events,
    hybrid_rhs,
)
from rubcosim.components.jit import njit
from rubcosim.components.kernels import planar_newton
from rubcosim.components.rotor import jeffcott_force, journal_force, two_mass_disc_force
from rubcosim.components.stator import (
    MODE_FREE,
    MODE_SLIDE_POS,
    MODE_STICK,
    chattering_ended,
    constraint_normal_force,
    contact_force_components,
    contact_geometry,
    friction_force,
    friction_reserve,
    rigid_impact,
    settle_mode,
    sticking_friction,
)

# The array layout is part of this module's interface (``system as S; S.P_ROTOR_MASS``),
# so all of it is imported here, and every kernel below reads its slots by name: module
# integers, which numba compiles in as constants.
# ruff: noqa: F405
from .layout import *  # noqa: F403


@nb.njit(cache=True, inline="always")
def control_active(t: float, p: np.ndarray, ip: np.ndarray) -> bool:
    on = ip[IP_FAMILY] == FAMILY_ROTOR and ip[IP_CONTROLLER] != CONTROLLER_NONE
    return on and t >= p[P_CONTROLLER_T_ON]


@nb.njit(cache=True, inline="always")
def current_delay(t: float, p: np.ndarray, ip: np.ndarray) -> float:
    """The controller's delay tau(t), s."""
    return delay_at(
        t,
        p[P_CONTROLLER_BASE_DELAY],
        p[P_CONTROLLER_MODULATION_AMPLITUDE],
        p[P_CONTROLLER_MODULATION_FREQUENCY],
        ip[IP_CONTROLLER_MODULATION_SHAPE],
        int(p[P_CONTROLLER_MODULATION_SEED]),
    )


@nb.njit(cache=True, inline="always")
def control_force(t: float, y: np.ndarray, yd: np.ndarray, p: np.ndarray, ip: np.ndarray):
    """Controller force on the disc, N (zero before t_on)."""
    if not control_active(t, p, ip):
        return 0.0, 0.0
    k = p[P_CONTROLLER_GAIN]
    if ip[IP_CONTROLLER_FEEDBACK] == CONTROLLER_FEEDBACK_POSITION:
        return feedback_force(k, y[0], yd[0]), feedback_force(k, y[1], yd[1])
    return feedback_force(k, y[2], yd[2]), feedback_force(k, y[3], yd[3])


@nb.njit(cache=True, inline="always")
def disc_external_force(t: float, y: np.ndarray, yd: np.ndarray, p: np.ndarray, ip: np.ndarray):
    """Every force on the disc except the stator contact, N."""
    x, yy, vx, vy = y[0], y[1], y[2], y[3]
    if ip[IP_ROTOR] == ROTOR_TWO_MASS:
        j = ip[IP_ROTOR_JOURNAL_X]
        fx, fy = two_mass_disc_force(
            t, y, 0, j, p[P_ROTOR_MASS], p[P_ROTOR_DAMPING], p[P_ROTOR_STIFFNESS],
            p[P_ROTOR_SHAFT_DAMPING], p[P_ROTOR_ECCENTRICITY], p[P_ROTOR_SPEED],
            p[P_ROTOR_GRAVITY],
        )  # fmt: skip
    else:
        fx, fy = jeffcott_force(
            t, x, yy, vx, vy, p[P_ROTOR_MASS], p[P_ROTOR_DAMPING], p[P_ROTOR_STIFFNESS],
            p[P_ROTOR_ECCENTRICITY], p[P_ROTOR_SPEED], p[P_ROTOR_GRAVITY],
        )  # fmt: skip
    if not control_active(t, p, ip):
        # no control force: adding its zeros would put one more addition on the chain
        # from one Runge-Kutta stage to the next (x + 0.0 is x, but for the sign of a zero)
        return fx, fy
    ux, uy = control_force(t, y, yd, p, ip)
    return fx + ux, fy + uy


@nb.njit(cache=True, inline="always")
def stator_centre(y: np.ndarray, p: np.ndarray, ip: np.ndarray):
    """Stator centre position and velocity (the casing moves it)."""
    c = ip[IP_STATOR_CASING_X]
    if c >= 0:
        return p[P_STATOR_X_OFFSET] + y[c], p[P_STATOR_Y_OFFSET] + y[c + 1], y[c + 2], y[c + 3]
    return p[P_STATOR_X_OFFSET], p[P_STATOR_Y_OFFSET], 0.0, 0.0


@nb.njit(cache=True, inline="always")
def contact_kinematics(y: np.ndarray, p: np.ndarray, ip: np.ndarray):
    """Distance, normal (nx, ny) and relative normal/tangential speeds of the disc."""
    cx, cy, cvx, cvy = stator_centre(y, p, ip)
    dist, nx, ny = contact_geometry(y[0] - cx, y[1] - cy)
    rvx, rvy = y[2] - cvx, y[3] - cvy
    return dist, nx, ny, rvx * nx + rvy * ny, -rvx * ny + rvy * nx


@nb.njit(cache=True, inline="always")
def casing_support_force(y: np.ndarray, p: np.ndarray, ip: np.ndarray):
    c = ip[IP_STATOR_CASING_X]
    if c < 0:
        return 0.0, 0.0
    # the casing mount is an isotropic spring-damper: the linear bearing's law
    return linear_bearing_force(
        y[c], y[c + 1], y[c + 2], y[c + 3], p[P_STATOR_STIFFNESS], p[P_STATOR_DAMPING]
    )


# The contact laws below take the disc's other forces (fx, fy) from their caller, which
# evaluates them once: each evaluation is a copy of the forcing's trigonometry in every
# compiled right-hand side, and there are many of those (a cold compile's time).
@nb.njit(cache=True, inline="always")
def force_for_contact_laws(t, y, yd, mode, p, ip):
    """The disc's other forces (:func:`disc_external_force`, N) where the contact laws in
    ``mode`` read them, else zeros: the rigid stator's constraint force and every
    sticking contact read them; free flight and an elastic stator's sliding do not."""
    if mode != MODE_FREE and (ip[IP_STATOR] == STATOR_RIGID or mode == MODE_STICK):
        return disc_external_force(t, y, yd, p, ip)
    return 0.0, 0.0


@nb.njit(cache=True, inline="always")
def contact_normal_force(fx, fy, p, ip, dist, nx, ny, vn, vt):
    """Normal contact force on a disc in contact, N (> 0 pushes it inward); ``(fx, fy)``
    every other force on the disc (:func:`disc_external_force`)."""
    if ip[IP_STATOR] == STATOR_RIGID:
        return constraint_normal_force(
            fx, fy, nx, ny, vt, vn, dist, p[P_STATOR_CLEARANCE], p[P_ROTOR_MASS], p[P_OMEGA_B]
        )
    # the stator type's declared law (components.contact_law), its quantities side by side
    return contact_law.penalty_law_normal(ip[IP_STATOR_LAW], dist, vn, p, P_STATOR_LAW_0)


@nb.njit(cache=True, inline="always")
def holding_friction(fx, fy, y, p, ip, dist, nx, ny, vn, vt):
    """Tangential force that keeps the slip speed at zero (sticking contact), N; ``(fx,
    fy)`` every other force on the disc."""
    sx, sy = casing_support_force(y, p, ip)
    ms = p[P_STATOR_MASS] if ip[IP_STATOR_CASING_X] >= 0 else math.inf
    return sticking_friction(
        -fx * ny + fy * nx, -sx * ny + sy * nx, vt, vn, dist, p[P_ROTOR_MASS], ms
    )


@nb.njit(cache=True, inline="always")
def contact_force(fx, fy, y, mode, p, ip):
    """Stator contact force on the disc (fx, fy) and its normal part, N; the arguments
    ``(fx, fy)`` every other force on the disc (read where :func:`force_for_contact_laws` says)."""
    if ip[IP_STATOR] == STATOR_NONE or mode == MODE_FREE:
        return 0.0, 0.0, 0.0
    dist, nx, ny, vn, vt = contact_kinematics(y, p, ip)
    n = contact_normal_force(fx, fy, p, ip, dist, nx, ny, vn, vt)
    hold = 0.0
    if mode == MODE_STICK:
        hold = holding_friction(fx, fy, y, p, ip, dist, nx, ny, vn, vt)
    ft = friction_force(mode, p[P_STATOR_FRICTION], n, hold)
    cfx, cfy = contact_force_components(n, ft, nx, ny)
    return cfx, cfy, n


@nb.njit(cache=True, inline="always")
def bearing_force(y: np.ndarray, p: np.ndarray, ip: np.ndarray):
    """The bearing's force on the journal, N: its type's declared law
    (components.bearing_law), its quantities side by side."""
    j, law = ip[IP_ROTOR_JOURNAL_X], ip[IP_BEARING_LAW]
    if j < 0 or law < 0:
        return 0.0, 0.0
    return bearing_law.bearing_law_force(
        law, y[j], y[j + 1], y[j + 2], y[j + 3], p, P_BEARING_LAW_0
    )


@nb.njit(cache=True, inline="always")
def rotor_rhs(t, y, yd, mode, p, ip, dy):
    fx, fy = disc_external_force(t, y, yd, p, ip)
    cfx, cfy, _ = contact_force(fx, fy, y, mode, p, ip)
    if mode == MODE_FREE:  # no contact force to add (see disc_external_force)
        planar_newton(y, 0, fx, fy, p[P_ROTOR_MASS], dy)
    else:
        planar_newton(y, 0, fx + cfx, fy + cfy, p[P_ROTOR_MASS], dy)
    j = ip[IP_ROTOR_JOURNAL_X]
    if j >= 0:
        jx, jy = journal_force(
            y, 0, j, p[P_ROTOR_STIFFNESS], p[P_ROTOR_SHAFT_DAMPING], p[P_ROTOR_JOURNAL_MASS],
            p[P_ROTOR_JOURNAL_DAMPING], p[P_ROTOR_GRAVITY],
        )  # fmt: skip
        bx, by = bearing_force(y, p, ip)
        planar_newton(y, j, jx + bx, jy + by, p[P_ROTOR_JOURNAL_MASS], dy)
    c = ip[IP_STATOR_CASING_X]
    if c >= 0:
        sx, sy = casing_support_force(y, p, ip)
        planar_newton(y, c, -cfx + sx, -cfy + sy, p[P_STATOR_MASS], dy)


@nb.njit(cache=True, inline="always")
def rhs(t, y, yd, mode, p, ip, dy):
    """dy/dt for the system in ``mode``; ``yd`` is the delayed disc state."""
    if ip[IP_FAMILY] == FAMILY_ROTOR:
        rotor_rhs(t, y, yd, mode, p, ip, dy)
    else:
        hybrid_rhs(ip[IP_FAMILY] - FAMILY_HYBRID, t, y, mode, p, dy)


@nb.njit(cache=True, inline="always")
def rotor_events(t, y, yd, mode, p, ip, g, dirs, rates):
    kind = ip[IP_STATOR]
    if kind == STATOR_NONE:
        return
    dist, nx, ny, vn, vt = contact_kinematics(y, p, ip)
    if mode == MODE_FREE:
        g[0] = p[P_STATOR_CLEARANCE] - dist
        g[1] = -vn
        dirs[0] = -1
        rates[0] = 1
        return
    fx, fy = force_for_contact_laws(t, y, yd, mode, p, ip)
    n = contact_normal_force(fx, fy, p, ip, dist, nx, ny, vn, vt)
    if kind == STATOR_RIGID:
        g[0] = n
        dirs[0] = -1
    else:
        g[0] = p[P_STATOR_CLEARANCE] - dist
        g[1] = -vn
        dirs[0] = 1
        rates[0] = 1
    if mode == MODE_STICK:
        hold = holding_friction(fx, fy, y, p, ip, dist, nx, ny, vn, vt)
        g[2] = friction_reserve(p[P_STATOR_FRICTION], n, hold)
        dirs[2] = -1
    else:
        g[2] = vt + p[P_ROTOR_DISC_RADIUS] * p[P_ROTOR_SPEED]
        dirs[2] = -1 if mode == MODE_SLIDE_POS else 1


@nb.njit(cache=True, inline="always")
def events(t, y, yd, mode, p, ip, g, dirs, rates):
    """Fill the event functions ``g``, their directions and rate companions."""
    for k in range(N_EVENTS):
        g[k] = 1.0
        dirs[k] = 0
        rates[k] = -1
    if ip[IP_FAMILY] == FAMILY_ROTOR:
        rotor_events(t, y, yd, mode, p, ip, g, dirs, rates)
    else:
        hybrid_events(ip[IP_FAMILY] - FAMILY_HYBRID, t, y, mode, p, g, dirs, rates)


@njit(borrows=True)
def settle_contact(t, y, yd, p, ip, slip_threshold, current):
    """Mode of a disc in contact: sliding with the sign of the slip, or sticking
    if the slip is (below ``slip_threshold``) zero and friction can hold it."""
    dist, nx, ny, vn, vt = contact_kinematics(y, p, ip)
    fx, fy = disc_external_force(t, y, yd, p, ip)
    n = contact_normal_force(fx, fy, p, ip, dist, nx, ny, vn, vt)
    hold = holding_friction(fx, fy, y, p, ip, dist, nx, ny, vn, vt)
    reserve = friction_reserve(p[P_STATOR_FRICTION], n, hold)
    spin = p[P_ROTOR_DISC_RADIUS] * p[P_ROTOR_SPEED]  # surface speed Rd w
    mode = settle_mode(vt + spin, slip_threshold, reserve, hold, current)
    if mode == MODE_STICK and ip[IP_STATOR] == STATOR_RIGID:
        # rolling without slip on a fixed stator: tangential speed exactly -Rd w
        dvt = -spin - vt
        y[2] -= dvt * ny
        y[3] += dvt * nx
    return mode


@njit(borrows=True)
def rotor_apply(k, t, y, yd, mode, p, ip):
    rigid = ip[IP_STATOR] == STATOR_RIGID
    if k == 2:
        return settle_contact(t, y, yd, p, ip, math.inf, mode), KIND_SLIP
    if mode != MODE_FREE:
        return MODE_FREE, KIND_RELEASE if rigid else KIND_CONTACT_OFF
    if not rigid:
        return settle_contact(t, y, yd, p, ip, p[P_VCHAT], mode), KIND_CONTACT_ON
    d = p[P_STATOR_CLEARANCE]
    dist, nx, ny = contact_geometry(y[0] - p[P_STATOR_X_OFFSET], y[1] - p[P_STATOR_Y_OFFSET])
    # The event locator leaves the disc within round-off of the stator: put it on it.
    y[0] = p[P_STATOR_X_OFFSET] + d * nx
    y[1] = p[P_STATOR_Y_OFFSET] + d * ny
    vx, vy = rigid_impact(
        y[2], y[3], nx, ny,
        p[P_STATOR_RESTITUTION], p[P_STATOR_FRICTION], p[P_ROTOR_DISC_RADIUS], p[P_ROTOR_SPEED],
    )  # fmt: skip
    vn = vx * nx + vy * ny
    y[2] = vx
    y[3] = vy
    # This engine resolves every flight: only the rebound speed ends chattering.
    if not chattering_ended(-vn, p[P_VCHAT], math.inf, 0.0):
        return MODE_FREE, KIND_IMPACT
    # The rebound is too small to leave: chattering has ended.
    y[2] = vx - vn * nx
    y[3] = vy - vn * ny
    fx, fy = disc_external_force(t, y, yd, p, ip)
    vt = -y[2] * ny + y[3] * nx
    n = constraint_normal_force(fx, fy, nx, ny, vt, 0.0, d, d, p[P_ROTOR_MASS], 0.0)
    if n > 0.0:
        return settle_contact(t, y, yd, p, ip, p[P_VCHAT], np.int64(MODE_FREE)), KIND_IMPACT
    return MODE_FREE, KIND_IMPACT


@njit(borrows=True, inline="always")  # a dispatch: inlined, one call less per event
def apply_event(k, t, y, yd, mode, p, ip):
    """Apply the event of slot ``k`` at time t: may change y in place.

    Returns ``(new_mode, kind)``.
    """
    if ip[IP_FAMILY] == FAMILY_ROTOR:
        return rotor_apply(k, t, y, yd, mode, p, ip)
    return hybrid_apply(ip[IP_FAMILY] - FAMILY_HYBRID, k, t, y, mode, p)
