"""Event protocols: which indicators the master watches and what an event does.

A protocol looks at the units through the master (their latest outputs) and
acts on them only through inputs the connections do not drive: the rotor's
velocity reset and the rigid stator's contact mode.  Its own state (contact
mode, reset counter, last impact) is saved and restored with the master's.
"""

from __future__ import annotations

from typing import Any, Protocol

from rubcosim.components import rigid_protocol
from rubcosim.components.contact_law import EVENT_KINDS, WATCHED, penalty_state

from .events import Indicator


class MasterView(Protocol):
    out: dict[str, dict[str, Any]]
    time: float

    def set_event_input(self, unit: str, name: str, value: float) -> None: ...

    def apply_now(self, unit: str) -> None: ...

    def settle(self) -> None: ...


def watched(kind: str, state: int, stator: str) -> list[Indicator]:
    """The indicators of ``stator`` in ``state`` of its contact ``kind`` (the table
    :data:`rubcosim.components.contact_law.WATCHED`, which the compiled master reads too)."""
    return [Indicator(stator, o, d, k, r or None) for o, d, k, r in WATCHED[kind][state]]


class EventProtocol:
    """Base: no indicators, no state."""

    state: dict[str, Any]

    def indicators(self, master: MasterView) -> list[Indicator]:
        return []

    def handle(self, master: MasterView, ind: Indicator) -> str:
        raise NotImplementedError

    def overdue(self, master: MasterView) -> Indicator | None:
        """An event that should already have happened (a crossing too small to resolve),
        to be handled now; None when all is well."""
        return None


class RigidContact(EventProtocol):
    """A rotor against a rigid stator: impacts through the velocity reset, then,
    when the rebounds die out (chattering), sustained sliding or sticking contact
    held by the stator's constraint force, and release when it falls to zero.
    What an event does is the rigid stator's protocol program
    (:mod:`rubcosim.components.rigid_protocol`, which the compiled master runs
    too); this class performs its actions on the units.

    ``v_chat`` (m/s): a rebound slower than this ends chattering.  ``min_flight``
    (s): impacts closer together than this also end it, so an accumulation of
    impacts never stalls the master.
    """

    def __init__(self, stator: str, rotor: str, v_chat: float, min_flight: float) -> None:
        self.stator, self.rotor = stator, rotor
        self.v_chat, self.min_flight = v_chat, min_flight
        self.state = rigid_protocol.initial_state()

    @property
    def mode(self) -> int:
        """The contact mode (:data:`rubcosim.components.stator.MODE_FREE` ...)."""
        return int(self.state[rigid_protocol.ST_MODE])

    def indicators(self, master: MasterView) -> list[Indicator]:
        return watched("rigid", self.mode, self.stator)

    def overdue(self, master: MasterView) -> Indicator | None:
        """A disc found inside the stator, still approaching, missed an impact (a rebound
        too small for the event locator to resolve): the impact is applied now."""
        out = master.out[self.stator]
        if rigid_protocol.overdue(self.state, out["gap"], out["gap_rate"]):
            return self.indicators(master)[0]
        return None

    def handle(self, master: MasterView, ind: Indicator) -> str:
        rigid_protocol.start(self.state, EVENT_KINDS.index(ind.kind))
        while True:
            out = master.out[self.stator]
            action, arg = rigid_protocol.next_action(
                self.state, master.time, out["gap_rate"], out["slip"], out["hold_margin"],
                out["hold_force"], out["normal_force"], self.v_chat, self.min_flight,
            )  # fmt: skip
            if action == rigid_protocol.ACT_DONE:
                return ind.kind
            if action == rigid_protocol.ACT_SET_MODE:
                master.set_event_input(self.stator, "contact_mode", int(arg))
            else:
                master.set_event_input(self.rotor, "reset_vx", out["vx_plus"])
                master.set_event_input(self.rotor, "reset_vy", out["vy_plus"])
                master.set_event_input(self.rotor, "reset_counter", int(arg))
                master.apply_now(self.rotor)
            master.settle()


class ElasticContact(EventProtocol):
    """A penalty stator: the master steps onto contact onset and release, where the
    contact force has a kink, and restarts its extrapolation there."""

    def __init__(self, stator: str) -> None:
        self.stator = stator
        self.state = {}

    def indicators(self, master: MasterView) -> list[Indicator]:
        return watched("penalty", penalty_state(master.out[self.stator]["gap"]), self.stator)

    def handle(self, master: MasterView, ind: Indicator) -> str:
        return ind.kind
