"""The continuation part of the Python API (:mod:`rubcosim.api`'s conventions):
periodic orbits followed in one parameter, special points followed in two."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .api import Params, ScenarioLike, _scenario


def continuation(
    scenario: ScenarioLike,
    param: str,
    start: float | None,
    stop: float,
    *,
    period: int = 1,
    y0: Sequence[float] | None = None,
    settle: int = 300,
    rtol: float | None = None,
    step: float = 0.02,
    max_step: float = 0.05,
    max_points: int = 500,
    doublings: int = 0,
    set: Params = None,  # noqa: A002
    progress: bool = False,
) -> Any:
    """Pseudo-arclength continuation (``rubcosim continue``) of the scenario's
    ``period``-periodic orbit in ``param`` (``unit.name``) from ``start`` (default: its
    value in the scenario) toward ``stop``.

    The orbit is found by Newton on the stroboscopic map from ``y0`` (the state at
    forcing phase 0), or from where the scenario's initial state settles after
    ``settle`` periods; ``rtol`` is the map's tolerance (default 1e-12).  ``step`` and
    ``max_step``: arclength steps in fractions of the range; ``max_points`` per branch.
    ``doublings``: switch at the first flip onto the period-doubled branch, that many
    times (``branch.cascade`` then holds the branches, the flips and their ratios).

    Returns a ``Branch``: ``points`` (parameter, state, Floquet multipliers, impacts,
    Newton's residual), ``special`` (located folds, branch points, flips,
    Neimark-Sacker points and grazing) and ``stop_reason``.
    """
    from .analysis.continue_scenario import run_continuation

    return run_continuation(
        _scenario(scenario, set),
        param,
        start,
        stop,
        period=period,
        y0=y0,
        settle=settle,
        rtol=rtol,
        step=step,
        max_step=max_step,
        max_points=max_points,
        doublings=doublings,
        progress=progress,
    )


def bifurcation_curve(
    branch: Any,
    kind: str,
    param2: str,
    stop2: float,
    *,
    start2: float | None = None,
    param_range: tuple[float, float] | None = None,
    which: int = 0,
    max_step: float | None = None,
    max_points: int | None = None,
) -> Any:
    """Two-parameter continuation (``rubcosim continue --curve``): the curve of the
    ``which``-th ``kind`` point (``"fold"`` or ``"flip"``) of ``branch`` (a result of
    :func:`continuation`) in (the branch's parameter, ``param2``), from ``param2``'s
    value in the scenario (or ``start2``) toward ``stop2``, the branch's parameter kept
    in ``param_range`` (default: the branch's range).  ``max_step`` and ``max_points``
    default to the branch's.  Returns a ``Curve``: its points
    carry ``param``, ``param2``, the state and the multipliers."""
    from .analysis.two_parameter import bifurcation_curve as follow

    options = {k: v for k, v in (("max_step", max_step), ("max_points", max_points))
               if v is not None}  # fmt: skip
    return follow(branch, kind, param2, stop2, start2=start2, param_range=param_range,
                  which=which, **options)  # fmt: skip


def basin_continuation(
    scenario: ScenarioLike,
    param: str,
    values: Sequence[float],
    grid: tuple[int, int] | str | None = None,
    samples: int | None = None,
    region: tuple[float, float, float, float] | str | None = None,
    *,
    method: str | None = None,
    seed: int | None = None,
    rtol: float | None = None,
    check: int | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    checkpoint_dir: str | Path | None = None,
    set: Params = None,  # noqa: A002
    progress: bool = False,
) -> Any:
    """Basin fractions continued over ``param`` (``rubcosim basins --continue``): the
    basins at every value of ``values`` as :func:`rubcosim.api.basins` computes them
    (the same settings), the attractors matched from one value to the next by their
    distance on the section, then by the overlap of their basins, and where they are
    born, die or merge (:mod:`rubcosim.analysis.basin_continuation`).  Each value is
    kept in ``checkpoint_dir`` as it is done.  Returns a ``BasinContinuation``
    (``.fractions``, ``.events``, ``.report()``)."""
    import numpy as np

    from .analysis.basin_continuation import continue_basins
    from .api import basins

    sc = _scenario(scenario, set)
    vals = np.asarray(values, dtype=float)
    for v in (vals.min(), vals.max()):
        sc.with_params({param: float(v)})  # a value out of the parameter's range: named

    def run(value: float) -> Any:
        return basins(sc.with_params({param: value}), grid, samples, region, method=method,
                      seed=seed, rtol=rtol, check=check, workers=workers,
                      scheduler=scheduler, progress=progress)  # fmt: skip

    ckpt = None if checkpoint_dir is None else Path(checkpoint_dir)
    return continue_basins(run, param, vals, np.asarray(sc.system.state_scale), ckpt)
