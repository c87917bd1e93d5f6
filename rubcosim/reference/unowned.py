"""Views of scratch arrays that numba does not reference-count, for the engines' hot loops.

Every array that a compiled function receives is reference-counted by numba: an
atomic increment and decrement around each use the optimiser cannot prove
redundant.  In the step loop of the ``fast`` engine (a right-hand side per
Runge-Kutta stage, event functions at every step end) those atomics cost about
a quarter of the time of a small system.  An array whose ``meminfo`` is null is
not counted (numba's ``NRT_incref`` and ``NRT_decref`` return at once), so the
engine works on such views of its scratch arrays.  A view does not keep its
array alive: the array must stay referenced by the caller for as long as the
view is used (:func:`unowned` documents where each caller keeps its owners).
"""

from __future__ import annotations

import numba as nb
from numba.core import cgutils
from numba.extending import intrinsic
from numba.np.arrayobj import make_array


@intrinsic
def unowned(typingctx, arr):  # pragma: no cover - compiled
    """A view of ``arr`` (same data, shape and strides) without its memory owner: not
    reference-counted, valid only while ``arr`` itself is alive."""

    def codegen(context, builder, sig, args):
        src = make_array(sig.args[0])(context, builder, value=args[0])
        view = make_array(sig.return_type)(context, builder)
        for field in ("parent", "nitems", "itemsize", "data", "shape", "strides"):
            setattr(view, field, getattr(src, field))
        view.meminfo = cgutils.get_null_value(view.meminfo.type)
        return view._getvalue()

    return arr(arr), codegen


@nb.njit(cache=True)
def keep_alive(owners) -> None:  # pragma: no cover - compiled
    """A use of ``owners`` at the point up to which the views of them are used: numba
    releases a variable after its last use, which would free the views' memory."""
