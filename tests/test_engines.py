"""Engines: fast vs accurate on every scenario, published impact-oscillator orbits, delays."""

import importlib
import math
from pathlib import Path

import numpy as np
import pytest

from rubcosim.components.controller import MODULATION_SHAPES, modulation
from rubcosim.reference import build_system, make_unit, simulate
from rubcosim.runner import run_scenario
from rubcosim.scenario import load_scenario

SCENARIOS = sorted((Path(__file__).parents[1] / "scenarios").glob("*.toml"))
# the module, not the function that rubcosim.reference exports under its name
SIM_MODULE = importlib.import_module("rubcosim.reference.simulate")


def relative_errors(a, b):
    """Per output: max |a - b| over the grid divided by max |b|."""
    scale = np.nanmax(np.abs(b.outputs), axis=0)
    scale[scale == 0.0] = 1.0
    return np.nanmax(np.abs(a.outputs - b.outputs), axis=0) / scale


# A chaotic motion amplifies round-off differences by about 1.25 per period: the two
# engines are compared over its first 20 periods only.
SHORTENED = {
    "jeffcott_chaos_control": ["sim.t_end=0.3"],
    "jeffcott_penalty_chaos_control": ["sim.t_end=0.05"],
}
# The chaotic rotor on a stiff penalty stator (100 k): the engines take 221 and 223
# steps over its first three periods and part by 1e-8 in the states at 0.034 s, which
# its Lyapunov exponent (+32 1/s) and the contact stiffness make 1.7e-7 of the
# normal force by 0.05 s.
BOUNDS = {"jeffcott_penalty_chaos_control": 3e-7}


@pytest.mark.parametrize("path", SCENARIOS, ids=lambda p: p.stem)
def test_fast_agrees_with_accurate_on_every_scenario(path):
    scenario = load_scenario(path, SHORTENED.get(path.stem, []))
    fast = run_scenario(scenario, "fast").result
    accurate = run_scenario(scenario, "accurate").result
    assert fast.ok and accurate.ok
    assert not np.isnan(fast.outputs).any()
    errors = relative_errors(fast, accurate)
    worst = int(np.argmax(errors))
    bound = BOUNDS.get(path.stem, 1e-8)
    assert errors[worst] <= bound, f"{fast.output_names[worst]}: {errors[worst]:.3g}"


def test_scenario_list_is_complete():
    names = {p.stem for p in SCENARIOS}
    assert {
        "jeffcott_rigid_stator",
        "jeffcott_offset_rigid_stator",
        "jeffcott_elastic_stator",
        "jeffcott_elastic_casing",
        "two_mass_oilfilm_rub",
        "jeffcott_delayed_feedback",
        "impact_oscillator_linear",
        "impact_oscillator_symmetric",
        "impact_duffing",
    } <= names


# Budd & Dux (1994): x'' + x = cos(w t), stop at x = 0, r = 0.8; impact speed of
# the (1, n) orbit, n forcing periods between impacts.
BUDD_DUX = [(1.5, 1, 1.52708), (2.0, 1, 4.0 / (3.0 * 0.2)), (4.0, 2, 2.6667), (6.0, 3, 1.7143)]


@pytest.mark.parametrize("w,n,speed", BUDD_DUX)
def test_linear_impact_oscillator_reaches_published_orbits(w, n, speed):
    osc = make_unit(
        "oscillator",
        "impact_oscillator",
        dict(
            linear_stiffness=1.0,
            forcing_amplitude=1.0,
            forcing_frequency=w,
            barrier=0.0,
            restitution=0.8,
            x0=-1.0,
        ),
    )
    period = 2 * math.pi / w
    res = simulate(
        build_system({"oscillator": osc}),
        300 * period,
        output_step=period,
        engine="fast",
        rtol=1e-11,
    )
    assert res.ok
    impacts = res.events.of_kind("impact")
    pre_impact_speed = res.events.state[impacts, 1] / -0.8
    assert pre_impact_speed[-1] == pytest.approx(speed, rel=2e-4 if speed != 4.0 / 0.6 else 1e-9)
    assert np.diff(res.events.t[impacts][-5:]) == pytest.approx(n * period, rel=1e-9)


def duffing(x0):
    osc = make_unit(
        "oscillator",
        "impact_oscillator",
        dict(
            linear_stiffness=1.0,
            damping=0.1,
            cubic_stiffness=1.0,
            forcing_amplitude=1.0,
            forcing_frequency=2.0,
            barrier=1.0,
            restitution=0.8,
            x0=x0,
        ),
    )
    period = math.pi
    t_eval = period * np.arange(150, 200)
    return simulate(
        build_system({"oscillator": osc}), 200 * period, t_eval=t_eval, engine="fast"
    ), period


