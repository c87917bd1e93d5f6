"""Two costs of numba's inlining that grow faster than the code inlined (patches).

Every ``@njit(inline="always")`` call site makes numba build the callee's IR and
copy it into the caller (``InlineWorker.inline_function``, then ``inline_ir``).
The stage arithmetic of our steppers and the models' right-hand sides are inlined
hundreds of times into large callers, and two parts of that scale badly:

- **The copy** (``inline_ir``'s ``copy_ir``) deep-copies each block on its own,
  and every block holds the function's ``Scope``, which holds every variable of
  the function: the whole scope is copied once per block (blocks x variables).
  :class:`BlockGraphCopy` makes the blocks of one IR share one copy memo, i.e.
  copies them as one object graph, as ``copy.deepcopy(blocks)`` would: the copy
  shares nothing with the callee's IR (``copy_ir`` exists because inlining
  mutates the copy), and its blocks share one copy of the scope, as the
  original's share one scope.  Under cProfile, compiling the ``fast`` engine took
  155 s, 76 s of them in ``copy_ir``; without the profiler this cut that compile
  from 75 s to 50 s.  Upstream: numba issue 8989, "Spurious deep copies in
  inlining".
- **The build** runs the untyped pipeline over the callee at every call site, and
  that pipeline inlines the callee's own callees the same way, so nested inlining
  multiplies the builds.  :class:`CalleeMemo` builds each callee's IR once per
  function and compile options: a cold compile of the ``fast`` engine built callee
  IR 500 times, and builds it 77 times (66-69 s to 58-60 s, alternated, one core).

The compiled code is the same.  :func:`install` patches nothing when numba does
not have the structure it was written against (checked, not assumed);
``numba_compile_time`` installs it at the first compilation of a process.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any


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
    """Patch numba's ``InlineWorker.inline_ir`` and ``inline_function`` (once); True
    when both are in place."""
    try:
        from numba.core import inline_closurecall as icc
    except ImportError:
        return False
    return _install_block_graph_copy(icc) and _install_callee_memo(icc)


def _install_block_graph_copy(icc: Any) -> bool:
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


# Flags the untyped pipeline does not read (numba 0.68): the build sets enable_ssa
# itself; nrt (reference counting) and release_gil (nogil) are read by lowering and
# object mode only.  Callers that differ in these alone (an engine compiled nogil, an
# event search compiled without reference counting) share one callee IR.
_NOT_READ = frozenset({"enable_ssa", "nrt", "release_gil"})


class CalleeMemo:
    """The callee IR of ``InlineWorker.inline_function``, built once per function
    and compile options instead of once per call site.

    numba builds an inlined callee's IR by running the untyped pipeline over it at
    every call site, and that pipeline inlines the callee's own callees the same
    way: a kernel inlined at ``a`` sites that inlines one at ``b`` sites runs the
    inner one's pipeline ``a * b`` times.  The IR depends only on the function and
    on the options the pipeline reads (the worker's contexts, flags, locals and
    pipeline), so one build per such key gives the same IR: 77 builds where a cold
    compile of the ``fast`` engine made 500.  ``inline_ir``
    copies the callee's IR before it changes anything (``copy_ir``), so the stored IR
    is never modified.

    Only the functions of ``packages`` (rubcosim's, or an FMU's bundled copy of it)
    are kept: a host program's own numba code compiles as numba compiles it (an IR
    holds the globals' values at its build, and a program may change a global
    between two compilations).
    """

    def __init__(self) -> None:
        self._built: dict[Any, list[tuple[tuple[Any, ...], Any]]] = {}
        self.packages = {__name__.partition(".")[0]}

    def covers(self, function: Any) -> bool:
        """Whether the IR of ``function`` is built once: a function of ``packages``, or
        of a module they generate (``hybrid_dispatch``: ``<package>_..._<digest>``)."""
        module = getattr(function, "__module__", None) or ""
        return any(
            module.partition(".")[0] == p or module.startswith(p + "_") for p in self.packages
        )

    def callee_ir(self, worker: Any, function: Any, build: Callable[[], Any]) -> Any:
        options = (
            id(worker.typingctx),
            # every compilation makes its own target context from the flags (numba's
            # _make_subtarget): keyed by the flags below
            type(worker.targetctx),
            type(worker.pipeline),
            {k: v for k, v in worker.flags.values().items() if k not in _NOT_READ},
            dict(worker.locals or {}),
        )
        entries = self._built.setdefault(function, [])
        for key, ir in entries:
            if key == options:
                # the side effect of numba's own build: the flags say "no SSA"
                worker.flags.enable_ssa = False
                return ir
        ir = build()
        entries.append((options, ir))
        return ir


def _install_callee_memo(icc: Any) -> bool:
    worker = getattr(icc, "InlineWorker", None)
    original = getattr(worker, "inline_function", None)
    if getattr(original, "_rubcosim_callee_memo", False):
        return True
    if original is None or not hasattr(worker, "run_untyped_passes"):
        return False
    code = original.__code__
    # numba's inline_function: the callee's untyped IR, then inline_ir (which copies it)
    if code.co_varnames[:5] != ("self", "caller_ir", "block", "i", "function"):
        return False
    if not {"run_untyped_passes", "inline_ir"} <= set(code.co_names):
        return False
    memo = CalleeMemo()

    def inline_function(
        self: Any, caller_ir: Any, block: Any, i: int, function: Any, arg_typs: Any = None
    ) -> Any:
        if not memo.covers(function):
            return original(self, caller_ir, block, i, function, arg_typs=arg_typs)
        callee_ir = memo.callee_ir(self, function, lambda: self.run_untyped_passes(function))
        return self.inline_ir(
            caller_ir, block, i, callee_ir, function.__code__.co_freevars, arg_typs=arg_typs
        )

    inline_function._rubcosim_callee_memo = True  # type: ignore[attr-defined]
    inline_function.__wrapped__ = original  # type: ignore[attr-defined]
    worker.inline_function = inline_function
    return True
