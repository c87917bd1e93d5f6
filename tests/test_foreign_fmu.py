"""A foreign FMU (built without rubcosim) as a unit of a scenario, mixed with direct units."""

from __future__ import annotations

import json
import math
import shutil
import sys
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from rubcosim.cli import main
from rubcosim.orchestrator.assembly import run_cosim
from rubcosim.runner import run_scenario
from rubcosim.scenario import ScenarioError, build_scenario, load_scenario

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "foreign_fmu"
sys.path.insert(0, str(EXAMPLE))
from build import build  # noqa: E402


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    """The example scenario and a freshly built bouncing-ball FMU beside it."""
    d = tmp_path_factory.mktemp("foreign")
    build(d / "bouncing_ball.fmu")
    shutil.copy(EXAMPLE / "rotor_and_ball.toml", d)
    return d / "rotor_and_ball.toml"


def ball_height(t: np.ndarray, h0: float, e: float, g: float = 9.81) -> np.ndarray:
    """Closed form of the bouncing ball dropped from rest at h0."""
    out = np.empty_like(t)
    for i, ti in enumerate(t):
        t0, v = math.sqrt(2 * h0 / g), 0.0
        if ti < t0:
            out[i] = h0 - 0.5 * g * ti**2
            continue
        v = e * g * t0  # upward speed after the first bounce
        while ti >= t0 + 2 * v / g and v > 1e-6:
            t0 += 2 * v / g
            v *= e
        s = ti - t0
        out[i] = v * s - 0.5 * g * s**2 if v > 1e-6 else 0.0
    return out


def test_a_foreign_fmu_runs_beside_direct_units_with_rollbacks(example):
    sc = load_scenario(example)
    assert "ball.h" in sc.outputs and sc.unit_names == ["rotor", "stator", "ball"]
    r = run_cosim(sc)
    assert r.ok, r.message
    assert r.counters["events_impact"] >= 5 and r.counters["event_probes"] > 0  # rollbacks
    h = r.output("ball.h")
    assert np.max(np.abs(h - ball_height(r.t, 1e-4, 0.8))) < 1e-9
    assert r.output("ball.bounces")[-1] >= 10
    # the rotor sees nothing of the ball: the same as without it
    alone = load_scenario(example.parent / "rotor_and_ball.toml")
    alone.fmus.clear()
    r0 = run_cosim(alone, record=["rotor.x"], times=r.t)
    assert np.array_equal(r0.output("rotor.x"), r.output("rotor.x"))


def test_foreign_fmu_outputs_can_be_wired(example):
    # the ball's height as a (tiny) extra force on the disc: a connection from a foreign unit
    sc = load_scenario(example, ["sim.t_end=0.01"])
    sc.connections["rotor.fy"] = ["stator.fy", "ball.h"]
    r = run_cosim(sc, record=["rotor.y", "ball.h"])
    assert r.ok, r.message


def test_foreign_fmu_scenario_errors_name_the_key(example):
    data = tomllib.loads(example.read_text())
    good = data["fmus"]["ball"]
    bad = [
        ({"path": "missing.fmu"}, "fmus.ball.path: .*missing.fmu is not a file"),
        ({**good, "record": ["h", "speed"]}, "fmus.ball.record: 'speed' is not an output"),
        ({**good, "start": {"mass": 1.0}}, "fmus.ball.start.mass: not a parameter"),
        ({**good, "colour": 1}, "fmus.ball.colour is not a key"),
        ({"start": {}}, "fmus.ball.path is required"),
    ]
    for table, message in bad:
        with pytest.raises(ScenarioError, match=message):
            build_scenario({**data, "fmus": {"ball": table}}, source=str(example))
    with pytest.raises(ScenarioError, match="fmus.rotor: the name is already a unit"):
        build_scenario({**data, "fmus": {"rotor": good}}, source=str(example))
    # --set NAME.variable sets a start value
    assert load_scenario(example, ["ball.h0=0.5"]).fmus["ball"].start == {"h0": 0.5, "e": 0.8}
    with pytest.raises(ScenarioError, match="fmus.ball.start.wings"):
        load_scenario(example, ["ball.wings=2"])
    with pytest.raises(ScenarioError, match="monolithic engines cannot simulate a foreign FMU"):
        run_scenario(load_scenario(example))


def test_run_and_check_commands_with_a_foreign_fmu(example, tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", str(example), "--backend", "direct", "--set", "ball.e=0.5",
                 "--set", "sim.t_end=0.02", "--out", str(out)]) == 0  # fmt: skip
    assert (out / "results.csv").read_text().splitlines()[0].count("ball.h") == 1
    assert main(["check", str(example), "--out", str(tmp_path / "check")]) == 2
    assert "foreign FMU" in capsys.readouterr().err


def test_a_foreign_fmu_without_state_refuses_rollback(example):
    sc = load_scenario(example, ["sim.t_end=0.01"])
    sc.fmus["ball"] = replace(sc.fmus["ball"], can_get_set_state=False)
    with pytest.raises(Exception, match="cannot get and set its state"):
        run_cosim(sc)
    r = run_cosim(sc, replace(sc.cosim, adaptive=False, events="step"))
    assert r.ok, r.message


