"""Compile the numba kernels of every bundled model into the cache, in parallel.

A run compiles what it uses on first use, and says so: the engines (once for every
model) and its model's kernels (:mod:`rubcosim.reference.specialize`); nothing needs
compiling ahead.  ``rubcosim warm-up`` is for those who want every bundled model ready
(and for ``make test``, whose two workers would otherwise compile the same code at the
same time): the engines with and without a delay, the analyses' loops, the
co-simulation's units and master, and each bundled model's kernels, shared out over
the worker processes.  Every later
process loads the compiled code from the cache; a change of source compiles again,
once.
"""

from __future__ import annotations

import os
import time
from concurrent.futures import ProcessPoolExecutor
from functools import partial


def _engines(scenario: str) -> str:
    """The ``fast`` and ``accurate`` engines (one compilation serves every model), on
    the scenario's model: with a delay if it has one, else without."""
    from . import api

    sc = api.load(scenario)
    t_end = sc.sim["t_start"] + 1e-3 * sc.system.forcing_period
    for engine in ("fast", "accurate"):
        api.simulate(sc, engine, set={"sim.t_end": t_end})
    return f"the engines {'with' if sc.system.has_delay else 'without'} a delay"


def _kernels(scenario: str) -> str:
    """The scenario's model's kernels (:func:`.reference.specialize.compiled_model`)."""
    from . import api
    from .reference.specialize import compiled_model, kernels_label

    system = api.load(scenario).system
    compiled_model(system)
    return f"the kernels of {kernels_label(system)}"


def _analyses() -> str:
    """The stroboscopic maps and the variational equations (sweep, basins, Lyapunov),
    on the impact Duffing oscillator of the seed paper."""
    from . import api

    api.sweep("impact_duffing", "oscillator.forcing_amplitude", [0.5, 0.6], periods=2, discard=2)
    api.basins("impact_duffing", grid=(4, 4), samples=1, region="-2:1,-2:2")
    api.lyapunov("impact_duffing", periods=2, transient=1)
    return "the analyses' kernels (impact Duffing oscillator)"


def _other_analyses() -> str:
    """The analyses' kernels of the other families: the rotor's stroboscopic map and
    variational equations (a sweep, the Lyapunov spectrum of chaos control) and the
    two-DOF oscillator's map (basins on a slice)."""
    from . import api

    api.sweep("jeffcott_rigid_stator", "rotor.speed", [380.0, 390.0], periods=2, discard=1)
    api.lyapunov("jeffcott_rigid_stator", periods=1, transient=0)
    two = "two_dof_impact_oscillator"
    api.basins(two, (2, 2), 1, (-1, 0.5, -1, 1), slice=("oscillator.x2", "oscillator.v2"))
    return "the analyses' kernels (rotor, two-DOF oscillator)"


def _controller_kernels() -> None:
    """The delayed-feedback controller's kernels on a buffer (flat_controller)."""
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
    """The co-simulation's units (the compiled unit stepper for ODE and hybrid units),
    the master's compiled loop and the controller's kernels."""
    from . import api

    compiled = {"cosim.master": "compiled"}  # auto would take the Python master until then
    api.cosimulate("jeffcott_rigid_stator", "direct", set={"sim.t_end": 0.002, **compiled})
    api.cosimulate("jeffcott_elastic_casing", "direct", set={"sim.t_end": 0.002, **compiled})
    api.cosimulate("impact_duffing", "direct", set={"sim.t_end": 5.0, **compiled})
    _controller_kernels()
    return "the co-simulation's units and master"


def _distinct_models() -> list[str]:
    """One bundled scenario per model (scenarios of one model share its engines)."""
    from . import api
    from .reference.specialize import model_key

    seen: dict[tuple[int, ...], str] = {}
    for name in api.scenarios():
        seen.setdefault(model_key(api.load(name).system.ip), name)
    return sorted(seen.values())


def jobs() -> list[list]:
    """The warm-up's jobs in two phases, each longest first (so that the pool ends them
    together).  First the co-simulation, and in the other process the engines (which
    every model shares), then the analyses, which call them and find them compiled
    (the co-simulation keeps the other process busy until then); the analyses on the
    other families go to whichever process ends first.  Then every other model's
    kernels."""
    engines = [partial(_engines, "impact_duffing"), partial(_engines, "jeffcott_delayed_feedback")]
    models = [partial(_kernels, name) for name in _distinct_models()]
    return [[_units, *engines, _analyses, _other_analyses], models]


def warm_up(workers: int = 2) -> list[tuple[str, float]]:
    """Run the warm-up jobs (in ``workers`` processes; 1: in this one); returns what each
    compiled and its wall time (s)."""
    phases = jobs()
    if workers <= 1:
        return [_timed(job) for phase in phases for job in phase]
    # the workers keep the cores busy: no helper process of their own (compile_ahead)
    ahead = os.environ.get("RUBCOSIM_COMPILE_AHEAD")
    os.environ["RUBCOSIM_COMPILE_AHEAD"] = "0"
    try:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            return [done for phase in phases for done in pool.map(_timed, phase)]
    finally:
        if ahead is None:
            os.environ.pop("RUBCOSIM_COMPILE_AHEAD")
        else:
            os.environ["RUBCOSIM_COMPILE_AHEAD"] = ahead


def _timed(job) -> tuple[str, float]:
    start = time.perf_counter()
    what = job()
    return what, time.perf_counter() - start
