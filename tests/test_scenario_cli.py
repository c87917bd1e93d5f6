"""Scenario files, --set overrides, the runner's outputs and the ``rubcosim`` command."""

import copy
import csv
import json
import math
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from rubcosim.cli import EXIT_BAD_INPUT, EXIT_RUN_FAILED, main
from rubcosim.components.catalog import UNIT_TYPES
from rubcosim.runner import report, run_scenario, strobe_times
from rubcosim.scenario import (
    PLOT_KINDS,
    SIM_DEFAULTS,
    TOP_LEVEL,
    ScenarioError,
    build_scenario,
    load_scenario,
    parse_override,
)

REPO = Path(__file__).resolve().parents[1]
SCENARIO_DIR = REPO / "scenarios"
SCENARIOS = sorted(SCENARIO_DIR.glob("*.toml"))
RIGID = SCENARIO_DIR / "jeffcott_rigid_stator.toml"
FEEDBACK = SCENARIO_DIR / "jeffcott_delayed_feedback.toml"
LINEAR_OSC = SCENARIO_DIR / "impact_oscillator_linear.toml"
ROTOR_SHORT = "sim.t_end=0.02"
OSC_SHORT = "sim.t_end=5.0"
RUBCOSIM = Path(sys.executable).with_name("rubcosim")
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
REPORT_KEYS = {
    "scenario",
    "engine",
    "t_end",
    "wall_time_s",
    "n_events",
    "n_impacts",
    "parameters",
    "final_state",
}
PLOT_FILES = ("orbit.png", "timeseries.png", "poincare.png")

OSC_DATA = {
    "scenario": {"name": "osc_case", "description": "small test oscillator"},
    "sim": {"t_end": 5.0, "output_step": 0.01, "engine": "fast", "rtol": 1e-10},
    "units": {
        "oscillator": {
            "type": "impact_oscillator",
            "linear_stiffness": 1.0,
            "damping": 0.1,
            "forcing_amplitude": 1.0,
            "forcing_frequency": 2.0,
            "barrier": 1.0,
            "restitution": 0.8,
            "x0": 0.5,
        }
    },
    "outputs": {"record": ["oscillator.x"]},
    "plots": {
        "orbit": ["oscillator.x", "oscillator.v"],
        "timeseries": ["oscillator.x"],
        "poincare": ["oscillator.x", "oscillator.v"],
    },
}
ROTOR_DATA = {
    "sim": {"t_end": 0.02, "output_step": 2.5e-4},
    "units": {
        "rotor": {
            "type": "jeffcott",
            "mass": 10.0,
            "damping": 316.227766,
            "stiffness": 1.0e6,
            "eccentricity": 5.0e-5,
            "speed": 379.473319,
        },
        "stator": {"type": "rigid", "clearance": 1.0e-4, "friction": 0.15},
    },
}
DELETE = object()


# --------------------------------------------------------------------------- helpers


def _toml_value(value):
    if isinstance(value, str | bool | int | float | list):
        return json.dumps(value)
    raise TypeError(value)


def toml_text(data, prefix=""):
    """A small TOML writer: scalars first, then sub-tables."""
    lines = []
    scalars = {k: v for k, v in data.items() if not isinstance(v, dict)}
    tables = {k: v for k, v in data.items() if isinstance(v, dict)}
    if prefix and (scalars or not tables):
        lines.append(f"[{prefix}]")
    lines += [f"{k} = {_toml_value(v)}" for k, v in scalars.items()]
    for k, v in tables.items():
        lines.append(toml_text(v, f"{prefix}.{k}" if prefix else k))
    return "\n".join(lines) + "\n"


def changed(data, *edits):
    """A deep copy of ``data`` with ``(("a", "b"), value)`` edits; ``DELETE`` removes."""
    out = copy.deepcopy(data)
    for path, value in edits:
        table = out
        for key in path[:-1]:
            table = table.setdefault(key, {})
        if value is DELETE:
            del table[path[-1]]
        else:
            table[path[-1]] = value
    return out


def write(tmp_path, data, name="case.toml"):
    path = tmp_path / name
    path.write_text(toml_text(data) if isinstance(data, dict) else data, encoding="utf-8")
    return path


def scenario_error(path, overrides=(), *expected):
    with pytest.raises(ScenarioError) as info:
        load_scenario(path, overrides)
    msg = str(info.value)
    for text in expected:
        assert text in msg, f"{text!r} not in {msg!r}"
    return msg


def snapshot(root: Path):
    """Every entry under ``root`` with its bytes and modification time."""
    snap = {".": root.stat().st_mtime_ns}
    for p in sorted(root.rglob("*")):
        rel = str(p.relative_to(root))
        snap[rel] = (p.read_bytes() if p.is_file() else None, p.stat().st_mtime_ns)
    return snap


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], np.array(rows[1:], dtype=float)


def one_error_line(err, *expected):
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("rubcosim: error: "), err
    for text in expected:
        assert text in lines[0], f"{text!r} not in {lines[0]!r}"


def test_toml_writer_round_trips():
    assert tomllib.loads(toml_text(OSC_DATA)) == OSC_DATA
    assert tomllib.loads(toml_text(ROTOR_DATA)) == ROTOR_DATA


