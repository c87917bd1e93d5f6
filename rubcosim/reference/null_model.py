"""A model that stands still: C functions with the kernels' signatures and no physics.

The engines' machinery is compiled against the *type* of a model tuple, and numba types
a C function by its signature alone (:mod:`.model_calls`): a tuple of these functions
has the type of every model's tuple, so the machinery compiled with it is the entry
every model loads from the cache.  :mod:`.compile_ahead` uses it to compile the
machinery in a second process while the first compiles the model's own kernels; these
compile in a fraction of a second.

Run with it, an engine sees a motion that does not move and events that never come:
the right-hand side is zero, a step returns its start with zero stages, every event
function is +1 with no rate companion, every output is zero.  Every array is filled, so
nothing reads memory the kernel did not write.
"""

from __future__ import annotations

from typing import Any

import numba as nb
import numpy as np

from .model_calls import APPLY, DENSE, EVENTS, KIND_BASE, OUTPUTS, RHS, STEP, ModelTuple


@nb.cfunc(RHS, cache=True, _nrt=False)
def rhs_null(t, y, yd, mode, p, ip, dy):  # pragma: no cover - compiled
    for i in range(dy.shape[0]):
        dy[i] = 0.0


@nb.cfunc(EVENTS, cache=True, _nrt=False)
def events_null(t, y, yd, mode, p, ip, g, dirs, rates):  # pragma: no cover - compiled
    for k in range(g.shape[0]):
        g[k] = 1.0
        dirs[k] = 0
        rates[k] = -1


@nb.cfunc(APPLY, cache=True, _nrt=False)
def apply_null(k, t, y, yd, mode, p, ip):  # pragma: no cover - compiled
    return mode * KIND_BASE


@nb.cfunc(OUTPUTS, cache=True, _nrt=False)
def outputs_null(t, y, yd, mode, p, ip, out):  # pragma: no cover - compiled
    for i in range(out.shape[0]):
        out[i] = 0.0


@nb.cfunc(STEP, cache=True, _nrt=False)
def step_null(t, y, f, h, mode, p, ip, yd, K, y_new, f_new, ytmp):  # pragma: no cover
    for i in range(y.shape[0]):
        y_new[i] = y[i]
        f_new[i] = 0.0
        ytmp[i] = y[i]
    for s in range(K.shape[0]):
        for i in range(K.shape[1]):
            K[s, i] = 0.0


@nb.cfunc(DENSE, cache=True, _nrt=False)
def dense_null(t_old, h, y_old, y_new, f_new, mode, p, ip, yd, K, F, ytmp):  # pragma: no cover
    for s in range(F.shape[0]):
        for i in range(F.shape[1]):
            F[s, i] = 0.0
    for i in range(ytmp.shape[0]):
        ytmp[i] = y_old[i]


NULL_KERNELS = (rhs_null, events_null, apply_null, outputs_null, step_null, dense_null)


def null_model(ip: np.ndarray) -> Any:
    """The model tuple of a model with integer array ``ip`` that stands still."""
    return ModelTuple((np.array(ip, dtype=np.int64), *NULL_KERNELS))
