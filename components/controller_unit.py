"""Delayed-feedback controller unit: the disc state in, the Pyragas or ETDAS force out.

The unit keeps the fed-back signal's history as samples taken at the
communication points (its hidden state): rows ``(t, zx, zy, Sx, Sy)`` with the
ETDAS filter ``S(t) = (1 - R) z(t - tau) + R S(t - tau)`` beside the signal.
It evaluates ``z`` and ``S`` at ``t - tau(t)`` by cubic Lagrange interpolation
through the four samples around it; before the first sample the history is
the first sample (constant initial function, whose filter is itself).  The
force depends on the current input directly (feedthrough).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .controller import CONTROLLER_PARAMS, base_delay, delay_at, etdas_blend, feedback_force
from .declaration import Derived, FmuIdentity, Need, UnitType, Wire
from .delay_history import ROW
from .flat_controller import N_FOUND, OK, controller_outputs, controller_params, controller_step
from .parameters import nonnegative
from .unit import StepError, Unit, planar_motion, real_signal

SPEED = nonnegative(
    "speed",
    None,
    "rad/s",
    "rotor spin speed; sets the delay when it is given in periods (0 if delay is given)",
    example=379.473319,
)


class DelayedFeedbackUnit(Unit):
    """Delayed-feedback controller ``u = K (S(t) - z(t))`` on both axes, where
    ``S = (1 - R) z(t - tau) + R S(t - tau)`` (R = 0: Pyragas, ``S = z(t - tau)``).

    Its step and outputs are the kernels the compiled master runs on a buffer
    (:func:`.flat_controller.controller_step`, :func:`.flat_controller.controller_outputs`),
    here on the history alone with room after it for one step's rows: one definition of
    the history's bookkeeping for every master and for the FMU."""

    role = "controller"
    type_name = "delayed_feedback"
    # a zero-length step records the signal's left limit before a jump (see _advance)
    records_left_limits = True
    summary = "delayed-feedback controller (Pyragas or ETDAS), fixed or modulated delay"
    params_spec = (*CONTROLLER_PARAMS, SPEED)
    inputs = planar_motion("disc")
    outputs = (
        real_signal("ux", "N", "control force on the disc along x"),
        real_signal("uy", "N", "control force on the disc along y"),
        real_signal("current_delay", "s", "current delay tau(t)"),
    )

    def _check(self, params: dict[str, Any]) -> None:
        base_delay(params, params["speed"], self.name, f"{self.name}.speed")
        self._p = controller_params(params)

    def _initial_state(self) -> dict[str, Any]:
        # rows (t, zx, zy, Sx, Sy, kind); empty until the first step records a sample,
        # whose time is "start": the constant initial function meets the signal there
        # with a kink
        return {"history": np.zeros((0, ROW)), "start": math.nan}

    def _bounds(self, hist: np.ndarray) -> np.ndarray:
        return np.array([0.0, float(hist.shape[0]), self.state["start"]])

    def _inputs(self) -> tuple[float, float, float, float]:
        u = self.u
        return u["x"], u["y"], u["vx"], u["vy"]

    def _advance(self, t: float, h: float) -> None:
        hist = self.state["history"]
        n = hist.shape[0]
        # a step writes the filter's jumps and kinks it meets (two rows each, at most
        # N_FOUND of them) and its sample after the history
        buf = np.zeros((n + 2 * N_FOUND + 1, ROW))
        buf[:n] = hist
        cs = self._bounds(hist)
        scratch = np.empty((buf.shape[0] + 1, ROW))
        if controller_step(self._p, cs, buf, scratch, *self._inputs(), t) != OK:
            raise StepError(
                f"{self.name}: more than {N_FOUND} jumps of the delayed signal arrive in the "
                f"step from t = {t}; take shorter steps"
            )
        self.state["history"] = buf[int(cs[0]) : int(cs[1])].copy()
        self.state["start"] = float(cs[2])

    def _outputs(self) -> dict[str, float]:
        hist = self.state["history"]
        out = np.empty(3)
        scratch = np.empty((hist.shape[0] + 1, ROW))
        controller_outputs(self._p, self._bounds(hist), hist, scratch, *self._inputs(),
                           self.time, out)  # fmt: skip
        return {"ux": float(out[0]), "uy": float(out[1]), "current_delay": float(out[2])}


DELAYED_FEEDBACK = UnitType(
    DelayedFeedbackUnit,
    CONTROLLER_PARAMS,
    FmuIdentity("RubcosimDelayedFeedbackController"),
    needs=(Need("speed", "rotor.speed"),),
    derived=(
        Derived(
            "base_delay",
            "s",
            "delay tau0 (delay, or delay_periods spin periods)",
            lambda q: base_delay(q, q["speed"]),
        ),
    ),
    wiring=tuple(Wire(s, (f"rotor.{s}",)) for s in ("x", "y", "vx", "vy")),
    kernels=(delay_at, feedback_force, etdas_blend),
)
