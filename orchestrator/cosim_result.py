"""What a co-simulation returns, and how it fails."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .settings import CosimSettings


def fmi_counters(units: Iterable[Any]) -> dict[str, int]:
    """``{"fmi_calls": n}``: the FMI calls made by the FMU units among ``units``
    (:attr:`.fmu_unit.FmuUnit.fmi_calls`); empty when there are none."""
    calls = sum(getattr(unit, "fmi_calls", 0) for unit in units)
    return {"fmi_calls": calls} if calls else {}


class CosimError(RuntimeError):
    """The co-simulation cannot go on; the message names the unit and the time."""


@dataclass
class CosimResult:
    """Recorded outputs on the output grid, the events and the master's counters."""

    t: np.ndarray
    names: list[str]
    values: np.ndarray  # (len(t), len(names))
    event_t: np.ndarray
    event_kind: list[str]
    event_unit: list[str]
    counters: dict[str, int]
    status: str
    message: str
    t_reached: float
    wall_time_s: float
    settings: CosimSettings
    input_orders: dict[str, int] = field(default_factory=dict)
    master: str = "python"  # which master ran: "compiled" or "python" (cosim.master)
    # recorded String outputs of foreign FMUs: name -> text array (len(t),)
    texts: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    @property
    def engine(self) -> str:
        return f"cosim-{self.settings.backend}"

    def output(self, name: str) -> np.ndarray:
        """The recorded values of ``name`` (a text array for a String output)."""
        if name in self.texts:
            return self.texts[name]
        try:
            return self.values[:, self.names.index(name)]
        except ValueError:
            recorded = ", ".join([*self.names, *self.texts])
            raise KeyError(f"{name!r} was not recorded (recorded: {recorded})") from None

    def events_of_kind(self, kind: str) -> np.ndarray:
        return self.event_t[[k == kind for k in self.event_kind]]