def test_impact_duffing_has_coexisting_impacting_and_free_period_one_orbits():
    hit, period = duffing(-2.0)
    free, _ = duffing(0.0)
    for res in (hit, free):
        assert res.ok
        x = res.output("oscillator.x")
        assert np.ptp(x) < 1e-9  # period 1 on the stroboscopic section
    late_hits = hit.events.t[hit.events.t > 150 * period]
    assert len(late_hits) == 50  # one impact per period
    assert free.counters["impacts"] == 0
    assert abs(hit.output("oscillator.x")[-1] - free.output("oscillator.x")[-1]) > 0.1


M, K, Z, D = 10.0, 1.0e6, 0.05, 1.0e-4
WN = math.sqrt(K / M)


def whirl_rotor(s, **extra):
    w = s * WN
    amp = 0.5 * D * s * s / math.hypot(1 - s * s, 2 * Z * s)
    ph = math.atan2(2 * Z * s, 1 - s * s)
    params = dict(
        mass=M,
        damping=2 * Z * M * WN,
        stiffness=K,
        eccentricity=0.5 * D,
        speed=w,
        x0=amp * math.cos(ph),
        y0=-amp * math.sin(ph),
        vx0=amp * w * math.sin(ph),
        vy0=amp * w * math.cos(ph),
    )
    params.update(extra)
    return make_unit("rotor", "jeffcott", params), w, amp


@pytest.mark.parametrize("feedback", ["position", "velocity"])
def test_pyragas_force_vanishes_on_a_delay_periodic_orbit(feedback):
    rotor, w, amp = whirl_rotor(0.7)
    period = 2 * math.pi / w
    gain = 1e5 if feedback == "position" else 300.0
    ctl = make_unit(
        "controller",
        "delayed_feedback",
        dict(gain=gain, delay_periods=1, t_on=2 * period, feedback=feedback),
    )
    res = simulate(
        build_system({"rotor": rotor, "controller": ctl}),
        8 * period,
        output_step=period / 50,
        engine="fast",
        rtol=1e-12,
    )
    assert res.ok
    u = np.hypot(res.output("controller.ux"), res.output("controller.uy"))
    scale = gain * amp * (1.0 if feedback == "position" else w)
    assert np.all(u <= 1e-8 * scale)


def test_delay_history_reaches_back_past_the_start_and_across_many_steps():
    # delay of 1.5 periods, control on from t = 0: before t = tau the delayed
    # state is the initial state, after it the recorded trajectory itself.
    rotor, w, amp = whirl_rotor(0.7, x0=0.0, y0=0.0, vx0=0.0, vy0=0.0)
    tau = 1.5 * 2 * math.pi / w
    gain = 2e5
    ctl = make_unit("controller", "delayed_feedback", dict(gain=gain, delay=tau))
    system = build_system({"rotor": rotor, "controller": ctl})
    step = tau / 150
    res = simulate(system, 4 * tau, output_step=step, engine="accurate", rtol=1e-12)
    assert res.ok and res.counters["steps"] > 100
    x = res.output("rotor.x")
    ux = res.output("controller.ux")
    before = res.t < tau - 1e-12
    assert np.allclose(ux[before], gain * (0.0 - x[before]), rtol=0, atol=1e-9 * gain * amp)
    lag = 150
    assert np.allclose(ux[lag:], gain * (x[:-lag] - x[lag:]), rtol=0, atol=1e-8 * gain * amp)


