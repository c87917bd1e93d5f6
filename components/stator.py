"""Stator: rigid impact law, massless penalty contact, elastic casing.

Geometry: stator centred at (x_offset, y_offset) + casing displacement, radial
clearance ``d``.  For a disc at p, ``dist = |p - c|``, gap ``g = d - dist``
(positive when open), outward normal ``n = (p - c)/dist`` and tangent
``t = (-n_y, n_x)`` in the spin sense (x->y).  The slip speed of the disc
surface over the stator is ``vs = v.t + Rd w``; friction opposes it.

Sign convention for forces: returned forces act on the rotor disc; the casing
(if any) feels the opposite.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from .jit import njit
from .kernels import hypot
from .parameters import nonnegative, planar_initial_state, positive, real

# Contact modes of a disc on a stator: free, sliding with positive or negative slip,
# sticking.  The reference engine's mode variable and the rigid stator unit's
# contact_mode input use these numbers.
MODE_FREE, MODE_SLIDE_POS, MODE_SLIDE_NEG, MODE_STICK = 0, 1, 2, 3

CONTACT_GEOMETRY = (
    positive("clearance", None, "m", "radial clearance d between disc and stator", example=1e-4),
    real("x_offset", 0.0, "m", "stator centre x0 (offset rotor when nonzero)"),
    real("y_offset", 0.0, "m", "stator centre y0 (offset rotor when nonzero)"),
    nonnegative("friction", 0.0, "1", "Coulomb friction coefficient mu"),
)

RIGID_PARAMS = (
    *CONTACT_GEOMETRY,
    real("restitution", 0.8, "1", "Newton restitution coefficient r", 0.0, 1.0),
)

ELASTIC_PARAMS = (
    *CONTACT_GEOMETRY,
    positive("contact_stiffness", None, "N/m", "penalty contact stiffness kc", example=2e7),
    real(
        "contact_damping",
        -1.0,
        "N s/m",
        "contact damping cc; negative means derive it from the restitution",
        -1.0,
    ),
    real("restitution", 1.0, "1", "restitution used to derive cc when not given", 0.0, 1.0),
)

CASING_PARAMS = (
    *ELASTIC_PARAMS,
    positive("mass", None, "kg", "casing mass ms", example=5.0),
    positive("stiffness", None, "N/m", "casing support stiffness ks", example=2e6),
    nonnegative("damping", 0.0, "N s/m", "casing support damping cs"),
    *planar_initial_state("", "casing"),
)


@njit
def contact_geometry(rx: float, ry: float) -> tuple[float, float, float]:
    """Distance and outward unit normal for the relative position r = p - c.

    At the exact centre the normal is undefined; +x is returned so that the
    caller never divides by zero (the gap is then the full clearance).
    """
    dist = hypot(rx, ry)
    if dist == 0.0:
        return 0.0, 1.0, 0.0
    return dist, rx / dist, ry / dist


@njit
def slip_speed(vx: float, vy: float, nx: float, ny: float, rd: float, w: float) -> float:
    """Slip speed vs = v.t + Rd w of the disc surface over the stator, m/s."""
    return -vx * ny + vy * nx + rd * w


@njit
def rigid_impact(
    vx: float,
    vy: float,
    nx: float,
    ny: float,
    r: float,
    mu: float,
    rd: float,
    w: float,
) -> tuple[float, float]:
    """Post-impact disc velocity for a rigid stator at rest.

    Newton's law on the normal (vn+ = -r vn-) and a Coulomb impulse
    ``mu (1 + r) vn-`` against the slip on the tangent.  The friction impulse
    may stop the slip but never reverse it (sticking impact), so the impact
    never feeds energy into the relative motion (vn, vs).  Only an approaching
    disc (vn- > 0) is changed.
    """
    vn = vx * nx + vy * ny
    if vn <= 0.0:
        return vx, vy
    vt = -vx * ny + vy * nx
    vs = vt + rd * w
    dvt = mu * (1.0 + r) * vn
    if abs(vs) <= dvt:
        vt_new = -rd * w
    elif vs > 0.0:
        vt_new = vt - dvt
    else:
        vt_new = vt + dvt
    vn_new = -r * vn
    return vn_new * nx - vt_new * ny, vn_new * ny + vt_new * nx


@njit
def penalty_normal(dist: float, vn: float, d: float, kc: float, cc: float) -> float:
    """Kelvin-Voigt normal force ``Fn = kc (dist - d) + cc vn`` of a disc in contact, N.

    ``dist`` (m) is the disc's distance from the stator centre, ``vn`` (m/s) its
    outward normal speed relative to the stator; ``Fn > 0`` pushes the disc
    inward.  Linear, as in the brief: it may pull for a moment before
    separation, which keeps the restitution of :func:`damping_from_restitution`
    exact.  The caller decides contact (``dist > d``).
    """
    return kc * (dist - d) + cc * vn


@njit
def penalty_normal_force(
    rx: float, ry: float, rvx: float, rvy: float, d: float, kc: float, cc: float
) -> tuple[float, float, float, float]:
    """:func:`penalty_normal` for the relative position r (m) and velocity rv (m/s) of
    the disc; returns ``(Fn, dist, nx, ny)``."""
    dist, nx, ny = contact_geometry(rx, ry)
    return penalty_normal(dist, rvx * nx + rvy * ny, d, kc, cc), dist, nx, ny


@njit
def friction_limit(mu: float, n: float) -> float:
    """Largest Coulomb friction force ``mu max(Fn, 0)``, N.

    Friction follows the compressive part of the normal force only: in the
    moment before a penalty contact separates the damper makes ``Fn`` pull
    (``Fn < 0``), and ``mu Fn`` would then push the disc along its slip.
    """
    return mu * max(n, 0.0)


@njit
def friction_reserve(mu: float, n: float, hold: float) -> float:
    """How much more friction a sticking contact could give, ``mu max(Fn, 0) - |hold|``,
    N; it starts to slide when this falls through 0 (``hold``: the tangential force
    that keeps the slip speed constant, :func:`sticking_friction`)."""
    return friction_limit(mu, n) - abs(hold)


@njit
def friction_force(mode: int, mu: float, n: float, hold: float) -> float:
    """Tangential contact force on the disc along t (N) in contact mode ``mode``.

    Sliding with positive slip: ``-mu max(Fn, 0)`` (against the slip); with
    negative slip ``+mu max(Fn, 0)``; sticking: the holding force ``hold``;
    free: 0.
    """
    if mode == MODE_SLIDE_POS:
        return -friction_limit(mu, n)
    if mode == MODE_SLIDE_NEG:
        return friction_limit(mu, n)
    if mode == MODE_STICK:
        return hold
    return 0.0


@njit
def slip_mode(slip: float) -> int:
    """Contact mode of a contact that slips at ``slip`` m/s: sliding with its sign, or
    sticking (no friction needed to hold it) when it is exactly zero."""
    if slip > 0.0:
        return MODE_SLIDE_POS
    if slip < 0.0:
        return MODE_SLIDE_NEG
    return MODE_STICK


@njit
def settle_mode(slip: float, threshold: float, reserve: float, hold: float, current: int) -> int:
    """Mode of a disc settling into contact, or at a slip event of a contact in ``current``.

    ``slip`` (m/s) is the slip speed; above ``threshold`` (m/s; pass ``inf`` at
    a slip event, where the slip is zero by construction) the contact slides
    with its sign.  Otherwise it sticks if friction can hold it (``reserve =
    mu max(Fn, 0) - |hold| >= 0``, N) or if sliding would go back the way it
    came (``current``), which the slip event just ruled out (round-off).  A
    sticking contact whose reserve ran out (``current = MODE_STICK``) slides
    against the holding force ``hold`` (N, along t).
    """
    if abs(slip) > threshold:
        return MODE_SLIDE_POS if slip > 0.0 else MODE_SLIDE_NEG
    slide = MODE_SLIDE_NEG if hold > 0.0 else MODE_SLIDE_POS
    if current != MODE_STICK and (reserve >= 0.0 or slide == current):
        return MODE_STICK
    return slide


@njit
def chattering_ended(rebound: float, v_chat: float, flight: float, min_flight: float) -> bool:
    """Whether a rigid impact ends a chattering sequence.

    ``rebound`` (m/s, > 0 leaving the stator) is the normal speed just after
    the impact; below ``v_chat`` the next flight would rise a few ulps of the
    gap at most, so the disc is put on the stator (sustained contact if the
    other forces press it on, else free with zero normal speed).  ``flight``
    (s) is the time since the previous impact: a flight shorter than
    ``min_flight`` ends it too, so an accumulation of impacts never stalls a
    master that cannot resolve it (pass ``inf`` where every flight is
    resolved).
    """
    return rebound < v_chat or flight < min_flight


def reduced_mass(m: float, ms: float) -> float:
    """Reduced mass ``m ms / (m + ms)`` (kg) of a disc of mass m on a casing of mass ms:
    the mass a penalty contact sees, used to derive its damping from restitution."""
    return m * ms / (m + ms)


@njit
def contact_force_components(fn: float, ft: float, nx: float, ny: float) -> tuple[float, float]:
    """Cartesian force on the disc from a normal force ``fn`` (pushing along -n)
    and a tangential force ``ft`` (along t)."""
    return -fn * nx - ft * ny, -fn * ny + ft * nx


@njit
def penalty_force_components(
    fn: float,
    dist: float,
    nx: float,
    ny: float,
    rvx: float,
    rvy: float,
    d: float,
    mu: float,
    rd: float,
    w: float,
) -> tuple[float, float, float]:
    """Penalty contact force on the disc ``(fx, fy, Fn)`` from the normal force ``fn`` of
    its law (N, > 0 inward) at distance ``dist`` (m) along the outward normal (nx, ny),
    with Coulomb friction ``mu max(Fn, 0)`` against the slip of the relative velocity
    rv (m/s); nothing while the gap is open (``dist <= d``).

    Stateless form (contact whenever ``dist > d``, friction sign from the slip), for a
    unit that sees only the relative position and velocity; friction is
    :func:`friction_force` of the slip's sign (zero slip: none), the kernel the
    reference engines call too.
    """
    if dist <= d:
        return 0.0, 0.0, 0.0
    mode = slip_mode(slip_speed(rvx, rvy, nx, ny, rd, w))
    fx, fy = contact_force_components(fn, friction_force(mode, mu, fn, 0.0), nx, ny)
    return fx, fy, fn


@njit
def penalty_contact_force(
    rx: float,
    ry: float,
    rvx: float,
    rvy: float,
    d: float,
    kc: float,
    cc: float,
    mu: float,
    rd: float,
    w: float,
) -> tuple[float, float, float]:
    """:func:`penalty_force_components` of the Kelvin-Voigt law :func:`penalty_normal`,
    for the disc's position r (m) and velocity rv (m/s) relative to the stator.

    With ``cc = 0`` and positive slip this is the Chu-Zhang force
    ``-kc (1 - d/e) [rx - mu ry, mu rx + ry]``.  Returns ``(fx, fy, Fn)``.
    """
    fn, dist, nx, ny = penalty_normal_force(rx, ry, rvx, rvy, d, kc, cc)
    return penalty_force_components(fn, dist, nx, ny, rvx, rvy, d, mu, rd, w)


@njit
def sticking_friction(
    ft_disc: float, ft_stator: float, vt: float, vn: float, dist: float, m: float, ms: float
) -> float:
    """Tangential contact force (along t, on the disc) that keeps the slip speed constant.

    ``ft_disc``/``ft_stator`` are the tangential parts of every other force on
    the disc and on the casing; ``ms = inf`` for a fixed stator.  From
    ``d(vs)/dt = a_rel.t - vt vn / dist = 0`` with ``vs = v_rel.t + Rd w``.
    """
    inv = 1.0 / m if ms == math.inf else 1.0 / m + 1.0 / ms
    rhs = vt * vn / dist - ft_disc / m
    if ms != math.inf:
        rhs += ft_stator / ms
    return rhs / inv


@njit
def constraint_normal_force(
    fx: float,
    fy: float,
    nx: float,
    ny: float,
    vt: float,
    vn: float,
    dist: float,
    d: float,
    m: float,
    omega_b: float,
) -> float:
    """Normal force N (>= 0 pushes the disc inward) that keeps ``dist = d``.

    From the radial equation of a disc sliding on the stator under the other
    forces (fx, fy): ``N = F.n + m vt^2/dist``.  A Baumgarte term
    ``m (2 omega_b vn + omega_b^2 (dist - d))`` pulls numerical drift back onto
    the surface; it is zero on the exact constrained motion.
    """
    return (
        fx * nx
        + fy * ny
        + m * vt * vt / dist
        + m * (2.0 * omega_b * vn + omega_b * omega_b * (dist - d))
    )


def damping_from_restitution(restitution: float, stiffness: float, mass: float) -> float:
    """Contact damping cc, N s/m, giving restitution r for a linear spring-dashpot.

    For a mass ``mass`` hitting a spring-dashpot (kc, cc) the restitution is
    ``exp(-zeta pi / sqrt(1 - zeta^2))``, ``zeta = cc / (2 sqrt(kc m))``.
    ``r = 0`` gives critical damping.
    """
    if restitution >= 1.0:
        return 0.0
    if restitution <= 0.0:
        zeta = 1.0
    else:
        lr = math.log(restitution)
        zeta = -lr / math.sqrt(math.pi**2 + lr * lr)
    return 2.0 * zeta * math.sqrt(stiffness * mass)


def rub_onset_speed_ratios(damping_ratio: float, eccentricity_ratio: float) -> tuple[float, ...]:
    """Speed ratios s = w/wn where the free unbalance whirl radius equals the clearance.

    Solves ``(1 - rho^2) u^2 + (4 z^2 - 2) u + 1 = 0``, ``u = s^2``,
    ``rho = e/d``; returns the positive roots in increasing order (none when
    the whirl never reaches the stator).
    """
    z, rho = damping_ratio, eccentricity_ratio
    a, b, c = 1.0 - rho * rho, 4.0 * z * z - 2.0, 1.0
    if a == 0.0:
        roots = [-c / b] if b != 0.0 else []
    else:
        disc = b * b - 4.0 * a * c
        if disc < 0.0:
            return ()
        sq = math.sqrt(disc)
        roots = [(-b - sq) / (2.0 * a), (-b + sq) / (2.0 * a)]
    return tuple(sorted(math.sqrt(u) for u in roots if u > 0.0))


def penalty_damping(q: Mapping[str, Any]) -> float:
    """The contact damping (N s/m) of the penalty law: ``contact_damping`` if given (>= 0),
    else the one giving the restitution for the impact mass."""
    if q["contact_damping"] >= 0.0:
        return q["contact_damping"]
    return damping_from_restitution(q["restitution"], q["contact_stiffness"], q["impact_mass"])