# --------------------------------------------------------------------------- file errors


def test_missing_file(tmp_path):
    scenario_error(tmp_path / "nope.toml", (), "nope.toml", "no such scenario file")


def test_directory_is_not_a_scenario(tmp_path):
    scenario_error(tmp_path, (), "no such scenario file")


def test_invalid_toml(tmp_path):
    path = write(tmp_path, "[sim\nt_end = 1\n")
    scenario_error(path, (), "case.toml", "not valid TOML")


def test_non_utf8_file(tmp_path):
    path = tmp_path / "latin1.toml"
    path.write_bytes(toml_text(OSC_DATA).replace("small", "sm\xe4ll").encode("latin-1"))
    scenario_error(path, (), "latin1.toml", "UTF-8")


def test_valid_file_loads(tmp_path):
    sc = load_scenario(write(tmp_path, OSC_DATA))
    assert sc.name == "osc_case"
    assert sc.description == "small test oscillator"
    assert sc.source == str(tmp_path / "case.toml")
    assert sc.outputs == ["oscillator.x", "oscillator.v"]  # record + plotted names


def test_name_defaults_to_file_stem(tmp_path):
    sc = load_scenario(write(tmp_path, changed(OSC_DATA, (("scenario",), DELETE)), "my_run.toml"))
    assert sc.name == "my_run"
    assert sc.description == ""


BAD_FILES = [
    ("unknown_section", [(("plot",), {"orbit": ["oscillator.x", "oscillator.v"]})], ["[plot]"]),
    ("units_empty", [(("units",), {})], ["[units]"]),
    ("units_missing", [(("units",), DELETE)], ["[units]"]),
    ("units_not_table", [(("units",), "oscillator")], ["[units]"]),
    ("unit_not_table", [(("units", "oscillator"), 5)], ["units.oscillator"]),
    ("unknown_role", [(("units", "pendulum"), {"type": "x"})], ["units.pendulum"]),
    ("missing_type", [(("units", "oscillator", "type"), DELETE)], ["units.oscillator.type"]),
    ("unknown_type", [(("units", "oscillator", "type"), "pendulum")], ["oscillator.type"]),
    ("unknown_param", [(("units", "oscillator", "mass"), 1.0)], ["oscillator.mass"]),
    (
        "bad_restitution",
        [(("units", "oscillator", "restitution"), 1.5)],
        ["oscillator.restitution", "[0, 1]"],
    ),
    ("bad_stop", [(("units", "oscillator", "stop"), "soft")], ["oscillator.stop"]),
    ("missing_required", [(("units", "oscillator", "linear_stiffness"), DELETE)], []),
    ("sim_not_table", [(("sim",), 5)], ["[sim]"]),
    ("unknown_sim", [(("sim", "tend"), 1.0)], ["sim.tend"]),
    ("missing_t_end", [(("sim", "t_end"), DELETE)], ["sim.t_end"]),
    ("missing_sim", [(("sim",), DELETE)], ["sim.t_end"]),
    ("t_end_equal_start", [(("sim", "t_start"), 5.0)], ["sim.t_end", "sim.t_start"]),
    ("t_end_before_start", [(("sim", "t_end"), -1.0)], ["sim.t_end"]),
    ("t_end_string", [(("sim", "t_end"), "5")], ["sim.t_end"]),
    ("t_end_bool", [(("sim", "t_end"), True)], ["sim.t_end"]),
    ("rtol_one", [(("sim", "rtol"), 1.0)], ["sim.rtol"]),
    ("rtol_tiny", [(("sim", "rtol"), 1e-20)], ["sim.rtol"]),
    ("rtol_negative", [(("sim", "rtol"), -1e-6)], ["sim.rtol"]),
    ("output_step_zero", [(("sim", "output_step"), 0.0)], ["sim.output_step"]),
    ("output_step_negative", [(("sim", "output_step"), -0.01)], ["sim.output_step"]),
    ("atol_zero", [(("sim", "atol"), 0.0)], ["sim.atol"]),
    ("chatter_tol_one", [(("sim", "chatter_tol"), 1.0)], ["sim.chatter_tol"]),
    ("engine_bad", [(("sim", "engine"), "rk4")], ["sim.engine", "fast", "accurate"]),
    ("engine_number", [(("sim", "engine"), 1)], ["sim.engine"]),
    ("max_events_zero", [(("sim", "max_events"), 0)], ["sim.max_events"]),
    ("max_events_float", [(("sim", "max_events"), 2.5)], ["sim.max_events"]),
    ("max_events_bool", [(("sim", "max_events"), True)], ["sim.max_events"]),
    ("max_events_string", [(("sim", "max_events"), "many")], ["sim.max_events"]),
    ("discard_negative", [(("sim", "poincare_discard"), -1.0)], ["sim.poincare_discard"]),
    (
        "record_unknown",
        [(("outputs", "record"), ["oscillator.y"])],
        ["outputs.record", "'oscillator.y'"],
    ),
    ("record_not_list", [(("outputs", "record"), "oscillator.x")], ["outputs.record"]),
    ("outputs_unknown_key", [(("outputs", "recrod"), ["oscillator.x"])], ["outputs.recrod"]),
    ("plot_kind", [(("plots", "phase"), ["oscillator.x", "oscillator.v"])], ["plots.phase"]),
    (
        "orbit_three",
        [(("plots", "orbit"), ["oscillator.x", "oscillator.v", "oscillator.contact"])],
        ["plots.orbit"],
    ),
    ("poincare_one", [(("plots", "poincare"), ["oscillator.x"])], ["plots.poincare"]),
    (
        "plot_unknown_output",
        [(("plots", "timeseries"), ["rotor.x"])],
        ["plots.timeseries", "'rotor.x'"],
    ),
    ("orbit_unknown_output", [(("plots", "orbit"), ["oscillator.x", "x"])], ["plots.orbit", "'x'"]),
    ("plot_not_list", [(("plots", "orbit"), "oscillator.x")], ["plots.orbit"]),
    (
        "two_sided_barrier",
        [
            (("units", "oscillator", "stop"), "rigid_two_sided"),
            (("units", "oscillator", "barrier"), 0.0),
        ],
        ["oscillator.barrier"],
    ),
]


