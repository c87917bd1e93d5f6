"""The rigid stator's protocol program (components/rigid_protocol.py): the actions it asks
of a master for each event, against the sequence its docstring and the README state.

These check the program's decisions, not physics: both co-simulation masters run this
program, and their results against the reference are checked in test_cosim.py and
test_flat_master.py.
"""

from __future__ import annotations

import math

from rubcosim.components import rigid_protocol as rp
from rubcosim.components.contact_law import EV_IMPACT, EV_RELEASE, EV_SLIP
from rubcosim.components.stator import MODE_FREE, MODE_SLIDE_NEG, MODE_SLIDE_POS, MODE_STICK

V_CHAT, MIN_FLIGHT = 1e-6, 1e-5


def run(st, kind, outputs, time=1.0):
    """The actions of the program for an event of ``kind``; ``outputs`` gives the stator's
    outputs (gap_rate, slip, hold_margin, hold_force, normal_force) after each action."""
    rp.start(st, kind)
    actions = []
    for _ in range(10):
        action, arg = rp.next_action(st, time, *outputs(actions), V_CHAT, MIN_FLIGHT)
        if action == rp.ACT_DONE:
            return actions
        actions.append((int(action), float(arg)))
    raise AssertionError(f"the program did not end: {actions}")


def fixed(gap_rate=0.0, slip=0.0, hold_margin=1.0, hold_force=0.0, normal=1.0):
    return lambda actions: (gap_rate, slip, hold_margin, hold_force, normal)


def test_an_impact_with_a_fast_rebound_resets_the_rotor_and_stays_free():
    st = rp.initial_state()
    assert run(st, EV_IMPACT, fixed(gap_rate=1e-3)) == [(rp.ACT_RESET_ROTOR, 1.0)]
    assert st[rp.ST_MODE] == MODE_FREE and st[rp.ST_COUNTER] == 1
    assert st[rp.ST_LAST_IMPACT] == 1.0
    # the counter the rotor is given counts the impacts
    assert run(st, EV_IMPACT, fixed(gap_rate=1e-3), time=2.0) == [(rp.ACT_RESET_ROTOR, 2.0)]


def test_a_slow_rebound_pressed_on_sticks_when_friction_holds():
    st = rp.initial_state()
    actions = run(st, EV_IMPACT, fixed(gap_rate=1e-8, slip=1e-9, hold_margin=0.5))
    assert actions == [(rp.ACT_RESET_ROTOR, 1.0), (rp.ACT_SET_MODE, float(MODE_STICK))]
    assert st[rp.ST_MODE] == MODE_STICK


def test_a_slow_rebound_with_slip_slides_with_the_slip_sign():
    st = rp.initial_state()
    actions = run(st, EV_IMPACT, fixed(gap_rate=1e-8, slip=-0.2))
    assert actions[-1] == (rp.ACT_SET_MODE, float(MODE_SLIDE_NEG))
    assert actions[1] == (rp.ACT_SET_MODE, float(MODE_STICK))  # first a contact mode


def test_a_slow_rebound_not_pressed_on_is_released():
    st = rp.initial_state()
    actions = run(st, EV_IMPACT, fixed(gap_rate=1e-8, slip=0.3, normal=-1.0))
    assert actions[-1] == (rp.ACT_SET_MODE, float(MODE_FREE))
    assert st[rp.ST_MODE] == MODE_FREE


def test_impacts_closer_than_the_minimum_flight_end_chattering():
    st = rp.initial_state()
    run(st, EV_IMPACT, fixed(gap_rate=1e-3), time=1.0)
    actions = run(st, EV_IMPACT, fixed(gap_rate=1e-3, slip=0.1), time=1.0 + MIN_FLIGHT / 2)
    assert actions[-1] == (rp.ACT_SET_MODE, float(MODE_SLIDE_POS))


def test_release_frees_and_a_slip_event_of_sticking_slides_against_the_hold():
    st = rp.initial_state()
    st[rp.ST_MODE] = MODE_STICK
    # the reserve is used up: sliding opposes the holding force
    assert run(st, EV_SLIP, fixed(hold_margin=-1.0, hold_force=2.0)) == [
        (rp.ACT_SET_MODE, float(MODE_SLIDE_NEG))
    ]
    assert run(st, EV_RELEASE, fixed()) == [(rp.ACT_SET_MODE, float(MODE_FREE))]


def test_an_impact_is_overdue_only_inside_the_stator_and_approaching():
    st = rp.initial_state()
    assert not rp.overdue(st, 1e-4, -1.0)  # outside
    assert st[rp.ST_SCALE] == 1e-4
    assert not rp.overdue(st, -1e-14, -1.0)  # within round-off of the largest gap
    assert not rp.overdue(st, -1e-6, 1.0)  # inside but leaving
    assert rp.overdue(st, -1e-6, -1.0)
    st[rp.ST_MODE] = MODE_SLIDE_POS
    assert not rp.overdue(st, -1e-6, -1.0)  # in contact, not a missed impact


def test_the_initial_state_has_had_no_impact():
    st = rp.initial_state()
    assert st[rp.ST_LAST_IMPACT] == -math.inf and st.shape == (rp.N_STATE,)
