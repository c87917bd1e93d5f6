"""Unit steps and outputs over flat arrays, for the compiled co-simulation master.

The compiled master (:mod:`rubcosim.orchestrator.flat_master`) keeps every unit as
one row of a float array instead of a :class:`.unit.Unit` object, so that a
whole macro step (and its rollback) runs without Python.  A row holds:

the state, the step size to try next, the time and the inputs' values and
derivatives (:mod:`.flat_rows` has the layout).

:func:`outputs` is the one definition of these units' outputs: the unit classes
take theirs from it too (:class:`RowOutputs`, on the row of the unit object), so the
Python master, the FMUs and the compiled master evaluate the same kernel.
:func:`do_step` follows :meth:`.unit.Unit.do_step` and the classes' ``_advance``
operation for operation, from the same physics kernels (:mod:`.rotor`,
:mod:`.linear_propagation`, :mod:`.stepping`); ``tests/test_flat_master.py`` holds
the two masters to 1e-12 (they are bit-identical).  The hybrid unit types (the
impact oscillators) step on rows through :mod:`.flat_hybrid`.  A unit type without a
row form (FMUs) runs on the Python master; the controller's row holds the bounds of
its history, which lives in a buffer of the master's (:mod:`.flat_controller`).
Which row form a unit type has, and its parameter row: :mod:`.flat_params`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from . import bearing_law
from .flat_hybrid import hybrid_step
from .flat_params import flat_params, flat_type
from .flat_rows import (  # noqa: F401 - the row layout, kinds and statuses, re-exported
    HY_IMPACTS,
    HY_MODE,
    IV,
    K_BEARING,
    K_CASING,
    K_CONTROLLER,
    K_HYBRID,
    K_JEFFCOTT,
    K_PENALTY,
    K_RIGID,
    K_TWO_MASS,
    MAX_INPUTS,
    MAX_OUTPUTS,
    MAX_PARAMS,
    ROW,
    STEP_BAD_INPUT,
    STEP_FAILED,
    STEP_NO_ROOM,
    STEP_NOT_FINITE,
    STEP_OK,
    H,
    T,
    U,
    Y,
)
from .jit import njit
from .kernels import all_finite
from .linear_propagation import exact_step
from .rotor import jeffcott_force, two_mass_disc_force
from .stator import (
    MODE_FREE,
    MODE_SLIDE_NEG,
    MODE_SLIDE_POS,
    MODE_STICK,
    constraint_normal_force,
    contact_force_components,
    contact_geometry,
    friction_force,
    friction_reserve,
    rigid_impact,
    slip_speed,
    sticking_friction,
)
from .stepping import OK, advance
from .unit_odes import (
    row_contact_force,
)

OUT_NO_FILM = 4  # a journal at or past its bearing law's wall: no bearing force
OUT_BAD_MODE = 5  # a contact mode that is not 0, 1, 2 or 3
OUT_NO_MASS = 6  # sustained contact without a disc mass
OUT_NO_KIND = 8  # a row of no kind this module knows
# why a step or the outputs failed, as both masters report it
REASONS = {
    STEP_BAD_INPUT: "an input or the step is not finite",
    STEP_FAILED: "the unit's integrator failed (step size below round-off)",
    STEP_NOT_FINITE: "the state is not finite after the step",
    STEP_NO_ROOM: "its history outgrew its buffer",
    OUT_NO_FILM: "the journal touches the bearing wall (eccentricity ratio {ratio:.6g} >= 1); "
    "{model} has no force there",
    OUT_BAD_MODE: "{name}.contact_mode = {mode} is not 0, 1, 2 or 3",
    OUT_NO_MASS: "{name}.disc_mass must be > 0 for sustained contact",
    OUT_NO_KIND: "{name} has no row form",
}


@njit
def _input_rows(st, idx, n):
    u = np.zeros((n, 3))
    for i in range(n):
        j = U + 3 * idx[i]
        u[i, 0] = st[j]
        u[i, 1] = st[j + 1]
        u[i, 2] = st[j + 2]
    return u


# inlined into its one caller, the C function :func:`.flat_calls.step_c`: compiled on its
# own it was one more module holding a copy of every unit type's integrator
@njit(inline="always")
def do_step(kind, ode_kind, exact, n_y, n_in, ode_idx, p, tol, model, st, t, h):
    """Advance the unit in row ``st`` from ``t`` to ``t + h`` (s); on failure the row is
    left as it was and the status (not :data:`STEP_OK`) says why.  ``model`` is the
    rotor's affine model (:func:`.linear_propagation.affine_model`) when ``exact``."""
    if not (math.isfinite(t) and math.isfinite(h)) or h < 0.0:
        return STEP_BAD_INPUT
    for i in range(n_in):
        if not math.isfinite(st[U + 3 * i]):
            return STEP_BAD_INPUT
    if kind == K_HYBRID:
        return hybrid_step(ode_kind, n_y, ode_idx.shape[0], ode_idx, p, tol, st, t, h)
    if kind != K_JEFFCOTT and kind != K_TWO_MASS and kind != K_CASING:
        st[T] = t + h  # no dynamics of its own
        return STEP_OK
    saved = st.copy()
    st[T] = t
    y = st[Y : Y + n_y].copy()
    if kind != K_CASING:
        # the rotor's velocity reset protocol (RESET_PROTOCOL of rotor_unit)
        counter = float(int(st[U + 3 * 4]))
        if counter != st[IV]:
            y[2] = st[U + 3 * 2]
            y[3] = st[U + 3 * 3]
            st[IV] = counter
    u = _input_rows(st, ode_idx, ode_idx.shape[0])
    status = OK
    if kind != K_CASING and exact:
        if h > 0.0:
            y = exact_step(t, h, y, model, p[4], u)
    else:
        # np.int64, not a literal 0: numba compiles a literal argument as its own version
        mode = np.int64(0)
        h_next, _, _, status = advance(ode_kind, t, t + h, y, mode, st[H], p, u, tol[0], tol[1])
        st[H] = h_next
    bad = status != OK or not math.isfinite(st[H]) or not all_finite(y, n_y)
    if bad:
        st[:] = saved
        return STEP_FAILED if status != OK else STEP_NOT_FINITE
    st[Y : Y + n_y] = y
    st[T] = t + h
    return STEP_OK