@pytest.mark.parametrize(
    ("edits", "expected"), [c[1:] for c in BAD_FILES], ids=[c[0] for c in BAD_FILES]
)
def test_bad_scenario_file(tmp_path, edits, expected):
    path = write(tmp_path, changed(OSC_DATA, *edits))
    scenario_error(path, (), "case.toml", *expected)


def test_missing_required_unit_param_names_it(tmp_path):
    path = write(tmp_path, changed(OSC_DATA, (("units", "oscillator", "linear_stiffness"), DELETE)))
    scenario_error(path, (), "oscillator.linear_stiffness", "required")


BAD_ROTOR_FILES = [
    ("negative_mass", [(("units", "rotor", "mass"), -1.0)], ["rotor.mass", "(0, inf]"]),
    (
        "stator_restitution",
        [(("units", "stator", "restitution"), 1.5)],
        ["stator.restitution", "[0, 1]"],
    ),
    (
        "bearing_on_jeffcott",
        [(("units", "bearing"), {"type": "linear", "stiffness": 1e7})],
        ["bearing", "two_mass"],
    ),
    (
        "two_mass_no_bearing",
        [(("units", "rotor", "type"), "two_mass"), (("units", "rotor", "journal_mass"), 2.0)],
        ["rotor.type", "bearing"],
    ),
    ("disc_outside", [(("units", "rotor", "x0"), 2e-4)], ["rotor.x0"]),
    (
        "rotor_and_oscillator",
        [(("units", "oscillator"), OSC_DATA["units"]["oscillator"])],
        ["oscillator"],
    ),
    ("stator_only", [(("units", "rotor"), DELETE)], ["rotor", "oscillator"]),
]


@pytest.mark.parametrize(
    ("edits", "expected"), [c[1:] for c in BAD_ROTOR_FILES], ids=[c[0] for c in BAD_ROTOR_FILES]
)
def test_bad_rotor_scenario_file(tmp_path, edits, expected):
    path = write(tmp_path, changed(ROTOR_DATA, *edits))
    scenario_error(path, (), "case.toml", *expected)


def test_rotor_base_file_is_valid(tmp_path):
    sc = load_scenario(write(tmp_path, ROTOR_DATA))
    assert sc.system.output_names[:2] == ["rotor.x", "rotor.y"]


def test_empty_timeseries_is_rejected(tmp_path):
    path = write(tmp_path, changed(OSC_DATA, (("plots", "timeseries"), [])))
    scenario_error(path, (), "plots.timeseries")


def test_unknown_scenario_key_is_rejected(tmp_path):
    path = write(tmp_path, changed(OSC_DATA, (("scenario", "descripton"), "typo")))
    scenario_error(path, (), "scenario.descripton")


# --------------------------------------------------------------------------- parse_override


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("rotor.mass=12", ("rotor", "mass", 12)),
        ("rotor.mass = 1e3", ("rotor", "mass", 1000.0)),
        ("rotor.x0=-1.5e-5", ("rotor", "x0", -1.5e-5)),
        ("oscillator.stop=rigid_two_sided", ("oscillator", "stop", "rigid_two_sided")),
        ('oscillator.stop="rigid_two_sided"', ("oscillator", "stop", "rigid_two_sided")),
        ("oscillator.stop='none'", ("oscillator", "stop", "none")),
        ("sim.engine=accurate", ("sim", "engine", "accurate")),
        ("sim.max_events=3", ("sim", "max_events", 3)),
        ("unit.flag=true", ("unit", "flag", True)),
        ("unit.list=[1, 2]", ("unit", "list", [1, 2])),
        ("unit.text=a=b", ("unit", "text", "a=b")),
        ("unit.text=two words", ("unit", "text", "two words")),
        ("unit.empty=", ("unit", "empty", "")),
    ],
)
def test_parse_override(text, expected):
    role, name, value = parse_override(text)
    assert (role, name, value) == expected
    assert type(value) is type(expected[2])


def test_parse_override_non_finite():
    assert parse_override("rotor.speed=inf")[2] == math.inf
    assert math.isnan(parse_override("rotor.speed=nan")[2])