@pytest.mark.parametrize("shape", ["sine", "sawtooth", "telegraph"])
@pytest.mark.parametrize("engine", ["fast", "accurate"])
def test_variable_delay_uses_the_modulated_delay(engine, shape):
    rotor, w, amp = whirl_rotor(0.7, x0=0.0, y0=0.0, vx0=0.0, vy0=0.0)
    period = 2 * math.pi / w
    eps, nu, gain = 0.2 * period, 3.0, 2e5
    ctl = make_unit(
        "controller",
        "delayed_feedback",
        dict(
            gain=gain,
            delay_periods=1,
            modulation_amplitude=eps,
            modulation_frequency=nu,
            modulation_shape=shape,
            modulation_seed=3,
            t_on=3 * period,
        ),
    )
    system = build_system({"rotor": rotor, "controller": ctl})
    t = np.linspace(4 * period, 6 * period, 97)
    res = simulate(system, 6 * period, t_eval=t, engine=engine, rtol=1e-12)
    # the recorded times do not change the steps: read x at t - tau(t) from a second run
    code = MODULATION_SHAPES.index(shape)
    f = np.array([modulation(ti, nu, code, 3) for ti in t])  # checked in test_etdas.py
    t_delayed = t - (period + eps * f)
    order = np.argsort(t_delayed)
    res_d = simulate(system, 6 * period, t_eval=t_delayed[order], engine=engine, rtol=1e-12)
    x_delayed = np.empty_like(t)
    x_delayed[order] = res_d.output("rotor.x")
    expected = gain * (x_delayed - res.output("rotor.x"))
    assert np.allclose(res.output("controller.ux"), expected, rtol=0, atol=1e-9 * gain * amp)


def test_impacts_with_delay_feedback_agree_between_engines():
    scenario = load_scenario(
        Path(__file__).parents[1] / "scenarios" / "jeffcott_delayed_feedback.toml",
        ["sim.t_end=0.3"],
    )
    fast = run_scenario(scenario, "fast").result
    accurate = run_scenario(scenario, "accurate").result
    assert fast.counters["impacts"] == accurate.counters["impacts"] > 0
    assert relative_errors(fast, accurate).max() <= 1e-8


def test_simulate_rejects_bad_arguments():
    rotor, _, _ = whirl_rotor(0.7)
    system = build_system({"rotor": rotor})
    with pytest.raises(ValueError, match="engine"):
        simulate(system, 1.0, engine="euler")
    with pytest.raises(ValueError, match="sim.t_end"):
        simulate(system, 0.0)
    with pytest.raises(ValueError, match="sim.rtol"):
        simulate(system, 1.0, rtol=1e-20)
    with pytest.raises(ValueError, match="sim.atol"):
        simulate(system, 1.0, atol=0.0)


@pytest.mark.parametrize("engine", ["fast", "accurate"])
def test_grazing_contact_inside_one_step_is_found(engine):
    # free linear oscillator x = -A cos(t) (no forcing, no damping) and a barrier
    # 1e-4 below its peak: the contact would last 0.028 s, far shorter than the
    # ~0.3 s steps DOP853 takes here, and the gap does not change sign between
    # step ends.  The extremum of the gap must be found and checked.
    amp = 1.0
    osc = make_unit(
        "oscillator",
        "impact_oscillator",
        dict(
            linear_stiffness=1.0,
            forcing_frequency=1.0,
            barrier=amp - 1e-4,
            restitution=1.0,
            x0=-amp,
        ),
    )
    res = simulate(
        build_system({"oscillator": osc}), 4.0, output_step=0.5, engine=engine, rtol=1e-8
    )
    assert res.ok
    assert res.counters["steps"] < 40  # big steps indeed
    assert res.counters["impacts"] == 1
    # first touch where -cos(t) = 1 - 1e-4
    assert res.events.t[0] == pytest.approx(math.pi - math.acos(1 - 1e-4), abs=1e-5)


def test_output_grid_ends_exactly_at_t_end():
    from rubcosim.reference import output_grid

    grid = output_grid(0.0, 1.0, 0.3)
    assert grid[0] == 0.0 and grid[-1] == 1.0
    assert np.allclose(np.diff(grid[:-1]), 0.3)
    assert output_grid(0.0, 1.0, 0.25)[-1] == 1.0
    assert len(output_grid(0.0, 1.0, 0.25)) == 5


@pytest.mark.parametrize("stop", ["elastic_one_sided", "elastic_two_sided"])
def test_piecewise_linear_stop_contact_duration(stop):
    # x'' + x = 0, stop of stiffness k2 beyond |x| = D: inside the stop the
    # motion is harmonic at w2 = sqrt(1 + k2) about x_e = k2 D / (1 + k2);
    # entering at x = D with speed v, the contact lasts 2 atan2(v / w2, D - x_e) / w2.
    amp, barrier, k2 = 1.0, 0.6, 50.0
    osc = make_unit(
        "oscillator",
        "impact_oscillator",
        dict(
            linear_stiffness=1.0,
            forcing_frequency=1.0,
            barrier=barrier,
            stop=stop,
            stop_stiffness=k2,
            v0=amp,
        ),
    )
    res = simulate(
        build_system({"oscillator": osc}), 20.0, output_step=0.05, engine="fast", rtol=1e-12
    )
    assert res.ok
    on = res.events.t[res.events.of_kind("contact_on")]
    off = res.events.t[res.events.of_kind("contact_off")]
    w2 = math.sqrt(1 + k2)
    v = math.sqrt(amp**2 - barrier**2)
    expected = 2 * math.atan2(v / w2, barrier - k2 * barrier / (1 + k2)) / w2
    assert len(on) >= 3 and len(off) >= 3
    assert off[: len(on)] - on[: len(off)] == pytest.approx(expected, rel=1e-9)
    if stop == "elastic_two_sided":
        assert np.any(res.events.slot == 2)  # the lower stop is hit too
    assert np.all(np.abs(res.output("oscillator.x")) <= amp + 1e-9)  # no energy gained


