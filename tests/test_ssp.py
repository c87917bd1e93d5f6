"""SSP 1.0 export: the package passes the SSP schema, FMPy's SSP master runs it, and it
agrees with our own fixed-step Jacobi master on the same step; what SSP cannot carry
(a summed input) is refused by name."""

from __future__ import annotations

import sys
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest

from rubcosim import api
from rubcosim.cli import main
from rubcosim.errors import ScenarioError
from rubcosim.orchestrator.assembly import fmu_paths, run_cosim
from rubcosim.orchestrator.settings import cosim_settings
from rubcosim.scenario import load_scenario
from rubcosim.ssp_export import export_ssp

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "examples" / "foreign_fmu"))
fmpy_ssd = pytest.importorskip("fmpy.ssp.ssd")
fmpy_sim = pytest.importorskip("fmpy.ssp.simulation")

T_END = 0.03


@pytest.fixture(scope="module")
def elastic(tmp_path_factory):
    sc = load_scenario("jeffcott_elastic_stator", [f"sim.t_end={T_END}"])
    return sc, export_ssp(sc, tmp_path_factory.mktemp("ssp") / "system.ssp")


def _bindings(ssd) -> dict[str, dict[str, object]]:
    values = {}
    for comp in fmpy_ssd.find_components(ssd.system):
        for binding in comp.parameterBindings:
            for pset in binding.parameterValues:
                values[comp.name] = {p.name: (p.type, p.value) for p in pset.parameters}
    return values


def test_package_passes_the_schema_with_units_connections_and_parameters(elastic):
    sc, path = elastic
    ssd = fmpy_ssd.read_ssd(str(path), validate=True)  # SSP 1.0 XML schema
    assert {c.name for c in fmpy_ssd.find_components(ssd.system)} == {"rotor", "stator"}
    links = {(a.parent.name, a.name, b.parent.name, b.name)
             for a, b in fmpy_ssd.get_connections(ssd.system)}  # fmt: skip
    want = {(u, o, c.unit, c.input) for c in sc.graph.connections for u, o in c.pairs}
    assert links == want and len(want) >= 6
    values = _bindings(ssd)
    assert float(values["rotor"]["mass"][1]) == sc.graph.units["rotor"].params["mass"]
    stiffness = sc.graph.units["stator"].params["contact_stiffness"]
    assert float(values["stator"]["contact_stiffness"][1]) == stiffness
    with zipfile.ZipFile(path) as zf:  # FMPy does not read the DefaultExperiment
        root = ET.fromstring(zf.read("SystemStructure.ssd"))
        assert sorted(zf.namelist()) == [
            "SystemStructure.ssd", "resources/RubcosimElasticStator.fmu",
            "resources/RubcosimJeffcottRotor.fmu",
        ]  # fmt: skip
    experiment = root.find(
        "{http://ssp-standard.org/SSP1/SystemStructureDescription}DefaultExperiment"
    )
    assert float(experiment.get("stopTime")) == T_END


def _fmpy_and_ours(sc, path, h):
    ssd = fmpy_ssd.read_ssd(str(path))
    pset = fmpy_ssd.ParameterSet(name="scenario")
    for comp, params in _bindings(ssd).items():
        for name, (kind, value) in params.items():
            if kind in ("Real", "Integer"):  # FMPy's SSP master sets no String
                pset.parameters.append(fmpy_ssd.Parameter(name=f"{comp}.{name}", type=kind,
                                                          value=value))  # fmt: skip
    out = fmpy_sim.simulate_ssp(str(path), stop_time=T_END, step_size=h, parameter_set=pset)
    # FMPy: Jacobi, inputs held over the step, outputs read after it (row k: t_k + h)
    plain = cosim_settings(
        {
            "adaptive": False,
            "step": h,
            "algorithm": "jacobi",
            "extrapolation": 0,
            "events": "off",
        }  # fmt: skip
    )
    times = np.asarray(out["time"]) + h
    ours = run_cosim(sc, plain, record=["rotor.x", "rotor.y", "stator.gap"], times=times)
    assert ours.ok
    n = min(len(ours.t), len(times))
    return out, ours, n