@pytest.mark.parametrize(
    "text", ["rotor.mass", "rotormass=1", "a.b.c=1", ".mass=1", "rotor.=1", "=1", "", "rotor"]
)
def test_parse_override_malformed(text):
    with pytest.raises(ScenarioError) as info:
        parse_override(text)
    assert "unit.parameter=value" in str(info.value)
    assert repr(text) in str(info.value)


# --------------------------------------------------------------------------- overrides


@pytest.mark.parametrize(
    ("override", "expected"),
    [
        ("rotor.mass=-1", ["rotor.mass", "(0, inf]"]),
        ("stator.restitution=1.5", ["stator.restitution", "[0, 1]"]),
        ("stator.friction=-0.1", ["stator.friction"]),
        ("rotor.speed=fast", ["rotor.speed", "not a number"]),
        ("rotor.speed=inf", ["rotor.speed"]),
        ("rotor.masss=1", ["rotor.masss"]),
        ("bearing.stiffness=1e6", ["bearing.stiffness", "not in this scenario"]),
        ("oscillator.x0=0", ["oscillator.x0"]),
        ("sim.tend=1", ["sim.tend"]),
        ("sim.t_end=0", ["sim.t_end"]),
        ("sim.t_end=abc", ["sim.t_end"]),
        ("sim.engine=rk4", ["sim.engine"]),
        ("sim.max_events=0", ["sim.max_events"]),
        ("sim.rtol=2", ["sim.rtol"]),
        ("rotor.type=three_mass", ["rotor.type"]),
        ("rotor.x0=1", ["rotor.x0"]),
        ("rotormass=1", ["rotormass=1"]),
    ],
)
def test_bad_override(override, expected):
    scenario_error(RIGID, [override], "jeffcott_rigid_stator.toml", *expected)


def test_oscillator_restitution_override():
    scenario_error(LINEAR_OSC, ["oscillator.restitution=1.5"], "oscillator.restitution", "[0, 1]")


@pytest.mark.parametrize(
    "override",
    [
        "sim.engine=[1]",
        "rotor.type=[1]",
        "controller.delay_periods=inf",
        "controller.delay_periods=nan",
    ],
)
def test_odd_override_values_are_scenario_errors(override):
    key = override.split("=")[0]
    scenario_error(FEEDBACK, [override], key)


def test_string_override_of_choice(tmp_path):
    path = write(tmp_path, OSC_DATA)
    sc = load_scenario(path, ["oscillator.stop=rigid_two_sided"])
    assert sc.parameters["oscillator.stop"] == "rigid_two_sided"
    sc = load_scenario(
        path, ['oscillator.stop="elastic_one_sided"', "oscillator.stop_stiffness=50"]
    )
    assert sc.parameters["oscillator.stop"] == "elastic_one_sided"
    assert sc.parameters["oscillator.stop_stiffness"] == 50.0
    scenario_error(path, ["oscillator.stop=sideways"], "oscillator.stop")


def test_type_override(tmp_path):
    sc = load_scenario(RIGID, ["stator.type=elastic", "stator.contact_stiffness=2e7"])
    assert sc.parameters["stator.type"] == "elastic"
    assert sc.parameters["stator.contact_stiffness"] == 2e7
    assert sc.system.units["stator"].type == "elastic"


def test_last_override_wins():
    sc = load_scenario(RIGID, ["rotor.mass=5", "rotor.mass=7", "sim.t_end=0.1", "sim.t_end=0.2"])
    assert sc.parameters["rotor.mass"] == 7.0
    assert sc.sim["t_end"] == 0.2


def test_overrides_reach_parameters_and_system():
    sc = load_scenario(
        RIGID,
        [
            ROTOR_SHORT,
            "rotor.x0=2e-5",
            "rotor.vy0=0.01",
            "stator.friction=0.2",
            "sim.engine=accurate",
            "sim.output_step=1e-3",
        ],
    )
    p = sc.parameters
    assert p["rotor.x0"] == 2e-5
    assert p["rotor.vy0"] == 0.01
    assert p["stator.friction"] == 0.2
    assert p["sim.t_end"] == 0.02
    assert p["sim.engine"] == "accurate"
    assert p["sim.output_step"] == 1e-3
    assert p["rotor.mass"] == 10.0  # untouched value from the file
    assert sc.system.y0.tolist() == [2e-5, 0.0, 0.0, 0.01]
    # the file's own values are not modified by loading with overrides
    assert load_scenario(RIGID).parameters["rotor.x0"] == 0.0


def test_overrides_take_effect_in_rotor_run():
    sc = load_scenario(
        RIGID, [ROTOR_SHORT, "rotor.x0=2e-5", "rotor.vy0=0.01", "sim.output_step=1e-3"]
    )
    run = run_scenario(sc)
    assert run.result.ok
    assert run.result.t_reached == pytest.approx(0.02)
    assert run.time[0] == 0.0
    assert run.time[-1] == pytest.approx(0.02)
    assert np.allclose(np.diff(run.time), 1e-3)
    assert run.series("rotor.x")[0] == pytest.approx(2e-5)
    assert run.series("rotor.vy")[0] == pytest.approx(0.01)
    assert run.series("rotor.y")[0] == 0.0


