"""SSP 1.0 export: the package passes the SSP schema, FMPy's SSP master runs it, and it
agrees with our own fixed-step Jacobi master on the same step; what SSP cannot carry
(a summed input) is refused by name."""

from __future__ import annotations

import zipfile
from xml.etree import ElementTree as ET

import numpy as np
import pytest

from rubcosim.cli import main
from rubcosim.errors import ScenarioError
from rubcosim.orchestrator.assembly import run_cosim
from rubcosim.orchestrator.settings import cosim_settings
from rubcosim.scenario import load_scenario
from rubcosim.ssp_export import export_ssp

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
