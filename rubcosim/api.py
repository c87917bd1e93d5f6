"""The Python API, re-exported by ``rubcosim``::

    import rubcosim as rc

    sc = rc.load("jeffcott_rigid_stator", set={"rotor.speed": 400})
    res = rc.simulate(sc, engine="fast")
    res["rotor.x"], res.t, res.to_csv("out.csv")

Every function takes a :class:`~rubcosim.scenario.Scenario`, or what :func:`load`
takes (a bundled scenario's name, a TOML path, a dict of the TOML's structure).
Values are in SI units (m, s, rad/s, kg, N/m) as in the scenario files.  A bad key or
value raises :class:`~rubcosim.scenario.ScenarioError` (a ``ValueError``) naming it.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .bundled import bundled_scenarios
from .results import CheckResult, SimulationResult
from .scenario import Scenario, ScenarioError, build_scenario, load_scenario, override_table

if TYPE_CHECKING:
    from .analysis.cellmap import Basins
    from .analysis.lyapunov import Lyapunov
    from .analysis.sweep import ParamRange, SweepResult

ScenarioLike = Scenario | str | Path | Mapping[str, Any]
Params = Mapping[str, Any] | Iterable[str] | None


def scenarios() -> dict[str, str]:
    """The bundled scenarios: name -> description (``rubcosim scenarios``)."""
    return bundled_scenarios()


def load(source: ScenarioLike, set: Params = None) -> Scenario:  # noqa: A002
    """A validated scenario from a bundled scenario's name (``"impact_duffing"``), a
    TOML file's path, an SSP package's path (``system.ssp``), or a dict with the TOML's
    structure (``{"sim": {...},
    "units": {...}}``), with the overrides ``set``: ``{"rotor.speed": 400,
    "sim.t_end": 0.5}`` or ``["rotor.speed=400"]`` (as ``--set``).  The scenario keeps
    them: ``scenario.with_params({...})`` adds more."""
    params = set if isinstance(set, Mapping) else None
    strings = [] if set is None or params is not None else [set] if isinstance(set, str) else set
    if isinstance(source, Scenario):
        table = override_table(strings, params)
        return source.with_params(table) if table else source
    if isinstance(source, Mapping):
        return build_scenario(source, strings, params=params)
    if str(source).endswith(".ssp"):  # an SSP package (rubcosim export-ssp, or by hand)
        from .ssp_import import scenario_table

        return build_scenario(scenario_table(source), strings, params=params)
    return load_scenario(source, strings, params=params)


def _rtol(rtol: float | None, default: float) -> float:
    rtol = default if rtol is None else rtol
    if not 1e-14 <= rtol < 1.0:
        raise ScenarioError(f"--rtol {rtol!r}: must be in [1e-14, 1)")
    return rtol


def _scenario(scenario: ScenarioLike, params: Params = None) -> Scenario:
    if isinstance(scenario, Scenario) and params is None:
        return scenario
    return load(scenario, params)


def simulate(
    scenario: ScenarioLike,
    engine: str | None = None,
    set: Params = None,  # noqa: A002
    progress: bool = False,
) -> SimulationResult:
    """Integrate the scenario with a monolithic engine: ``"fast"`` (compiled DOP853 with
    event location) or ``"accurate"`` (scipy); default its ``sim.engine``.  ``set``:
    overrides as in :func:`load` (``rc.simulate("impact_duffing", set={"sim.t_end":
    50.0})``, like FMPy's ``simulate_fmu(filename, start_values=...)``).  ``progress``:
    a bar in simulated time on a terminal when the run lasts more than two seconds."""
    from rubcosim.reference.simulate import ENGINES

    from .runner import run_scenario

    if engine is not None and engine not in ENGINES:
        raise ScenarioError(f"engine = {engine!r} is not one of {', '.join(ENGINES)}")
    return SimulationResult(
        run_scenario(_scenario(scenario, set), engine=engine, progress=progress)
    )


def _settings(scenario: Scenario, backend: str | None) -> Any:
    from rubcosim.orchestrator.settings import BACKENDS

    if backend is not None and backend not in BACKENDS:
        raise ScenarioError(f"backend = {backend!r} is not one of {', '.join(BACKENDS)}")
    return scenario.cosim if backend is None else replace(scenario.cosim, backend=backend)


def cosimulate(
    scenario: ScenarioLike,
    backend: str | None = None,
    set: Params = None,  # noqa: A002
    progress: bool = False,
) -> SimulationResult:
    """Co-simulate the scenario's units with the orchestrator: ``backend="direct"``
    (in-process units) or ``"fmu"`` (the FMUs through fmpy); default its
    ``cosim.backend``.  Its other settings come from the ``[cosim]`` table (``set``
    reaches them: ``{"cosim.rtol": 1e-6}``)."""
    from .runner import run_cosim_scenario

    sc = _scenario(scenario, set)
    return SimulationResult(
        run_cosim_scenario(sc, _settings(sc, backend).backend, progress=progress)
    )


def check(
    scenario: ScenarioLike,
    backend: str | None = None,
    set: Params = None,  # noqa: A002
    progress: bool = False,
) -> CheckResult:
    """Co-simulate the scenario and compare it with the ``accurate`` engine (``rubcosim
    check``): per output the largest difference, impact counts and times (s);
    ``progress`` as for :func:`simulate`."""
    from rubcosim.consistency import compare

    sc = _scenario(scenario, set)
    report, ref, co, rows = compare(sc, _settings(sc, backend), progress=progress)
    return CheckResult(sc, report, ref, co, rows)


def sweep(
    scenario: ScenarioLike,
    param: str | ParamRange,
    values: Sequence[float] | Any = None,
    *,
    periods: int = 100,
    discard: int = 200,
    direction: str = "up",
    rtol: float | None = None,
    floquet: bool = False,
    lyapunov: bool = False,
    grazing: bool = False,
    chains: int = 1,
    workers: int | None = None,
    scheduler: str | None = None,
    checkpoint_dir: str | Path | None = None,
    progress: bool = False,
) -> SweepResult:
    """Bifurcation diagram: ``param`` (``"rotor.speed"``) over ``values`` (its unit) by
    continuation, ``discard`` forcing periods of transient then ``periods`` stroboscopic
    points per value, sweeping ``"up"``, ``"down"`` or ``"both"``.  ``floquet``: the
    multipliers of every periodic motion of period <= 8 (``result.multipliers``);
    ``lyapunov``: the largest Lyapunov exponent (1/s) of each value's motion over
    ``periods`` periods (``result.lyapunov``);
    ``grazing``: locate where impacts start or stop and fit the square-root law there
    (``result.grazings``).  ``workers`` local processes or a Dask ``scheduler``."""
    from .analysis.maps import DEFAULT_RTOL
    from .analysis.sweep import sweep as run_sweep

    sc = _scenario(scenario)
    result = run_sweep(
        sc,
        param,
        values,
        periods=periods,
        discard=discard,
        direction=direction,
        rtol=_rtol(rtol, DEFAULT_RTOL),
        workers=workers,
        scheduler=scheduler,
        checkpoint_dir=checkpoint_dir,
        chains=chains,
        progress=progress,
    )
    if floquet:
        from .analysis.floquet import sweep_floquet

        result.multipliers = sweep_floquet(sc, result)
    if lyapunov:
        from .analysis.lyapunov import sweep_lyapunov

        result.lyapunov = sweep_lyapunov(sc, result)
    if grazing:
        from .analysis.grazing import sweep_grazings

        result.grazings = sweep_grazings(sc, result)
    return result


def basins(
    scenario: ScenarioLike,
    grid: tuple[int, int] | str | None = None,
    samples: int | None = None,
    region: tuple[float, float, float, float] | str | None = None,
    *,
    seed: int | None = None,
    rtol: float | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    checkpoint_dir: str | Path | None = None,
    progress: bool = False,
    method: str | None = None,
    slice: str | Sequence[str] | None = None,  # noqa: A002
    check: int | None = None,
) -> Basins:
    """Basins of attraction on the stroboscopic section: ``grid = (nx, nv)`` cells over
    ``region = (x0, x1, v0, v1)`` (the state's units, e.g. m and m/s), ``samples``
    random points per cell from ``seed``.  ``method``: ``"pursuit"`` (the default without
    ``slice``), every sample of a single-DOF scenario's section followed to a verified
    attractor, with the saddles by Newton (:mod:`rubcosim.analysis.pursuit`; it finds
    what cell mapping misses where the map is close to the identity, as in Feng & Yang's
    case); ``"gcm"``, generalized cell mapping on the one-period map
    (:mod:`rubcosim.analysis.cellmap`: faster, and its check may say it is wrong);
    ``"slice"`` (the default with ``slice``), any delay-free scenario: the grid spans
    the two state components ``slice = (name1, name2)`` (default the first two), the
    others keep the scenario's initial values, and every sample is followed in the
    full state space (:mod:`rubcosim.analysis.slices`).  Each of ``method``, ``grid``,
    ``samples``, ``region``, ``seed`` and ``slice`` not given here is taken from the
    scenario's ``[basins]`` table (:mod:`rubcosim.basinsettings`) when it has it;
    ``grid``, ``samples`` and ``region`` are needed from one or the other.
    ``check`` samples (default :data:`rubcosim.analysis.fate_check.DRAW`; 0: none) with
    a definite fate are simulated directly and their fates compared
    (:mod:`rubcosim.analysis.fate_check`): ``result.info["fate_check"]``.
    ``result.info`` holds the wall time (s) too."""
    import time

    from .analysis.cellmap import CELL_MAP_RTOL, Grid, cell_mapping
    from .analysis.errors import AnalysisError
    from .analysis.fate_check import DRAW, check_fates
    from .analysis.maps import StroboscopicMap
    from .analysis.pursuit import pursuit_basins
    from .analysis.slices import parse_slice, slice_basins, slice_states
    from .basinsettings import BASIN_METHODS

    sc = _scenario(scenario)
    given = {"grid": grid, "samples": samples, "region": region, "seed": seed}
    given |= {"method": method, "slice": slice}
    opts = {k: v if v is not None else sc.basins.get(k) for k, v in given.items()}
    for key in ("grid", "samples", "region"):
        if opts[key] is None:
            raise AnalysisError(
                f"--{key}: not given, and the scenario has no basins.{key} to default to"
            )
    grid, samples, region, slice = opts["grid"], opts["samples"], opts["region"], opts["slice"]
    seed = 0 if opts["seed"] is None else opts["seed"]
    method = opts["method"] or ("pursuit" if slice is None else "slice")
    draw = DRAW if check is None else check
    if not (isinstance(draw, int) and draw >= 0):
        raise AnalysisError(f"--check {check!r}: a number of samples >= 0")
    if method not in BASIN_METHODS:
        raise AnalysisError(f"--method {method!r}: one of {', '.join(BASIN_METHODS)}")
    axes = parse_slice(sc.system, slice) if slice is not None or method == "slice" else (0, 1)
    if method != "slice" and axes != (0, 1):
        raise AnalysisError(
            f"--slice {slice!r}: --method {method} works on the first two states only; "
            "use --method slice"
        )
    cells = Grid.parse(grid, region)
    smap = StroboscopicMap(sc.system, _rtol(rtol, CELL_MAP_RTOL))
    t0 = time.perf_counter()
    if method == "slice":
        where = {"workers": workers, "scheduler": scheduler, "progress": progress}
        where["checkpoint_dir"] = checkpoint_dir
        result = slice_basins(smap, cells, samples, seed, axes, where)
    else:
        run = pursuit_basins if method == "pursuit" else cell_mapping
        result = run(
            smap, cells, samples, seed, workers, scheduler, checkpoint_dir, progress=progress
        )
    wall = time.perf_counter() - t0
    if draw:
        states_of = (lambda pts: slice_states(smap, pts, axes)) if method == "slice" else None
        result.info["fate_check"] = check_fates(smap, result, states_of, draw, seed=seed)
    result.info = {
        **result.info,
        "method": method,
        "parameters": sc.parameters,
        "state_names": sc.system.state_names,
        "rtol": smap.rtol,
        "wall_time_s": wall,
    }
    return result


def lyapunov(
    scenario: ScenarioLike,
    periods: int = 1000,
    transient: int = 200,
    *,
    rtol: float | None = None,
    set: Params = None,  # noqa: A002
    count: int | None = None,
    uncontrolled: bool = False,
) -> Lyapunov:
    """Lyapunov spectrum (``rubcosim lyapunov``) of the scenario's motion from its initial
    state: ``transient`` forcing periods discarded, then ``periods`` measured, the
    tangent re-orthonormalised every period; the variational equations on the fast
    engine, with the saltation matrix at every impact and switch.  ``count``: only the
    largest few.  ``result.exponents`` (1/s, largest first), ``result.per_interval``
    (per period), ``result.liouville`` (their sum by Liouville's formula).
    ``uncontrolled``: of the scenario without its delayed-feedback controller (a delay
    equation has no finite spectrum here)."""
    from .analysis.lyapunov import LYAPUNOV_RTOL, lyapunov_spectrum

    sc = _scenario(scenario, set)
    if uncontrolled:
        from .analysis.control_study import uncontrolled as without_controller

        sc = without_controller(sc)
    return lyapunov_spectrum(
        sc.system, periods, transient, rtol=_rtol(rtol, LYAPUNOV_RTOL), count=count
    )


def control_study(
    scenario: ScenarioLike,
    switch_on: str | tuple[float, float, int],
    gains: Sequence[float] | None = None,
    memories: Sequence[float] | None = None,
    *,
    periods: int = 200,
    lyapunov_periods: int = 500,
    transient: int = 200,
    rtol: float = 1e-10,
    workers: int | None = None,
    scheduler: str | None = None,
    set: Params = None,  # noqa: A002
    progress: bool = False,
) -> Any:
    """Chaos control study (``rubcosim control-study``) of a scenario with a delayed-
    feedback controller: the uncontrolled Lyapunov spectrum, the target orbit of period
    ``controller.delay_periods`` (Newton, Floquet multipliers), then a controlled run per
    gain x memory x switch-on time (``"A:B:N"``, s) judged converged or not
    (:mod:`rubcosim.analysis.control_study`).  Returns a ``ControlStudy``."""
    from .analysis.control_study import run_control_study

    sc = _scenario(scenario, set)
    return run_control_study(
        sc,
        switch_on,
        list(gains) if gains else None,
        list(memories) if memories else None,
        periods=periods,
        lyapunov_periods=lyapunov_periods,
        transient=transient,
        rtol=rtol,
        workers=workers,
        scheduler=scheduler,
        progress=progress,
    )
