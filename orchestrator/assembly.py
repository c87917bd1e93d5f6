"""From a scenario to a running co-simulation: units on a backend, connections, protocols.

The ``direct`` backend builds the unit classes of :mod:`rubcosim.components` in
this process; the ``fmu`` backend loads the FMUs built from the same classes
(building them once into a cache directory when missing) through fmpy.  The
master does not know the difference.

Parameters a unit needs from another (the stator's spin speed, disc radius
and disc mass, the bearing's and controller's speed) are taken from the
rotor here, exactly as the monolithic assembler does, so that the
co-simulation and the reference simulate the same model.
"""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from rubcosim.components.stator import reduced_mass
from rubcosim.components.units import unit_class
from rubcosim.reference import system as S

from .connections import Connection, apply_table, check_connections, default_connections
from .master import CosimError, CosimResult, Master
from .protocols import ElasticContact, EventProtocol, RigidContact
from .settings import CosimSettings

FMU_CACHE_ENV = "RUBCOSIM_FMU_DIR"
DIVERGED = 100.0  # displacements past this many length scales: the run has diverged


def unit_parameters(scenario: Any, settings: CosimSettings) -> dict[str, dict[str, Any]]:
    """Every unit's co-simulation parameters: its scenario parameters plus what it
    needs from the rotor, and the units' own integrator tolerances."""
    units = scenario.system.units
    params = {role: dict(u.params) for role, u in units.items()}
    tolerances = {"rtol": settings.unit_rtol, "atol": settings.unit_atol}
    if "oscillator" in params:
        params["oscillator"].update(tolerances)
        params["oscillator"]["chatter_tol"] = scenario.sim["chatter_tol"]
        return params
    rotor = params["rotor"]
    rotor.update(tolerances)
    w = rotor["speed"]
    if "stator" in params:
        stator, kind = params["stator"], units["stator"].type
        stator.update(speed=w, disc_radius=rotor["disc_radius"])
        if kind == "rigid":
            stator.update(
                disc_mass=rotor["mass"], constraint_rate=float(scenario.system.p[S.P_OMEGA_B])
            )
        elif kind == "elastic":
            stator["impact_mass"] = rotor["mass"]
        else:
            m, ms = rotor["mass"], stator["mass"]
            stator.update(impact_mass=reduced_mass(m, ms), **tolerances)
    for role in ("bearing", "controller"):
        if role in params and (role == "controller" or units[role].type == "oilfilm"):
            params[role]["speed"] = w
    return params


def scenario_connections(scenario: Any) -> list[Connection]:
    types = {role: u.type for role, u in scenario.system.units.items()}
    connections = apply_table(default_connections(types), scenario.connections)
    classes = {role: unit_class(role, t) for role, t in types.items()}
    foreign = scenario.fmus
    check_connections(
        connections,
        {
            **{r: [s.name for s in c.inputs] for r, c in classes.items()},
            **{n: list(f.inputs) for n, f in foreign.items()},
        },
        {
            **{r: [s.name for s in c.outputs] for r, c in classes.items()},
            **{n: list(f.outputs) for n, f in foreign.items()},
        },
    )
    return connections


def _measure_scales(scenario: Any) -> dict[str, float]:
    """The system's scale for each unit of measure (as the reference engines scale their
    absolute tolerance): the length scale for m, the velocity scale for m/s, and mass
    times the velocity scale times the frequency for N."""
    system = scenario.system
    length = float(system.state_scale[0])
    vscale = float(system.velocity_scale)
    mass = float(system.units["rotor"].params["mass"]) if "rotor" in system.units else 1.0
    return {"m": length, "m/s": vscale, "N": mass * vscale * vscale / length}


def _input_measures(scenario: Any, connections: list[Connection]) -> dict[str, str]:
    """The unit of measure of every connected input ("" for a foreign FMU's)."""
    types = {role: u.type for role, u in scenario.system.units.items()}
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
    units = scenario.system.units
    if "stator" not in units:
        return []
    if units["stator"].type == "rigid":
        v_chat = settings.chatter_tol * scenario.system.velocity_scale
        min_flight = 10.0 * settings.event_tol * scenario.system.forcing_period
        return [RigidContact("stator", "rotor", v_chat, min_flight)]
    return [ElasticContact("stator")]


def default_fmu_dir() -> Path:
    """Where the ``fmu`` backend keeps the FMUs it builds (``$RUBCOSIM_FMU_DIR`` or the
    user cache), one directory per version of the bundled sources."""
    from rubcosim.fmus.build import source_digest

    base = os.environ.get(FMU_CACHE_ENV)
    root = Path(base) if base else Path.home() / ".cache" / "rubcosim" / "fmus"
    return root / source_digest()


def fmu_paths(roles_types: Mapping[str, str], fmu_dir: Path | None) -> dict[str, Path]:
    """The FMU file of every unit, built into ``fmu_dir`` first when missing."""
    from rubcosim.fmus.build import MODEL_IDENTIFIERS, build_fmus

    directory = Path(fmu_dir) if fmu_dir is not None else default_fmu_dir()
    ids = {role: MODEL_IDENTIFIERS[(role, t)] for role, t in roles_types.items()}
    missing = sorted({i for i in ids.values() if not (directory / f"{i}.fmu").is_file()})
    if missing:
        build_fmus(directory, only=missing)
    return {role: directory / f"{i}.fmu" for role, i in ids.items()}


@contextlib.contextmanager
def open_units(
    scenario: Any, settings: CosimSettings, fmu_dir: Path | None = None
) -> Iterator[tuple[dict[str, Any], dict[str, bool], dict[str, bool]]]:
    """The scenario's units on the chosen backend (those in ``cosim.fmu_units`` as FMUs
    whatever the backend), and its foreign FMUs (always through fmpy), with their
    feedthrough and input-interpolation flags; FMU instances are freed on exit."""
    from .fmu_unit import FmuUnit

    params = unit_parameters(scenario, settings)
    types = {role: u.type for role, u in scenario.system.units.items()}
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
                units[role] = FmuUnit(paths[role], name=role, params=params[role], start_time=t0)
                interpolates[role] = bool(units[role].md.coSimulation.canInterpolateInputs)
            else:
                units[role] = classes[role](name=role, **params[role])
                interpolates[role] = True
        for name, f in foreign.items():
            units[name] = FmuUnit(f.path, name=name, params=f.start, start_time=t0)
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


def output_times(scenario: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sorted union of the output grid and the stroboscopic times, and where each
    of the two lies in it (the reference run records the same times)."""
    from rubcosim.reference.simulate import output_grid
    from rubcosim.runner import strobe_times

    sim = scenario.sim
    grid = output_grid(sim["t_start"], sim["t_end"], sim["output_step"])
    strobe = strobe_times(scenario)
    both = np.concatenate((grid, strobe))
    order = np.argsort(both, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return both[order], rank[: grid.size], rank[grid.size :]


def run_cosim(
    scenario: Any,
    settings: CosimSettings | None = None,
    record: list[str] | None = None,
    times: np.ndarray | None = None,
    fmu_dir: Path | None = None,
) -> CosimResult:
    """Co-simulate a scenario; ``record`` defaults to the scenario's outputs and ``times``
    to its output grid plus stroboscopic times."""
    settings = settings or scenario.cosim
    if times is None:
        times = output_times(scenario)[0]
    connections = scenario_connections(scenario)
    types = {role: u.type for role, u in scenario.system.units.items()}
    period = scenario.system.forcing_period
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
        )
        return master.run(
            scenario.sim["t_start"], scenario.sim["t_end"], times, record or scenario.outputs
        )
