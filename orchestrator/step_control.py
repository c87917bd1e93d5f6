"""Macro-step size policies: fixed, or a PI controller on the coupling error estimate."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass
class PIController:
    """Proportional-integral step-size control (Gustafsson; Hairer & Wanner IV.2).

    ``order`` is the order of the local error estimate (extrapolation order + 1);
    an error norm ``err <= 1`` is accepted.  ``h_next = h * safety * err^-a *
    err_prev^b`` with ``a = 0.7 / order`` and ``b = 0.4 / order``, the change
    bounded to [``min_factor``, ``max_factor``].
    """

    order: int
    safety: float = 0.9
    min_factor: float = 0.2
    max_factor: float = 5.0
    err_prev: float = 1e-4

    def accept(self, h: float, err: float) -> float:
        """Next step size after an accepted step with error norm ``err``."""
        err = max(err, 1e-10)
        a, b = 0.7 / self.order, 0.4 / self.order
        factor = self.safety * err**-a * self.err_prev**b
        self.err_prev = err
        return h * min(self.max_factor, max(self.min_factor, factor))

    def reject(self, h: float, err: float) -> float:
        """Smaller step after a rejected one (no integral memory)."""
        factor = self.safety * err ** (-1.0 / self.order) if math.isfinite(err) else 0.0
        return h * min(0.9, max(self.min_factor, factor))

    def restart(self) -> None:
        """Forget the error history (after an event the coupling signals restart)."""
        self.err_prev = 1e-4