def test_fmpy_runs_the_package_as_our_fixed_step_jacobi_master_does(elastic):
    sc, path = elastic
    h = sc.system.forcing_period / 400.0
    out, ours, n = _fmpy_and_ours(sc, path, h)
    scale = np.abs(ours.output("rotor.x")[:n]).max()
    assert n > 700 and scale > 1e-5  # the disc has moved, up to the stator
    # Free flight: the same FMUs, parameters and wiring, the same master: to round-off
    free = int(np.argmax(ours.output("stator.gap")[:n] < 0.0))
    assert free > 100
    for name in ("rotor.x", "rotor.y"):
        diff = np.abs(np.asarray(out[name][:free]) - ours.output(name)[:free]).max()
        assert diff <= 1e-12 * scale, (name, diff)
    # In contact FMPy's master reads the stator's force before its inputs see the disc's
    # new position (one step late: it knows no feedthrough); ours sets them first.  Both
    # are first order: their difference halves with the step.
    out2, ours2, n2 = _fmpy_and_ours(sc, path, h / 2.0)
    gap = np.abs(np.asarray(out["rotor.x"][n - 1]) - ours.output("rotor.x")[n - 1])
    gap2 = np.abs(np.asarray(out2["rotor.x"][n2 - 1]) - ours2.output("rotor.x")[n2 - 1])
    assert 0.0 < gap2 < 0.65 * gap, (gap, gap2)


def test_a_summed_input_is_refused_naming_the_connection(tmp_path):
    sc = load_scenario("jeffcott_delayed_feedback")
    with pytest.raises(ScenarioError, match="connections.rotor.fx sums"):
        export_ssp(sc, tmp_path / "x.ssp")


def test_cli_export_ssp_writes_the_package_and_refuses_a_bad_name(tmp_path, capsys):
    args = ["export-ssp", "jeffcott_elastic_stator"]
    assert main([*args, "--out", str(tmp_path / "a" / "system.ssp")]) == 0
    assert (tmp_path / "a" / "system.ssp").is_file()
    assert main([*args, "--out", str(tmp_path / "system.zip")]) == 2
    assert "ends in .ssp" in capsys.readouterr().err


# --- running an SSP package (rubcosim run system.ssp) -------------------------------


def test_an_exported_package_runs_as_the_scenario_it_came_from(elastic, tmp_path):
    sc, path = elastic
    back = api.load(str(path))
    assert set(back.graph.units) == {"rotor", "stator"}
    want = run_cosim(sc, record=["rotor.x", "stator.normal_force"])
    got = run_cosim(back, record=["rotor.x", "stator.normal_force"], times=want.t)
    assert got.ok and np.array_equal(got.output("rotor.x"), want.output("rotor.x"))
    assert main(["run", str(path), "--backend", "direct", "--out", str(tmp_path / "r")]) == 0


BALL_SSD = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="rotor_and_ball"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">
  <ssd:System name="rotor_and_ball">
    <ssd:Elements>
      <ssd:Component name="disc" type="application/x-fmu-sharedlibrary"
          source="resources/RubcosimJeffcottRotor.fmu">
        <ssd:Connectors>
          <ssd:Connector name="fy" kind="input"><ssc:Real/></ssd:Connector>
          <ssd:Connector name="y" kind="output"><ssc:Real/></ssd:Connector>
        </ssd:Connectors>
        <ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>
          <ssv:ParameterSet version="1.0" name="disc"><ssv:Parameters>
            <ssv:Parameter name="eccentricity"><ssv:Real value="5e-05"/></ssv:Parameter>
            <ssv:Parameter name="damping"><ssv:Real value="316.227766"/></ssv:Parameter>
          </ssv:Parameters></ssv:ParameterSet>
        </ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>
      </ssd:Component>
      <ssd:Component name="ball" type="application/x-fmu-sharedlibrary"
          source="resources/bouncing_ball.fmu">
        <ssd:Connectors><ssd:Connector name="h" kind="output"><ssc:Real/></ssd:Connector>
        </ssd:Connectors>
        <ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>
          <ssv:ParameterSet version="1.0" name="ball"><ssv:Parameters>
            <ssv:Parameter name="h0"><ssv:Real value="0.0001"/></ssv:Parameter>
          </ssv:Parameters></ssv:ParameterSet>
        </ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>
      </ssd:Component>
    </ssd:Elements>
    <ssd:Connections>
      <ssd:Connection startElement="ball" startConnector="h" endElement="disc" endConnector="fy"/>
    </ssd:Connections>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="0.02"/>
