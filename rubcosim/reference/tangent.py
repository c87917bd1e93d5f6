"""Variational equations on the ``fast`` engine: the tangent matrix through steps and events.

The ``fast`` engine carries a tangent matrix ``Phi`` (n x k, the derivative of the
state with respect to k initial directions) when it is given one
(:func:`new_tangent`; ``integrate(..., tan=...)``).  Nothing else changes: the
step-size controller sees the state only, so the trajectory, its steps and its
events are those of the plain run, bit for bit.

Between events ``Phi' = J(t, x) Phi`` is integrated with the accepted step's own
DOP853 stages: the tangent's stage ``s`` is ``J(t_s, y_s) Phi_s`` at the state's
stage point ``y_s``, so ``Phi`` over a step is the derivative of the Runge-Kutta
step itself (the augmented system's step with the state's step sizes).  A step cut
short by an event is re-taken from its start to the event for the tangent only.

``J`` is the system's own right-hand side (:func:`rubcosim.reference.history.full_rhs`,
in the step's mode) differentiated by central differences, ``fd[j]`` along state j
(1e-6 of its scale: truncation and round-off both near 1e-10 relative).  A step's
first and last stage may sit exactly on a kink of the vector field (the edge of a
piecewise-linear stop, a breakpoint event that does not change the mode; the
friction of a penalty contact, which follows the compressive normal force only),
where a central difference would average the two sides; there the forward,
backward or central difference (1e-8 of the scale) nearest to the Jacobian of the
neighbouring stage is taken, which picks the side the step lies on.  A kink that
the trajectory crosses inside a step (a penalty contact with damping pulls for a
moment before it separates) is smoothed over, as the state's own step does.

At an event of slot k (surface ``h = g_k(t, x) = 0``, map ``x+ = G(x-)``, mode m- ->
m+) the saltation matrix is applied::

    S = DG + (f+ - DG f-) grad_h^T / (grad_h . f- + dh/dt)

with ``f- = f(t, x-, m-)``, ``f+ = f(t, x+, m+)`` (the book's discontinuity map of
a transversal crossing; ``dh/dt`` the explicit time derivative, e.g. the release
of a stuck mass, whose indicator depends on the forcing phase only).  ``DG``,
``grad_h`` and ``dh/dt`` are central differences of the system's own event map
(:func:`~rubcosim.reference.system.apply_event`) and event functions.  A rigid
impact gives ``det S = R^2`` (Newton's law) times the ratio of normal
accelerations; a contact switch of a penalty stator or a kink of a stop (no jump:
``DG = I``) gives ``S = I + (f+ - f-) grad_h^T / (grad_h . f-)``, the identity when
the vector field is continuous there.

Sticking and sliding in sustained contact are modes with their own (constrained)
vector field, so their tangent is that field's Jacobian: a mass stuck on a barrier
has ``f = 0`` and its tangent stands still; the event that ends chattering maps
every nearby state onto the barrier at rest (``DG`` of rank 0 in the normal
directions), so the tangent loses those directions, as nearby motions do (they
stick too).  A disc in sustained rub on a rigid stator moves on ``|p - c| = d``
under the constraint force with a Baumgarte term (rate ``omega_b``) that only
acts off the constraint; the entry into that mode projects the tangent onto the
constraint, so the Baumgarte directions stay empty.

Delay equations (the delayed-feedback controller) are not supported: their state
is a function, not a vector (the callers refuse them).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from rubcosim.components.dop853 import N_EXT, N_STAGES, B, C, solution_point, stage_point
from rubcosim.components.jit import njit

from .core import C_EVENTS
from .history import dense_eval, full_rhs
from .model_calls import apply_event, events
from .system import N_EVENTS

FD_REL = 1e-6  # central-difference step, in state scales
END_REL = 1e-8  # difference step at a step's ends (one-sided there: sqrt of round-off)
# tangent statistics (``tan[-1]``)
T_TRACE, T_LOGDET, T_SALTATIONS = range(3)


@nb.njit(cache=True)
def new_tangent(Phi, fd, t_fd):
    """The engine's tangent argument for the matrix ``Phi`` (n x k, C-contiguous,
    advanced in place), with difference steps ``fd`` (per state, its units) and
    ``t_fd`` (s).  Its statistics ``tan[-1]`` accumulate ``int tr J dt`` (T_TRACE),
    ``sum ln|det S|`` over the events (T_LOGDET) and the events (T_SALTATIONS):
    Liouville's formula for the sum of the Lyapunov exponents."""
    n, k = Phi.shape
    return (
        Phi,
        fd,
        fd * (END_REL / FD_REL),
        t_fd,
        np.empty((N_EXT, n)),  # the state's stages of a step re-taken up to an event
        np.empty((N_STAGES, n * k)),  # the tangent's stages
        np.empty(n * k),
        np.empty(n * k),
        np.empty((N_STAGES, n, n)),  # J at each stage; [0] is DG at an event
        np.empty((N_STAGES, n)),  # the stage points
        np.empty(n),
        np.empty(n),
        np.empty((n, k)),  # scratch for S Phi
        np.zeros(3),
    )


