"""How the engines' machinery calls a model: through the pointers of a model tuple.

A *model tuple* is ``(ip, rhs, events, apply, outputs, step, dense)``: the system's integer
array and its kernels, C functions compiled per model family (:mod:`.model_kernels`,
:func:`.specialize.compiled_model`).  Every module of the machinery takes it where
the kernels of :mod:`.system` once took ``ip``, and calls the model through the
functions below, which have :mod:`.system`'s signatures.  numba types a C function as
a ``FunctionType`` of its signature, not as the function itself, so the machinery is
compiled, and cached, once for every model: what a new model compiles is its kernels.

The price is an indirect call where the right-hand side used to be inlined into the
Runge-Kutta stages (measured in ``benchmarks/bench_engines.py``).
"""

from __future__ import annotations

import warnings
from typing import Any

import numba as nb
from numba.core import types
from numba.core.errors import NumbaExperimentalFeatureWarning
from numba.experimental import structref
from numba.extending import typeof_impl

# numba calls first-class function types experimental; they are what this module is
warnings.filterwarnings("ignore", category=NumbaExperimentalFeatureWarning)

M_IP, M_RHS, M_EVENTS, M_APPLY, M_OUTPUTS, M_STEP, M_DENSE = range(7)


class ModelTuple(tuple):
    """A model tuple as Python code holds it (:func:`.specialize.compiled_model`).  numba
    types a plain tuple of C functions anew at every call from Python, some 0.2 ms, and
    the ``accurate`` engine calls compiled code with it at every stage; this one is
    typed once (every model tuple has the same type: the kernels' signatures are fixed)."""

    __slots__ = ()


_MODEL_TYPE: list[Any] = []


@typeof_impl.register(ModelTuple)
def _typeof_model(val: ModelTuple, c: Any) -> Any:
    if not _MODEL_TYPE:
        _MODEL_TYPE.append(nb.typeof(tuple(val)))
    return _MODEL_TYPE[0]


# The kernels' signatures, the contract between the machinery and a model's C functions
# (:mod:`.model_kernels`): every array C-contiguous.
_F, _I = types.float64, types.int64
_A, _IA = types.float64[::1], types.int64[::1]
# (t, y, yd, mode, p, ip, ...): yd the delayed disc state, p and ip the system's arrays
RHS = types.void(_F, _A, _A, _I, _A, _IA, _A)  # ..., dy
EVENTS = types.void(_F, _A, _A, _I, _A, _IA, _A, _IA, _IA)  # ..., g, dirs, rates
APPLY = types.int64(_I, _F, _A, _A, _I, _A, _IA)  # (k, t, y, yd, mode, p, ip)
OUTPUTS = types.void(_F, _A, _A, _I, _A, _IA, _A)  # ..., out
# (t, y, f, h, mode, p, ip, yd, K, y_new, f_new, ytmp): a DOP853 step without a delay
_M = types.float64[:, ::1]
STEP = types.void(_F, _A, _A, _F, _I, _A, _IA, _A, _M, _A, _A, _A)
# (t_old, h, y_old, y_new, f_new, mode, p, ip, yd, K, F, ytmp): its dense output
DENSE = types.void(_F, _F, _A, _A, _A, _I, _A, _IA, _A, _M, _M, _A)

# an event map's (new mode, kind) travels as new mode * KIND_BASE + kind (every kind is
# below it): a C function returns one scalar
KIND_BASE = 64


@nb.njit(cache=True, inline="always")
def ip_of(model):
    """The system's integer array (family, units, state offsets)."""
    return model[M_IP]


@nb.njit(cache=True, inline="always")
def rhs(t, y, yd, mode, p, model, dy):
    """dy/dt for the system in ``mode``; ``yd`` the delayed disc state."""
    model[M_RHS](t, y, yd, mode, p, model[M_IP], dy)


@nb.njit(cache=True, inline="always")
def events(t, y, yd, mode, p, model, g, dirs, rates):
    """Fill the event functions ``g``, their directions and rate companions."""
    model[M_EVENTS](t, y, yd, mode, p, model[M_IP], g, dirs, rates)


@nb.njit(cache=True, inline="always")
def apply_event(k, t, y, yd, mode, p, model):
    """Apply the event of slot ``k`` at time t (may change y in place); returns
    ``(new_mode, kind)``."""
    code = model[M_APPLY](k, t, y, yd, mode, p, model[M_IP])
    return code // KIND_BASE, code % KIND_BASE


@nb.njit(cache=True, inline="always")
def outputs(t, y, yd, mode, p, model, out):
    """The recorded outputs (:func:`.system_outputs.output_names`) into ``out``."""
    model[M_OUTPUTS](t, y, yd, mode, p, model[M_IP], out)


@nb.njit(cache=True, inline="always")
def rk_step(t, y, f, h, mode, p, model, yd, K, y_new, f_new, ytmp):
    """A DOP853 step of a delay-free model (:func:`.model_kernels.step_c`)."""
    model[M_STEP](t, y, f, h, mode, p, model[M_IP], yd, K, y_new, f_new, ytmp)


@nb.njit(cache=True, inline="always")
def dense_output(t_old, h, y_old, y_new, f_new, mode, p, model, yd, K, F, ytmp):
    """The dense output of a delay-free model's step (:func:`.model_kernels.dense_c`)."""
    model[M_DENSE](t_old, h, y_old, y_new, f_new, mode, p, model[M_IP], yd, K, F, ytmp)


# ------------------------------------------------- the model for many calls from Python
@structref.register
class ModelRefType(types.StructRef):
    def preprocess_fields(self, fields: Any) -> tuple:
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class ModelRef(structref.StructRefProxy):
    """The model tuple behind one reference, for Python code that calls compiled code
    with it many times (the ``accurate`` engine, at every Runge-Kutta stage): passing the
    tuple makes numba look up each C function's address at every call (some 80 us for the
    seven), passing this a pointer.  :func:`as_ref` makes one, :func:`unpack` gives the
    tuple back in compiled code."""


structref.define_proxy(ModelRef, ModelRefType, ["ip", "rhs", "events", "apply", "outputs",
                                                "step", "dense"])  # fmt: skip


@nb.njit(cache=True)
def _new_ref(ip, rhs, events, apply, outputs, step, dense):
    return ModelRef(ip, rhs, events, apply, outputs, step, dense)


def as_ref(model: tuple) -> ModelRef:
    """A model tuple (:func:`.specialize.compiled_model`) behind one reference."""
    return _new_ref(*model)


@nb.njit(cache=True, inline="always")
def unpack(ref):
    """The model tuple of a :class:`ModelRef`."""
    return (ref.ip, ref.rhs, ref.events, ref.apply, ref.outputs, ref.step, ref.dense)