@njit
def _penalty(st, p, cx, cy, cvx, cvy, out):
    rx, ry = st[U] - cx, st[U + 3] - cy
    rvx, rvy = st[U + 6] - cvx, st[U + 9] - cvy
    fx, fy, fn = row_contact_force(rx, ry, rvx, rvy, p)
    dist, nx, ny = contact_geometry(rx, ry)
    gap = p[0] - dist
    out[0], out[1], out[2] = fx, fy, fn
    out[3], out[4] = gap, -(rvx * nx + rvy * ny)
    out[5] = 1.0 if gap < 0.0 else 0.0


@njit
def _rigid(st, p, out):
    rx, ry = st[U] - p[0], st[U + 3] - p[1]
    rvx, rvy = st[U + 6] - 0.0, st[U + 9] - 0.0
    dist, nx, ny = contact_geometry(rx, ry)
    vx, vy = rigid_impact(rvx, rvy, nx, ny, p[2], p[3], p[4], p[5])
    vn = rvx * nx + rvy * ny
    out[0] = p[6] - dist
    out[1] = -vn
    out[2], out[3] = vx, vy
    out[8] = slip_speed(rvx, rvy, nx, ny, p[4], p[5])
    for k in (4, 5, 6, 7, 9, 10):
        out[k] = 0.0
    mode = int(st[U + 18])
    if mode == MODE_FREE:
        return STEP_OK
    if mode != MODE_SLIDE_POS and mode != MODE_SLIDE_NEG and mode != MODE_STICK:
        return OUT_BAD_MODE
    m = p[7]
    if m <= 0.0:
        return OUT_NO_MASS
    ofx, ofy = st[U + 12], st[U + 15]
    vt = -rvx * ny + rvy * nx
    n = constraint_normal_force(ofx, ofy, nx, ny, vt, vn, dist, p[6], m, p[8])
    hold = sticking_friction(-ofx * ny + ofy * nx, 0.0, vt, vn, dist, m, math.inf)
    ft = friction_force(mode, p[3], n, hold)
    out[4], out[5] = contact_force_components(n, ft, nx, ny)
    out[6] = n
    out[7] = 2.0 if mode == MODE_STICK else 1.0
    out[9] = friction_reserve(p[3], n, hold)
    out[10] = hold
    return STEP_OK


