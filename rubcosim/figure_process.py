"""A helper process that draws a command's figures, with matplotlib imported meanwhile.

Importing matplotlib takes about a quarter of a second, and drawing a basin map
a few tenths more; a command that ends with a figure (``rubcosim basins``) pays
both after its analysis, one core busy and the other idle.  A
:class:`FigureProcess` is forked when the command starts, before the analysis
opens its workers or any thread: the child imports matplotlib while the parent
loads its compiled kernels, then waits.  At the end the parent sends it the
figure to draw (a module-level function and its arguments, pickled) and writes
its other files in the same time.

Whatever goes wrong in the helper (it could not start, it died, the drawing
raised) ends the same way: the figure is drawn in this process, as it would be
without the helper, and an error of the drawing itself is raised here.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import traceback
from collections.abc import Callable
from typing import Any


def _serve(conn: Any) -> None:  # pragma: no cover - runs in the child
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot  # noqa: F401 - imported now, while the parent computes
    except Exception:  # the job will then fail and be drawn by the parent
        pass
    while True:
        try:
            job = conn.recv()
        except EOFError:
            return
        if job is None:
            return
        fn, args = job
        try:
            fn(*args)
            conn.send(None)
        except Exception:
            conn.send(traceback.format_exc())


class FigureProcess:
    """Draw figures in a child process forked now (see the module doc).  Use as a
    context manager; :meth:`submit` a figure, do other work, then :meth:`wait`."""

    def __init__(self) -> None:
        self._conn: Any = None
        self._proc: Any = None
        self._job: tuple[Callable[..., None], tuple[Any, ...]] | None = None
        try:
            ctx = mp.get_context("fork")
            self._conn, child = ctx.Pipe()
            self._proc = ctx.Process(target=_serve, args=(child,), daemon=True)
            self._proc.start()
            child.close()
        except (OSError, ValueError):  # no fork on this platform, or no process left
            self._conn = self._proc = None

    def submit(self, fn: Callable[..., None], *args: Any) -> None:
        """Start drawing ``fn(*args)`` (``fn`` importable by name); at most one at a
        time."""
        self._job = (fn, args)
        if self._proc is None:
            return
        try:
            self._conn.send(self._job)
        except (OSError, ValueError, EOFError):  # the helper is gone: draw here at wait()
            self._close()

    def wait(self) -> None:
        """Until the submitted figure is written; drawn here if the helper failed."""
        job, self._job = self._job, None
        if job is None:
            return
        if self._proc is not None:
            try:
                if self._conn.recv() is None:
                    return
            except (OSError, EOFError):
                pass
            self._close()  # it failed: what it could not do, this process does
        job[0](*job[1])

    def _close(self) -> None:
        if self._proc is None:
            return
        with contextlib.suppress(OSError, ValueError):
            self._conn.send(None)
        self._conn.close()
        self._proc.join(timeout=5)
        if self._proc.is_alive():
            self._proc.terminate()
        self._proc = None

    def __enter__(self) -> FigureProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self._job = None
        self._close()