def test_foreign_outputs_of_every_fmi_type(example):
    # the ball also has a String output (phase) and a Boolean one (resting): by default
    # every numeric output is recorded, the String one is not, and nothing crashes
    data = tomllib.loads(example.read_text())
    table = {k: v for k, v in data["fmus"]["ball"].items() if k != "record"}
    sc = build_scenario({**data, "fmus": {"ball": table}, "sim": {"t_end": 0.06}},
                        source=str(example))  # fmt: skip
    assert sc.fmus["ball"].strings == ("phase",)
    r = run_cosim(sc)
    assert r.ok, r.message
    resting, h = r.output("ball.resting"), r.output("ball.h")
    # the ball is at rest by about 41 ms (1e-4 m drop, e = 0.8): resting follows h
    assert resting[0] == 0.0 and resting[-1] == 1.0 and h[-1] == 0.0
    assert np.all(h[resting == 1.0] == 0.0)
    assert "ball.phase" not in r.names and not r.texts
    # connecting the String output is refused, naming it
    wired = {**data, "connections": {"rotor.fy": ["stator.fy", "ball.phase"]}}
    with pytest.raises(ScenarioError, match="rotor.fy: ball.phase is a String variable"):
        build_scenario(wired, source=str(example))
    # a Boolean output drives a Real input (as 0 or 1)
    wired = {**data, "connections": {"rotor.fy": ["stator.fy", "ball.resting"]}}
    assert build_scenario(wired, source=str(example)).graph.connections


@pytest.mark.parametrize("isolate", [False, True])
def test_a_string_output_is_recorded_as_text_where_asked(example, tmp_path, isolate):
    # the ball's phase ("falling", "rising", "resting") recorded beside its height: it
    # follows the closed form's velocity (the FMU's own String, read at each output time)
    data = tomllib.loads(example.read_text())
    ball = {**data["fmus"]["ball"], "record": ["h", "v", "phase"], "isolate": isolate}
    sc = build_scenario({**data, "fmus": {"ball": ball}, "sim": {"t_end": 0.06}},
                        source=str(example))  # fmt: skip
    assert "ball.phase" in sc.outputs
    r = run_cosim(sc)
    assert r.ok, r.message
    phase, v, h = r.output("ball.phase"), r.output("ball.v"), r.output("ball.h")
    assert phase.dtype.kind == "U" and phase.shape == r.t.shape
    expected = np.where((h <= 0.0) & (v == 0.0), "resting", np.where(v > 0.0, "rising", "falling"))
    assert list(phase) == list(expected)
    assert {"falling", "rising", "resting"} <= set(phase)
    # results.csv: the texts in their own quoted column, the numbers as before
    sc2 = build_scenario({**data, "fmus": {"ball": {**ball, "record": ["h", "phase"]}},
                          "sim": {"t_end": 0.02}}, source=str(example))  # fmt: skip
    from rubcosim.runner import run_cosim_scenario
    from rubcosim.writing import write_csv

    run = run_cosim_scenario(sc2)
    lines = write_csv(run, tmp_path / "results.csv").read_text().splitlines()
    header = lines[0].split(",")
    col = header.index("ball.phase")
    cells = [line.split(",") for line in lines[1:]]
    assert all(c[col] in ('"falling"', '"rising"', '"resting"') for c in cells)
    hcol = header.index("ball.h")
    assert [float(c[hcol]) for c in cells] == list(run.series("ball.h"))


def test_a_discrete_input_takes_only_a_source_of_its_type():
    from rubcosim.components.wiring import Connection, CouplingError, check_connections

    inputs = {"fmu": ["count", "level"], "a": []}
    outputs = {"fmu": [], "a": ["n", "x"]}
    types = {"fmu": {"count": "Integer", "level": "Real"}, "a": {"n": "Enumeration", "x": "Real"}}
    check_connections([Connection("fmu.count", ("a.n",))], inputs, outputs, types=types)
    check_connections([Connection("fmu.level", ("a.n",))], inputs, outputs, types=types)
    with pytest.raises(
        CouplingError, match="fmu.count is an Integer input; its source a.x is Real"
    ):
        check_connections([Connection("fmu.count", ("a.x",))], inputs, outputs, types=types)


def test_an_isolated_fmu_that_crashes_fails_the_run_and_keeps_its_results(example, tmp_path):
    # the ball segfaults in its 400th fmi2DoStep; run in a worker process, it ends the run
    # with status failed, naming it and the time, and what was computed before is kept
    data = tomllib.loads(example.read_text())
    ball = {**data["fmus"]["ball"], "isolate": True,
            "start": {**data["fmus"]["ball"]["start"], "crash_at_step": 400}}  # fmt: skip
    sc = build_scenario({**data, "fmus": {"ball": ball}}, source=str(example))
    r = run_cosim(sc)
    assert r.status == "failed"
    assert "ball: the FMU's worker process died (killed by SIGSEGV) in do_step at t =" in r.message
    assert 0.0 < r.t[-1] < sc.sim["t_end"] and r.t.size > 10
    assert np.max(np.abs(r.output("ball.h") - ball_height(r.t, 1e-4, 0.8))) < 1e-9
    # isolated and healthy: the same results as in-process, bit for bit
    healthy = build_scenario({**data, "sim": {**data["sim"], "t_end": 0.01},
                              "fmus": {"ball": {**ball, "start": data["fmus"]["ball"]["start"]}}},
                             source=str(example))  # fmt: skip
    isolated = run_cosim(healthy)
    healthy.fmus["ball"] = replace(healthy.fmus["ball"], isolate=False)
    in_process = run_cosim(healthy)
    assert isolated.ok and in_process.ok
    assert np.array_equal(isolated.values, in_process.values)
    # the command line writes the report of the failed run, with its results
    out = tmp_path / "crash"
    assert main(["run", str(example), "--backend", "direct", "--set", "ball.crash_at_step=400",
                 "--set", "cosim.isolate=true", "--out", str(out)]) != 0  # fmt: skip
    report = json.loads((out / "report.json").read_text())
    assert report["status"] == "failed" and "SIGSEGV" in report["message"]
    assert sorted(p.name for p in out.iterdir() if p.suffix == ".csv")  # the results so far