def test_overrides_take_effect_in_oscillator_run():
    sc = load_scenario(LINEAR_OSC, [OSC_SHORT, "oscillator.x0=-0.5", "oscillator.v0=0.25"])
    assert sc.parameters["oscillator.v0"] == 0.25
    run = run_scenario(sc)
    assert run.result.ok
    assert run.time[-1] == 5.0
    assert run.result.t_reached == pytest.approx(5.0)
    assert run.series("oscillator.x")[0] == -0.5
    assert run.series("oscillator.v")[0] == 0.25


def test_t_start_override_shifts_the_run():
    sc = load_scenario(LINEAR_OSC, ["sim.t_start=1.0", "sim.t_end=3.0", "oscillator.x0=-0.5"])
    run = run_scenario(sc)
    assert run.time[0] == 1.0
    assert run.time[-1] == 3.0
    assert run.series("oscillator.x")[0] == -0.5


def test_engine_argument_overrides_sim_engine():
    sc = load_scenario(LINEAR_OSC, [OSC_SHORT])
    assert sc.sim["engine"] == "fast"
    run = run_scenario(sc, engine="accurate")
    assert run.result.engine == "accurate"
    rep = report(run)
    assert rep["engine"] == "accurate"
    assert rep["parameters"]["sim.engine"] == "accurate"


# --------------------------------------------------------------------------- the scenario files


def test_scenario_files_exist():
    assert len(SCENARIOS) >= 9
    assert RIGID in SCENARIOS


@pytest.mark.parametrize("path", SCENARIOS, ids=[p.stem for p in SCENARIOS])
def test_scenario_file_keys_are_declared(path):
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    assert set(data) <= set(TOP_LEVEL)
    assert set(data.get("scenario", {})) <= {"name", "description"}
    assert set(data["sim"]) <= set(SIM_DEFAULTS)
    assert set(data.get("outputs", {})) <= {"record"}
    assert set(data.get("plots", {})) <= set(PLOT_KINDS)
    for role, table in data["units"].items():
        assert role in UNIT_TYPES
        declared = {p.name for p in UNIT_TYPES[role][table["type"]]}
        assert set(table) - {"type"} <= declared, f"{path.name}: units.{role}"


@pytest.mark.parametrize("path", SCENARIOS, ids=[p.stem for p in SCENARIOS])
def test_scenario_file_loads_and_uses_every_key(path):
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    sc = load_scenario(path)
    assert sc.name == data.get("scenario", {}).get("name", path.stem)
    assert sc.name == path.stem
    for key, value in data["sim"].items():
        assert sc.sim[key] == value, f"sim.{key}"
        assert sc.parameters[f"sim.{key}"] == value
    for role, table in data["units"].items():
        for key, value in table.items():
            assert sc.parameters[f"{role}.{key}"] == value, f"{role}.{key}"
    for kind, names in data.get("plots", {}).items():
        assert sc.plots[kind] == names
        assert set(names) <= set(sc.outputs)


@pytest.mark.parametrize("engine", ["fast", "accurate"])
@pytest.mark.parametrize("path", SCENARIOS, ids=[p.stem for p in SCENARIOS])
def test_scenario_file_runs_briefly(path, engine):
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    t_end = 5.0 if "oscillator" in data["units"] else 0.02
    sc = load_scenario(path, [f"sim.t_end={t_end}", f"sim.engine={engine}"])
    run = run_scenario(sc)
    assert run.result.ok, run.result.message
    assert run.result.engine == engine
    assert run.time[-1] == t_end
    for name in sc.outputs:
        assert np.all(np.isfinite(run.series(name)))


# --------------------------------------------------------------------------- strobe_times


def osc_scenario(**sim):
    data = changed(OSC_DATA, *[(("sim", k), v) for k, v in sim.items()])
    return build_scenario(data)


def check_strobe(times, sc):
    sim = sc.sim
    period = sc.system.forcing_period
    w = 2.0 * math.pi / period
    assert times.size > 1
    assert np.allclose(np.diff(times), period, rtol=1e-12, atol=0.0)
    k = (w * times - sim["poincare_phase"]) / (2.0 * math.pi)
    assert np.allclose(k, np.round(k), atol=1e-9)
    start = sim["t_start"] + sim["poincare_discard"]
    assert times[0] >= start - 1e-9
    assert times[0] - period < start
    assert times[-1] <= sim["t_end"] + 1e-9
    assert times[-1] + period > sim["t_end"]


@pytest.mark.parametrize(
    "sim",
    [
        {"t_end": 100.0},
        {"t_end": 100.0, "poincare_discard": 20.0},
        {"t_end": 100.0, "poincare_discard": 20.0, "poincare_phase": 1.0},
        {"t_end": 100.0, "poincare_phase": -1.0},
        {"t_end": 100.0, "poincare_phase": 4.0 * math.pi + 0.5},
        {"t_start": 3.0, "t_end": 50.0, "poincare_discard": 7.0, "poincare_phase": 2.0},
        {"t_start": -10.0, "t_end": 10.0},
    ],
)
def test_strobe_times(sim):
    sc = osc_scenario(**sim)
    assert sc.system.forcing_period == pytest.approx(math.pi)  # forcing_frequency = 2
    check_strobe(strobe_times(sc), sc)


