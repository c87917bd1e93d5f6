"""Compile the numba kernels once, into the cache, before the first real run.

A fresh checkout has an empty numba cache: its first run compiles the engine,
the unit stepper and the analysis kernels (a minute or more on two cores) for
a simulation of milliseconds.  ``rubcosim warm-up`` (run by ``make run`` and
``make test``) does that once: short runs of bundled scenarios that reach every
compiled path, in parallel processes where the paths do not overlap.  Every later
process loads the compiled code from the cache (keyed by the sources, see
``rubcosim/__init__.py``), so a change of source compiles again, once.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor


def _engines() -> str:
    """The monolithic engine (fast and accurate) and, built on it, the stroboscopic map
    kernels of the analyses and the engine with its tangent (Lyapunov, Floquet): one
    process, because each of those compiles on the plain engine's kernels."""
    from . import api

    api.simulate("jeffcott_rigid_stator", "fast", set={"sim.t_end": 0.005})
    api.simulate("impact_duffing", "fast", set={"sim.t_end": 10.0})
    api.sweep("impact_duffing", "oscillator.forcing_amplitude", [0.5, 0.6], periods=2, discard=2)
    api.basins("impact_duffing", grid=(4, 4), samples=1, region="-2:1,-2:2")
    api.lyapunov("impact_duffing", periods=2, transient=1)
    api.simulate("jeffcott_rigid_stator", "accurate", set={"sim.t_end": 0.002})
    _controller_kernels()
    return "engines, analysis kernels, the variational equations, the controller's kernels"


def _controller_kernels() -> None:
    """The delayed-feedback controller's kernels on a buffer (flat_controller): in this
    job, the shorter of the two, where their compilation fits in the other's time."""
    import numpy as np

    from .components.delay_history import ROW
    from .components.flat_controller import (
        controller_outputs,
        controller_params,
        controller_step,
        make_room,
    )
    from .components.units import make_unit

    unit = make_unit("controller", "delayed_feedback", gain=1.0, delay=1e-3, memory=0.5, speed=0.0)
    p = controller_params(unit.params)
    cs, buf, scratch = np.array([0.0, 0.0, np.nan]), np.zeros((8, ROW)), np.zeros((9, ROW))
    controller_step(p, cs, buf, scratch, 0.0, 0.0, 0.0, 0.0, 0.0)
    controller_outputs(p, cs, buf, scratch, 0.0, 0.0, 0.0, 0.0, 0.0, np.empty(3))
    make_room(cs, buf, 1)


def _units() -> str:
    """The co-simulation's units (the compiled unit stepper for ODE and hybrid units) and
    the master's compiled loop, then the engine with a delay (``fast``, then the
    ``accurate`` engine's compiled event handling on it): last, so that what it
    shares with the plain engine (event maps, outputs) is in the cache by then instead
    of being compiled in both processes at once."""
    from . import api

    api.cosimulate("jeffcott_rigid_stator", "direct", set={"sim.t_end": 0.002})
    api.cosimulate("jeffcott_elastic_casing", "direct", set={"sim.t_end": 0.002})
    api.cosimulate("impact_duffing", "direct", set={"sim.t_end": 5.0})
    api.simulate("jeffcott_delayed_feedback", "fast", set={"sim.t_end": 0.005})
    api.simulate("jeffcott_delayed_feedback", "accurate", set={"sim.t_end": 0.002})
    return "co-simulation units and master, the engine with a delay (fast and accurate)"


JOBS: tuple[Callable[[], str], ...] = (_engines, _units)


def warm_up(workers: int = 2) -> list[tuple[str, float]]:
    """Run the warm-up jobs (in ``workers`` processes; 1: in this one); returns what each
    compiled and its wall time (s)."""
    if workers <= 1:
        return [_timed_job(i) for i in range(len(JOBS))]
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = [pool.submit(_timed_job, i) for i in range(len(JOBS))]
        return [f.result() for f in futures]


def _timed_job(index: int) -> tuple[str, float]:
    start = time.perf_counter()
    what = JOBS[index]()
    return what, time.perf_counter() - start
