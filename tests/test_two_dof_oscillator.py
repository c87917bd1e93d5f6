"""The two-DOF vibro-impact oscillator (a hybrid unit type) against conservation laws
and its sticking condition, written here independently of the kernels."""

from __future__ import annotations

import math

import numpy as np
import pytest

import rubcosim as rc
from rubcosim.components.graph import make_node
from rubcosim.reference import build_system, simulate

M1, M2, K1, K2 = 1.0, 0.5, 1.0, 0.5


def energy(y: np.ndarray) -> np.ndarray:
    """Mechanical energy of the free, unforced system, J: rows of (x1, v1, x2, v2)."""
    x1, v1, x2, v2 = y.T
    return 0.5 * (M1 * v1**2 + M2 * v2**2 + K1 * x1**2 + K2 * (x2 - x1) ** 2)


def system(**params):
    base = dict(mass1=M1, mass2=M2, stiffness1=K1, stiffness2=K2, forcing_frequency=0.3)
    return build_system({"oscillator": make_node("oscillator", "two_dof_impact", base | params)})


@pytest.mark.parametrize("engine", ["fast", "accurate"])
def test_each_impact_takes_the_restitution_share_of_m2s_kinetic_energy(engine):
    # undamped and unforced: energy is constant in flight, and an impact at speed v
    # takes (1 - R^2) m2 v^2 / 2 from it
    R = 0.7
    sys_ = system(gap=0.3, restitution=R, x1_0=0.8, x2_0=0.0)
    res = simulate(sys_, 40.0, output_step=0.5, engine=engine, rtol=1e-12)
    assert res.ok, res.message
    impacts = res.events.of_kind("impact")
    assert impacts.size >= 5
    e_after = energy(res.events.state[impacts])
    e0 = energy(np.array([[0.8, 0.0, 0.0, 0.0]]))[0]
    e_before = np.concatenate(([e0], e_after[:-1]))  # flight conserves energy
    v_plus = res.events.state[impacts, 3]
    v_minus = -v_plus / R
    expected = e_before - 0.5 * M2 * (1.0 - R * R) * v_minus**2
    assert np.allclose(e_after, expected, rtol=1e-8, atol=1e-12 * e0)
    x1, v1, x2, v2 = (res.output(f"oscillator.{n}") for n in ("x1", "v1", "x2", "v2"))
    assert np.all(x2 <= 0.3 + 1e-12)
    grid = energy(np.column_stack((x1, v1, x2, v2)))
    assert np.all(np.diff(grid) <= 1e-10 * e0)  # energy only ever drops


@pytest.mark.parametrize("engine", ["fast", "accurate"])
def test_m2_sticks_while_pressed_on_the_stop_and_leaves_when_the_link_force_turns(engine):
    sc = rc.load("two_dof_impact_oscillator", set={"sim.t_end": 70.0})
    res = simulate(sc.system, 70.0, output_step=0.05, engine=engine, rtol=1e-10)
    assert res.ok, res.message
    releases = res.events.of_kind("release")
    assert releases.size >= 2
    q = sc.graph.units["oscillator"].params
    for i in releases:
        t = res.events.t[i]
        x1, v1, x2, v2 = res.events.state[i]
        assert x2 == q["gap"] and v2 == 0.0
        # the force the stop must supply on m2 (link + its share of the drive) is zero
        drive = q["force_ratio"] * q["forcing_amplitude"] * math.cos(q["forcing_frequency"] * t)
        push = q["stiffness2"] * (x1 - q["gap"]) + q["damping2"] * v1 + drive
        assert abs(push) < 1e-9 * q["stiffness2"] * q["gap"]
    stuck = res.output("oscillator.contact") == 2.0
    assert stuck.any() and (~stuck).any()
    assert np.all(res.output("oscillator.contact_force")[stuck] >= 0.0)


def test_bad_parameters_name_the_field():
    with pytest.raises(ValueError, match="oscillator.x2_0"):
        system(gap=0.3, x2_0=0.5)
    with pytest.raises(ValueError, match="oscillator.restitution"):
        system(gap=0.3, restitution=1.5)
    with pytest.raises(ValueError, match="oscillator.mass2"):
        system(gap=0.3, mass2=-1.0)