@njit(borrows=True)
def rhs_at(t, y, mode, p, model, hist, yd, dy):
    """The system's right-hand side as a call, not inlined: for the sites that run once
    per event (each inlined copy costs seconds of compilation)."""
    full_rhs(t, y, mode, p, model, hist, yd, dy)


@njit(borrows=True)
def jacobian(t, ys, mode, p, model, hist, yd, fd, J, fp, fm):
    """J = df/dy at (t, ys) in ``mode`` by central differences of steps ``fd``."""
    n = ys.shape[0]
    for j in range(n):
        save = ys[j]
        ys[j] = save + fd[j]
        up = ys[j] - save  # the step actually taken, exact in floating point
        full_rhs(t, ys, mode, p, model, hist, yd, fp)
        ys[j] = save - fd[j]
        down = save - ys[j]
        full_rhs(t, ys, mode, p, model, hist, yd, fm)
        ys[j] = save
        for i in range(n):
            J[i, j] = (fp[i] - fm[i]) / (up + down)


@njit(borrows=True)
def sided_jacobian(t, ys, fs, mode, p, model, hist, yd, fd, J, ref, fp, fm):
    """J at a step's end point (``fs = f(t, ys)``), which may sit on a kink of the
    vector field: per column the forward, backward or central difference (steps
    ``fd``) nearest to ``ref``, the Jacobian at the nearest stage inside the step.  Across a
    kink exactly one one-sided difference lies on the step's side (both do for a
    direction along the kink, where f is continuous), the one that extends the
    Jacobian inside the step; away from a kink all three agree to round-off."""
    n = ys.shape[0]
    for j in range(n):
        save = ys[j]
        ys[j] = save + fd[j]
        up = ys[j] - save
        full_rhs(t, ys, mode, p, model, hist, yd, fp)
        ys[j] = save - fd[j]
        down = save - ys[j]
        full_rhs(t, ys, mode, p, model, hist, yd, fm)
        ys[j] = save
        best = math.inf
        for c in range(3):
            dist = 0.0
            for i in range(n):
                if c == 0:
                    v = (fp[i] - fs[i]) / up
                elif c == 1:
                    v = (fs[i] - fm[i]) / down
                else:
                    v = (fp[i] - fm[i]) / (up + down)
                dist = max(dist, abs(v - ref[i, j]) * fd[j] / fd[i])
            if dist < best:
                best = dist
                for i in range(n):
                    if c == 0:
                        J[i, j] = (fp[i] - fs[i]) / up
                    elif c == 1:
                        J[i, j] = (fs[i] - fm[i]) / down
                    else:
                        J[i, j] = (fp[i] - fm[i]) / (up + down)


@njit(borrows=True)
def tangent_stages(tan, t, h, y, K, mode, p, model, hist, yd):
    """Advance ``Phi`` over the step of size h from (t, y) with the state's stages K."""
    Phi, fd, small, _, _, KP, ptmp, pnew, Js, Ys, fp, fm, _, stats = tan
    n, k = Phi.shape
    phi = Phi.reshape(n * k)
    for s in range(N_STAGES):
        stage_point(K, s, y, h, Ys[s])
    last = N_STAGES - 1  # C[0] = 0 and C[last] = 1: the step's ends
    for s in range(1, last):
        jacobian(t + C[s] * h, Ys[s], mode, p, model, hist, yd, fd, Js[s], fp, fm)
    # the ends may sit on a kink: their side is told by the nearest stage inside
    sided_jacobian(t, Ys[0], K[0], mode, p, model, hist, yd, small, Js[0], Js[1], fp, fm)
    end = t + h
    sided_jacobian(
        end, Ys[last], K[last], mode, p, model, hist, yd, small, Js[last], Js[last - 1], fp, fm
    )
    trace = 0.0
    for s in range(N_STAGES):
        J = Js[s]
        stage_point(KP, s, phi, h, ptmp)
        for i in range(n):
            trace += B[s] * J[i, i]
            for c in range(k):
                acc = 0.0
                for j in range(n):
                    acc += J[i, j] * ptmp[j * k + c]
                KP[s, i * k + c] = acc
    solution_point(KP, phi, h, pnew)
    for i in range(n * k):
        phi[i] = pnew[i]
    stats[T_TRACE] += h * trace


@njit(borrows=True)
def fresh_stages(tan, t, h, y, K, mode, p, model, hist, yd):
    """The state's stages 1.. of a step of size h from (t, y) into K (``K[0] = f(t, y)``
    given): a step cut short by an event, re-taken for the tangent.  Apart from
    :func:`tangent_stages` so that it compiles once (a flag there made two copies)."""
    Ys, fp = tan[9], tan[10]
    for s in range(1, N_STAGES):
        stage_point(K, s, y, h, Ys[s])
        rhs_at(t + C[s] * h, Ys[s], mode, p, model, hist, yd, fp)
        for i in range(y.shape[0]):
            K[s, i] = fp[i]


