"""Two-degree-of-freedom vibro-impact oscillator (the book's chapter 3).

Mass m1 is tied to the frame by a spring-damper (k1, c1) and to mass m2 by
another (k2, c2); a harmonic force ``P cos(w t)`` drives m1, and a share
``q P cos(w t)`` drives m2.  Displacements x1, x2 (m) are measured from the
unloaded position, positive towards the stop.  m2 meets a rigid stop at
``x2 = B`` with Newton's law ``v2+ = -R v2-``; a chattering sequence (rebounds
slower than ``chatter_tol * B * w``) ends with m2 resting on the stop, where it
sticks while the other forces push it into the stop and is released when the
contact force they imply turns tensile::

    m1 x1'' = -k1 x1 - c1 x1' + k2 (x2 - x1) + c2 (x2' - x1') + P cos(w t)
    m2 x2'' = -k2 (x2 - x1) - c2 (x2' - x1') + q P cos(w t)        (x2 < B)

The impact law and the end of chattering are the impact oscillator's kernels
(:func:`.oscillator.stop_impact`, :func:`.oscillator.pressing`).  One
declaration: the monolithic reference compiles the kernels below, the
co-simulation unit (and its FMU) steps them (:mod:`.hybrid`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from . import trig
from .declaration import FmuIdentity, State, UnitType
from .hybrid import HybridKernels, HybridUnit, input_value
from .hybrid_dispatch import KIND_IMPACT, KIND_RELEASE
from .jit import njit
from .oscillator import barrier_gap, pressing, stop_impact
from .parameters import ParameterError, nonnegative, positive, real
from .unit import INTEGRATOR_PARAMS, integer_signal, real_signal

# parameter array slots (pack below); the input force from INPUTS on (see .hybrid)
M1, M2, K1, C1, K2, C2, AMP, W, Q, GAP, R, VCHAT, INPUTS = range(13)
FREE, STUCK = 0, 1

PARAMS = (
    positive("mass1", None, "kg", "mass m1 (driven, on the frame spring)", example=1.0),
    positive("mass2", None, "kg", "mass m2 (meets the stop)", example=0.5),
    positive("stiffness1", None, "N/m", "frame-to-m1 stiffness k1", example=1.0),
    nonnegative("damping1", 0.0, "N s/m", "frame-to-m1 damping c1"),
    positive("stiffness2", None, "N/m", "m1-to-m2 stiffness k2", example=1.0),
    nonnegative("damping2", 0.0, "N s/m", "m1-to-m2 damping c2"),
    nonnegative("forcing_amplitude", 0.0, "N", "amplitude P of the force on m1"),
    positive("forcing_frequency", None, "rad/s", "forcing frequency w", example=1.0),
    real("force_ratio", 0.0, "1", "share q of the force that also drives m2", 0.0, 1.0),
    positive("gap", None, "m", "distance B of the stop from m2's unloaded position", example=0.1),
    real("restitution", 0.8, "1", "Newton restitution coefficient R at the stop", 0.0, 1.0),
    real("x1_0", 0.0, "m", "initial displacement of m1"),
    real("v1_0", 0.0, "m/s", "initial velocity of m1"),
    real("x2_0", 0.0, "m", "initial displacement of m2 (at most the gap)"),
    real("v2_0", 0.0, "m/s", "initial velocity of m2"),
)
CHATTER_TOL = positive(
    "chatter_tol",
    1e-10,
    "1",
    "rebound speed, in units of gap * forcing_frequency, below which m2 sticks on the stop",
)


@njit(inline="always")
def link_forces(t: float, x1: float, v1: float, x2: float, v2: float, p: np.ndarray):
    """Forces (N) on m1 and m2 from the springs, dampers, forcing and the input force on
    m1 (not the stop)."""
    drive = p[AMP] * trig.cos(p[W] * t)
    link = p[K2] * (x2 - x1) + p[C2] * (v2 - v1)  # pulls m1 towards m2
    f1 = -p[K1] * x1 - p[C1] * v1 + link + drive + input_value(p, INPUTS, 0, t)
    return f1, -link + p[Q] * drive


@njit(inline="always")
def rhs(t: float, y: np.ndarray, mode: int, p: np.ndarray, dy: np.ndarray) -> None:
    """State (x1, v1, x2, v2); stuck on the stop, m2 stays at x2 = B at rest."""
    x2, v2 = (p[GAP], 0.0) if mode == STUCK else (y[2], y[3])
    f1, f2 = link_forces(t, y[0], y[1], x2, v2, p)
    dy[0] = y[1]
    dy[1] = f1 / p[M1]
    dy[2] = 0.0 if mode == STUCK else y[3]
    dy[3] = 0.0 if mode == STUCK else f2 / p[M2]


@njit(inline="always")
def events(t, y, mode, p, g, dirs, rates) -> None:
    """Free: the gap of m2 to the stop falls through 0 (its rate -v2 in slot 1).
    Stuck: how hard m2 is pressed on the stop falls through 0 (release)."""
    if mode == FREE:
        g[0] = barrier_gap(y[2], p[GAP], 1)
        g[1] = -y[3]
        dirs[0] = -1
        rates[0] = 1
    else:
        _, f2 = link_forces(t, y[0], y[1], p[GAP], 0.0, p)
        g[2] = pressing(1, f2)
        dirs[2] = -1


@njit
def apply(k: int, t: float, y: np.ndarray, mode: int, p: np.ndarray):
    """Impact of m2 on the stop (slot 0), or its release from it (slot 2)."""
    if mode == STUCK:
        return FREE, KIND_RELEASE
    y[2] = p[GAP]  # the locator leaves m2 within round-off of the stop
    _, f2 = link_forces(t, y[0], y[1], p[GAP], 0.0, p)
    v2, stuck = stop_impact(y[3], p[R], p[VCHAT], 1, f2)
    y[3] = v2
    return (STUCK if stuck else FREE), KIND_IMPACT


@njit
def output(t: float, y: np.ndarray, mode: int, p: np.ndarray, out: np.ndarray) -> None:
    """x1, v1, x2, v2, the contact state (0 free, 2 stuck) and the stop's force on m2
    (N, > 0 pushing it back, while stuck)."""
    for i in range(4):
        out[i] = y[i]
    out[4] = 2.0 if mode == STUCK else 0.0
    out[5] = link_forces(t, y[0], y[1], p[GAP], 0.0, p)[1] if mode == STUCK else 0.0


def pack(q: Mapping[str, Any]) -> np.ndarray:
    """The kernels' parameters (slots M1..VCHAT); the chattering speed is
    ``chatter_tol * B * w``."""
    v_chat = q.get("chatter_tol", CHATTER_TOL.default) * q["gap"] * q["forcing_frequency"]
    names = ("mass1", "mass2", "stiffness1", "damping1", "stiffness2", "damping2")
    drive = ("forcing_amplitude", "forcing_frequency", "force_ratio", "gap", "restitution")
    return np.array([*(q[n] for n in (*names, *drive)), v_chat], dtype=float)


def initial(q: Mapping[str, Any]) -> tuple[np.ndarray, int]:
    if q["x2_0"] > q["gap"]:
        raise ParameterError(f"oscillator.x2_0 = {q['x2_0']!r} starts m2 beyond the stop")
    return np.array([q["x1_0"], q["v1_0"], q["x2_0"], q["v2_0"]]), FREE


KERNELS = HybridKernels(
    rhs,
    events,
    apply,
    output,
    ("x1", "v1", "x2", "v2", "contact", "contact_force"),
    pack,
    initial,
    inputs=("force",),
    input_base=INPUTS,
)


class TwoDofImpactOscillatorUnit(HybridUnit):
    """Two masses on springs and dampers; the second meets a rigid stop and may stick."""

    role = "oscillator"
    type_name = "two_dof_impact"
    summary = "two-DOF vibro-impact oscillator: rigid stop on the second mass, sticking"
    params_spec = (*PARAMS, *INTEGRATOR_PARAMS, CHATTER_TOL)
    kernels = KERNELS
    inputs = (real_signal("force", "N", "external force on m1 (another unit's)"),)
    outputs = (
        real_signal("x1", "m", "displacement of m1"),
        real_signal("v1", "m/s", "velocity of m1"),
        real_signal("x2", "m", "displacement of m2"),
        real_signal("v2", "m/s", "velocity of m2"),
        real_signal("contact", "1", "0 free, 2 m2 stuck on the stop"),
        real_signal("contact_force", "N", "force of the stop on m2 while stuck (> 0)"),
        integer_signal("impacts", "number of impacts on the stop so far"),
        integer_signal("mode", "0 free, 1 m2 stuck on the stop"),
    )

    def _check(self, params: Mapping[str, Any]) -> None:
        initial(params)


TWO_DOF_IMPACT_OSCILLATOR = UnitType(
    TwoDofImpactOscillatorUnit,
    PARAMS,
    FmuIdentity("RubcosimTwoDofImpactOscillator"),
    states=(
        State("x1", "m", "length"),
        State("v1", "m/s", "velocity"),
        State("x2", "m", "length"),
        State("v2", "m/s", "velocity"),
    ),
    length_scale=lambda q: q["gap"],
    clock=lambda q: (q["forcing_frequency"], q["forcing_frequency"]),
    kernels=(link_forces, rhs, events, apply, output),
    hybrid=KERNELS,
)
