"""What the Python master records on the output grid: numbers and texts.

The numeric outputs come from what the master reads after every step (each unit's
``get_outputs``).  A String output of a foreign FMU (``text_outputs`` of
:class:`.fmu_unit.FmuUnit`) is never read by the master's coupling; where the scenario
records it, it is read from its FMU at each recorded time, with one
``fmi2GetString`` per FMU, and kept as text.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np


class Recorder:
    """The recorded outputs (``unit.output`` names), row by row."""

    def __init__(self, record: Sequence[str], units: Mapping[str, Any]) -> None:
        pairs = [tuple(name.split(".", 1)) for name in record]
        self.numbers: list[tuple[str, str]] = []
        self.texts: dict[str, list[str]] = {}  # unit -> its String outputs recorded
        for u, o in pairs:
            if o in getattr(units.get(u), "text_outputs", ()):
                self.texts.setdefault(u, []).append(o)
            else:
                self.numbers.append((u, o))
        self.rows: list[list[float]] = []
        self.text_rows: list[list[str]] = []

    def take(self, out: Mapping[str, Mapping[str, float]], units: Mapping[str, Any]) -> None:
        """One row: the numbers from ``out`` (the outputs the master read last), the
        texts from their FMUs (at the same time: the master records after a step)."""
        self.rows.append([float(out[u][o]) for u, o in self.numbers])
        if self.texts:
            row: list[str] = []
            for u, names in self.texts.items():
                values = units[u].get_values(names)
                row.extend(str(values[o]) for o in names)
            self.text_rows.append(row)

    def __len__(self) -> int:
        return len(self.rows)

    def truncate(self, n: int) -> None:
        """Keep the first ``n`` rows (a rollback to a checkpoint drops the later ones)."""
        del self.rows[n:], self.text_rows[n:]

    def arrays(self, n: int) -> tuple[list[str], np.ndarray, dict[str, np.ndarray]]:
        """The first ``n`` rows: numeric names, their values ``(n, len(names))``, and
        name -> text array for the String outputs."""
        names = [".".join(p) for p in self.numbers]
        values = np.array(self.rows[:n], dtype=float).reshape(n, len(names))
        text_names = [f"{u}.{o}" for u, names_ in self.texts.items() for o in names_]
        columns = np.array(self.text_rows[:n], dtype=str).reshape(n, len(text_names))
        return names, values, {name: columns[:, i] for i, name in enumerate(text_names)}
