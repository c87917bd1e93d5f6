"""Cheaper cold compiles of rubcosim's kernels, with the same compiled code.

numba's front end spends most of a cold compile of our engines in passes whose
cost grows faster than the code: inlining (:mod:`.numba_inlining`) and SSA
reconstruction (:mod:`.numba_ssa`).  Each module patches one of them, produces the
same IR, and patches nothing when numba does not have the structure it was
written against.

:func:`install_before_first_compile` installs them when numba starts compiling
for the first time in a process: numba's inliner module takes 25 ms to import,
and a process that only loads compiled code from the cache (a warm
``rubcosim run``) never needs either.
"""

from __future__ import annotations

from typing import Any

_DEFERRED: list[Any] = []  # the listener, once registered


def install() -> dict[str, bool]:
    """Install both patches now; which of them are in place."""
    from . import numba_inlining, numba_ssa

    return {"inlining": numba_inlining.install(), "ssa": numba_ssa.install()}


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
