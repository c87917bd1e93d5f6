"""The ODE of every unit with a continuous state, as one compiled right-hand side.

A unit's inputs are polynomials over its step (value, first and second
derivative at the step's start, see :class:`.unit.Unit`); they arrive here
as rows ``u[i] = (value, d1, d2)`` in the order of the unit's ``ode_inputs``, with
``t0`` the step's start.  Parameters come as a flat array in the order the
``*_P`` names below give (a stator's: :data:`PENALTY_P`, then its contact law).
One function with a ``kind`` switch, not one per unit: numba caches a compiled
function only if it takes no function arguments, and the stepper
(:func:`.stepping.advance`) must be cached.
"""

from __future__ import annotations

from . import contact_law
from .bearing import linear_bearing_force
from .jit import njit
from .kernels import planar_newton, polynomial_at
from .rotor import jeffcott_force, journal_force, two_mass_disc_force
from .stator import contact_geometry, penalty_force_components

JEFFCOTT = 0
TWO_MASS = 1
CASING = 2

# parameter order per kind (names of the unit's parameters)
JEFFCOTT_P = ("mass", "damping", "stiffness", "eccentricity", "speed", "gravity")
TWO_MASS_P = (*JEFFCOTT_P, "shaft_damping", "journal_mass", "journal_damping")
# A penalty stator's parameter row (massless: the casing's mount and mass zero), then
# the index of its contact law (:mod:`.contact_law`) and, from LAW_AT on, the quantities
# the law takes.
PENALTY_P = (
    "clearance",
    "friction",
    "disc_radius",
    "speed",
    "x_offset",
    "y_offset",
    "stiffness",
    "damping",
    "mass",
)
LAW = len(PENALTY_P)
LAW_AT = LAW + 1


@njit
def row_contact_force(rx, ry, rvx, rvy, p):
    """The penalty contact force ``(fx, fy, Fn)`` on the disc (N) at position r (m) and
    velocity rv (m/s) relative to the stator, for the stator whose parameter row (the
    order of :data:`PENALTY_P`, then its law) is ``p``."""
    dist, nx, ny = contact_geometry(rx, ry)
    law = int(p[LAW])
    fn = contact_law.penalty_law_normal(law, dist, rvx * nx + rvy * ny, p, LAW_AT)
    return penalty_force_components(fn, dist, nx, ny, rvx, rvy, p[0], p[1], p[2], p[3])


@njit
def input_at(u, i, s):
    """Input ``i`` at ``s`` seconds into the step."""
    return polynomial_at(u[i, 0], u[i, 1], u[i, 2], s)


@njit
def unit_rhs(kind, t, y, p, u, t0, dy):
    """dy/dt of unit ``kind`` at time ``t`` (s), written into ``dy``."""
    s = t - t0
    if kind == JEFFCOTT:
        # state (x, y, vx, vy) of the disc; inputs fx, fy (N)
        m = p[0]
        fx, fy = jeffcott_force(t, y[0], y[1], y[2], y[3], m, p[1], p[2], p[3], p[4], p[5])
        planar_newton(y, 0, fx + input_at(u, 0, s), fy + input_at(u, 1, s), m, dy)
    elif kind == TWO_MASS:
        # state: disc (x, y, vx, vy), journal (x, y, vx, vy); inputs fx, fy on the disc
        # and journal_fx, journal_fy
        m, k, g, cs, mj, cj = p[0], p[2], p[5], p[6], p[7], p[8]
        fx, fy = two_mass_disc_force(t, y, 0, 4, m, p[1], k, cs, p[3], p[4], g)
        jx, jy = journal_force(y, 0, 4, k, cs, mj, cj, g)
        planar_newton(y, 0, fx + input_at(u, 0, s), fy + input_at(u, 1, s), m, dy)
        planar_newton(y, 4, jx + input_at(u, 2, s), jy + input_at(u, 3, s), mj, dy)
    elif kind == CASING:
        # state: casing (x, y, vx, vy); inputs: disc x, y, vx, vy.  The mount is an
        # isotropic spring-damper (the linear bearing's law); the casing feels the
        # opposite of the contact force on the disc.
        cx = p[4] + y[0]
        cy = p[5] + y[1]
        fx, fy, _ = row_contact_force(
            input_at(u, 0, s) - cx,
            input_at(u, 1, s) - cy,
            input_at(u, 2, s) - y[2],
            input_at(u, 3, s) - y[3],
            p,
        )
        sx, sy = linear_bearing_force(y[0], y[1], y[2], y[3], p[6], p[7])
        planar_newton(y, 0, sx - fx, sy - fy, p[8], dy)