@njit(borrows=True)
def event_function(k, t, y, mode, p, model, yd, g, dirs, rates):
    events(t, y, yd, mode, p, model, g, dirs, rates)
    return g[k]


@nb.njit(cache=True)
def saltation(tan, k, te, ym, mode, yp, mode_new, p, model, hist, yd):
    """Apply the saltation matrix of the event of slot k at ``te`` (pre-event state
    ``ym`` in ``mode``, post-event ``yp`` in ``mode_new``) to ``Phi``."""
    Phi, fd, _, t_fd, _, _, _, _, Js, Ys, fp, fm, work, stats = tan
    DG, ys = Js[0], Ys[0]
    n, k_cols = Phi.shape
    g = np.empty(N_EVENTS)
    dirs = np.empty(N_EVENTS, dtype=np.int64)
    rates = np.empty(N_EVENTS, dtype=np.int64)
    grad = np.empty(n)
    rhs_at(te, ym, mode, p, model, hist, yd, fm)
    rhs_at(te, yp, mode_new, p, model, hist, yd, fp)
    for j in range(n):
        for i in range(n):
            ys[i] = ym[i]
        ys[j] = ym[j] + fd[j]
        up = ys[j] - ym[j]
        g_up = event_function(k, te, ys, mode, p, model, yd, g, dirs, rates)
        apply_event(k, te, ys, yd, mode, p, model)
        for i in range(n):
            DG[i, j] = ys[i]
        for i in range(n):
            ys[i] = ym[i]
        ys[j] = ym[j] - fd[j]
        down = ym[j] - ys[j]
        g_down = event_function(k, te, ys, mode, p, model, yd, g, dirs, rates)
        apply_event(k, te, ys, yd, mode, p, model)
        for i in range(n):
            DG[i, j] = (DG[i, j] - ys[i]) / (up + down)
        grad[j] = (g_up - g_down) / (up + down)
    h_t = (
        event_function(k, te + t_fd, ym, mode, p, model, yd, g, dirs, rates)
        - event_function(k, te - t_fd, ym, mode, p, model, yd, g, dirs, rates)
    ) / (2.0 * t_fd)
    rate = h_t
    for j in range(n):
        rate += grad[j] * fm[j]
    # jump of the vector field not accounted for by DG, f+ - DG f-, into fp
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += DG[i, j] * fm[j]
        fp[i] -= acc
    if rate != 0.0 and math.isfinite(rate):
        for i in range(n):
            for j in range(n):
                DG[i, j] += fp[i] * grad[j] / rate
    sign, logdet = np.linalg.slogdet(DG)
    stats[T_LOGDET] += logdet if sign != 0.0 else -math.inf
    stats[T_SALTATIONS] += 1.0
    for i in range(n):
        for c in range(k_cols):
            acc = 0.0
            for j in range(n):
                acc += DG[i, j] * Phi[j, c]
            work[i, c] = acc
    for i in range(n):
        for c in range(k_cols):
            Phi[i, c] = work[i, c]


@njit(borrows=True)
def tangent_step(tan, t, h, y, K, mode, p, model, hist, yd):
    """The engine's hook after a step [t, t + h] accepted without dense output."""
    if tan is None:
        return
    tangent_stages(tan, t, h, y, K, mode, p, model, hist, yd)


@nb.njit(cache=True)
def tangent_after(tan, seg, K, t_next, modes, y_next, out, p, model, hist, yd):
    """The engine's hook after :func:`~rubcosim.reference.core.after_step` of the step
    ``seg = (t, h, y, F)`` with stages K: the step (up to the event, if one was
    applied at ``t_next``) and the event's saltation matrix; ``modes = (mode before,
    mode after, forced slot)`` as the engine has them, ``y_next`` the state after."""
    if tan is None:
        return
    t, h, y, F = seg
    mode, mode_next, fs = modes
    evlog, cnt = out[2], out[3]
    if fs < 0 and mode_next == mode:  # no event: the whole step
        tangent_stages(tan, t, h, y, K, mode, p, model, hist, yd)
        return
    te = t_next
    Ks = tan[4]
    if te >= t + h:
        tangent_stages(tan, t, h, y, K, mode, p, model, hist, yd)
    elif te > t:
        for i in range(y.shape[0]):
            Ks[0, i] = K[0, i]
        fresh_stages(tan, t, te - t, y, Ks, mode, p, model, hist, yd)
        tangent_stages(tan, t, te - t, y, Ks, mode, p, model, hist, yd)
    ym = np.empty(y.shape[0])
    dense_eval(t, h, y, F, te, ym, y.shape[0])
    k = evlog[2][cnt[C_EVENTS] - 1]
    saltation(tan, k, te, ym, mode, y_next, mode_next, p, model, hist, yd)
