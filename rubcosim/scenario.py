"""Scenario files: TOML that names the units, their parameters, the run and its plots.

Layout::

    [scenario]            name, description
    [sim]                 t_end (required), t_start, output_step, engine, rtol, atol,
                          max_events, chatter_tol, poincare_discard, poincare_phase
    [units.ROLE]          type = "...", then the unit's parameters (see rubcosim.components)
    [outputs]             record = ["rotor.x", ...]   (default: every output)
    [plots]               orbit = [X, Y], timeseries = [...], poincare = [X, Y]
    [cosim]               co-simulation settings (rubcosim.orchestrator.settings.CosimSettings)
    [connections]         "unit.input" = ["unit.output", ...] (summed); replaces the
                          role-based default for that input, [] disconnects it
    [basins]              method, grid, samples, region, seed, slice: defaults of
                          `rubcosim basins` (rubcosim.basinsettings)

``--set role.name=value`` overrides any unit parameter (initial states
included: ``rotor.x0``...) or setting (``sim.t_end``, ``cosim.algorithm``...).  Every error is a
:class:`ScenarioError` naming the file, the key and what is allowed.  A scenario keeps
the parsed table and its overrides: :meth:`Scenario.with_params` rebuilds it with more.
"""

from __future__ import annotations

import copy
import tomllib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rubcosim.components.catalog import UNIT_TYPES
from rubcosim.components.graph import ForeignNode, ModelGraph, build_graph, make_node
from rubcosim.components.parameters import ParameterError
from rubcosim.components.wiring import CouplingError
from rubcosim.orchestrator.foreign import ForeignFmu, ForeignFmuError, foreign_fmu
from rubcosim.orchestrator.settings import CosimSettings, SettingsError, cosim_settings
from rubcosim.reference.assemble import System, build_system

from .basinsettings import basin_settings
from .errors import ScenarioError
from .simsettings import SIM_DEFAULTS, sim_settings

PLOT_KINDS = ("orbit", "timeseries", "poincare")
SCENARIO_KEYS = ("name", "description")
TOP_LEVEL = (
    "scenario", "sim", "units", "fmus", "outputs", "plots", "cosim", "connections", "basins"
)  # fmt: skip


@dataclass
class Scenario:
    name: str
    description: str
    sim: dict[str, Any]
    units: dict[str, dict[str, Any]]
    record: list[str] | None
    plots: dict[str, list[str]]
    system: System
    graph: ModelGraph
    source: str = ""
    parameters: dict[str, Any] = field(default_factory=dict)
    cosim: CosimSettings = field(default_factory=CosimSettings)
    connections: dict[str, Any] = field(default_factory=dict)
    fmus: dict[str, ForeignFmu] = field(default_factory=dict)
    # the parsed scenario table and every override applied to it ("role.name": value)
    data: dict[str, Any] = field(default_factory=dict, repr=False)
    overrides: dict[str, Any] = field(default_factory=dict)
    # defaults of `rubcosim basins` on this scenario (rubcosim.basinsettings), keys given
    basins: dict[str, Any] = field(default_factory=dict)

    def with_params(self, params: Mapping[str, Any]) -> Scenario:
        """A new validated scenario: this one's table with its overrides and then
        ``params`` (``{"stator.clearance": 1e-4}``, ``{"sim.t_end": 2.0}``; SI units, as
        in the scenario file) applied.  Raises :class:`ScenarioError` naming a bad key."""
        try:
            return build_scenario(
                self.data, params={**self.overrides, **params}, source=self.source
            )
        except ScenarioError as exc:
            raise ScenarioError(_prefixed(self.source, exc)) from None

    @property
    def outputs(self) -> list[str]:
        """Names of the recorded outputs."""
        if self.record:
            return list(self.record)
        foreign = [f"{n}.{o}" for n, f in self.fmus.items() for o in f.record]
        return [*self.system.output_names, *foreign]

    @property
    def unit_names(self) -> list[str]:
        """Every unit of a co-simulation: the rubcosim units, then the foreign FMUs."""
        return [*self.graph.units, *self.fmus]


def _prefixed(source: str, exc: Exception) -> str:
    return f"{Path(source).name}: {exc}" if source else str(exc)


def _split_key(key: Any, text: str) -> tuple[str, str]:
    if not isinstance(key, str) or key.count(".") != 1 or not all(key.split(".")):
        raise ScenarioError(f"--set {text!r}: expected unit.parameter=value")
    role, name = key.split(".")
    return role, name


def _plain(value: Any) -> Any:
    """A numpy scalar as the Python number it holds (parameters are checked by type)."""
    item = getattr(value, "item", None)
    return item() if callable(item) and getattr(value, "shape", None) == () else value


