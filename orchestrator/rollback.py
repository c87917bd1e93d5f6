"""Rollback for the master: snapshots of every unit and of the master's own state.

A mixin of :class:`.master.Master`.  A unit snapshot is whatever the unit's
``get_state`` returns (an FMU's is an ``fmi2FMUstate``, freed through
``free_state``); the master's state is everything a replay from a checkpoint
must find as it was: time, step, the controller's memory, the input histories,
the protocols' states and how much has been recorded.
"""

from __future__ import annotations

import copy
from collections import deque
from collections.abc import Mapping
from typing import Any


class Rollback:
    """Snapshots and restores for a master (see :mod:`.master`)."""

    def _snapshot(self) -> dict[str, Any]:
        self.counters["snapshots"] += 1
        return {name: unit.get_state() for name, unit in self.units.items()}

    def _restore(self, snap: Mapping[str, Any]) -> None:
        for name, unit in self.units.items():
            unit.set_state(snap[name])

    def _free(self, snap: Mapping[str, Any] | None) -> None:
        if snap is None:
            return
        for name, unit in self.units.items():
            free = getattr(unit, "free_state", None)
            if free is not None:
                free(snap[name])

    def _master_state(self) -> dict[str, Any]:
        return copy.deepcopy(
            {
                "time": self.time,
                "h": self.h,
                "err_prev": self.pi.err_prev,
                "hist": self.hist,
                "scale": self.scale,
                "accel": self.accel,
                "out": self.out,
                "protocols": [p.state for p in self.protocols],
                "rows": len(self.recorder),
                "events": len(self.events),
                "k_out": self.k_out,
                "recent": list(self.recent_events),
            }
        )

    def _set_master_state(self, s: dict[str, Any]) -> None:
        s = copy.deepcopy(s)
        self.time, self.h, self.pi.err_prev = s["time"], s["h"], s["err_prev"]
        self.hist, self.scale, self.accel, self.out = s["hist"], s["scale"], s["accel"], s["out"]
        for p, state in zip(self.protocols, s["protocols"], strict=True):
            p.state = state
        self.recorder.truncate(s["rows"])
        del self.events[s["events"] :]
        self.k_out = s["k_out"]
        self.recent_events = deque(s["recent"])
