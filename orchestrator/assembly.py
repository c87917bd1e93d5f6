"""From a scenario to a running co-simulation: units on a backend, connections, protocols.

The ``direct`` backend builds the unit classes of :mod:`rubcosim.components` in
this process; the ``fmu`` backend loads the FMUs built from the same classes
(building them once into a cache directory when missing) through fmpy.  The
master does not know the difference.

Parameters a unit needs from another (the stator's spin speed, disc radius
and disc mass, the bearing's and controller's speed) are taken from the
rotor here as each unit type declares them (its ``needs``), with the values
the monolithic assembler uses, so that the co-simulation and the reference
simulate the same model.
"""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from rubcosim.components.declaration import SCALE_KINDS
from rubcosim.components.registry import REGISTRY
from rubcosim.components.units import unit_class, unit_type
from rubcosim.components.wiring import (
    Connection,
)

from .master import CosimError, CosimResult, Master
from .protocols import ElasticContact, EventProtocol, RigidContact
from .settings import CosimSettings

FMU_CACHE_ENV = "RUBCOSIM_FMU_DIR"
DIVERGED = 100.0  # displacements past this many length scales: the run has diverged


def unit_parameters(scenario: Any, settings: CosimSettings) -> dict[str, dict[str, Any]]:
    """Every unit's co-simulation parameters: its scenario parameters, what it needs from
    its neighbours (as its type declares: :meth:`Registry.neighbour_params`), and, where
    its class has them, the units' own integrator tolerances and the chattering tolerance."""
    units = scenario.graph.units
    types = {role: u.type for role, u in units.items()}
    params = {role: dict(u.params) for role, u in units.items()}
    for role, values in REGISTRY.neighbour_params(types, params).items():
        params[role].update(values)
    from_settings = {
        "integrator": settings.unit_integrator,
        "rtol": settings.unit_rtol,
        "atol": settings.unit_atol,
        "chatter_tol": scenario.sim["chatter_tol"],
    }
    for role, type_name in types.items():
        declared = {p.name for p in unit_class(role, type_name).params_spec}
        params[role].update({k: v for k, v in from_settings.items() if k in declared})
    return params


def _measure_scales(scenario: Any) -> dict[str, float]:
    """The model's scale for each unit of measure (as the reference engines scale their
    absolute tolerance): the length scale for m, the velocity scale for m/s, and the
    declared mass scale times the velocity scale times the frequency for N."""
    graph = scenario.graph
    scales = graph.scales
    mass = REGISTRY.mass_scale(graph.types, graph.params)
    return {
        SCALE_KINDS["length"]: scales.length,
        SCALE_KINDS["velocity"]: scales.velocity,
        "N": mass * scales.velocity * scales.velocity / scales.length,
    }


def _input_measures(scenario: Any, connections: list[Connection]) -> dict[str, str]:
    """The unit of measure of every connected input ("" for a foreign FMU's)."""
    types = {role: u.type for role, u in scenario.graph.units.items()}
    measures = {}
    for c in connections:
        if c.unit not in types:  # a foreign FMU: no declared unit of measure to go by
            measures[c.target] = ""
            continue
        signal = {s.name: s for s in unit_class(c.unit, types[c.unit]).inputs}[c.input]
        measures[c.target] = signal.unit
    return measures


def connection_scales(scenario: Any, connections: list[Connection]) -> dict[str, float]:
    """A nominal magnitude for every connected input, from the unit of measure its unit
    declares (:func:`_measure_scales`).  The master never measures a coupling error
    against less: a signal that starts from zero has no size of its own yet."""
    scales = _measure_scales(scenario)
    return {k: scales.get(m, 0.0) for k, m in _input_measures(scenario, connections).items()}


def divergence_bounds(scenario: Any, connections: list[Connection]) -> dict[str, float]:
    """For every connected displacement, the size past which the run has diverged:
    ``DIVERGED`` times the length scale (a disc a hundred clearances off its stator)."""
    length = _measure_scales(scenario)["m"]
    measures = _input_measures(scenario, connections)
    return {k: DIVERGED * length for k, m in measures.items() if m == "m"}


def scenario_protocols(scenario: Any, settings: CosimSettings) -> list[EventProtocol]:
    units = scenario.graph.units
    if "stator" not in units:
        return []
    # the protocol follows the stator type's declared contact (components.contact_law)
    if unit_type("stator", units["stator"].type).contact.kind == "rigid":
        v_chat = settings.chatter_tol * scenario.graph.scales.velocity
        min_flight = 10.0 * settings.event_tol * scenario.graph.scales.forcing_period
        return [RigidContact("stator", "rotor", v_chat, min_flight)]
    return [ElasticContact("stator")]


def default_fmu_dir() -> Path:
    """Where the ``fmu`` backend keeps the FMUs it builds (``$RUBCOSIM_FMU_DIR`` or the
    user cache), one directory per version of the bundled sources."""
    from rubcosim.fmus.build import source_digest

    base = os.environ.get(FMU_CACHE_ENV)
    cache = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    root = Path(base) if base else Path(cache) / "rubcosim" / "fmus"
    return root / source_digest()


