"""Event protocols: which indicators the master watches and what an event does.

A protocol looks at the units through the master (their latest outputs) and
acts on them only through inputs the connections do not drive: the rotor's
velocity reset and the rigid stator's contact mode.  Its own state (contact
mode, reset counter, last impact) is saved and restored with the master's.
"""

from __future__ import annotations

import math
from typing import Any, Protocol

from rubcosim.components.contact_law import WATCHED, penalty_state
from rubcosim.components.stator import MODE_FREE, MODE_STICK, chattering_ended, settle_mode

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

    ``v_chat`` (m/s): a rebound slower than this ends chattering.  ``min_flight``
    (s): impacts closer together than this also end it, so an accumulation of
    impacts never stalls the master.
    """

    def __init__(self, stator: str, rotor: str, v_chat: float, min_flight: float) -> None:
        self.stator, self.rotor = stator, rotor
        self.v_chat, self.min_flight = v_chat, min_flight
        self.state = {"mode": MODE_FREE, "counter": 0, "last_impact": -math.inf, "scale": 0.0}

    def indicators(self, master: MasterView) -> list[Indicator]:
        return watched("rigid", self.state["mode"], self.stator)

    def overdue(self, master: MasterView) -> Indicator | None:
        """A disc found inside the stator, still approaching, missed an impact (a rebound
        too small for the event locator to resolve): the impact is applied now."""
        out = master.out[self.stator]
        self.state["scale"] = max(self.state["scale"], abs(out["gap"]))
        if (
            self.state["mode"] == MODE_FREE
            and out["gap"] < -1e-9 * self.state["scale"]
            and out["gap_rate"] < 0.0
        ):
            return self.indicators(master)[0]
        return None

    def _set_mode(self, master: MasterView, mode: int) -> None:
        self.state["mode"] = mode
        master.set_event_input(self.stator, "contact_mode", mode)
        master.settle()

    def handle(self, master: MasterView, ind: Indicator) -> str:
        if ind.kind == "impact":
            return self._impact(master)
        if ind.kind == "release":
            self._set_mode(master, MODE_FREE)
            return "release"
        self._settle_contact(master, slipping_from=self.state["mode"])
        return "slip"

    def _impact(self, master: MasterView) -> str:
        out = master.out[self.stator]
        self.state["counter"] += 1
        master.set_event_input(self.rotor, "reset_vx", out["vx_plus"])
        master.set_event_input(self.rotor, "reset_vy", out["vy_plus"])
        master.set_event_input(self.rotor, "reset_counter", self.state["counter"])
        master.apply_now(self.rotor)
        master.settle()
        flight = master.time - self.state["last_impact"]
        self.state["last_impact"] = master.time
        # the rebound is the normal speed the stator sees after the reset: its gap rate
        rebound = master.out[self.stator]["gap_rate"]
        if chattering_ended(rebound, self.v_chat, flight, self.min_flight):
            # the disc stays on the stator if it is pressed onto it
            self._settle_contact(master, slipping_from=MODE_FREE)
        return "impact"

    def _settle_contact(self, master: MasterView, slipping_from: int) -> None:
        """Sliding with the sign of the slip, or sticking when the slip is zero and
        friction can hold it (the kernel the reference calls); free when nothing
        presses the disc onto the stator."""
        if slipping_from == MODE_FREE:
            # the stator gives its normal and holding forces only in a contact mode
            self._set_mode(master, MODE_STICK)
        out = master.out[self.stator]
        threshold = self.v_chat if slipping_from == MODE_FREE else math.inf
        mode = settle_mode(
            out["slip"], threshold, out["hold_margin"], out["hold_force"], slipping_from
        )
        if mode != self.state["mode"]:
            self._set_mode(master, mode)
        if master.out[self.stator]["normal_force"] <= 0.0:
            self._set_mode(master, MODE_FREE)


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
