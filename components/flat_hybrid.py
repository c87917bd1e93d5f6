"""Hybrid unit types (:mod:`.hybrid`) on rows, for the compiled co-simulation master.

A hybrid unit's row (:mod:`.flat_rows`) holds its state, its mode at ``HY_MODE`` and
its impact count at ``HY_IMPACTS``; its parameter row is its kernels' array
(:meth:`.hybrid.HybridKernels.parameters`) with the type's index and ``input_base``
at the end.  :func:`hybrid_step` is :meth:`.hybrid.HybridUnit._advance` on the row
(the same :func:`.stepping.advance` of the same kernels, the inputs written into
the kernels' array the same way).  :func:`hybrid_outputs` gives the outputs, for
both masters (``HybridUnit._outputs`` calls it on the unit's row): the kernels'
outputs, the impact count, the mode and the type's mode outputs
(:attr:`.hybrid.HybridUnit.mode_outputs`), in the unit class's order
(:func:`output_map`).  ``tests/test_flat_master.py`` holds the two masters to 1e-12.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from . import hybrid_dispatch
from .flat_rows import (
    HY_IMPACTS,
    HY_MODE,
    K_HYBRID,
    MAX_OUTPUTS,
    MAX_PARAMS,
    P_HYBRID,
    P_INPUT_BASE,
    STEP_FAILED,
    STEP_NOT_FINITE,
    STEP_OK,
    H,
    T,
    U,
    Y,
)
from .hybrid_dispatch import hybrid_types
from .jit import njit
from .kernels import all_finite
from .stepping import HYBRID, OK, advance

# where output j of a hybrid unit comes from (>= 0: the kernels' output of that index)
OUT_IMPACTS, OUT_MODE, OUT_BY_MODE = -1, -2, -3
MAX_MODES = 4  # modes a mode output may list


def _hybrid_index(role: str, type_name: str) -> int:
    for i, t in enumerate(hybrid_types()):
        if (t.role, t.type_name) == (role, type_name):
            return i
    return -1


def hybrid_flat_type(role: str, type_name: str) -> tuple[int, int, tuple, tuple] | None:
    """``(K_HYBRID, step kind, (), kernel inputs)`` of a hybrid unit type (the entry
    :data:`.flat_units.FLAT_TYPES` has for the other types), None for any other."""
    i = _hybrid_index(role, type_name)
    if i < 0:
        return None
    return K_HYBRID, HYBRID + i, (), hybrid_types()[i].hybrid.inputs


def hybrid_params(role: str, type_name: str, params: Mapping[str, Any]) -> np.ndarray:
    """The parameter row of a hybrid unit: its kernels' array, zero-padded, with the
    type's index at ``P_HYBRID`` and its ``input_base`` at ``P_INPUT_BASE``."""
    i = _hybrid_index(role, type_name)
    kernels = hybrid_types()[i].hybrid
    packed = kernels.parameters(params)
    if packed.size > P_HYBRID:
        raise ValueError(f"{role}.{type_name}: {packed.size} parameters, rows hold {P_HYBRID}")
    row = np.zeros(MAX_PARAMS)
    row[: packed.size] = packed
    row[P_HYBRID], row[P_INPUT_BASE] = i, kernels.input_base
    return row


def output_map(unit: Any) -> tuple[np.ndarray, np.ndarray]:
    """Per output of hybrid ``unit`` (its class's order): where it comes from (an index
    of the kernels' outputs, :data:`OUT_IMPACTS`, :data:`OUT_MODE` or
    :data:`OUT_BY_MODE`), and for the last its value in each mode."""
    names = unit.kernels.outputs
    code = np.zeros(MAX_OUTPUTS, np.int64)
    by_mode = np.zeros((MAX_OUTPUTS, MAX_MODES))
    for j, s in enumerate(unit.outputs):
        if s.name in names:
            code[j] = names.index(s.name)
        elif s.name == "impacts":
            code[j] = OUT_IMPACTS
        elif s.name == "mode":
            code[j] = OUT_MODE
        else:
            table = unit.mode_outputs[s.name]
            code[j] = OUT_BY_MODE
            by_mode[j, : len(table)] = table
    return code, by_mode


def row_output_args(unit: Any) -> tuple:
    """``(n_y, idx, code, by_mode, p)`` of hybrid ``unit`` for :func:`hybrid_outputs` on
    its row (:func:`.flat_units.unit_row`): what the compiled master holds per unit."""
    ins = [s.name for s in unit.inputs]
    idx = np.array([ins.index(name) for name in unit.kernels.inputs], np.int64)
    code, by_mode = output_map(unit)
    p = hybrid_params(unit.role, unit.type_name, unit.params)
    return len(unit.state["y"]), idx, code, by_mode, p


@njit
def _kernel_array(p, st, n_in, idx, t):  # pragma: no cover - compiled
    """The kernels' parameter array with the inputs of row ``st`` written from its
    ``input_base`` on: the time ``t``, then value, d1, d2 of each kernel input
    (``idx[i]``: kernel input ``i``'s index among the unit's inputs)."""
    q = p.copy()
    base = int(p[P_INPUT_BASE])
    q[base] = t
    for i in range(n_in):
        j = U + 3 * idx[i]
        q[base + 1 + 3 * i] = st[j]
        q[base + 2 + 3 * i] = st[j + 1]
        q[base + 3 + 3 * i] = st[j + 2]
    return q


@njit
def hybrid_step(step_kind, n_y, n_in, idx, p, tol, st, t, h):  # pragma: no cover - compiled
    """:meth:`.hybrid.HybridUnit._advance` on row ``st``: from ``t`` to ``t + h`` (s);
    on failure the row is left as it was and the status says why."""
    q = _kernel_array(p, st, n_in, idx, t)
    y = st[Y : Y + n_y].copy()
    mode = np.int64(st[HY_MODE])
    # a fresh array, not stepping.NO_INPUTS: a global is a read-only constant to
    # numba, a second signature of advance and seconds more of compilation
    no_inputs = np.zeros((0, 3))
    h_next, mode, impacts, status = advance(
        step_kind, t, t + h, y, mode, st[H], q, no_inputs, tol[0], tol[1]
    )
    if status != OK:
        return STEP_FAILED
    if not math.isfinite(h_next) or not all_finite(y, n_y):
        return STEP_NOT_FINITE
    st[Y : Y + n_y] = y
    st[HY_MODE] = mode
    st[HY_IMPACTS] += impacts
    st[H] = h_next
    st[T] = t + h
    return STEP_OK


@njit
def hybrid_outputs(n_y, n_in, n_out, idx, code, by_mode, p, st, out):  # pragma: no cover
    """:meth:`.hybrid.HybridUnit._outputs` of row ``st`` into ``out``, in the order of
    :func:`output_map`'s ``code`` and ``by_mode``."""
    t = st[T]
    q = _kernel_array(p, st, n_in, idx, t)
    mode = np.int64(st[HY_MODE])
    kernel_out = np.empty(MAX_OUTPUTS)
    # the dispatch module is generated on first use (hybrid_dispatch's docstring)
    hybrid_dispatch.hybrid_outputs(np.int64(p[P_HYBRID]), t, st[Y : Y + n_y], mode, q, kernel_out)
    for j in range(n_out):
        c = code[j]
        if c >= 0:
            out[j] = kernel_out[c]
        elif c == OUT_IMPACTS:
            out[j] = st[HY_IMPACTS]
        elif c == OUT_MODE:
            out[j] = mode
        else:
            out[j] = by_mode[j, mode]
    return STEP_OK