@njit
def outputs(kind, p, st, out):
    """The outputs of the unit in row ``st`` at its time for its current input values,
    in the order of the unit class's ``outputs``; returns a status."""
    if kind == K_JEFFCOTT or kind == K_TWO_MASS:
        t = st[T]
        if kind == K_JEFFCOTT:
            fx, fy = jeffcott_force(t, st[0], st[1], st[2], st[3], p[0], p[1], p[2], p[3],
                                    p[4], p[5])  # fmt: skip
        else:
            fx, fy = two_mass_disc_force(t, st, 0, 4, p[0], p[1], p[2], p[6], p[3], p[4], p[5])
            for i in range(4):
                out[7 + i] = st[4 + i]
        for i in range(4):
            out[i] = st[i]
        out[4] = st[IV]
        out[5], out[6] = fx, fy
        return STEP_OK
    if kind == K_RIGID:
        return _rigid(st, p, out)
    if kind == K_PENALTY:
        _penalty(st, p, p[4], p[5], 0.0, 0.0, out)
        return STEP_OK
    if kind == K_CASING:
        _penalty(st, p, p[4] + st[0], p[5] + st[1], st[2], st[3], out)
        for i in range(4):
            out[6 + i] = st[i]
        return STEP_OK
    if kind == K_BEARING:
        law = int(p[0])
        fx, fy = bearing_law.bearing_law_force(law, st[U], st[U + 3], st[U + 6], st[U + 9], p, 1)
        if not (math.isfinite(fx) and math.isfinite(fy)):
            return OUT_NO_FILM
        out[0], out[1] = fx, fy
        return STEP_OK
    return OUT_NO_KIND


def failure_reason(status: int, row: np.ndarray, p: np.ndarray, name: str) -> str:
    """What a nonzero status of :func:`do_step` or :func:`outputs` on the row (and
    parameter row ``p``) of unit ``name`` means."""
    mode = int(row[U + 18]) if status == OUT_BAD_MODE else 0
    ratio, model = 0.0, ""
    if status == OUT_NO_FILM:  # the journal's distance from the centre over the law's wall
        law = int(p[0])
        ratio = bearing_law.wall_ratio(law, row[U], row[U + 3], p[1:])
        model = bearing_law.bearing_laws()[law].model
    return REASONS[status].format(name=name, mode=mode, ratio=ratio, model=model)


def unit_row(unit: Any) -> np.ndarray:
    """The row of a unit object (:class:`.unit.Unit`): its state, time and inputs."""
    row = np.zeros(ROW)
    y = unit.state.get("y")
    if y is not None:
        row[Y : Y + len(y)] = y
    row[H] = unit.state.get("h", 0.0)
    row[IV] = unit.state.get("resets_applied", 0)
    if "impacts" in unit.state:  # a hybrid unit (flat_hybrid)
        row[HY_MODE] = unit.state["mode"]
        row[HY_IMPACTS] = unit.state["impacts"]
    row[T] = unit.time
    # value, d1, d2 per input in one list and one assignment: a slice assignment per input
    # costs a microsecond, and the Python master and the FMUs build a row per output read
    u, du, none = unit.u, unit.du, (0.0, 0.0)
    values = []
    for s in unit.inputs:
        values.append(u[s.name])
        values.extend(du.get(s.name, none))
    row[U : U + len(values)] = values
    return row


class RowOutputs:
    """``_outputs`` of a unit class from :func:`outputs` on the unit's row: the unit
    classes (the Python master, the FMUs) and the compiled master evaluate the same
    kernel, so what feeds which output is written once."""

    def _outputs(self) -> dict[str, float]:
        # the row form and parameter row are the type's and the parameters': read once
        # (the parameters never change after the unit is built)
        form = getattr(self, "_row_form", None)
        if form is None:
            p = flat_params(self.role, self.type_name, self.params)
            form = self._row_form = (flat_type(self.role, self.type_name)[0], p)
        kind, p = form
        out = np.zeros(MAX_OUTPUTS)
        row = unit_row(self)
        status = outputs(kind, p, row, out)
        if status != STEP_OK:
            raise ValueError(failure_reason(status, row, p, self.name))
        return {
            s.name: (int(v) if s.kind == "integer" else float(v))
            for s, v in zip(self.outputs, out, strict=False)
        }