def test_strobe_times_values():
    sc = osc_scenario(t_end=10.0, poincare_phase=1.0)
    expected = (2.0 * math.pi * np.arange(4) + 1.0) / 2.0
    assert np.allclose(strobe_times(sc), expected)


def test_strobe_includes_time_at_discard():
    sc = osc_scenario(t_end=100.0, poincare_discard=10.0 * math.pi)
    times = strobe_times(sc)
    assert times[0] == pytest.approx(10.0 * math.pi)


def test_strobe_phase_is_periodic():
    a = strobe_times(osc_scenario(t_end=100.0, poincare_phase=0.3))
    b = strobe_times(osc_scenario(t_end=100.0, poincare_phase=0.3 + 2.0 * math.pi))
    assert np.allclose(a, b)


def test_strobe_empty_when_discard_exceeds_run():
    sc = osc_scenario(t_end=5.0, poincare_discard=10.0)
    assert strobe_times(sc).size == 0


def test_strobe_rotor_period():
    sc = load_scenario(RIGID)
    period = 2.0 * math.pi / 379.473319
    assert sc.system.forcing_period == pytest.approx(period)
    times = strobe_times(sc)
    check_strobe(times, sc)
    assert times[0] >= 0.25  # poincare_discard of the file
    # without spin the section uses the natural period
    sc = build_scenario(changed(ROTOR_DATA, (("units", "rotor", "speed"), 0.0)))
    assert sc.system.forcing_period == pytest.approx(2.0 * math.pi / math.sqrt(1.0e6 / 10.0))


def test_run_samples_poincare_at_strobe_times():
    sc = osc_scenario(t_end=20.0, poincare_discard=5.0, poincare_phase=0.7)
    run = run_scenario(sc)
    times = strobe_times(sc)
    assert np.allclose(run.result.t[run.strobe_rows], times)
    assert report(run)["poincare_points"] == times.size
    assert run.poincare("oscillator.x").size == times.size
    # the grid is not disturbed by the strobe samples
    assert np.allclose(np.diff(run.time), 0.01)


# --------------------------------------------------------------------------- CLI in-process


def test_cli_good_run(tmp_path, capsys):
    out = tmp_path / "out"
    rc = main(
        ["run", str(RIGID), "--set", ROTOR_SHORT, "--set", "rotor.x0=2e-5", "--out", str(out)]
    )
    captured = capsys.readouterr()
    assert rc == 0, captured.err
    assert captured.err == ""
    assert "jeffcott_rigid_stator" in captured.out and "fast" in captured.out
    for name in ("results.csv", "report.json", *PLOT_FILES):
        assert (out / name).is_file(), name
    for name in PLOT_FILES:
        assert (out / name).read_bytes()[:8] == PNG_MAGIC
    sc = load_scenario(RIGID, [ROTOR_SHORT])
    header, table = read_csv(out / "results.csv")
    assert header == ["time", *sc.system.output_names]
    assert all(name.count(".") == 1 for name in header[1:])
    assert table.shape == (81, len(header))  # output_step 2.5e-4 over 0.02 s
    assert table[0, 0] == 0.0 and table[-1, 0] == pytest.approx(0.02)
    assert table[0, header.index("rotor.x")] == pytest.approx(2e-5)

    rep = json.loads((out / "report.json").read_text())
    assert set(rep) >= REPORT_KEYS
    assert rep["scenario"] == "jeffcott_rigid_stator"
    assert rep["engine"] == "fast"
    assert rep["status"] == "ok"
    assert rep["t_end"] == 0.02
    assert rep["wall_time_s"] > 0.0
    assert isinstance(rep["n_events"], int) and isinstance(rep["n_impacts"], int)
    assert rep["n_impacts"] >= 1  # the disc reaches the stator within 0.02 s
    assert set(rep["final_state"]) == set(sc.system.state_names)
    params = rep["parameters"]
    for role, unit in sc.system.units.items():
        assert params[f"{role}.type"] == unit.type
        for p in UNIT_TYPES[role][unit.type]:
            assert f"{role}.{p.name}" in params, f"{role}.{p.name}"
    for key in SIM_DEFAULTS:
        assert f"sim.{key}" in params, key
    assert params["rotor.x0"] == 2e-5
    assert params["sim.t_end"] == 0.02
    assert params["sim.engine"] == "fast"
    assert params["rotor.mass"] == 10.0
    assert params["stator.friction"] == 0.15


def test_cli_csv_columns_follow_record(tmp_path, capsys):
    path = write(tmp_path, OSC_DATA)
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out)]) == 0
    header, table = read_csv(out / "results.csv")
    assert header == ["time", "oscillator.x", "oscillator.v"]
    assert table.shape == (501, 3)
    assert table[0, 1] == 0.5


@pytest.mark.parametrize(
    ("file_engine", "cli_engine"), [("fast", "accurate"), ("accurate", "fast")]
)
def test_cli_engine_overrides_scenario(tmp_path, capsys, file_engine, cli_engine):
    path = write(tmp_path, changed(OSC_DATA, (("sim", "engine"), file_engine)))
    out = tmp_path / "out"
    assert main(["run", str(path), "--engine", cli_engine, "--out", str(out)]) == 0
    assert f"{cli_engine} engine" in capsys.readouterr().out
    rep = json.loads((out / "report.json").read_text())
    assert rep["engine"] == cli_engine
    assert rep["parameters"]["sim.engine"] == cli_engine


