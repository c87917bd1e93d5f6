"""Extended delayed feedback (ETDAS) and variable delays: closed forms, a brute-force
root scan, the reduction to plain Pyragas feedback, and the two engines and the
co-simulation against each other."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import rubcosim as rc
from rubcosim.components.controller import (
    MODULATION_SHAPES,
    PIECE_TOL,
    SHAPE_SAWTOOTH,
    SHAPE_SINE,
    SHAPE_TELEGRAPH,
    delay_at,
    delayed_arrivals,
    modulation,
    telegraph_sign,
)
from rubcosim.components.parameters import ParameterError
from rubcosim.components.units import make_unit
from rubcosim.consistency import compare
from rubcosim.reference import build_system, simulate
from rubcosim.reference import make_unit as make_reference_unit

SCENARIO = Path(__file__).parents[1] / "scenarios" / "jeffcott_delayed_feedback.toml"


def table(res) -> np.ndarray:
    """Every recorded output of a scenario run, one column each."""
    return np.column_stack([res[name] for name in res.names])


# ---------------------------------------------------------------- modulations
def test_periodic_modulations_have_zero_mean_and_unit_range():
    nu = 3.0
    t = np.linspace(0.0, 2 * math.pi / nu, 200001)[:-1]  # one period, uniform
    for shape in (SHAPE_SINE, SHAPE_SAWTOOTH):
        f = np.array([modulation(ti, nu, shape, 0) for ti in t])
        assert abs(f.mean()) < 1e-4
        assert f.min() == pytest.approx(-1.0, abs=1e-4) and f.max() == pytest.approx(1.0, abs=1e-4)
    # the sawtooth is a ramp of slope nu / pi between its jumps at 2 pi m / nu
    ramp = np.array([modulation(ti, nu, SHAPE_SAWTOOTH, 0) for ti in t])
    assert np.allclose(ramp, nu * t / math.pi - 1.0, atol=1e-12)


def test_telegraph_signs_are_balanced_and_uncorrelated():
    nu, n = 1.0, 20000
    # one sample in the middle of each interval of length pi / nu
    f = np.array([modulation((k + 0.5) * math.pi / nu, nu, SHAPE_TELEGRAPH, 7) for k in range(n)])
    assert set(np.unique(f)) == {-1.0, 1.0}
    # a fair coin: the mean and the lag-1 correlation within 4 standard deviations
    assert abs(f.mean()) < 4 / math.sqrt(n)
    assert abs(np.mean(f[1:] * f[:-1])) < 4 / math.sqrt(n)
    other = np.array([modulation((k + 0.5) * math.pi, nu, SHAPE_TELEGRAPH, 8) for k in range(n)])
    assert abs(np.mean(f * other)) < 4 / math.sqrt(n)  # another seed, another sequence


def closed_form_delay(s, tau0, eps, nu, shape, seed):
    """tau(s) on an array, written out from the definitions (a second implementation)."""
    if shape == "sine":
        return tau0 + eps * np.sin(nu * s)
    width = (2 if shape == "sawtooth" else 1) * math.pi / nu
    k = np.floor(s / width + PIECE_TOL)
    if shape == "sawtooth":
        return tau0 + eps * (2 * (s / width - k) - 1)
    pieces, where = np.unique(k, return_inverse=True)
    signs = np.array([telegraph_sign(int(i), seed) for i in pieces])
    return tau0 + eps * signs[where]


@pytest.mark.parametrize("shape", MODULATION_SHAPES)
def test_delayed_arrivals_are_every_root_of_the_delayed_time(shape):
    # second method: a dense scan of g(s) = s - tau(s) - tj for sign changes
    code = MODULATION_SHAPES.index(shape)
    tau0, nu = 1.0, 2.5
    eps = 0.3 if shape == "sine" else 0.9  # eps nu < 1 (sine), < pi (the others)
    rng = np.random.default_rng(3)
    out = np.empty(4)
    found_twice = 0
    for tj in rng.uniform(0.0, 20.0, 200):
        n = delayed_arrivals(tj, tau0, eps, nu, code, 5, out)
        s = np.linspace(tj + tau0 - eps - 1e-3, tj + tau0 + eps + 1e-3, 200001)
        g = s - closed_form_delay(s, tau0, eps, nu, shape, 5) - tj
        # a root is a change of sign with g continuous: not across a jump of tau
        cross = np.flatnonzero((g[:-1] < 0) & (g[1:] >= 0) & (g[1:] - g[:-1] < 1e-3))
        assert n == cross.size, (tj, out[:n], s[cross])
        assert np.allclose(out[:n], s[cross], atol=2 * (s[1] - s[0]))
        for root in out[:n]:
            assert root - delay_at(root, tau0, eps, nu, code, 5) == pytest.approx(tj, abs=1e-12)
        found_twice += n > 1
    # a telegraph switch that lengthens the delay makes some jumps arrive twice
    assert (found_twice > 0) == (shape == "telegraph")


# ---------------------------------------------------------------- parameters
def controller_units(**given):
    rotor = make_reference_unit("rotor", "jeffcott", dict(ROTOR))
    return {
        "rotor": rotor,
        "controller": make_reference_unit("controller", "delayed_feedback", {"gain": 1e4, **given}),
    }


@pytest.mark.parametrize("memory", [1.0, -0.1, 1.5])
def test_memory_outside_its_range_names_the_key(memory):
    with pytest.raises(ParameterError, match=r"controller\.memory.*\[0, 1\)"):
        build_system(controller_units(memory=memory))


def test_telegraph_switching_faster_than_its_amplitude_is_refused():
    given = dict(delay=0.01, modulation_amplitude=0.004, modulation_shape="telegraph")
    build_system(controller_units(**given, modulation_frequency=700.0))  # 2.8 < pi
    with pytest.raises(ParameterError, match="modulation_frequency must be < pi"):
        build_system(controller_units(**given, modulation_frequency=800.0))


# ---------------------------------------------------------------- closed forms
M, K, Z, E = 10.0, 1.0e6, 0.05, 2.0e-5
WN = math.sqrt(K / M)
W = 0.8 * WN
ROTOR = dict(mass=M, damping=2 * Z * M * WN, stiffness=K, eccentricity=E, speed=W)


def steady_whirl_radius(gain, tau, memory):
    """Radius of the forced whirl of a Jeffcott rotor under ETDAS position feedback:
    x + i y = X e^(i w t) with S = G X, G = (1 - R) e^(-i w tau) / (1 - R e^(-i w tau))."""
    lag = np.exp(-1j * W * tau)
    g = (1 - memory) * lag / (1 - memory * lag)
    return abs(M * E * W**2 / (K - M * W**2 + 1j * 2 * Z * M * WN * W - gain * (g - 1)))


@pytest.mark.parametrize("memory", [0.0, 0.6])
@pytest.mark.parametrize("engine", ["fast", "accurate"])
def test_etdas_forced_whirl_follows_the_closed_form(engine, memory):
    # a delay that is no multiple of the period: the force stays on, and the
    # filter's infinite sum sets the whirl radius; transients die as e^(-Z WN t)
    # and R^(t / tau)
    gain, tau = 0.1 * K, 0.37 * 2 * math.pi / W
    units = controller_units(delay=tau, memory=memory, gain=gain)
    period = 2 * math.pi / W
    t = np.linspace(60 * period, 61 * period, 41)
    res = simulate(build_system(units), t[-1], t_eval=t, engine=engine, rtol=1e-11)
    assert res.ok
    radius = np.hypot(res.output("rotor.x"), res.output("rotor.y"))
    want = steady_whirl_radius(gain, tau, memory)
    assert np.allclose(radius, want, rtol=1e-7, atol=0)
    # the closed form differs between R = 0 and 0.6 by far more than the tolerance
    assert abs(steady_whirl_radius(gain, tau, 0.6) / steady_whirl_radius(gain, tau, 0.0) - 1) > 0.01


def test_etdas_unit_follows_the_closed_form_of_a_sampled_sine():
    # the co-simulation unit fed z = A sin(w t): u -> K A Im[(G - 1) e^(i w t)]; the
    # delay is no multiple of the step, so every lookup interpolates
    gain, tau, w, amp, memory = 1e5, 2.037e-3, 1000.0, 1e-5, 0.5
    unit = make_unit(
        "controller", "delayed_feedback", gain=gain, delay=tau, memory=memory, speed=0.0
    )
    h = 1e-4
    lag = np.exp(-1j * w * tau)
    g = (1 - memory) * lag / (1 - memory * lag)
    errors = []
    for i in range(2000):
        t = i * h
        unit.set_inputs({"x": amp * math.sin(w * t)})
        unit.do_step(t, h)
        t += h
        unit.set_inputs({"x": amp * math.sin(w * t)})
        if t > 60 * tau:  # R^60 ~ 1e-18: the constant initial function is forgotten
            want = gain * amp * ((g - 1) * np.exp(1j * w * t)).imag
            errors.append(abs(unit.get_outputs()["ux"] - want))
    assert len(errors) > 500
    # cubic interpolation of samples 0.1 rad apart: (w h)^4 / 24 ~ 4e-6 of K A
    assert max(errors) < 1e-5 * gain * amp


def test_etdas_unit_carries_a_jump_of_its_input_one_delay_at_a_time():
    # z = sin(w t) + 0.5 H(t - tj): S jumps by (1 - R) R^(k-1) 0.5 at tj + k tau; the
    # unit records each jump as two samples, so its force follows the closed sum
    gain, tau, w, memory, tj = 1.0, 2.037e-3, 1000.0, 0.5, 0.05033

    def z(t):
        return (math.sin(w * t) + (0.5 if t >= tj else 0.0)) if t >= 0 else 0.0

    def filtered(t):
        return (1 - memory) * sum(memory ** (k - 1) * z(t - k * tau) for k in range(1, 80))

    unit = make_unit(
        "controller", "delayed_feedback", gain=gain, delay=tau, memory=memory, speed=0.0
    )
    h, t, worst = 1e-4, 0.0, 0.0
    while t < 0.08:
        t_next = tj if t < tj < t + h - 1e-12 else t + h
        unit.set_inputs({"x": z(t)})
        unit.do_step(t, t_next - t)
        if t_next == tj:  # as the orchestrator does at an event: the left limit
            unit.set_inputs({"x": math.sin(w * tj)})
            unit.do_step(tj, 0.0)
        t = t_next
        unit.set_inputs({"x": z(t)})
        if t > tj:
            worst = max(worst, abs(unit.get_outputs()["ux"] - gain * (filtered(t) - z(t))))
    # without the jump samples the error near each arrival is the jump itself (0.25, ...)
    assert worst < 1e-5


# ---------------------------------------------------------------- R = 0 is Pyragas
def test_vanishing_memory_reduces_to_plain_pyragas_bit_for_bit():
    # R = 1e-300 runs the filter (its history, its fit, its blend) and must give
    # exactly the plain feedback: (1 - R) z + R S rounds to z
    plain = rc.simulate(SCENARIO, set={"sim.t_end": 0.25})
    tiny = rc.simulate(SCENARIO, set={"sim.t_end": 0.25, "controller.memory": 1e-300})
    assert plain.counters["impacts"] > 0
    assert np.array_equal(table(plain), table(tiny))
    unit_plain = make_unit("controller", "delayed_feedback", gain=1e5, delay=2e-3, speed=0.0)
    unit_tiny = make_unit(
        "controller", "delayed_feedback", gain=1e5, delay=2e-3, memory=1e-300, speed=0.0
    )
    for i in range(80):
        for unit in (unit_plain, unit_tiny):
            unit.set_inputs({"x": 1e-5 * math.sin(0.1 * i)})
            unit.do_step(i * 1e-4, 1e-4)
            unit.set_inputs({"x": 1e-5 * math.sin(0.1 * (i + 1))})
        assert unit_plain.get_outputs()["ux"] == unit_tiny.get_outputs()["ux"]


@pytest.mark.parametrize("memory", [0.0, 0.5])
@pytest.mark.parametrize("feedback", ["position", "velocity"])
def test_etdas_force_vanishes_on_a_delay_periodic_orbit(feedback, memory):
    # the free whirl is periodic with the forcing: z(t - k T) = z(t) for every k >= 1
    # once t - k T >= 0, so u = 0 but for the filter's memory of the constant initial
    # function before t = 0, which fades as R^(t / T): 2^-40 ~ 1e-12 after 40 periods
    s = 0.7
    w = s * WN
    amp = E * s * s / math.hypot(1 - s * s, 2 * Z * s)
    ph = math.atan2(2 * Z * s, 1 - s * s)
    rotor = make_reference_unit(
        "rotor",
        "jeffcott",
        dict(ROTOR, speed=w, x0=amp * math.cos(ph), y0=-amp * math.sin(ph))
        | dict(vx0=amp * w * math.sin(ph), vy0=amp * w * math.cos(ph)),
    )
    period = 2 * math.pi / w
    gain = 1e5 if feedback == "position" else 300.0
    ctl = make_reference_unit(
        "controller",
        "delayed_feedback",
        dict(gain=gain, delay_periods=1, t_on=2 * period, feedback=feedback, memory=memory),
    )
    system = build_system({"rotor": rotor, "controller": ctl})
    t = np.linspace(40 * period, 48 * period, 401)
    res = simulate(system, t[-1], t_eval=t, engine="fast", rtol=1e-12)
    assert res.ok
    u = np.hypot(res.output("controller.ux"), res.output("controller.uy"))
    scale = gain * amp * (1.0 if feedback == "position" else w)
    assert np.all(u <= 1e-8 * scale)


# ---------------------------------------------------------------- impacts, three ways
VARIANTS = {
    "etdas": {"controller.memory": 0.5},
    "sawtooth": {
        "controller.modulation_shape": "sawtooth",
        "controller.modulation_amplitude": 2e-3,
        "controller.modulation_frequency": 150.0,
    },
    "telegraph_etdas": {
        "controller.memory": 0.3,
        "controller.modulation_shape": "telegraph",
        "controller.modulation_amplitude": 2e-3,
        "controller.modulation_frequency": 300.0,
        "controller.modulation_seed": 11,
    },
}


@pytest.mark.parametrize("variant", VARIANTS)
def test_rub_impact_under_extended_and_variable_feedback_agrees_between_engines(variant):
    given = {"sim.t_end": 0.3, **VARIANTS[variant]}
    fast = rc.simulate(SCENARIO, "fast", set=given)
    accurate = rc.simulate(SCENARIO, "accurate", set=given)
    assert fast.ok and accurate.ok
    assert fast.counters["impacts"] == accurate.counters["impacts"] > 0
    scale = np.nanmax(np.abs(table(accurate)), axis=0)
    scale[scale == 0.0] = 1.0
    assert (np.nanmax(np.abs(table(fast) - table(accurate)), axis=0) / scale).max() <= 1e-7
    # the control force is on and differs from plain Pyragas feedback
    plain = rc.simulate(SCENARIO, "fast", set={"sim.t_end": 0.3})
    assert np.nanmax(np.abs(fast["controller.ux"] - plain["controller.ux"])) > 1.0


def test_cosimulation_of_position_feedback_through_impacts_matches_the_reference():
    # a fed-back position keeps its value at an impact and reverses its slope: the unit
    # records the event's two equal samples, and no stencil spans that kink (spanning it
    # cost 0.6 % of the force and 2.6e-4 of the states; the bounds are the other cases)
    given = {"sim.t_end": 0.15, "controller.feedback": "position", "controller.gain": 1e5,
             "controller.memory": 0.4, "controller.t_on": 0.02}  # fmt: skip
    report, _, _, _ = compare(rc.load(SCENARIO, set=given))
    assert report["status"] == "ok", report["message"]
    assert report["impacts"]["cosim"] == report["impacts"]["reference"] > 0
    assert report["outputs"]["controller.ux"]["reference_max_abs"] > 5.0  # the force is on
    for name, out in report["outputs"].items():
        assert out["max_rel_error"] < (2e-5 if name.startswith("controller.") else 2e-6), name


@pytest.mark.parametrize("variant", ["etdas", "sawtooth"])
def test_cosimulation_of_extended_and_variable_feedback_matches_the_reference(variant):
    # the unit samples z and S at the communication points only: between two jumps
    # of S closer than four samples it interpolates S with fewer points, so its force
    # is looser than the states (measured with ETDAS: 3.3e-5 and 7.7e-7)
    given = {"sim.t_end": 0.2, **VARIANTS[variant]}
    report, _, _, _ = compare(rc.load(SCENARIO, set=given))
    assert report["status"] == "ok", report["message"]
    assert report["impacts"]["cosim"] == report["impacts"]["reference"] > 0
    for name, out in report["outputs"].items():
        bound = 2e-4 if name.startswith("controller.") else 2e-6
        assert out["max_rel_error"] < bound, (name, out)
