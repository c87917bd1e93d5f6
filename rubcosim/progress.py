"""A progress bar in simulated time for long runs, fed by a watcher thread.

The integrators are not slowed down to report progress: a thread reads how far a run
has got (the co-simulation master's time, or the output-grid index a compiled engine
has recorded up to: the ``fast`` engine releases the GIL) every ``every`` seconds and
moves a tqdm bar on stderr.  Nothing is shown for runs shorter than ``delay`` seconds,
nor when stderr is not a terminal, nor when the caller turns it off (``rubcosim run
--no-progress``).  Imports nothing of rubcosim: every layer may use it.
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager

DELAY_S = 2.0  # runs shorter than this show nothing
EVERY_S = 0.2


@contextmanager
def watch(
    label: str,
    t_start: float,
    t_end: float,
    read: Callable[[], float],
    enabled: bool = True,
    delay: float | None = None,
    every: float | None = None,
) -> Iterator[None]:
    """Show a bar from ``t_start`` to ``t_end`` (s of simulated time) while the block
    runs, at the time ``read()`` returns; ``delay`` and ``every`` (s) default to
    :data:`DELAY_S` and :data:`EVERY_S`."""
    delay = DELAY_S if delay is None else delay
    every = EVERY_S if every is None else every
    stream = sys.stderr
    if not enabled or not t_end > t_start or not getattr(stream, "isatty", lambda: False)():
        yield
        return
    from tqdm import tqdm

    total = t_end - t_start

    def describe(t: float) -> str:
        return f"{label}: t = {t:.4g} of {t_end:.4g} s"

    bar = tqdm(
        total=total,
        desc=describe(t_start),
        delay=delay,
        mininterval=every,
        leave=False,
        file=stream,
        bar_format="{desc} {percentage:3.0f}%|{bar}| [{elapsed}<{remaining}]",
    )
    stop = threading.Event()

    def poll() -> None:
        while not stop.wait(every):
            done = min(max(read() - t_start, 0.0), total)
            if done > bar.n:
                bar.set_description_str(describe(t_start + done), refresh=False)
                bar.update(done - bar.n)

    thread = threading.Thread(target=poll, name="rubcosim-progress", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()
        bar.close()