</ssd:SystemStructureDescription>
"""


def _ball_package(tmp_path, ssd: str = BALL_SSD):
    from build import build  # examples/foreign_fmu/build.py: a C FMU built with gcc

    ball = build(tmp_path / "bouncing_ball.fmu")
    rotor = fmu_paths({"rotor": "jeffcott"}, None)["rotor"]
    path = tmp_path / "by_hand.ssp"
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("SystemStructure.ssd", ssd)
        zf.write(rotor, f"resources/{rotor.name}")
        zf.write(ball, "resources/bouncing_ball.fmu")
    return path


def test_a_package_written_by_hand_wires_a_c_fmu_to_ours(tmp_path, capsys):
    path = _ball_package(tmp_path)
    sc = api.load(str(path))
    assert sc.graph.units["rotor"].params["eccentricity"] == 5e-5 and "ball" in sc.fmus
    # the same system written as a scenario: the SSP's wiring, nothing else
    table = {
        "scenario": {"name": "by_toml"},
        "sim": {"t_end": 0.02},
        "units": {
            "rotor": {
                "type": "jeffcott",
                "eccentricity": 5e-5,
                "damping": 316.227766,
                # what the SSD leaves unbound: the FMU's start values (its examples)
                "mass": 10.0,
                "stiffness": 1e6,
                "speed": 379.473319,
            }
        },  # fmt: skip
        "fmus": {"ball": {"path": str(tmp_path / "bouncing_ball.fmu"), "start": {"h0": 1e-4}}},
        "connections": {"rotor.fy": ["ball.h"], "rotor.fx": []},
    }
    ref = run_cosim(api.load(table), record=["rotor.y", "ball.h"])
    got = run_cosim(sc, record=["rotor.y", "ball.h"], times=ref.t)
    assert got.ok and np.array_equal(got.output("rotor.y"), ref.output("rotor.y"))
    table["connections"]["rotor.fy"] = []
    alone = run_cosim(api.load(table), record=["rotor.y"], times=ref.t)
    assert np.max(np.abs(alone.output("rotor.y") - got.output("rotor.y"))) > 0.0  # ball pushes
    out = tmp_path / "run"
    assert main(["run", str(path), "--backend", "fmu", "--out", str(out)]) == 0
    assert (out / "report.json").is_file()


@pytest.mark.parametrize(
    "damage, message",
    [
        (lambda s: s.replace('endElement="disc"', 'endElement="shaft"'), "names a component"),
        (
            lambda s: s.replace('endConnector="fy"', 'endConnector="fz"'),
            r"disc has no input 'fz' \(its inputs: .*fy",
        ),
        (
            lambda s: s.replace('startConnector="h"', 'startConnector="hh"'),
            r"ball has no output 'hh' \(its outputs: h, v",
        ),
        (
            lambda s: s.replace("resources/bouncing_ball.fmu", "resources/missing.fmu"),
            "is not in the package",
        ),  # fmt: skip
    ],
)
def test_a_broken_package_is_refused_naming_the_element(tmp_path, damage, message):
    path = _ball_package(tmp_path, damage(BALL_SSD))
    with pytest.raises(ScenarioError, match=message):
        api.load(str(path))
    (tmp_path / "junk.ssp").write_text("not a zip")
    with pytest.raises(ScenarioError, match="not an SSP package"):
        api.load(str(tmp_path / "junk.ssp"))


def test_a_package_without_its_system_structure_is_refused_naming_it(tmp_path):
    path = tmp_path / "empty.ssp"
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("resources/readme.txt", "no SystemStructure.ssd here")
    with pytest.raises(ScenarioError, match="no SystemStructure.ssd"):
        api.load(str(path))
