"""The side of :mod:`.compile_ahead` that the running process uses: start the helper
process that compiles an engine variant, wait for it, and the markers in numba's cache
directory that record a compiled variant.  The helper's own program (what it runs, which
is the engine itself) stays in :mod:`.compile_ahead`, so :mod:`.simulate` imports this
module and the helper imports :mod:`.simulate`, without a cycle."""

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