def test_a_reused_event_log_leaves_every_result_its_own_events():
    # simulate keeps the event log between runs (reference/simulate.py): a result must
    # hold copies, and a run on a log full of an earlier run's events must log exactly
    # what a run on a new log does
    def oscillator(x0):
        unit = make_unit(
            "oscillator",
            "impact_oscillator",
            dict(linear_stiffness=1.0, forcing_frequency=1.0, barrier=0.5, restitution=0.8, x0=x0),
        )
        return build_system({"oscillator": unit})

    first = simulate(oscillator(-1.0), 20.0, engine="fast", rtol=1e-9)
    kept = {k: getattr(first.events, k).copy() for k in ("t", "kind", "slot", "mode", "state")}
    assert len(first.events.t) > 3
    log = SIM_MODULE._SPARE_LOGS[(100_000, 2)]
    second = simulate(oscillator(-0.9), 15.0, engine="fast", rtol=1e-9)
    assert SIM_MODULE._SPARE_LOGS[(100_000, 2)] is log  # taken and given back
    for name, values in kept.items():
        np.testing.assert_array_equal(getattr(first.events, name), values)
    SIM_MODULE._SPARE_LOGS.clear()
    fresh = simulate(oscillator(-0.9), 15.0, engine="fast", rtol=1e-9)
    assert len(second.events.t) == len(fresh.events.t) > 2
    for name in kept:
        np.testing.assert_array_equal(getattr(second.events, name), getattr(fresh.events, name))
    assert first.events.t[0] != second.events.t[0]


def test_simulate_keeps_at_most_four_event_logs_the_latest_runs_used():
    rotor, _, _ = whirl_rotor(0.7)
    system = build_system({"rotor": rotor})
    SIM_MODULE._SPARE_LOGS.clear()
    for capacity in (10, 20, 30, 40, 50, 20):
        simulate(system, 1e-4, engine="fast", max_events=capacity)
    assert list(SIM_MODULE._SPARE_LOGS) == [(30, 4), (40, 4), (50, 4), (20, 4)]


def test_a_delay_history_that_overflows_is_grown_and_the_run_redone(monkeypatch):
    # 16 segments hold less than one delay of steps: the first run overflows, simulate
    # grows the history eightfold and runs again on the same event log until it holds;
    # the result is that of a history large enough from the start, events included
    # (the log written from the start again, not appended to)
    scenario = load_scenario(
        Path(__file__).parents[1] / "scenarios" / "jeffcott_delayed_feedback.toml",
        ["sim.t_end=0.25", "controller.t_on=0.05"],
    )

    def run(capacity):
        return simulate(
            scenario.system, 0.25, output_step=1e-3, engine="fast", history_capacity=capacity
        )

    run(1 << 16)  # the process's warm-up run, if not done yet, outside the record below
    new_history = SIM_MODULE.new_history
    made = []

    def recorded(capacity, t_init, y_init):
        made.append(capacity)
        return new_history(capacity, t_init, y_init)

    monkeypatch.setattr(SIM_MODULE, "new_history", recorded)
    grown = run(16)
    tries, made[:] = list(made), []
    large = run(1 << 16)
    assert tries[0] == 16 and len(tries) > 1 and made == [1 << 16]
    assert all(b == 8 * a for a, b in zip(tries, tries[1:], strict=False))
    assert grown.ok and large.ok and large.counters["impacts"] > 0
    assert grown.counters == large.counters
    np.testing.assert_array_equal(grown.outputs, large.outputs)
    for field in ("t", "kind", "slot", "mode", "state"):
        np.testing.assert_array_equal(getattr(grown.events, field), getattr(large.events, field))
    # the control force is on, so the delayed state was read from the history
    assert np.nanmax(np.abs(large.output("controller.ux"))) > 0.0
