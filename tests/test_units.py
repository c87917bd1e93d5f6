"""The co-simulation units stepped in-process (what the FMUs and the direct backend wrap)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rubcosim.components import jit, unit_odes
from rubcosim.components.bearing import oilfilm_force, oilfilm_sigma
from rubcosim.components.catalog import UNIT_TYPES
from rubcosim.components.controller import base_delay
from rubcosim.components.delay_history import FILTER_PAIR, SAMPLE, first_kept
from rubcosim.components.parameters import ParameterError
from rubcosim.components.rotor import free_whirl, jeffcott_force
from rubcosim.components.stator import penalty_contact_force, rigid_impact
from rubcosim.components.stepping import step_ode
from rubcosim.components.unit import StepError, Unit
from rubcosim.components.units import UNIT_CLASSES, make_unit, unit_class
from rubcosim.fmus.build import MODEL_IDENTIFIERS
from rubcosim.reference import build_system, simulate
from rubcosim.reference import make_unit as make_reference_unit

from controller_arrays import lagrange_cubic, lookup, lookup_arrays

W = 379.473319
ROTOR = dict(mass=10.0, damping=316.227766, stiffness=1e6, eccentricity=5e-5, speed=W)

# inputs that make every unit do something, as functions of time
STIMULI = {
    ("rotor", "jeffcott"): ({}, lambda t: {"fx": 50.0 * math.sin(900 * t), "fy": 1.0}),
    ("rotor", "two_mass"): ({}, lambda t: {"fx": 5.0, "journal_fx": -20.0 * math.cos(500 * t)}),
    ("stator", "rigid"): ({"friction": 0.2, "disc_radius": 0.05, "speed": W}, None),
    ("stator", "elastic"): ({"friction": 0.1, "impact_mass": 10.0, "restitution": 0.7}, None),
    ("stator", "casing"): ({"friction": 0.1, "impact_mass": 10.0, "restitution": 0.7}, None),
    ("stator", "hunt_crossley"): ({"friction": 0.1, "restitution": 0.7}, None),
    ("bearing", "oilfilm"): ({}, lambda t: {"x": 3e-5 * math.cos(700 * t), "vx": 0.01}),
    ("bearing", "linear"): ({}, lambda t: {"x": 3e-5 * math.cos(700 * t), "vy": 0.01}),
    ("bearing", "anisotropic"): (
        {"kxy": 1.5e6, "kyx": -1.5e6, "cxx": 4e3, "cyy": 3e3, "cxy": 200.0},
        lambda t: {"x": 3e-5 * math.cos(700 * t), "y": 1e-5, "vx": 0.01, "vy": -0.02},
    ),
    ("controller", "delayed_feedback"): (
        # ETDAS with a telegraph delay, 0.37 ms +- 0.1 ms: within the tests' 10-20 steps
        # of 0.1 ms the history, the filter and the modulation's jumps are all at work
        {
            "delay": 3.7e-4,
            "memory": 0.5,
            "modulation_shape": "telegraph",
            "modulation_amplitude": 1e-4,
            "modulation_frequency": 3000.0,
        },
        lambda t: {"x": 1e-5 * math.sin(1000 * t), "y": 1e-5 * math.cos(1300 * t)},
    ),
    ("oscillator", "impact_oscillator"): (
        {"forcing_amplitude": 1.0, "barrier": 0.4, "damping": 0.1},
        lambda t: {"force": 0.1 * math.sin(t)},
    ),
    ("oscillator", "two_dof_impact"): (
        {"forcing_amplitude": 1.0, "forcing_frequency": 0.3, "gap": 0.05, "restitution": 0.3},
        lambda t: {"force": 0.2 * math.sin(2.0 * t)},
    ),
}


def ex(role: str, type_name: str, **overrides) -> Unit:
    """A unit at its example parameters with ``overrides``."""
    return unit_class(role, type_name).example(**overrides)


def _disc_near_stator(t: float) -> dict[str, float]:
    # the disc sweeps through the clearance (1e-4 m) and back
    r = 1e-4 * (1.0 + 0.05 * math.sin(2000 * t))
    return {"x": r * math.cos(W * t), "y": r * math.sin(W * t), "vx": -W * r * math.sin(W * t)}


def stimulus(key: tuple[str, str]):
    """Example parameters with the stimulus overrides, and the input functions."""
    params, inputs = STIMULI[key]
    return {**unit_class(*key).example_params(), **params}, inputs or _disc_near_stator


KEY_OF = {ident: key for key, ident in MODEL_IDENTIFIERS.items()}  # FMU -> (role, type)


def step_size(role: str) -> float:
    """Communication step used for a unit of this role in the tests, s."""
    return 0.05 if role == "oscillator" else 1e-4


def run(unit, inputs, t0: float, n: int, h: float) -> list[dict[str, float]]:
    """Step a Unit or an FmuUnit ``n`` times with ``inputs(t)``; outputs after each step."""
    out = []
    t = t0
    for _ in range(n):
        unit.set_inputs(inputs(t))
        unit.do_step(t, h)
        t += h
        unit.set_inputs(inputs(t))
        out.append(unit.get_outputs())
    return out


def test_every_catalogued_unit_type_has_a_unit_class_with_its_parameters():
    catalogued = {(role, t): ps for role, types in UNIT_TYPES.items() for t, ps in types.items()}
    assert set(UNIT_CLASSES) == set(catalogued)
    for key, cls in UNIT_CLASSES.items():
        assert set(catalogued[key]) <= set(cls.params_spec)


@pytest.mark.parametrize("key", sorted(UNIT_CLASSES))
def test_unit_declares_what_it_computes(key):
    params, _ = stimulus(key)
    unit = make_unit(*key, **params)
    assert set(unit.get_outputs()) == {s.name for s in unit.outputs}
    assert set(unit.u) == {s.name for s in unit.inputs}
    assert unit.summary and all(
        s.description and s.kind in ("real", "integer") for s in unit.outputs
    )
    for p in unit.params_spec:
        assert p.default is not None or p.example is not None, f"{key} {p.name} has no start value"


@pytest.mark.parametrize("key", sorted(UNIT_CLASSES))
def test_snapshot_restore_is_bit_identical(key):
    params, inputs = stimulus(key)
    unit = make_unit(*key, **params)
    h = step_size(unit.role)
    run(unit, inputs, 0.0, 5, h)
    snap = unit.get_state()
    first = run(unit, inputs, 5 * h, 5, h)
    unit.set_state(snap)
    again = run(unit, inputs, 5 * h, 5, h)
    unit.set_state(snap)  # the same snapshot, a second time
    third = run(unit, inputs, 5 * h, 5, h)
    data = Unit.state_to_bytes(snap)
    unit.set_state(Unit.state_from_bytes(data))
    fourth = run(unit, inputs, 5 * h, 5, h)
    assert first == again == third == fourth
    assert any(v != 0 for o in first for v in o.values())


@pytest.mark.parametrize("key", sorted(UNIT_CLASSES))
def test_a_snapshot_before_the_first_step_survives_bytes_with_its_shapes(key):
    """Right after it is built, a unit's state may hold empty tables (the controller's
    delay history, shape (0, 6)): through bytes each array keeps its shape, and the unit
    restored from them steps as the original does."""
    params, inputs = stimulus(key)
    unit = make_unit(*key, **params)
    h = step_size(unit.role)
    snap = unit.get_state()
    back = Unit.state_from_bytes(Unit.state_to_bytes(snap))
    for name, value in snap["state"].items():
        if isinstance(value, np.ndarray):
            assert back["state"][name].shape == value.shape, name
    first = run(unit, inputs, 0.0, 3, h)
    unit.set_state(back)
    assert run(unit, inputs, 0.0, 3, h) == first


@pytest.mark.parametrize("key", sorted(UNIT_CLASSES))
def test_failed_step_leaves_the_state_untouched(key):
    params, inputs = stimulus(key)
    unit = make_unit(*key, **params)
    h = step_size(unit.role)
    run(unit, inputs, 0.0, 3, h)
    before = Unit.state_to_bytes(unit.get_state())
    name = next(s.name for s in unit.inputs if s.kind == "real")
    unit.set_input(name, math.nan)
    with pytest.raises(StepError, match=name):
        unit.do_step(3 * h, h)
    unit.set_inputs(inputs(3 * h))
    after = unit.get_state()
    after["u"] = Unit.state_from_bytes(before)["u"]
    assert Unit.state_to_bytes(after) == before
    unit.do_step(3 * h, h)  # and it goes on


def test_bad_parameters_name_the_field():
    with pytest.raises(ParameterError, match=r"rotor\.mass"):
        make_unit("rotor", "jeffcott", mass=-1.0)
    with pytest.raises(ParameterError, match=r"stator\.clearance is required"):
        make_unit("stator", "rigid")
    with pytest.raises(ParameterError, match=r"stator\.restitution"):
        ex("stator", "rigid", restitution=1.5)
    with pytest.raises(ParameterError, match=r"stator\.impact_mass"):
        ex("stator", "elastic", restitution=0.5)
    with pytest.raises(ParameterError, match=r"oscillator\.barrier"):
        ex("oscillator", "impact_oscillator", stop="rigid_two_sided", barrier=-1.0)
    with pytest.raises(ParameterError, match=r"controller\.speed"):
        ex("controller", "delayed_feedback", speed=0.0)
    with pytest.raises(ParameterError, match=r"rotor\.type"):
        make_unit("rotor", "flexible")
    with pytest.raises(ValueError, match="not a state snapshot"):
        ex("rotor", "jeffcott").set_state({"time": 0.0})
    with pytest.raises(ValueError, match="not a serialised"):
        Unit.state_from_bytes(b"\xff")
    with pytest.raises(KeyError, match=r"rotor\.force"):
        ex("rotor", "jeffcott").set_input("force", 1.0)
    with pytest.raises(StepError, match="invalid step"):
        ex("rotor", "jeffcott").do_step(0.0, -1.0)


def test_rotor_on_its_free_whirl_matches_the_closed_form():
    A, phase = free_whirl(
        **{k: ROTOR[k] for k in ("mass", "damping", "stiffness", "eccentricity", "speed")}
    )
    x0, y0 = A * math.cos(-phase), A * math.sin(-phase)
    unit = make_unit("rotor", "jeffcott", **ROTOR, x0=x0, y0=y0, vx0=-W * y0, vy0=W * x0)
    h = 2 * math.pi / W / 40
    worst = 0.0
    for i in range(200):
        unit.do_step(i * h, h)
        t = (i + 1) * h
        o = unit.get_outputs()
        worst = max(
            worst,
            math.hypot(o["x"] - A * math.cos(W * t - phase), o["y"] - A * math.sin(W * t - phase)),
        )
    assert worst < 1e-8 * A


def test_rotor_applies_a_reset_at_the_start_of_the_next_step():
    unit = make_unit("rotor", "jeffcott", **{**ROTOR, "eccentricity": 0.0})
    unit.set_inputs({"reset_vx": 0.3, "reset_vy": -0.2, "reset_counter": 1})
    assert unit.get_outputs()["vx"] == 0.0  # not before the step
    unit.do_step(0.0, 0.0)
    o = unit.get_outputs()
    assert (o["vx"], o["vy"], o["resets_applied"]) == (0.3, -0.2, 1)
    unit.do_step(0.0, 1e-4)  # the same counter: no second reset
    assert unit.get_outputs()["vx"] != 0.3
    # free motion from the reset velocity: x = v0 sin(wn t)/wn (undamped check with c = 0)
    free = make_unit("rotor", "jeffcott", **{**ROTOR, "damping": 0.0, "eccentricity": 0.0})
    free.set_inputs({"reset_vx": 0.3, "reset_counter": 7})
    free.do_step(0.0, 1e-3)
    wn = math.sqrt(1e6 / 10.0)
    assert free.get_outputs()["x"] == pytest.approx(0.3 * math.sin(wn * 1e-3) / wn, rel=1e-9)


def test_two_mass_rotor_journal_feels_the_bearing_input():
    unit = make_unit("rotor", "two_mass", **{**ROTOR, "eccentricity": 0.0}, journal_mass=2.0)
    unit.set_inputs({"journal_fx": 100.0})
    unit.do_step(0.0, 1e-4)
    o = unit.get_outputs()
    # at first the journal accelerates alone: x ~ F t^2 / (2 mj)
    assert o["journal_x"] == pytest.approx(100.0 * 1e-8 / 4.0, rel=1e-2)
    assert abs(o["x"]) < 1e-3 * o["journal_x"]


def test_rigid_stator_outputs_the_impact_law():
    unit = make_unit(
        "stator", "rigid", clearance=1e-4, x_offset=1e-5, restitution=0.8, friction=0.15,
        disc_radius=0.05, speed=W,
    )  # fmt: skip
    unit.set_inputs({"x": 1.1e-4, "y": 2e-5, "vx": 0.05, "vy": 0.01})
    o = unit.get_outputs()
    rx, ry = 1e-4, 2e-5
    dist = math.hypot(rx, ry)
    nx, ny = rx / dist, ry / dist
    assert o["gap"] == pytest.approx(1e-4 - dist, abs=1e-18)
    assert o["gap_rate"] == pytest.approx(-(0.05 * nx + 0.01 * ny))
    assert (o["vx_plus"], o["vy_plus"]) == rigid_impact(0.05, 0.01, nx, ny, 0.8, 0.15, 0.05, W)


def test_elastic_stator_force_is_the_penalty_law():
    unit = ex("stator", "elastic", contact_stiffness=2e7, contact_damping=50.0, friction=0.1,
                     disc_radius=0.05, speed=W)  # fmt: skip
    unit.set_inputs({"x": 1.02e-4, "y": 1e-5, "vx": 0.01, "vy": 0.02})
    o = unit.get_outputs()
    fx, fy, fn = penalty_contact_force(1.02e-4, 1e-5, 0.01, 0.02, 1e-4, 2e7, 50.0, 0.1, 0.05, W)
    assert (o["fx"], o["fy"], o["normal_force"]) == (fx, fy, fn)
    assert o["gap"] < 0 and fn > 0


def test_casing_oscillates_freely_while_the_disc_is_clear():
    ms, ks = 5.0, 2e6
    unit = ex("stator", "casing", mass=ms, stiffness=ks, x0=2e-5, contact_stiffness=2e7,
                     contact_damping=0.0)  # fmt: skip
    ws = math.sqrt(ks / ms)
    h = 1e-4
    for i in range(50):
        unit.do_step(i * h, h)
        assert unit.get_outputs()["casing_x"] == pytest.approx(
            2e-5 * math.cos(ws * (i + 1) * h), abs=1e-14
        )
    assert unit.get_outputs()["fx"] == 0.0


def test_bearings_output_their_force_laws():
    oil = make_unit("bearing", "oilfilm", viscosity=0.02, radius=0.03, length=0.03,
                    clearance=1.5e-4, speed=700.0)  # fmt: skip
    oil.set_inputs({"x": 5e-5, "y": -3e-5, "vx": 0.01, "vy": 0.0})
    sigma = oilfilm_sigma(0.02, 700.0, 0.03, 0.03, 1.5e-4)
    assert tuple(oil.get_outputs().values()) == oilfilm_force(
        5e-5, -3e-5, 0.01, 0.0, 700.0, 1.5e-4, sigma
    )
    oil.set_inputs({"x": 2e-4})
    with pytest.raises(ValueError, match="touches the bearing wall"):
        oil.get_outputs()
    # the message says how far: |journal| / clearance = hypot(2e-4, 3e-5) / 1.5e-4
    with pytest.raises(ValueError, match=r"eccentricity ratio 1\.34825 >= 1"):
        oil.get_outputs()
    lin = make_unit("bearing", "linear", stiffness=1e7, damping=100.0)
    lin.set_inputs({"x": 1e-5, "vy": 0.1})
    assert lin.get_outputs() == pytest.approx({"fx": -100.0, "fy": -10.0}, rel=1e-15)


def test_controller_force_follows_the_delayed_signal():
    K, tau, w = 1e5, 2e-3, 1000.0
    unit = make_unit("controller", "delayed_feedback", gain=K, delay=tau, speed=0.0)
    h = 1e-4
    worst = 0.0
    for i in range(100):
        t = i * h
        unit.set_inputs({"x": 1e-5 * math.sin(w * t)})
        unit.do_step(t, h)
        t += h
        unit.set_inputs({"x": 1e-5 * math.sin(w * t)})
        if t > tau + 3 * h:
            want = K * 1e-5 * (math.sin(w * (t - tau)) - math.sin(w * t))
            worst = max(worst, abs(unit.get_outputs()["ux"] - want))
    # cubic interpolation of samples 0.1 rad apart: error ~ (w h)^4 / 24 of K A
    assert worst < 1e-4 * K * 1e-5
    late = make_unit("controller", "delayed_feedback", gain=K, delay=tau, speed=0.0, t_on=1.0)
    late.set_inputs({"x": 1e-5})
    assert late.get_outputs()["ux"] == 0.0


def test_base_delay_checks():
    p = dict(delay=0.0, delay_periods=2, modulation_amplitude=0.0, modulation_frequency=0.0)
    assert base_delay(p, 100.0) == pytest.approx(4 * math.pi / 100.0)
    with pytest.raises(ParameterError, match="rotor.speed"):
        base_delay(p, 0.0)
    with pytest.raises(ParameterError, match="modulation_amplitude"):
        base_delay({**p, "delay": 0.1, "modulation_amplitude": 0.2}, 1.0)


def test_lagrange_cubic_is_exact_for_cubics():
    ts = np.array([0.0, 0.3, 0.7, 1.0])
    zs = np.stack([ts**3 - ts, 2 * ts], axis=1)
    assert lagrange_cubic(ts, zs, 0.5) == pytest.approx([0.125 - 0.5, 1.0])


def test_an_equal_pair_of_samples_is_a_kink_of_z_that_no_stencil_spans():
    # z = |t - 0.5| (a fed-back position whose velocity an impact reversed at 0.5): with
    # the event's two equal samples there, each side is a line, interpolated exactly;
    # the same pair marked as one of the filter alone leaves z's stencils across the kink
    ts = np.array([0.0, 0.15, 0.3, 0.42, 0.5, 0.5, 0.61, 0.7, 0.85, 1.0])
    z = np.abs(ts - 0.5)
    rows = np.stack([ts, z, 2 * z, ts, ts, np.full(ts.size, SAMPLE)], axis=1)
    for tq in (0.35, 0.45, 0.48, 0.52, 0.58, 0.65):
        want = abs(tq - 0.5)
        for got in (lookup(rows, tq), lookup_arrays(rows, tq)):
            assert got[:2] == pytest.approx([want, 2 * want], rel=1e-12)
    spanned = rows.copy()
    spanned[4:6, 5] = FILTER_PAIR
    assert abs(lookup(spanned, 0.45)[0] - 0.05) > 1e-3


def test_history_lookup_is_exact_for_cubics_and_takes_each_side_of_a_jump():
    # z = t^3 - t and S = 2 t sampled unevenly: cubic Lagrange reproduces them exactly
    ts = np.array([0.0, 0.1, 0.3, 0.45, 0.7, 1.0, 1.2])
    rows = np.stack([ts, ts**3 - ts, 2 * ts, 2 * ts, ts**2], axis=1)
    for tq in (0.05, 0.5, 0.71, 1.1):
        assert lookup(rows, tq) == pytest.approx([tq**3 - tq, 2 * tq, 2 * tq, tq**2], rel=1e-13)
    assert np.array_equal(lookup(rows, -1.0), rows[0, 1:])  # before the first sample
    # a jump of z at t = 0.45 (two rows at one time): each side from its own piece
    jump = np.insert(rows, 4, rows[3], axis=0)
    jump[4:, 1:] += np.array([5.0, 6.0, 7.0, 8.0]) - rows[3, 1:]  # the right piece: shifted
    assert lookup(jump, 0.45, "left") == pytest.approx(rows[3, 1:], rel=1e-13)
    assert lookup(jump, 0.45, "right") == pytest.approx([5.0, 6.0, 7.0, 8.0], rel=1e-13)


@pytest.mark.parametrize("seed", range(6))
def test_compiled_history_lookup_agrees_with_array_operations_bit_for_bit(seed):
    # random histories with jumps of both signals and of the filter alone, queried at,
    # between and beyond the samples, on both sides
    # (a pair of the filter alone, a jump of the signal, an equal pair: a kink), with and
    # without the rows' kind column
    rng = np.random.default_rng(seed)
    rows = _random_history(rng)
    queries = np.concatenate((rows[:, 0], rng.uniform(-0.1, 1.1, 20)))
    for samples in (rows, rows[:, :5]):
        for tq in queries:
            for side in ("left", "right"):
                got = lookup(samples, tq, side)
                assert np.array_equal(got, lookup_arrays(samples, tq, side))


def _random_history(rng: np.random.Generator) -> np.ndarray:
    """Rows (t, zx, zy, Sx, Sy, kind) at sorted random times, with pairs at one time:
    jumps of the filter alone, of the signal and the filter, and kinks (equal pairs)."""
    n = int(rng.integers(1, 40))
    ts = np.sort(rng.uniform(0.0, 1.0, n))
    rows = np.column_stack((ts, rng.normal(size=(n, 4)), np.full(n, SAMPLE)))
    for _ in range(int(rng.integers(0, 6))):
        r = int(rng.integers(0, n))
        extra = rows[r].copy()
        kind = rng.integers(0, 3)
        if kind == 0:  # the filter alone jumps
            extra[3:5] = rng.normal(size=2)
            rows[r, 5] = extra[5] = FILTER_PAIR
        elif kind == 1:  # the signal and the filter
            extra[1:5] = rng.normal(size=4)
        rows = np.insert(rows, r + 1, extra, axis=0)
    return rows


@pytest.mark.parametrize("seed", range(40))
def test_trimming_the_history_changes_no_lookup_after_the_kept_time(seed):
    # The controller drops the rows older than it needs at every step (first_kept).
    # A lookup between the kept time and the newest sample (the delayed times the next
    # step asks for) must give what the whole history gives: a trim that moved a
    # stencil made the force jump within a step, and the master shrank that step to
    # its minimum (two samples 1.7e-11 s apart whose filters disagreed by 3e-8;
    # through them, one delay later, a 2.4 N spike).
    rng = np.random.default_rng(seed)
    rows = _random_history(rng)
    last = rows[-1, 0]
    for keep in np.concatenate((rows[:, 0], rng.uniform(-0.1, last, 10))):
        later = rows[(rows[:, 0] > keep), 0]
        for samples in (rows, np.ascontiguousarray(rows[:, :5])):  # with, without the kind
            first = int(first_kept(samples, keep))
            assert first == 0 or rows[first, 0] != rows[first - 1, 0]  # no pair split
            kept = samples[first:]
            for tq in np.concatenate(([keep], later, rng.uniform(keep, last, 5))):
                for side in ("left", "right"):
                    assert np.array_equal(lookup(kept, tq, side), lookup(samples, tq, side))


def _reference_oscillator(params: dict, times: np.ndarray) -> np.ndarray:
    system = build_system(
        {"oscillator": make_reference_unit("oscillator", "impact_oscillator", params)}
    )
    res = simulate(system, float(times[-1]), t_eval=times, engine="fast", rtol=1e-12, atol=1e-14)
    return res.output("oscillator.x")


@pytest.mark.parametrize(
    "params",
    [
        # Budd & Dux: linear oscillator, barrier at 0, w = 2.8 (chattering-free impacting orbit)
        dict(linear_stiffness=1.0, forcing_amplitude=1.0, forcing_frequency=2.8, barrier=0.0,
             restitution=0.8, x0=-0.2),
        # the paper's one-sided impact Duffing oscillator
        dict(linear_stiffness=1.0, damping=0.1, cubic_stiffness=1.0, forcing_amplitude=1.0,
             forcing_frequency=2.0, barrier=1.0, restitution=0.8, x0=-2.0),
        dict(linear_stiffness=1.0, damping=0.05, forcing_amplitude=0.5, forcing_frequency=1.5,
             barrier=0.3, stop="rigid_two_sided", restitution=0.7),
        dict(linear_stiffness=1.0, damping=0.05, forcing_amplitude=0.5, forcing_frequency=1.5,
             barrier=0.3, stop="elastic_one_sided", stop_stiffness=20.0),
    ],
)  # fmt: skip
def test_oscillator_unit_matches_the_reference_engine(params):
    unit = make_unit("oscillator", "impact_oscillator", **params)
    period = 2 * math.pi / params["forcing_frequency"]
    h = period / 16
    times = h * np.arange(1, 161)
    xs = []
    for i in range(times.size):
        unit.do_step(i * h, h)
        xs.append(unit.get_outputs()["x"])
    want = _reference_oscillator(params, np.concatenate(([0.0], times)))[1:]
    assert np.max(np.abs(np.array(xs) - want)) < 1e-7


def test_oscillator_sticks_after_chattering_and_is_released():
    # a low-restitution mass pushed onto the barrier by a slow force: chatter, stick, release
    unit = make_unit(
        "oscillator", "impact_oscillator", linear_stiffness=1.0, damping=0.0,
        forcing_amplitude=2.0, forcing_frequency=0.5, barrier=0.5, restitution=0.3,
    )  # fmt: skip
    seen_stuck = seen_free_after = False
    h = 0.1
    for i in range(200):
        unit.do_step(i * h, h)
        o = unit.get_outputs()
        if o["stuck"] == 1:
            seen_stuck = True
            assert o["x"] == 0.5 and o["v"] == 0.0
        elif seen_stuck:
            seen_free_after = True
    assert seen_stuck and seen_free_after and unit.get_outputs()["impacts"] > 5


def test_hybrid_unit_locates_an_impact_inside_one_step_to_the_closed_form():
    # x'' = -x from (0, 1) against a barrier at 0.5: x = sin t reaches it at t1 = pi/6
    # with v = cos t1, leaves with -R v, and is x = 0.5 cos(t - t1) - R v sin(t - t1) after
    r = 0.8
    unit = make_unit("oscillator", "impact_oscillator", linear_stiffness=1.0,
                     forcing_amplitude=0.0, forcing_frequency=1.0, barrier=0.5, restitution=r,
                     x0=0.0, v0=1.0,
                     rtol=1e-12, atol=1e-14)  # fmt: skip
    unit.do_step(0.0, 1.5)  # one communication step across the impact
    t1, v1 = math.pi / 6, math.cos(math.pi / 6)
    s = 1.5 - t1
    o = unit.get_outputs()
    assert o["impacts"] == 1
    assert o["x"] == pytest.approx(0.5 * math.cos(s) - r * v1 * math.sin(s), abs=1e-11)
    assert o["v"] == pytest.approx(-0.5 * math.sin(s) - r * v1 * math.cos(s), abs=1e-11)


def test_compiled_unit_step_matches_scipy_with_polynomial_inputs():
    # the Jeffcott ODE with fx = 3 + 40 s + 500 s^2 (s into the step), fy = -2
    q = dict(ROTOR, gravity=0.0)
    p = np.array([q[k] for k in unit_odes.JEFFCOTT_P])
    u = np.array([[3.0, 40.0, 1000.0], [-2.0, 0.0, 0.0]])
    y0 = np.array([1e-5, -2e-5, 3e-3, 1e-3])
    t0, t1 = 0.01, 0.03

    def rhs(t, y):
        s = t - t0
        fx, fy = jeffcott_force(t, *y, q["mass"], q["damping"], q["stiffness"],
                                q["eccentricity"], q["speed"], 0.0)  # fmt: skip
        m = q["mass"]
        return np.array([y[2], y[3], (fx + 3.0 + 40.0 * s + 500.0 * s * s) / m, (fy - 2.0) / m])

    want = solve_ivp(rhs, (t0, t1), y0, "DOP853", rtol=1e-12, atol=1e-16).y[:, -1]
    got, h_next = step_ode(unit_odes.JEFFCOTT, t0, t1, y0, 0.0, p, u, 1e-12, 1e-16)
    assert np.allclose(got, want, rtol=1e-9, atol=1e-14) and h_next > 0.0
    assert np.array_equal(y0, [1e-5, -2e-5, 3e-3, 1e-3])  # the caller's state is untouched
    # the step it proposes restarts the next call; a zero-length span changes nothing
    again, _ = step_ode(unit_odes.JEFFCOTT, t1, t1, got, h_next, p, u, 1e-12, 1e-16)
    assert np.array_equal(again, got)


def test_unit_step_without_numba_goes_to_scipy_with_the_same_result(monkeypatch):
    from rubcosim.components import stepping

    q = dict(ROTOR, gravity=0.0)
    p = np.array([q[k] for k in unit_odes.JEFFCOTT_P])
    u = np.array([[3.0, 40.0, 1000.0], [-2.0, 0.0, 0.0]])
    y0 = np.array([1e-5, -2e-5, 3e-3, 1e-3])
    compiled, _ = step_ode(unit_odes.JEFFCOTT, 0.0, 0.02, y0, 0.0, p, u, 1e-12, 1e-16)
    monkeypatch.setattr(stepping, "USE_NUMBA", False)
    plain, h_next = step_ode(unit_odes.JEFFCOTT, 0.0, 0.02, y0, 0.0, p, u, 1e-12, 1e-16)
    assert np.allclose(plain, compiled, rtol=1e-9, atol=1e-14) and h_next > 0.0


def test_compiled_unit_step_reports_failures():
    p = np.array([1.0, 0.0, 1.0, 0.0, 0.0, 0.0])
    bad = np.array([[math.inf, 0.0, 0.0], [0.0, 0.0, 0.0]])
    with pytest.raises(RuntimeError, match="between t = 0.0 and 1.0"):
        step_ode(unit_odes.JEFFCOTT, 0.0, 1.0, np.zeros(4), 0.0, p, bad, 1e-8, 1e-12)


def test_input_polynomial_in_one_call():
    rotor = make_unit("rotor", "jeffcott", **ROTOR)
    rotor.set_input_polynomial("fx", 1.0, 2.0, 4.0)
    assert rotor.input_at("fx", 0.5) == pytest.approx(1.0 + 1.0 + 0.5)
    assert rotor.input_rows(("fy", "fx")).tolist() == [[0.0, 0.0, 0.0], [1.0, 2.0, 4.0]]
    with pytest.raises(KeyError, match="rotor.fz is not an input"):
        rotor.set_input_polynomial("fz", 1.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="not finite"):
        rotor.set_input_polynomial("fx", 1.0, math.nan, 0.0)


def test_kernels_are_compiled_in_the_installed_package():
    assert jit.USE_NUMBA


def test_hybrid_unit_finds_rebounds_shorter_than_its_step_to_the_closed_form():
    # a mass pushed onto the stop by a constant force f = 1 (w ~ 0), leaving it at
    # speed 1: rebound n lasts 2 R^(n-1) / f, so impact n is at t_n = 4 (1 - R^n) for
    # R = 0.5; with steps of 1, rebounds 3 to 5 (0.5, 0.25, 0.125) start and end
    # inside one step, and the first starts on the stop (the event function is 0)
    r, barrier = 0.5, 0.5
    unit = make_unit("oscillator", "impact_oscillator", linear_stiffness=0.0,
                     forcing_amplitude=1.0, forcing_frequency=1e-9, barrier=barrier,
                     restitution=r, x0=barrier, v0=-1.0, rtol=1e-12, atol=1e-14)  # fmt: skip
    for i in range(3):
        unit.do_step(float(i), 1.0)
    unit.do_step(3.0, 0.9)
    t5, v5 = 4.0 * (1.0 - r**5), r**5  # the 5th impact and the speed it leaves with
    s = 3.9 - t5
    o = unit.get_outputs()
    assert o["impacts"] == 5
    assert o["x"] == pytest.approx(barrier - v5 * s + 0.5 * s * s, abs=1e-10)
    assert o["v"] == pytest.approx(-v5 + s, abs=1e-10)