def test_cli_set_engine_without_flag(tmp_path, capsys):
    out = tmp_path / "out"
    assert (
        main(
            [
                "run",
                str(LINEAR_OSC),
                "--set",
                OSC_SHORT,
                "--set",
                "sim.engine=accurate",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert json.loads((out / "report.json").read_text())["engine"] == "accurate"


BAD_SETS = [
    ("rotor.mass=-1", ["rotor.mass", "(0, inf]"]),
    ("stator.restitution=1.5", ["stator.restitution", "[0, 1]"]),
    ("rotor.masss=1", ["rotor.masss"]),
    ("sim.tend=1", ["sim.tend"]),
    ("sim.t_end=-1", ["sim.t_end"]),
    ("bearing.clearance=1e-4", ["bearing.clearance"]),
    ("rotor.x0=1", ["rotor.x0"]),
    ("nonsense", ["nonsense"]),
]


@pytest.mark.parametrize(("override", "expected"), BAD_SETS, ids=[b[0] for b in BAD_SETS])
def test_cli_bad_set_exits_2_and_writes_nothing(tmp_path, capsys, override, expected):
    out = tmp_path / "out"
    before = sorted(tmp_path.iterdir())
    rc = main(["run", str(RIGID), "--set", ROTOR_SHORT, "--set", override, "--out", str(out)])
    captured = capsys.readouterr()
    assert rc == EXIT_BAD_INPUT == 2
    one_error_line(captured.err, *expected)
    assert captured.out == ""
    assert not out.exists()
    assert sorted(tmp_path.iterdir()) == before


def test_cli_oscillator_restitution_exits_2(tmp_path, capsys):
    out = tmp_path / "out"
    rc = main(["run", str(LINEAR_OSC), "--set", "oscillator.restitution=1.5", "--out", str(out)])
    assert rc == 2
    one_error_line(capsys.readouterr().err, "oscillator.restitution", "[0, 1]")
    assert not out.exists()


@pytest.mark.parametrize(
    ("content", "expected"),
    [
        (None, ["missing.toml"]),
        ("[sim\n", ["case.toml", "TOML"]),
        (toml_text(changed(OSC_DATA, (("sim", "rtol"), 2.0))), ["sim.rtol"]),
        (toml_text(changed(OSC_DATA, (("plots", "orbit"), ["oscillator.x"]))), ["plots.orbit"]),
        (
            toml_text(changed(OSC_DATA, (("units", "oscillator", "restitution"), 1.5))),
            ["oscillator.restitution"],
        ),
    ],
    ids=["missing", "invalid_toml", "rtol", "orbit", "restitution"],
)
def test_cli_bad_scenario_exits_2(tmp_path, capsys, content, expected):
    path = tmp_path / "missing.toml" if content is None else write(tmp_path, content)
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out)]) == 2
    captured = capsys.readouterr()
    one_error_line(captured.err, *expected)
    assert not out.exists()


def test_cli_bad_input_leaves_old_result_untouched(tmp_path, capsys):
    path = write(tmp_path, OSC_DATA)
    out = tmp_path / "out"
    assert main(["run", str(path), "--set", "sim.t_end=2.0", "--out", str(out)]) == 0
    (out / "notes.txt").write_text("keep me")
    capsys.readouterr()
    before = snapshot(out)
    bad_inputs = [
        [str(path), "--set", "oscillator.restitution=1.5"],
        [str(path), "--set", "oscillator.x0=2.0"],
        [str(path), "--set", "sim.engine=rk4"],
        [str(path), "--set", "no_equals_sign"],
        [str(tmp_path / "absent.toml")],
        [str(write(tmp_path, "not = [valid", "broken.toml"))],
    ]
    parent_before = sorted(tmp_path.iterdir())
    for args in bad_inputs:
        assert main(["run", *args, "--out", str(out)]) == 2, args
        one_error_line(capsys.readouterr().err)
        assert snapshot(out) == before, args
        assert sorted(tmp_path.iterdir()) == parent_before, args


def test_cli_good_run_replaces_old_result(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "stale.txt").write_text("old")
    (out / "results.csv").write_text("old")
    (out / "report.json").write_text("{}")
    assert main(["run", str(LINEAR_OSC), "--set", OSC_SHORT, "--out", str(out)]) == 0
    assert not (out / "stale.txt").exists()
    assert (out / "results.csv").read_text().startswith("time,")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no temporary leftovers


