"""What a rigid stator's contact does at an event in a co-simulation: one program, which
both masters run (the Python master, :mod:`rubcosim.orchestrator.protocols`, and the
compiled one, :mod:`rubcosim.orchestrator.flat_events`).

A master does not evaluate the stator's laws: it sees the stator's outputs and acts
through two inputs, the stator's contact mode and the rotor's velocity reset.  So the
protocol is a small program.  The master starts it for an event (:func:`start`), then
calls :func:`next_action` with the stator's latest outputs and performs the action it
returns, until :data:`ACT_DONE`:

* :data:`ACT_SET_MODE` (argument: the mode): set the stator's ``contact_mode`` input,
  then settle the connections, so that the stator's outputs follow the new mode;
* :data:`ACT_RESET_ROTOR` (argument: the reset counter): set the rotor's ``reset_vx``
  and ``reset_vy`` inputs from the stator's ``vx_plus`` and ``vy_plus`` outputs and its
  ``reset_counter`` input to the argument, apply them at once (a zero-length step) and
  settle.

Every decision is made here, with the stator's kernels (:mod:`.stator`): the impact
counter, the flight since the last impact, the end of chattering
(:func:`~.stator.chattering_ended`), the mode a disc settles into
(:func:`~.stator.settle_mode`), and release when nothing presses the disc onto the
stator.  The monolithic reference makes the same decisions with the same kernels on its
own state (:func:`rubcosim.reference.system.rotor_apply`).

The protocol's state is a float array of :data:`N_STATE` slots (``ST_*``), saved and
restored with the master's: the contact mode, the impact counter, the time of the last
impact (s), the largest gap seen (m, the scale of :func:`overdue`), and where the
program is.
"""

from __future__ import annotations

import math

import numpy as np

from .contact_law import EV_IMPACT, EV_RELEASE
from .jit import njit
from .stator import MODE_FREE, MODE_STICK, chattering_ended, settle_mode

ST_MODE, ST_COUNTER, ST_LAST_IMPACT, ST_SCALE, ST_PC, ST_FROM = range(6)
N_STATE = 6

ACT_DONE, ACT_SET_MODE, ACT_RESET_ROTOR = range(3)

# where the program is (ST_PC)
_PC_DONE, _PC_IMPACT, _PC_AFTER_RESET, _PC_SETTLE, _PC_SETTLE_MODE, _PC_PRESSED = range(6)
_PC_RELEASE = 6
# an overdue impact: the disc found this far inside the stator (relative to the largest
# gap seen), still approaching
_OVERDUE = 1e-9


def initial_state() -> np.ndarray:
    """A protocol's state before the run: free flight, no impact yet."""
    st = np.zeros(N_STATE)
    st[ST_MODE] = MODE_FREE
    st[ST_LAST_IMPACT] = -math.inf
    return st


@njit
def start(st: np.ndarray, kind: int) -> None:
    """Start the program for an event of ``kind`` (``EV_*`` of :mod:`.contact_law`):
    an impact, a release (the constraint force through zero), or a slip event (the
    slip speed through zero, or a sticking contact's friction reserve used up)."""
    if kind == EV_IMPACT:
        st[ST_PC] = _PC_IMPACT
    elif kind == EV_RELEASE:
        st[ST_PC] = _PC_RELEASE
    else:
        st[ST_FROM] = st[ST_MODE]
        st[ST_PC] = _PC_SETTLE


@njit
def next_action(
    st: np.ndarray,
    time: float,
    gap_rate: float,
    slip: float,
    hold_margin: float,
    hold_force: float,
    normal_force: float,
    v_chat: float,
    min_flight: float,
):
    """The next action of the program, ``(ACT_*, argument)``, from the stator's latest
    outputs: ``gap_rate`` (m/s, > 0 leaving), ``slip`` (m/s), ``hold_margin`` and
    ``hold_force`` (N), ``normal_force`` (N, > 0 pressing the disc onto the stator), at
    the master's ``time`` (s).  ``v_chat`` (m/s): a rebound slower than this ends
    chattering; ``min_flight`` (s): so do impacts closer together than this."""
    while True:
        pc = int(st[ST_PC])
        if pc == _PC_IMPACT:
            st[ST_COUNTER] += 1.0
            st[ST_PC] = _PC_AFTER_RESET
            return ACT_RESET_ROTOR, st[ST_COUNTER]
        if pc == _PC_AFTER_RESET:
            flight = time - st[ST_LAST_IMPACT]
            st[ST_LAST_IMPACT] = time
            # the rebound is the normal speed the stator sees after the reset: its gap rate
            if not chattering_ended(gap_rate, v_chat, flight, min_flight):
                st[ST_PC] = _PC_DONE
                return ACT_DONE, 0.0
            # the disc stays on the stator if it is pressed onto it
            st[ST_FROM] = MODE_FREE
            st[ST_PC] = _PC_SETTLE
        elif pc == _PC_SETTLE:
            st[ST_PC] = _PC_SETTLE_MODE
            if int(st[ST_FROM]) == MODE_FREE:
                # the stator gives its normal and holding forces only in a contact mode
                st[ST_MODE] = MODE_STICK
                return ACT_SET_MODE, float(MODE_STICK)
        elif pc == _PC_SETTLE_MODE:
            origin = int(st[ST_FROM])
            threshold = v_chat if origin == MODE_FREE else math.inf
            mode = settle_mode(slip, threshold, hold_margin, hold_force, origin)
            st[ST_PC] = _PC_PRESSED
            if mode != int(st[ST_MODE]):
                st[ST_MODE] = mode
                return ACT_SET_MODE, float(mode)
        elif pc == _PC_PRESSED:
            st[ST_PC] = _PC_DONE
            if normal_force <= 0.0:
                st[ST_MODE] = MODE_FREE
                return ACT_SET_MODE, float(MODE_FREE)
            return ACT_DONE, 0.0
        elif pc == _PC_RELEASE:
            st[ST_PC] = _PC_DONE
            st[ST_MODE] = MODE_FREE
            return ACT_SET_MODE, float(MODE_FREE)
        else:
            return ACT_DONE, 0.0


@njit
def overdue(st: np.ndarray, gap: float, gap_rate: float) -> bool:
    """Whether an impact is overdue: the disc, in free flight, found inside the stator
    (``gap`` m below zero by more than round-off of the largest gap seen) and still
    approaching (``gap_rate`` < 0), missed a rebound too small for the event locator to
    resolve; the master applies the impact now.  Keeps the largest gap in the state."""
    st[ST_SCALE] = max(st[ST_SCALE], abs(gap))
    return int(st[ST_MODE]) == MODE_FREE and gap < -_OVERDUE * st[ST_SCALE] and gap_rate < 0.0
