"""Cheaper cold compiles of rubcosim's kernels, with the same compiled code.

numba's front end spends much of a cold compile of our engines in its inlining, whose
cost grows faster than the code inlined (:mod:`.numba_inlining`, which patches it,
produces the same IR, and patches nothing when numba does not have the structure it was
written against).  numba's SSA reconstruction was patched too, until the engines' model
kernels were compiled apart from their machinery: without that patch a cold compile of
the flagship's engines took the same time (``benchmarks/profile_compile.py``, two
alternated pairs: 52.7 and 54.9 s against 52.3 and 55.3 s with it), the co-simulation's
units and master 169.4 s against 162.5 s (one pair, within this machine's drift), and
it went.

:func:`install_before_first_compile` installs the patch when numba starts compiling for
the first time in a process: numba's inliner module takes 25 ms to import, and a process
that only loads compiled code from the cache (a warm ``rubcosim run``) never needs it.
"""

from __future__ import annotations

from typing import Any

_DEFERRED: list[Any] = []  # the listener, once registered


def install() -> dict[str, bool]:
    """Install the patch now; whether it is in place."""
    from . import numba_inlining

    return {"inlining": numba_inlining.install()}


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
