"""The compiled master against the Python master: same algorithm, same numbers.

Second-method checks: the two masters are separate implementations of one
algorithm (the Python one steps the unit objects, the compiled one the unit rows of
``components/flat_units.py``).  On every scenario the compiled master can run, and
on the master's variants (Jacobi, lower extrapolation orders, fixed steps with
iteration, events at communication points, no events, DOP853 unit steps, a
failure), both must give the same recorded outputs to 1e-12, the same events and
the same counters.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from rubcosim.orchestrator.assembly import run_cosim
from rubcosim.orchestrator.cosim_result import CosimError
from rubcosim.orchestrator.settings import SettingsError, cosim_settings
from rubcosim.scenario import load_scenario

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"

CASES = [
    ("jeffcott_rigid_stator", 0.12, {}),
    ("jeffcott_offset_rigid_stator", 0.1, {}),
    ("jeffcott_elastic_stator", 0.05, {}),
    ("jeffcott_elastic_casing", 0.08, {}),
    ("two_mass_oilfilm_rub", 0.08, {}),
    ("jeffcott_rigid_stator", 0.05, {"algorithm": "jacobi", "extrapolation": 1}),
    ("jeffcott_rigid_stator", 0.01, {"extrapolation": 0}),
    ("jeffcott_elastic_casing", 0.04, {"adaptive": False, "iterations": 3}),
    ("jeffcott_rigid_stator", 0.05, {"adaptive": False, "events": "step"}),
    ("jeffcott_elastic_stator", 0.03, {"events": "off"}),
    ("two_mass_oilfilm_rub", 0.03, {"unit_integrator": "dop853"}),
    ("impact_duffing", 10.0, {}),
    ("two_dof_impact_oscillator", 40.0, {}),
    # the controller: Pyragas velocity feedback, switched on at 0.166 s, through impacts
    ("jeffcott_delayed_feedback", 0.3, {}),
    # ETDAS on position, a sine-modulated delay (a signal continuous at the impacts)
    (
        "jeffcott_delayed_feedback",
        0.12,
        {
            "set": [
                "controller.memory=0.4",
                'controller.feedback="position"',
                "controller.t_on=0.02",
                "controller.modulation_amplitude=2e-3",
                "controller.modulation_frequency=40.0",
            ]
        },
    ),
    # ETDAS on velocity, a sawtooth delay (the filter's own jumps), penalty contact
    (
        "jeffcott_penalty_chaos_control",
        0.08,
        {
            "set": [
                "controller.memory=0.5",
                "controller.t_on=0.02",
                "controller.modulation_amplitude=2e-3",
                "controller.modulation_frequency=60.0",
                'controller.modulation_shape="sawtooth"',
            ]
        },
    ),
]


def _both(name: str, t_end: float, settings: dict):
    settings = dict(settings)
    overrides = [f"sim.t_end={t_end}", *settings.pop("set", [])]
    if "unit_integrator" in settings:  # a unit parameter set from the settings
        overrides.append(f'cosim.unit_integrator="{settings["unit_integrator"]}"')
    sc = load_scenario(SCENARIOS / f"{name}.toml", overrides)
    python = run_cosim(sc, replace(sc.cosim, master="python", **settings))
    compiled = run_cosim(sc, replace(sc.cosim, master="compiled", **settings))
    return python, compiled


@pytest.mark.parametrize("name,t_end,settings", CASES)
def test_compiled_master_equals_the_python_master(name, t_end, settings):
    python, compiled = _both(name, t_end, settings)
    _assert_same(python, compiled, t_end)


def test_a_replay_from_the_checkpoint_restores_the_controllers_history():
    # fixed steps: a crossing the indicators did not announce is replayed from the
    # checkpoint, whose copy of the history the compiled master restores
    overrides = ["controller.t_on=0.02", "controller.memory=0.3", "stator.x_offset=6e-5",
                 "stator.friction=0.15"]  # fmt: skip
    settings = {"adaptive": False, "step": 1e-4, "set": overrides}
    python, compiled = _both("jeffcott_chaos_control", 0.2, settings)
    assert python.counters["replays"] > 5
    _assert_same(python, compiled, 0.2)


def _assert_same(python, compiled, t_end):
    assert python.ok and compiled.ok, (python.message, compiled.message)
    assert (python.master, compiled.master) == ("python", "compiled")
    assert compiled.counters == python.counters
    assert compiled.event_kind == python.event_kind
    assert compiled.event_unit == python.event_unit
    np.testing.assert_allclose(compiled.event_t, python.event_t, rtol=0, atol=1e-12 * t_end)
    assert compiled.values.shape == python.values.shape
    scale = np.max(np.abs(python.values), axis=0) + 1e-300
    assert np.max(np.abs(compiled.values - python.values) / scale) <= 1e-12


def test_compiled_master_fails_where_the_python_master_fails_with_the_same_reason():
    sc = load_scenario(SCENARIOS / "two_mass_oilfilm_rub.toml")
    h = sc.system.forcing_period / 100  # far too coarse for the oil film
    fixed = replace(sc.cosim, adaptive=False, step=h)
    python = run_cosim(sc, replace(fixed, master="python"), record=["rotor.x"])
    compiled = run_cosim(sc, replace(fixed, master="compiled"), record=["rotor.x"])
    assert python.status == compiled.status == "failed"
    assert compiled.t_reached == python.t_reached
    assert compiled.counters == python.counters
    assert "bearing wall" in compiled.message and "bearing" in python.message
    np.testing.assert_array_equal(compiled.values, python.values)


def test_the_master_setting_is_validated_and_compiled_names_what_it_cannot_run(built_fmus):
    assert cosim_settings({"master": "compiled"}).master == "compiled"
    with pytest.raises(SettingsError, match=r"cosim\.master"):
        cosim_settings({"master": "numba"})
    sc = load_scenario(
        SCENARIOS / "jeffcott_rigid_stator.toml", ["sim.t_end=0.002", 'cosim.fmu_units=["stator"]']
    )
    fmu_dir = next(iter(built_fmus.values())).parent
    with pytest.raises(CosimError, match="unit stator is an FMU"):
        run_cosim(sc, replace(sc.cosim, master="compiled"), fmu_dir=fmu_dir)
    # auto falls back to the Python master for FMUs, and says so
    fallback = run_cosim(sc, replace(sc.cosim, master="auto"), fmu_dir=fmu_dir)
    assert fallback.ok and fallback.master == "python"


def test_controller_histories_that_outgrow_their_buffers_give_the_same_run(monkeypatch):
    # buffers of 64 rows: they grow (doubling) and their rows move to the front (when
    # the delay's worth of history fits) many times in the run; nothing may change
    from rubcosim.orchestrator import flat_master

    monkeypatch.setattr(flat_master, "HISTORY_ROWS", 64)
    python, compiled = _both("jeffcott_delayed_feedback", 0.2, {"set": ["controller.t_on=0.01"]})
    assert python.ok and compiled.ok, (python.message, compiled.message)
    assert compiled.counters == python.counters and compiled.counters["events_impact"] > 5
    np.testing.assert_array_equal(compiled.values, python.values)


@pytest.mark.parametrize(
    "name, overrides, unit_class",
    [
        # a linear oscillator pushed onto its stop: chattering, then stuck (mode 1)
        ("impact_oscillator_linear", ["oscillator.barrier=-0.5",
         "oscillator.forcing_amplitude=0.2", "oscillator.restitution=0.5"], "single"),
        ("two_dof_impact_oscillator", [], "two_dof"),
    ],
)  # fmt: skip
def test_compiled_master_gives_every_output_of_a_hybrid_unit(name, overrides, unit_class):
    # impacts counted, the mode, and the outputs that follow the mode ("stuck")
    from rubcosim.components.oscillator_unit import ImpactOscillatorUnit
    from rubcosim.components.two_dof_oscillator import TwoDofImpactOscillatorUnit

    cls = ImpactOscillatorUnit if unit_class == "single" else TwoDofImpactOscillatorUnit
    sc = load_scenario(SCENARIOS / f"{name}.toml", ["sim.t_end=20.0", *overrides])
    record = [f"oscillator.{s.name}" for s in cls.outputs]
    python = run_cosim(sc, replace(sc.cosim, master="python"), record=record)
    compiled = run_cosim(sc, replace(sc.cosim, master="compiled"), record=record)
    assert (python.master, compiled.master) == ("python", "compiled")
    assert python.ok and compiled.ok and compiled.counters == python.counters
    np.testing.assert_array_equal(compiled.values, python.values)
    values = dict(zip(record, python.values.T, strict=True))
    assert values["oscillator.impacts"][-1] > 5 and values["oscillator.mode"].max() == 1
    if "oscillator.stuck" in values:
        assert values["oscillator.stuck"].max() == 1