def fmu_paths(roles_types: Mapping[str, str], fmu_dir: Path | None) -> dict[str, Path]:
    """The FMU file of every unit, built into ``fmu_dir`` first when missing.  In the
    default directory (:func:`default_fmu_dir`), each use marks the sources' directory
    as used, and the directories of other sources unused for ``UNUSED_DAYS`` days go."""
    from rubcosim.fmus.build import build_fmus

    directory = Path(fmu_dir) if fmu_dir is not None else default_fmu_dir()
    fmus = {role: unit_type(role, t).fmu for role, t in roles_types.items()}
    missing = sorted(
        {f.identifier for f in fmus.values() if not (directory / f.file_name).is_file()}
    )
    if missing:
        build_fmus(directory, only=missing)
    if fmu_dir is None:
        remove_unused_builds(directory)
    return {role: directory / f.file_name for role, f in fmus.items()}


def remove_unused_builds(keep: Path) -> list[Path]:
    """Mark ``keep`` (a directory of :func:`default_fmu_dir`) as used and remove its
    siblings that are builds of other sources (named by a 12-hex-digit digest) no run has
    used for ``UNUSED_DAYS`` days, as numba's cache is cleaned
    (:func:`rubcosim.compile_key.remove_unused_entries`).  Returns what was removed."""
    from rubcosim.compile_key import UNUSED_DAYS, remove_unused_entries

    try:
        os.utime(keep)
    except OSError:
        return []
    return remove_unused_entries(keep.parent, r"[0-9a-f]{12}", keep.name, UNUSED_DAYS)


@contextlib.contextmanager
def open_units(
    scenario: Any, settings: CosimSettings, fmu_dir: Path | None = None
) -> Iterator[tuple[dict[str, Any], dict[str, bool], dict[str, bool]]]:
    """The scenario's units on the chosen backend (those in ``cosim.fmu_units`` as FMUs
    whatever the backend), and its foreign FMUs (always through fmpy), with their
    feedthrough and input-interpolation flags; FMU instances are freed on exit."""
    from .fmu_unit import FmuUnit
    from .isolated_fmu import IsolatedFmu

    params = unit_parameters(scenario, settings)
    types = {role: u.type for role, u in scenario.graph.units.items()}
    classes = {role: unit_class(role, t) for role, t in types.items()}
    foreign = scenario.fmus
    feedthrough = {role: cls.feedthrough for role, cls in classes.items()}
    feedthrough.update({n: f.feedthrough for n, f in foreign.items()})
    t0 = scenario.sim["t_start"]
    units: dict[str, Any] = {}
    interpolates: dict[str, bool] = {}
    as_fmu = {r for r in types if settings.backend == "fmu" or r in settings.fmu_units}
    try:
        fmu_types = {r: types[r] for r in as_fmu}
        paths = fmu_paths(fmu_types, fmu_dir) if as_fmu else {}
        for role in types:
            if role in as_fmu:
                kind = IsolatedFmu if settings.isolate else FmuUnit
                units[role] = kind(paths[role], name=role, params=params[role], start_time=t0)
                interpolates[role] = bool(units[role].md.coSimulation.canInterpolateInputs)
            else:
                units[role] = classes[role](name=role, **params[role])
                interpolates[role] = True
        for name, f in foreign.items():
            kind = IsolatedFmu if settings.isolate or f.isolate else FmuUnit
            units[name] = kind(f.path, name=name, params=f.start, start_time=t0)
            interpolates[name] = f.can_interpolate
        yield units, feedthrough, interpolates
    finally:
        for unit in units.values():
            close = getattr(unit, "close", None)
            if close is not None:
                close()


def check_rollback(scenario: Any, settings: CosimSettings) -> None:
    """A foreign FMU that cannot save its state cannot be rolled back: refuse settings
    that need rollback (error control, iteration, located events) up front."""
    needs = settings.adaptive or settings.iterations > 1 or settings.events == "locate"
    for name, f in scenario.fmus.items():
        if needs and not f.can_get_set_state:
            raise CosimError(
                f"fmus.{name}: {f.path.name} cannot get and set its state, which rollback "
                "needs; run it with cosim.adaptive = false, cosim.iterations = 1 and "
                'cosim.events = "step" (or "off")'
            )


def run_cosim(
    scenario: Any,
    settings: CosimSettings | None = None,
    record: list[str] | None = None,
    times: np.ndarray | None = None,
    fmu_dir: Path | None = None,
    progress: bool = False,
) -> CosimResult:
    """Co-simulate a scenario's model graph; ``record`` defaults to the scenario's
    outputs and ``times`` to its output grid plus stroboscopic times; ``progress`` shows
    a bar on a terminal for long runs."""
    from rubcosim.timegrid import output_times

    settings = settings or scenario.cosim
    if times is None:
        times = output_times(scenario)[0]
    graph = scenario.graph
    connections = list(graph.connections)
    types = graph.types
    period = graph.scales.forcing_period
    if not math.isfinite(period) or period <= 0.0:
        raise ValueError("the scenario has no forcing period to scale the macro step by")
    check_rollback(scenario, settings)
    with open_units(scenario, settings, fmu_dir) as (units, feedthrough, interpolates):
        master = Master(
            units,
            connections,
            settings,
            period,
            feedthrough,
            interpolates,
            scenario_protocols(scenario, settings),
            [r for r, t in types.items() if unit_class(r, t).records_left_limits],
            connection_scales(scenario, connections),
            divergence_bounds(scenario, connections),
            kink_sources=list(scenario.fmus),
        )
        return master.run(
            scenario.sim["t_start"],
            scenario.sim["t_end"],
            times,
            record or scenario.outputs,
            progress=progress,
        )
