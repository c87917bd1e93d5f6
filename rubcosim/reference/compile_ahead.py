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
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import time
from typing import Any

from rubcosim.compile_notice import is_marked, mark, quiet, write_line


def _name(engine: str, has_delay: bool) -> str:
    return f"{engine}-engine-{'delay' if has_delay else 'no-delay'}"


def engine_label(engine: str, has_delay: bool) -> str:
    """How the notices name an engine variant."""
    return f"the {engine} engine for every model {'with' if has_delay else 'without'} a delay"


def is_compiled(engine: str, has_delay: bool) -> bool:
    """Whether a process has compiled (or loaded) this engine variant with this cache."""
    return is_marked(_name(engine, has_delay))


def mark_compiled(engine: str, has_delay: bool) -> None:
    """Record that this engine variant is in the cache (after its first run)."""
    mark(_name(engine, has_delay))


def _enabled() -> bool:
    return os.environ.get("RUBCOSIM_COMPILE_AHEAD", "1") != "0" and (os.cpu_count() or 1) > 1


class Helper:
    """A process compiling an engine variant; :meth:`finish` waits for it."""

    def __init__(self, process: subprocess.Popen, what: str) -> None:
        self.process = process
        self.what = what
        self.started = time.perf_counter()

    def finish(self) -> bool:
        """Wait for the helper; whether it compiled the engine (if not, the caller's
        first call compiles it)."""
        _, err = self.process.communicate()
        ok = self.process.returncode == 0
        if not quiet():
            elapsed = time.perf_counter() - self.started
            if ok:
                write_line(f"rubcosim: compiled {self.what} in {elapsed:.1f} s")
            else:
                last = err.decode(errors="replace").strip().splitlines()[-1:] or ["no message"]
                write_line(f"rubcosim: the second process failed ({last[0]}); compiling here")
        return ok


def start(system: Any, engine: str) -> Helper | None:
    """A helper compiling ``engine``'s variant for ``system`` (with or without a delay),
    or None when it is compiled already, or helpers are off, or there is one core."""
    if not _enabled() or is_compiled(engine, system.has_delay):
        return None
    what = engine_label(engine, system.has_delay)
    env = dict(os.environ, RUBCOSIM_COMPILE_AHEAD="0", RUBCOSIM_QUIET_COMPILE="1")
    try:
        process = subprocess.Popen(
            [sys.executable, "-m", "rubcosim.reference.compile_ahead", engine],
            stdin=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            env=env,
        )
    except OSError:
        return None
    if not quiet():
        later = "later runs load it from the cache"
        write_line(f"rubcosim: compiling {what} in a second process (first use; {later})")
    # the system's arrays and names, a few kB: the pipe takes them before the helper reads
    try:
        process.stdin.write(pickle.dumps(system))
        process.stdin.close()
    except OSError:  # the helper died at start (BrokenPipeError): compile here instead
        process.kill()
        process.wait()
        return None
    process.stdin = None  # communicate() must not flush a closed pipe
    return Helper(process, what)


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
