"""The compiled master's unit steps and output reads behind C functions.

The compiled master (:mod:`rubcosim.orchestrator.flat_loop`) steps units from half a
dozen places (a macro step, its replay, the event location, the event maps).  Called
as a numba function, the step put a copy of every unit type's integrator (the DOP853
driver with every unit's right-hand side, the hybrid units' event location, the
matrix exponential, the controller's history) into each of those callers: numba
links a callee's compiled module into its caller's, and optimises and generates
machine code for the whole again.  That was most of the master's four-minute compile.
Called through the pointer of a C function (``numba.cfunc``, which numba types by its
signature), the step compiles once.  A unit step (an integration over a macro step)
costs far more than the indirect call.  So do the output reads, which are cheap and
frequent: the rotors', stators' and bearings' (:func:`outputs_c`) take four arguments
and no reference counting (``_nrt=False``: they allocate nothing), so that the call
costs little more than a direct one.

The signatures are the contract with the master (every array C-contiguous; a row
status back, :data:`.flat_rows.STEP_OK` when fine)::

    step_c(kind, ode, exact, ny, nin, node, idx, p, tol, A, Bu, a, b, c, st, buf, scratch, t, h)
    outputs_c(kind, p, st, out)
    other_outputs_c(kind, ny, node, nout, idx, omap, mval, p, st, buf, scratch, out)

:func:`step_c`: :func:`.flat_units.do_step` on the unit in row ``st`` (its ODE inputs
``idx[:node]``, ``(A, Bu, a, b, c)`` the rotor's affine model when ``exact`` is 1), or
for a controller :func:`.flat_controller.row_step` on its history ``buf`` and
``scratch``.  :func:`outputs_c`: :func:`.flat_units.outputs` (kinds below
:data:`.flat_units.K_HYBRID`); :func:`other_outputs_c`: a hybrid unit's
(:func:`.flat_hybrid.hybrid_outputs`) or a controller's
(:func:`.flat_controller.row_outputs`).
"""

from __future__ import annotations

import warnings

import numba as nb
from numba import types
from numba.core.errors import NumbaExperimentalFeatureWarning

from .flat_controller import row_outputs, row_step
from .flat_hybrid import hybrid_outputs
from .flat_units import K_CONTROLLER, K_HYBRID, do_step, outputs

# numba calls first-class function types experimental; the master calls this as one
warnings.filterwarnings("ignore", category=NumbaExperimentalFeatureWarning)

_F, _I = types.float64, types.int64
_A, _IA, _M = types.float64[::1], types.int64[::1], types.float64[:, ::1]
STEP = types.int64(_I, _I, _I, _I, _I, _I, _IA, _A, _A, _M, _M, _A, _A, _A, _A, _M, _M, _F, _F)
OUTPUTS = types.int64(_I, _A, _A, _A)
OTHER_OUTPUTS = types.int64(_I, _I, _I, _I, _IA, _IA, _M, _A, _A, _M, _M, _A)


def step_c(kind, ode, exact, ny, nin, node, idx, p, tol, A, Bu, a, b, c, st, buf, scratch, t, h):
    """Advance the unit in row ``st`` from ``t`` to ``t + h`` (s)."""
    if kind == K_CONTROLLER:
        return row_step(p, st, buf, scratch, t, h)
    return do_step(kind, ode, exact != 0, ny, nin, idx[:node], p, tol, (A, Bu, a, b, c), st, t, h)


def outputs_c(kind, p, st, out):
    """The outputs of the rotor, stator or bearing in row ``st`` at its time."""
    return outputs(kind, p, st, out)


def other_outputs_c(kind, ny, node, nout, idx, omap, mval, p, st, buf, scratch, out):
    """The outputs of the hybrid unit or controller in row ``st`` at its time."""
    if kind == K_HYBRID:
        return hybrid_outputs(ny, node, nout, idx[:node], omap, mval, p, st, out)
    return row_outputs(p, st, buf, scratch, out)


_COMPILED: list = []


def unit_calls() -> tuple:
    """``(step_c, outputs_c, other_outputs_c)`` as C functions, compiled (or loaded from
    numba's cache) at the first call: a ``numba.cfunc`` compiles where it is made, and a
    process that only imports the master (the Python master runs) must not pay for it."""
    if not _COMPILED:
        _COMPILED.append(
            (
                nb.cfunc(STEP, cache=True)(step_c),
                nb.cfunc(OUTPUTS, cache=True, _nrt=False)(outputs_c),
                nb.cfunc(OTHER_OUTPUTS, cache=True)(other_outputs_c),
            )
        )
    return _COMPILED[0]
