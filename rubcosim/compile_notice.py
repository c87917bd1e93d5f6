"""Say so when numba compiles: one line naming what, then the time it takes.

A first use of a model compiles its engine (tens of seconds); a run that loads the
compiled code from the cache shows nothing.  :func:`announce` sets what a block of
code would compile (``"the fast engine for rotor.jeffcott + stator.rigid"``); the
first time numba starts compiling inside it, one line goes to stderr, and when the
outermost compilation ends, a second line gives its wall time.  On a terminal the
first line is followed, past :data:`DELAY_S`, by the seconds elapsed, updated in
place.  ``RUBCOSIM_QUIET_COMPILE=1`` silences both.  Imports nothing of rubcosim.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

DELAY_S = 2.0  # a compilation shorter than this gets no timer
_state = threading.local()


def quiet() -> bool:
    """Whether compile notices are off (``RUBCOSIM_QUIET_COMPILE=1``)."""
    return os.environ.get("RUBCOSIM_QUIET_COMPILE") == "1"


class _Listener:
    """Receives numba's ``numba:compile`` events of one :func:`announce` block."""

    def __init__(self, what: str) -> None:
        self.what = what
        self.depth = 0
        self.started = 0.0
        self.compiled = 0.0  # total seconds compiled in this block
        self.functions = 0
        self._stop: threading.Event | None = None
        self._timer: threading.Thread | None = None

    def on_start(self) -> None:
        self.depth += 1
        self.functions += 1
        if self.depth > 1:
            return
        self.started = time.perf_counter()
        if self.compiled == 0.0:
            later = "later runs load it from the cache"
            write_line(f"rubcosim: compiling {self.what} (first use; {later})")
        if sys.stderr.isatty():
            self._stop = threading.Event()
            self._timer = threading.Thread(target=self._tick, daemon=True)
            self._timer.start()

    def on_end(self) -> None:
        self.depth -= 1
        if self.depth > 0:
            return
        self.compiled += time.perf_counter() - self.started
        if self._stop is not None:
            self._stop.set()
            self._timer.join()
            self._stop = self._timer = None
            sys.stderr.write("\r\x1b[K")

    def _tick(self) -> None:
        while not self._stop.wait(0.5):
            elapsed = self.compiled + time.perf_counter() - self.started
            if elapsed >= DELAY_S:
                sys.stderr.write(f"\r  compiling: {elapsed:4.0f} s, {self.functions} functions")
                sys.stderr.flush()


def write_line(line: str) -> None:
    """One notice line on stderr."""
    sys.stderr.write(line + "\n")
    sys.stderr.flush()


@contextmanager
def announce(what: str) -> Iterator[None]:
    """Within the block, a numba compilation is announced as compiling ``what``."""
    if quiet() or getattr(_state, "active", False):
        yield  # an enclosing block already announces (or nothing is said)
        return
    try:
        from numba.core import event
    except ImportError:  # a bundled copy without numba: nothing is compiled
        yield
        return
    listener = _Listener(what)

    class Forward(event.Listener):
        def on_start(self, ev: Any) -> None:
            if threading.current_thread() is owner:
                listener.on_start()

        def on_end(self, ev: Any) -> None:
            if threading.current_thread() is owner:
                listener.on_end()

    owner = threading.current_thread()
    _state.active = True
    try:
        with event.install_listener("numba:compile", Forward()):
            yield
    finally:
        _state.active = False
        if listener.compiled > 0.0:
            write_line(f"rubcosim: compiled {what} in {listener.compiled:.1f} s")


# Loading C functions from numba's cache takes tens of milliseconds (0.6 s seen on a busy
# machine); compiling them, seconds.
SLOW_S = 1.5


@contextmanager
def announce_when_slow(what: str) -> Iterator[None]:
    """:func:`announce` for code that compiles without numba's compile events (C
    functions, ``numba.cfunc``, compile as their module is imported): the first line
    comes once the block has run :data:`SLOW_S`, which loading from the cache does not."""
    if quiet() or getattr(_state, "active", False):
        yield
        return
    started = time.perf_counter()
    said = threading.Event()

    def first_line() -> None:
        said.set()
        write_line(f"rubcosim: compiling {what} (first use; later runs load it from the cache)")

    timer = threading.Timer(SLOW_S, first_line)
    timer.daemon = True
    timer.start()
    _state.active = True
    try:
        yield
    finally:
        _state.active = False
        timer.cancel()
        timer.join()
        if said.is_set():
            write_line(f"rubcosim: compiled {what} in {time.perf_counter() - started:.1f} s")


def _marker(name: str) -> Path | None:
    base = os.environ.get("NUMBA_CACHE_DIR")
    return Path(base) / "compiled" / f"{name}.done" if base else None


def is_marked(name: str) -> bool:
    """Whether a process recorded (:func:`mark`) that ``name`` is in this numba cache
    (the cache directory is keyed by the sources: an edit empties it of markers too)."""
    marker = _marker(name)
    return marker is not None and marker.is_file()


def mark(name: str) -> None:
    """Record that ``name`` (an engine variant, the co-simulation's compiled master) is
    compiled in this numba cache: a later process can count on loading it."""
    marker = _marker(name)
    if marker is None or marker.is_file():
        return
    try:
        marker.parent.mkdir(parents=True, exist_ok=True)
        marker.touch()
    except OSError:  # a read-only cache: no marker
        pass
