"""Read an SSP 1.0 package back into a scenario, so ``rubcosim run system.ssp`` runs it.

Each component of ``SystemStructure.ssd`` whose FMU is one of ours (its FMI model
identifier names a unit type of the registry) becomes that unit, with the parameters
its inline ``ParameterBindings`` give, else the FMU's start values (those a scenario
sets; what our FMUs take from
their neighbours or from the co-simulation settings is derived again); any other FMU
becomes a foreign FMU (``[fmus.NAME]``) with its bindings as start values.  The SSD's
connections become the scenario's, and the default wiring of our units that the SSD
does not make is left disconnected: the package's structure is what runs.  The
``DefaultExperiment`` gives ``sim.t_start`` and ``sim.t_end``.  Written by
:mod:`.ssp_export`, or by hand.
"""

from __future__ import annotations

import tempfile
import zipfile
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

from rubcosim.components.registry import REGISTRY

from .errors import ScenarioError
from .ssp_export import SSC, SSD, SSV

NS = {"ssd": SSD, "ssc": SSC, "ssv": SSV}
TYPED = {"Real": float, "Integer": int, "Boolean": lambda v: v == "true", "String": str}


def _describe(fmu: Path) -> tuple[str, dict[str, Any], dict[str, list[str]]]:
    """The FMU's model identifier, the start values of its parameters and the names of
    its inputs and outputs (the connectors a connection may name)."""
    from fmpy import read_model_description

    md = read_model_description(str(fmu), validate=False)
    if md.coSimulation is None:
        raise ScenarioError(f"{fmu.name}: not a co-simulation FMU")
    starts = {}
    connectors: dict[str, list[str]] = {"input": [], "output": []}
    for v in md.modelVariables:
        if v.causality == "parameter" and v.start is not None:
            starts[v.name] = TYPED.get(v.type, str)(v.start)
        if v.causality in connectors:
            connectors[v.causality].append(v.name)
    return md.coSimulation.modelIdentifier, starts, connectors


def _bindings(comp: ET.Element) -> dict[str, Any]:
    """The inline parameter values of a component (SSV types kept)."""
    values = {}
    path = "ssd:ParameterBindings/ssd:ParameterBinding/ssd:ParameterValues/ssv:ParameterSet"
    for pset in comp.findall(path, NS):
        for p in pset.findall("ssv:Parameters/ssv:Parameter", NS):
            for kind, cast in TYPED.items():
                v = p.find(f"ssv:{kind}", NS)
                if v is not None:
                    values[p.get("name")] = cast(v.get("value"))
    return values


def _read(path: Path) -> tuple[ET.Element, Path]:
    """The SSD's root and the folder the package was unpacked into."""
    if not path.is_file():
        raise ScenarioError(f"{path}: no such SSP package")
    try:
        with zipfile.ZipFile(path) as zf:
            if "SystemStructure.ssd" not in zf.namelist():
                raise ScenarioError(f"{path}: no SystemStructure.ssd in the package")
            root = ET.fromstring(zf.read("SystemStructure.ssd"))
            # kept for the run: the foreign FMUs are loaded from here
            folder = Path(tempfile.mkdtemp(prefix="rubcosim_ssp_"))
            zf.extractall(folder)
    except zipfile.BadZipFile:
        raise ScenarioError(f"{path}: not an SSP package (not a zip archive)") from None
    except ET.ParseError as exc:
        raise ScenarioError(f"{path}: SystemStructure.ssd is not XML ({exc})") from None
    return root, folder


def scenario_table(path: str | Path) -> dict[str, Any]:
    """The scenario (as a TOML-structured dict) an SSP package describes."""
    path = Path(path)
    root, folder = _read(path)
    system = root.find("ssd:System", NS)
    if system is None:
        raise ScenarioError(f"{path}: SystemStructure.ssd has no System")
    ours = {t.fmu.identifier: t for t in REGISTRY}
    units: dict[str, dict[str, Any]] = {}
    fmus: dict[str, dict[str, Any]] = {}
    names: dict[str, str] = {}
    connectors: dict[str, dict[str, list[str]]] = {}
    for comp in system.findall("ssd:Elements/ssd:Component", NS):
        name, source = comp.get("name"), comp.get("source")
        where = f"SystemStructure.ssd: Component {name!r}"
        if not name or not source:
            raise ScenarioError(f"{where}: a component needs a name and a source")
        fmu = folder / source
        if not fmu.is_file():
            raise ScenarioError(f"{where}: its source {source} is not in the package")
        values = _bindings(comp)
        identifier, starts, connectors[name] = _describe(fmu)
        utype = ours.get(identifier)
        if utype is None:
            names[name] = name
            fmus[name] = {"path": str(fmu), "start": values}
            continue
        if utype.role in units:
            raise ScenarioError(f"{where}: a second {utype.role} (one unit per role)")
        names[name] = utype.role
        # what the SSD does not bind keeps the FMU's start value, as in any SSP tool
        given = {**starts, **values}
        units[utype.role] = {
            "type": utype.type_name,
            **{p.name: given[p.name] for p in utype.params if p.name in given},
        }
    connections: dict[str, list[str]] = {}
    for c in system.findall("ssd:Connections/ssd:Connection", NS):
        start, end = c.get("startElement"), c.get("endElement")
        if start not in names or end not in names:
            raise ScenarioError(
                f"SystemStructure.ssd: Connection {start}.{c.get('startConnector')} -> "
                f"{end}.{c.get('endConnector')} names a component the system does not have"
            )
        for element, connector, causality in (
            (start, c.get("startConnector"), "output"),
            (end, c.get("endConnector"), "input"),
        ):
            if connector not in connectors[element][causality]:
                known = ", ".join(connectors[element][causality]) or "none"
                raise ScenarioError(
                    f"SystemStructure.ssd: Connection {start}.{c.get('startConnector')} -> "
                    f"{end}.{c.get('endConnector')}: {element} has no {causality} "
                    f"{connector!r} (its {causality}s: {known})"
                )
        target = f"{names[end]}.{c.get('endConnector')}"
        connections.setdefault(target, []).append(f"{names[start]}.{c.get('startConnector')}")
    for target, _ in REGISTRY.default_wiring({r: u["type"] for r, u in units.items()}):
        connections.setdefault(target, [])
    sim: dict[str, float] = {}
    experiment = root.find("ssd:DefaultExperiment", NS)
    if experiment is not None:
        for key, attr in (("t_start", "startTime"), ("t_end", "stopTime")):
            if experiment.get(attr) is not None:
                sim[key] = float(experiment.get(attr))
    return {
        "scenario": {"name": root.get("name") or path.stem, "description": f"SSP {path.name}"},
        "sim": sim,
        "units": units,
        "fmus": fmus,
        "connections": connections,
    }