def test_cli_no_plots_writes_results_and_report_only(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", str(LINEAR_OSC), "--set", OSC_SHORT, "--out", str(out), "--no-plots"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["report.json", "results.csv"]
    assert main(["run", str(LINEAR_OSC), "--set", OSC_SHORT, "--out", str(out)]) == 0
    assert {p.name for p in out.iterdir()} >= {"report.json", "results.csv", *PLOT_FILES}


def test_cli_creates_missing_parents(tmp_path, capsys):
    out = tmp_path / "a" / "b" / "out"
    assert main(["run", str(LINEAR_OSC), "--set", OSC_SHORT, "--out", str(out)]) == 0
    assert (out / "report.json").is_file()


def test_cli_simulation_failure_exits_3(tmp_path, capsys):
    out = tmp_path / "out"
    rc = main(["run", str(RIGID), "--set", "sim.max_events=3", "--out", str(out)])
    captured = capsys.readouterr()
    assert rc == EXIT_RUN_FAILED == 3
    assert "simulation failed" in captured.err
    rep = json.loads((out / "report.json").read_text())
    assert rep["status"] == "failed"
    assert "event" in rep["message"]
    assert rep["n_events"] == 3
    assert rep["parameters"]["sim.max_events"] == 3
    assert rep["t_reached"] < rep["t_end"] == 0.5
    header, table = read_csv(out / "results.csv")
    assert header[0] == "time"
    assert table[-1, 0] <= rep["t_reached"] + 1e-12
    assert np.all(np.isfinite(table))
    for name in PLOT_FILES:
        assert (out / name).is_file()


def test_cli_bad_engine_flag(tmp_path, capsys):
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as info:
        main(["run", str(RIGID), "--engine", "rk4", "--out", str(out)])
    assert info.value.code == 2
    assert "--engine" in capsys.readouterr().err
    assert not out.exists()


def test_cli_out_is_existing_file(tmp_path, capsys):
    target = tmp_path / "precious.txt"
    target.write_text("data")
    rc = main(["run", str(LINEAR_OSC), "--set", OSC_SHORT, "--out", str(target)])
    assert target.is_file() and target.read_text() == "data"
    assert rc == 2


@pytest.mark.parametrize("command", ["run", "export-ssp"])
def test_cli_out_that_cannot_be_created_is_refused_before_the_run(tmp_path, capsys, command):
    """An output under a file (its parent cannot be a directory) gets one error naming
    --out, exit code 2 and no traceback, before anything runs (issue 49)."""
    blocker = tmp_path / "a_file"
    blocker.write_text("data")
    out = blocker / ("system.ssp" if command == "export-ssp" else "results")
    args = [command, str(LINEAR_OSC), "--set", OSC_SHORT, "--out", str(out)]
    if command == "export-ssp":
        args = [command, "jeffcott_elastic_stator", "--out", str(out)]
    rc = main(args)
    err = capsys.readouterr().err
    assert rc == 2
    assert f"--out {out}: cannot write in {blocker}" in err
    assert "Traceback" not in err
    assert blocker.read_text() == "data"


def test_cli_out_is_current_directory(tmp_path, capsys, monkeypatch):
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    try:
        rc = main(["run", str(LINEAR_OSC), "--set", OSC_SHORT, "--out", "."])
    finally:
        leftovers = sorted(p.name for p in work.iterdir() if p.name.startswith("."))
    assert leftovers == []
    assert rc in (0, 2)


# --------------------------------------------------------------------------- CLI subprocess


def test_cli_subprocess(tmp_path):
    out = tmp_path / "out"
    good = subprocess.run(
        [
            str(RUBCOSIM),
            "run",
            str(LINEAR_OSC),
            "--set",
            OSC_SHORT,
            "--engine",
            "accurate",
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=300,
    )
    assert good.returncode == 0, good.stderr
    assert "accurate engine" in good.stdout
    for name in ("results.csv", "report.json", *PLOT_FILES):
        assert (out / name).is_file()
    rep = json.loads((out / "report.json").read_text())
    assert rep["engine"] == "accurate"
    assert rep["t_end"] == 5.0
    header, _ = read_csv(out / "results.csv")
    assert header == ["time", "oscillator.x", "oscillator.v", "oscillator.contact"]

    before = snapshot(out)
    bad = subprocess.run(
        [
            str(RUBCOSIM),
            "run",
            str(LINEAR_OSC),
            "--set",
            "oscillator.restitution=1.5",
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=300,
    )
    assert bad.returncode == 2
    one_error_line(bad.stderr, "oscillator.restitution")
    assert bad.stdout == ""
    assert snapshot(out) == before


# ------------------------------------------------------------------ limits, settings as used


@pytest.mark.parametrize(
    ("override", "key"),
    [
        ("sim.max_events=100000000", "sim.max_events"),
        ("sim.output_step=1e-9", "sim.output_step"),
    ],
)
def test_resource_limits_are_checked_before_running(override, key):
    scenario_error(LINEAR_OSC, [override], key)


def test_empty_record_list_is_rejected(tmp_path):
    path = write(tmp_path, changed(OSC_DATA, (("outputs", "record"), [])))
    scenario_error(path, (), "outputs.record")


def test_parameters_record_settings_as_used():
    sc = load_scenario(LINEAR_OSC, ["sim.rtol=1e-9"])
    assert sc.parameters["sim.output_step"] == sc.sim["output_step"] > 0
    assert sc.parameters["sim.atol"] == 1e-9


def test_cli_refuses_to_replace_a_foreign_directory(tmp_path, capsys):
    target = tmp_path / "documents"
    target.mkdir()
    (target / "thesis.tex").write_text("precious")
    rc = main(["run", str(LINEAR_OSC), "--set", OSC_SHORT, "--out", str(target)])
    assert rc == 2
    assert "holds no earlier result" in capsys.readouterr().err
    assert sorted(p.name for p in target.iterdir()) == ["thesis.tex"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["documents"]
