"""Compile kernels with numba in rubcosim; run them as plain Python inside an FMU.

The kernels are numba-compiled for the reference engines.  An FMU bundles a
copy of this package under another name; there the kernels run as plain
Python by default, because an FMU calls them a few times per communication
step, where compiling them at every load would cost seconds and gain
nothing, and because the importing machine may not have numba.  Setting
``RUBCOSIM_NUMBA=1`` compiles the bundled copy too (the installed package
always compiles: its engines call the kernels from compiled code).  Either
way the same source is the only definition of every equation.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

_BUNDLED = __package__ != "rubcosim.components"
_numba = None
if not _BUNDLED or os.environ.get("RUBCOSIM_NUMBA") == "1":
    try:
        import numba as _numba
    except ImportError:  # exercised by the FMU tests, in a process without numba
        _numba = None
USE_NUMBA = _numba is not None


def njit(
    function: Callable[..., Any] | None = None, *, inline: str = "never", borrows: bool = False
) -> Callable[..., Any]:
    """``numba.njit(cache=True)`` when numba is in use, else ``function`` itself.

    ``inline="always"`` inlines a small kernel into its callers at numba's IR
    level (the stage arithmetic of a Runge-Kutta step, called 12 times a step);
    used bare (``@njit``) or with options (``@njit(inline="always")``).

    ``borrows=True`` is for a kernel that only borrows the arrays it is given: it
    allocates none and keeps none after it returns (its callers own them all).  It is
    compiled without numba's reference counting (numba's ``_nrt`` option), so a call
    does not pay a runtime call per array argument on entry and another on exit: an
    event search called with a few dozen arrays spent more time there than in its
    arithmetic.  Numba refuses to compile such a kernel if it allocates.
    """
    if function is None:
        return lambda f: njit(f, inline=inline, borrows=borrows)
    if not USE_NUMBA:
        return function
    if borrows:
        return _numba.njit(cache=True, inline=inline, _nrt=False)(function)
    return _numba.njit(cache=True, inline=inline)(function)