def parse_override(text: str) -> tuple[str, str, Any]:
    """Split ``role.name=value``; the value is read as a TOML value, else as a string."""
    if "=" not in text:
        raise ScenarioError(f"--set {text!r}: expected unit.parameter=value")
    key, raw = text.split("=", 1)
    role, name = _split_key(key.strip(), text)
    try:
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return role, name, value


def _check_table(where: str, value: Any) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise ScenarioError(f"{where} must be a table")
    return value


def _names(where: str, value: Any) -> list[str]:
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise ScenarioError(f"{where} must be a list of output names")
    return list(value)


def override_table(overrides: Iterable[str], params: Mapping[str, Any] | None) -> dict[str, Any]:
    """``--set`` strings, then ``params``, as one table ``{"role.name": value}``."""
    table: dict[str, Any] = {}
    for text in overrides:
        role, name, value = parse_override(text)
        table.pop(f"{role}.{name}", None)  # the last setting of a key wins
        table[f"{role}.{name}"] = value
    for key, value in (params or {}).items():
        _split_key(key, f"{key}={value!r}")
        table.pop(key, None)
        table[key] = _plain(value)
    return table


def build_scenario(
    data: Mapping[str, Any],
    overrides: Iterable[str] = (),
    source: str = "",
    params: Mapping[str, Any] | None = None,
) -> Scenario:
    """Validate a parsed scenario, apply ``--set`` overrides (``"role.name=value"``
    strings) and then ``params`` (``{"role.name": value}``), and assemble the system."""
    original = copy.deepcopy(_check_table("the scenario", data))
    data = copy.deepcopy(original)  # the tables below are edited in place
    applied = override_table(overrides, params)
    unknown = sorted(set(data) - set(TOP_LEVEL))
    if unknown:
        raise ScenarioError(
            f"[{unknown[0]}] is not a scenario section (known: {', '.join(TOP_LEVEL)})"
        )
    meta = _check_table("[scenario]", data.get("scenario", {}))
    unknown = sorted(set(meta) - set(SCENARIO_KEYS))
    if unknown:
        raise ScenarioError(
            f"scenario.{unknown[0]} is not a key of [scenario] (known: name, description)"
        )
    units_raw = _check_table("[units]", data.get("units", {}))
    if not units_raw:
        raise ScenarioError("[units] is empty: name at least a rotor or an oscillator")
    units: dict[str, dict[str, Any]] = {}
    for role, table in units_raw.items():
        if role not in UNIT_TYPES:
            raise ScenarioError(
                f"units.{role} is not a known unit (known: {', '.join(UNIT_TYPES)})"
            )
        units[role] = dict(_check_table(f"[units.{role}]", table))
        if "type" not in units[role]:
            raise ScenarioError(
                f"units.{role}.type is required (one of {', '.join(UNIT_TYPES[role])})"
            )
    fmus_raw = {
        name: dict(_check_table(f"[fmus.{name}]", table))
        for name, table in _check_table("[fmus]", data.get("fmus", {})).items()
    }
    for name in fmus_raw:
        if name in units:
            raise ScenarioError(f"fmus.{name}: the name is already a unit of [units]")
    sim_raw = dict(_check_table("[sim]", data.get("sim", {})))
    cosim_raw = dict(_check_table("[cosim]", data.get("cosim", {})))
    connections: dict[str, Any] = {}
    for key, value in _check_table("[connections]", data.get("connections", {})).items():
        # an unquoted key rotor.fx = [...] is a nested table in TOML
        if isinstance(value, dict):
            connections.update({f"{key}.{k}": v for k, v in value.items()})
        else:
            connections[key] = value
    for key, value in applied.items():
        role, name = key.split(".")
        if role == "cosim":
            cosim_raw[name] = value
        elif role == "sim":
            if name not in SIM_DEFAULTS:
                raise ScenarioError(
                    f"--set sim.{name}: not a setting (known: {', '.join(SIM_DEFAULTS)})"
                )
            sim_raw[name] = value
        elif role in units:
            units[role][name] = value
        elif role in fmus_raw:
            start = fmus_raw[role].setdefault("start", {})
            if not isinstance(start, dict):
                raise ScenarioError(f"fmus.{role}.start must be a table of start values")
            start[name] = value
        else:
            known = ", ".join(["sim", "cosim", *units, *fmus_raw])
            raise ScenarioError(
                f"--set {role}.{name}: unit {role!r} is not in this scenario (known: {known})"
            )
    sim = sim_settings(sim_raw)
    try:
        cosim = cosim_settings(cosim_raw).with_chatter_tol(sim["chatter_tol"])
    except SettingsError as exc:
        raise ScenarioError(str(exc)) from None
    try:
        built = {
            role: make_node(role, t["type"], {k: v for k, v in t.items() if k != "type"})
            for role, t in units.items()
        }
        system = build_system(built, chatter_tol=sim["chatter_tol"])
    except ParameterError as exc:
        raise ScenarioError(str(exc)) from None
    base_dir = Path(source).parent if source else Path.cwd()
    try:
        fmus = {name: foreign_fmu(name, t, base_dir) for name, t in fmus_raw.items()}
    except ForeignFmuError as exc:
        raise ScenarioError(str(exc)) from None
    available_outputs = [
        *system.output_names,
        *(f"{n}.{o}" for n, f in fmus.items() for o in (*f.outputs, *f.texts)),
    ]
    outputs = _check_table("[outputs]", data.get("outputs", {}))
    unknown = sorted(set(outputs) - {"record"})
    if unknown:
        raise ScenarioError(f"outputs.{unknown[0]} is not a key of [outputs] (known: record)")
    record = _names("outputs.record", outputs["record"]) if "record" in outputs else None
    if record is not None and not record:
        raise ScenarioError("outputs.record is empty: name at least one output, or leave it out")
    for name in record or []:
        if name not in available_outputs:
            available = ", ".join(available_outputs)
            raise ScenarioError(
                f"outputs.record: {name!r} is not an output (available: {available})"
            )
    plots = {
        k: _names(f"plots.{k}", v)
        for k, v in _check_table("[plots]", data.get("plots", {})).items()
    }
    for kind, names in plots.items():
        if kind not in PLOT_KINDS:
            raise ScenarioError(f"plots.{kind} is not a plot kind (known: {', '.join(PLOT_KINDS)})")
        if not names:
            raise ScenarioError(f"plots.{kind} is empty: name the outputs to plot, or leave it out")
        if kind in ("orbit", "poincare") and len(names) != 2:
            raise ScenarioError(f"plots.{kind} needs exactly two output names [x, y]")
        for name in names:
            if name not in available_outputs:
                available = ", ".join(available_outputs)
                raise ScenarioError(
                    f"plots.{kind}: {name!r} is not an output (available: {available})"
                )
    if record is not None:
        for names in plots.values():
            for name in names:
                if name not in record:
                    record.append(name)
    parameters = {f"{role}.type": u.type for role, u in system.units.items()}
    for role, u in system.units.items():
        parameters.update({f"{role}.{k}": v for k, v in u.params.items()})
    parameters.update({f"sim.{k}": v for k, v in sim.items()})
    try:
        graph = build_graph(
            built,
            connections,
            [
                ForeignNode(n, tuple(f.inputs), tuple(f.outputs), f.refused(), f.types)
                for n, f in fmus.items()
            ],
        )
    except CouplingError as exc:
        raise ScenarioError(str(exc)) from None
    scenario = Scenario(
        name=str(meta.get("name", Path(source).stem if source else "scenario")),
        description=str(meta.get("description", "")),
        sim=sim,
        units=units,
        record=record,
        plots=plots,
        system=system,
        graph=graph,
        source=source,
        parameters=parameters,
        cosim=cosim,
        connections=connections,
        fmus=fmus,
        data=original,
        overrides=applied,
        basins=basin_settings(_check_table("[basins]", data.get("basins", {}))),
    )
    if cosim.order and sorted(cosim.order) != sorted(scenario.unit_names):
        raise ScenarioError(
            f"cosim.order = {list(cosim.order)} must name every unit once "
            f"({', '.join(scenario.unit_names)})"
        )
    own_units = list(scenario.graph.units)
    strays = [n for n in cosim.fmu_units if n not in own_units]
    if strays:
        raise ScenarioError(
            f"cosim.fmu_units names {strays[0]!r}, which is not one of the scenario's own "
            f"units ({', '.join(own_units)})"
        )
    return scenario


def load_scenario(
    path: str | Path, overrides: Iterable[str] = (), params: Mapping[str, Any] | None = None
) -> Scenario:
    """Read, validate and assemble a scenario file, or a bundled scenario by name
    (``"jeffcott_rigid_stator"``, see :func:`rubcosim.bundled.bundled_scenarios`)."""
    from .bundled import scenario_path

    found = scenario_path(path)
    if found is None:
        raise ScenarioError(
            f"{path}: no such scenario file (nor a bundled scenario: `rubcosim scenarios` "
            "lists them)"
        )
    path = found
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{path}: not valid TOML ({exc})") from None
    except UnicodeDecodeError:
        raise ScenarioError(f"{path}: not a UTF-8 text file") from None
    try:
        return build_scenario(data, overrides, source=str(path), params=params)
    except ScenarioError as exc:
        raise ScenarioError(_prefixed(str(path), exc)) from None
