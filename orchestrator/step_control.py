"""Macro-step size policies: fixed, or a PI controller on the coupling error estimate."""

from __future__ import annotations

from dataclasses import dataclass

from .coupling_kernels import PI_ERR_START, pi_accept, pi_reject


@dataclass
class PIController:
    """Proportional-integral step-size control (Gustafsson; Hairer & Wanner IV.2).

    ``order`` is the order of the local error estimate (extrapolation order + 1);
    an error norm ``err <= 1`` is accepted.  ``h_next = h * safety * err^-a *
    err_prev^b`` with ``a = 0.7 / order`` and ``b = 0.4 / order``, the change
    bounded to [0.2, 5] (:func:`.coupling_kernels.pi_accept`).
    """

    order: int
    err_prev: float = PI_ERR_START

    def accept(self, h: float, err: float) -> float:
        """Next step size after an accepted step with error norm ``err``."""
        h_next, self.err_prev = pi_accept(h, err, self.err_prev, self.order)
        return float(h_next)

    def reject(self, h: float, err: float) -> float:
        """Smaller step after a rejected one (no integral memory)."""
        return float(pi_reject(h, err, self.order))

    def restart(self) -> None:
        """Forget the error history (after an event the coupling signals restart)."""
        self.err_prev = PI_ERR_START
