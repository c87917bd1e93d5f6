"""Compile an engine in a second process while this one compiles the model's kernels.

A first run on an empty cache compiles two things that do not depend on each other:
the engine's machinery (once for every model, :mod:`.model_calls`) and the model's own
kernels (:mod:`.specialize`).  On a machine with more than one core,
:func:`start` hands the first to a helper process, which compiles it against a model
that stands still (:mod:`.null_model`: its tuple has every model's type, so what it
writes to numba's cache is the entry every model loads), and this process compiles
the kernels meanwhile; :meth:`Helper.finish` waits for the helper, and the engine's
first call then loads the machinery from the cache.

A marker in numba's cache directory (keyed, like the cache, by the sources) records
that an engine variant is compiled, so a warm process starts no helper.  The helper is
an optimisation only: if it fails, this process compiles the engine itself, as it
would without one.  ``RUBCOSIM_COMPILE_AHEAD=0`` turns it off (``rubcosim warm-up``
does, in its own worker processes).

This module is the helper's program (:func:`compile_engine`, run by ``python -m``); the
running process's side, which :mod:`.simulate` uses, is :mod:`.compile_helper`, whose
names are re-exported here.
"""

from __future__ import annotations

import pickle
import sys
from typing import Any

# the running process's side (the helper's start, the markers), re-exported here
from .compile_helper import Helper, engine_label, is_compiled, mark_compiled, start

__all__ = [
    "Helper",
    "compile_engine",
    "engine_label",
    "is_compiled",
    "main",
    "mark_compiled",
    "start",
]


def compile_engine(system: Any, engine: str) -> None:
    """Compile (or load) ``engine``'s variant for ``system``'s type, with the null model."""
    from .null_model import null_model
    from .simulate import tiny_run

    rtol = 1e-6
    tiny_run(system, null_model(system.ip), engine, 0.0, rtol, rtol, system.min_delay())
    mark_compiled(engine, system.has_delay)


def main() -> None:
    """The helper: the system pickled on stdin, the engine's name as the argument."""
    system = pickle.loads(sys.stdin.buffer.read())
    compile_engine(system, sys.argv[1])


if __name__ == "__main__":
    main()
