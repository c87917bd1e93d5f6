"""Export a scenario as an SSP 1.0 package that other FMI tools can open and run.

The package (a zip) holds the scenario's FMUs under ``resources/`` (ours, built from
the same sources as the ``fmu`` backend, and any foreign FMU of the scenario) and
``SystemStructure.ssd``: one component per unit with its connectors (the inputs a
connection drives, the outputs and the parameters, typed as the FMU declares them), its
parameter values as inline
``ParameterBindings``, the scenario's connections, and a ``DefaultExperiment`` over the
scenario's time span.

What SSP cannot say, and what a tool that knows nothing of rubcosim then does:

* **A summed input.**  An SSP connection carries one signal; a rubcosim input may be the
  sum of several outputs (``rotor.fx = stator.fx + controller.ux``).  Such a
  connection is refused with a message naming it: wire the sum through a unit, or
  drop a source with ``[connections]``.
* **Events.**  Our master locates a contact inside a step by rollback and applies a
  rigid impact through the rotor's velocity-reset protocol (``reset_vx``, ``reset_vy``,
  ``reset_counter``) and the stator's ``contact_mode``.  No SSP connection drives these;
  a plain fixed-step master leaves them at their start values, so a rigid stator never
  resets the disc (it flies through), and a penalty stator's contact onset is seen only
  at the next communication point.  Smooth couplings (penalty and casing stators,
  bearings) run in such a tool, at the accuracy of its master.
"""

from __future__ import annotations

import shutil
import tempfile
import zipfile
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

from rubcosim.components.units import unit_class
from rubcosim.orchestrator.assembly import fmu_paths, unit_parameters

from .errors import ScenarioError
from .writing import ensure_writable_folder

SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
ET.register_namespace("ssd", SSD)
ET.register_namespace("ssc", SSC)
ET.register_namespace("ssv", SSV)
FMU_MIME = "application/x-fmu-sharedlibrary"
PARAM_TYPES = {"real": "Real", "int": "Integer", "choice": "String"}
SIGNAL_TYPES = {"real": "Real", "integer": "Integer"}


def _q(ns: str, tag: str) -> str:
    return f"{{{ns}}}{tag}"


def _connector(parent: ET.Element, name: str, kind: str, type_name: str) -> None:
    c = ET.SubElement(parent, _q(SSD, "Connector"), name=name, kind=kind)
    ET.SubElement(c, _q(SSC, type_name))


def _value_text(value: Any, type_name: str) -> str:
    if type_name == "Real":
        return repr(float(value))
    if type_name == "Integer":
        return str(int(value))
    return str(value)


def _bindings(parent: ET.Element, name: str, values: list[tuple[str, str, Any]]) -> None:
    bindings = ET.SubElement(parent, _q(SSD, "ParameterBindings"))
    pb = ET.SubElement(bindings, _q(SSD, "ParameterBinding"))
    pvalues = ET.SubElement(pb, _q(SSD, "ParameterValues"))
    pset = ET.SubElement(pvalues, _q(SSV, "ParameterSet"), version="1.0", name=name)
    params = ET.SubElement(pset, _q(SSV, "Parameters"))
    for pname, type_name, value in values:
        p = ET.SubElement(params, _q(SSV, "Parameter"), name=pname)
        ET.SubElement(p, _q(SSV, type_name), value=_value_text(value, type_name))


def check_exportable(scenario: Any) -> None:
    """Refuse what SSP cannot carry: an input that sums several outputs."""
    for c in scenario.graph.connections:
        if len(c.sources) > 1:
            raise ScenarioError(
                f"connections.{c.target} sums {' + '.join(c.sources)}: an SSP connection "
                "carries one signal; give it one source in [connections] to export"
            )


def system_structure(scenario: Any, sources: dict[str, str]) -> ET.Element:
    """The ``SystemStructureDescription`` of ``scenario``; ``sources[unit]`` is the path
    of the unit's FMU inside the package."""
    graph = scenario.graph
    check_exportable(scenario)
    root = ET.Element(_q(SSD, "SystemStructureDescription"), version="1.0", name=scenario.name)
    system = ET.SubElement(root, _q(SSD, "System"), name=scenario.name)
    elements = ET.SubElement(system, _q(SSD, "Elements"))
    params = unit_parameters(scenario, scenario.cosim)
    driven = {c.target for c in graph.connections}
    for role, unit in graph.units.items():
        cls = unit_class(role, unit.type)
        comp = ET.SubElement(
            elements, _q(SSD, "Component"), name=role, type=FMU_MIME, source=sources[role]
        )
        conns = ET.SubElement(comp, _q(SSD, "Connectors"))
        for s in cls.inputs:
            # an input no connection drives (the velocity-reset protocol, the contact
            # mode) is not listed: FMPy's SSP master (0.3) wires an unconnected input
            # to the source of the connection it looked at before
            if f"{role}.{s.name}" in driven:
                _connector(conns, s.name, "input", SIGNAL_TYPES[s.kind])
        for s in cls.outputs:
            _connector(conns, s.name, "output", SIGNAL_TYPES[s.kind])
        values = []
        for p in cls.params_spec:
            type_name = PARAM_TYPES.get(p.kind, "Real")
            _connector(conns, p.name, "parameter", type_name)
            values.append((p.name, type_name, params[role][p.name]))
        _bindings(comp, role, values)
    for name, fmu in scenario.fmus.items():
        comp = ET.SubElement(
            elements, _q(SSD, "Component"), name=name, type=FMU_MIME, source=sources[name]
        )
        conns = ET.SubElement(comp, _q(SSD, "Connectors"))
        for signal in fmu.inputs:
            if f"{name}.{signal}" in driven:
                _connector(conns, signal, "input", "Real")
        for signal in fmu.outputs:
            _connector(conns, signal, "output", "Real")
    links = ET.SubElement(system, _q(SSD, "Connections"))
    for c in graph.connections:
        for unit, output in c.pairs:
            ET.SubElement(
                links,
                _q(SSD, "Connection"),
                startElement=unit,
                startConnector=output,
                endElement=c.unit,
                endConnector=c.input,
            )
    sim = scenario.sim
    ET.SubElement(
        root,
        _q(SSD, "DefaultExperiment"),
        startTime=repr(float(sim["t_start"])),
        stopTime=repr(float(sim["t_end"])),
    )
    return root


def export_ssp(scenario: Any, out: str | Path, fmu_dir: Path | None = None) -> Path:
    """Write ``scenario`` as an SSP package to ``out`` (``.ssp``); returns the path."""
    out = Path(out)
    if out.suffix != ".ssp":
        raise ScenarioError(f"--out {out}: an SSP package's name ends in .ssp")
    ensure_writable_folder(out.parent, out)
    check_exportable(scenario)  # before building any FMU
    types = {role: u.type for role, u in scenario.graph.units.items()}
    files = {role: Path(p) for role, p in fmu_paths(types, fmu_dir).items()}
    files.update({name: Path(f.path) for name, f in scenario.fmus.items()})
    sources = {name: f"resources/{path.name}" for name, path in files.items()}
    root = system_structure(scenario, sources)
    ET.indent(root)
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="rubcosim_ssp_") as tmp:
        staged = Path(tmp) / out.name
        with zipfile.ZipFile(staged, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.writestr(
                "SystemStructure.ssd",
                ET.tostring(root, encoding="UTF-8", xml_declaration=True),
            )
            for path in sorted(set(files.values())):
                zf.write(path, f"resources/{path.name}")
        shutil.move(staged, out)  # complete or not at all
    return out
