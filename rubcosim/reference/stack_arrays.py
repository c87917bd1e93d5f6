"""Scratch arrays on the stack of a compiled function, for the engines' step loops.

``np.empty`` inside a compiled function allocates on the heap, and the step loop
of the ``fast`` engine sees its scratch arrays only through pointers that the
optimiser cannot tell apart: every store into a Runge-Kutta stage may, for all
it knows, have changed the stage point or the state, so each stage reloads them
from memory.  An array whose buffer is the function's own stack slot (an LLVM
``alloca`` in the entry block) is known to overlap no other, and costs no
allocation: for the Feng & Yang oscillator a DOP853 step with its error norm
took 143 ns on stack arrays against 199 ns on heap ones (the same arithmetic, bit
for bit).

A stack array is sized at compile time (``capacity``, a module constant: numba
compiles it in as a literal) and viewed at run time with the shape asked for,
which must fit (the caller checks).  It has no memory owner (null ``meminfo``,
like :func:`.unowned.unowned`'s views): it lives until the function that made it
returns, including every function it is passed to, and must not be returned or
kept beyond that.  An intrinsic called inside a loop still allocates once, in
the function's entry block: the same buffer at every pass.
"""

from __future__ import annotations

from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic
from numba.np.arrayobj import make_array


def _stack_array(context, builder, arrty, capacity, shape):
    """An ``arrty`` array of ``shape`` (C order) over ``capacity`` elements of stack."""
    dtype = context.get_data_type(arrty.dtype)
    buf = cgutils.alloca_once(builder, dtype, size=context.get_constant(types.intp, capacity))
    ary = make_array(arrty)(context, builder)
    itemsize = context.get_constant(types.intp, context.get_abi_sizeof(dtype))
    strides = [itemsize]
    for extent in reversed(shape[1:]):
        strides.insert(0, builder.mul(strides[0], extent))
    context.populate_array(ary, data=buf, shape=shape, strides=strides, itemsize=itemsize,
                           meminfo=None)  # fmt: skip
    return ary._getvalue()


def _capacity(capacity) -> int:
    if not isinstance(capacity, types.IntegerLiteral):
        raise TypingError(
            f"a stack array's capacity must be a compile-time constant (a module integer, "
            f"not an expression): got {capacity}"
        )
    return capacity.literal_value


def _vector(capacity, size, dtype):
    """Typing and code of a stack vector of ``dtype`` (the intrinsics below)."""
    cap = _capacity(capacity)
    arrty = types.Array(dtype, 1, "C")

    def codegen(context, builder, sig, args):
        n = context.cast(builder, args[1], sig.args[1], types.intp)
        return _stack_array(context, builder, arrty, cap, [n])

    return arrty(capacity, size), codegen


@intrinsic
def stack_floats(typingctx, capacity, size):  # pragma: no cover - compiled
    """A float64 vector of ``size`` elements on the stack (``size <= capacity``)."""
    return _vector(capacity, size, types.float64)


@intrinsic
def stack_ints(typingctx, capacity, size):  # pragma: no cover - compiled
    """An int64 vector of ``size`` elements on the stack (``size <= capacity``)."""
    return _vector(capacity, size, types.int64)


@intrinsic
def stack_matrix(typingctx, capacity, rows, cols):  # pragma: no cover - compiled
    """A float64 ``rows x cols`` matrix (C order) on the stack (``rows * cols <= capacity``)."""
    cap = _capacity(capacity)
    arrty = types.Array(types.float64, 2, "C")

    def codegen(context, builder, sig, args):
        r = context.cast(builder, args[1], sig.args[1], types.intp)
        c = context.cast(builder, args[2], sig.args[2], types.intp)
        return _stack_array(context, builder, arrty, cap, [r, c])

    return arrty(capacity, rows, cols), codegen
