"""Copy an inlined callee's IR once per function instead of once per block (numba).

Every ``@njit(inline="always")`` call site makes numba copy the callee's IR
(``InlineWorker.inline_ir``'s ``copy_ir``).  It deep-copies each block on its
own, and every block holds the function's ``Scope``, which holds every variable
of the function: the whole scope is copied once per block, so the cost grows
with blocks x variables, and the stage arithmetic of our steppers is inlined
hundreds of times into large callers.  Under cProfile, compiling the ``fast``
engine took 155 s, 76 s of them in ``copy_ir``; without the profiler this copy cut
that compile from 75 s to 50 s.  Upstream: numba issue 8989, "Spurious deep copies
in inlining".

:func:`install` makes the blocks of one IR share one copy memo, i.e. copies them
as one object graph, as ``copy.deepcopy(blocks)`` would: the copy still shares
nothing with the callee's IR (``copy_ir`` exists because inlining mutates the
copy), but its blocks share one copy of the scope, like the original's blocks
share one scope.  The compiled code is the same.  It patches nothing when numba
does not have the structure it was written against (checked, not assumed).

:func:`install_before_first_compile` defers the patch to the start of the first
compilation: numba's inliner module takes 25 ms to import, and a process that
only loads compiled code from the cache (a warm ``rubcosim run``) never needs it.
"""

from __future__ import annotations

import copy
from typing import Any

_DEFERRED: list[Any] = []  # the listener of install_before_first_compile, once registered


class BlockGraphCopy:
    """Stands in for the ``copy`` module inside numba's ``inline_closurecall``
    during one ``inline_ir`` call: ``deepcopy(block)`` of blocks with the same
    scope share one memo; every other call is the ``copy`` module's own."""

    def __init__(self) -> None:
        self._scope: Any = None
        self._memo: dict[int, Any] = {}

    def deepcopy(self, x: Any, memo: dict[int, Any] | None = None) -> Any:
        scope = getattr(x, "scope", None)
        if memo is not None or scope is None:
            return copy.deepcopy(x, memo)
        if scope is not self._scope:
            self._scope, self._memo = scope, {}
        return copy.deepcopy(x, self._memo)

    def __getattr__(self, name: str) -> Any:
        return getattr(copy, name)


def install() -> bool:
    """Patch numba's ``InlineWorker.inline_ir`` (once); True when it is in place."""
    try:
        from numba.core import inline_closurecall as icc
    except ImportError:
        return False
    worker = getattr(icc, "InlineWorker", None)
    original = getattr(worker, "inline_ir", None)
    if getattr(original, "_rubcosim_block_graph_copy", False):
        return True
    if original is None or getattr(icc, "copy", None) is not copy:
        return False
    code = original.__code__
    # the closure copy_ir that this replaces the copy module for
    if "copy_ir" not in code.co_varnames + code.co_cellvars:
        return False

    def inline_ir(self: Any, *args: Any, **kwargs: Any) -> Any:
        # an inlining can compile another function, which inlines in turn: restore
        # what was there, not the module
        previous, icc.copy = icc.copy, BlockGraphCopy()
        try:
            return original(self, *args, **kwargs)
        finally:
            icc.copy = previous

    inline_ir._rubcosim_block_graph_copy = True  # type: ignore[attr-defined]
    inline_ir.__wrapped__ = original  # type: ignore[attr-defined]
    worker.inline_ir = inline_ir
    return True


def install_before_first_compile() -> None:
    """Run :func:`install` when numba starts compiling for the first time in this
    process (its ``numba:compile`` event fires on a cache miss, not on a cache load)."""
    if _DEFERRED:
        return
    from numba.core import event

    class InstallOnCompile(event.Listener):
        def __init__(self) -> None:
            self.installed = False

        def on_start(self, event: Any) -> None:
            if not self.installed:
                self.installed = True
                install()

        def on_end(self, event: Any) -> None:
            pass

    listener = InstallOnCompile()
    event.register("numba:compile", listener)
    _DEFERRED.append(listener)
