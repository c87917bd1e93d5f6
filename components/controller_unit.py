"""Delayed-feedback controller unit: the disc state in, the Pyragas force out.

The unit keeps the fed-back signal's history as samples taken at the
communication points (its hidden state) and evaluates ``z(t - tau(t))`` by
cubic Lagrange interpolation through the four samples around it; before the
first sample the history is the first sample (constant initial function).
The force depends on the current input directly (feedthrough).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .controller import CONTROLLER_PARAMS, base_delay, delay_at, feedback_force
from .declaration import Derived, FmuIdentity, Need, UnitType, Wire
from .parameters import nonnegative
from .unit import Unit, planar_motion, real_signal

SPEED = nonnegative(
    "speed",
    None,
    "rad/s",
    "rotor spin speed; sets the delay when it is given in periods (0 if delay is given)",
    example=379.473319,
)


def lagrange_cubic(ts: np.ndarray, zs: np.ndarray, tq: float) -> np.ndarray:
    """Interpolate rows ``zs`` given at times ``ts`` (up to 4) at ``tq``."""
    out = np.zeros(zs.shape[1])
    for i in range(ts.size):
        w = 1.0
        for j in range(ts.size):
            if j != i:
                w *= (tq - ts[j]) / (ts[i] - ts[j])
        out += w * zs[i]
    return out


class DelayedFeedbackUnit(Unit):
    """Pyragas controller ``u = K (z(t - tau) - z(t))`` on both axes."""

    role = "controller"
    type_name = "delayed_feedback"
    # a zero-length step records the signal's left limit before a jump (see _advance)
    records_left_limits = True
    summary = "delayed-feedback (Pyragas) controller, fixed or modulated delay"
    params_spec = (*CONTROLLER_PARAMS, SPEED)
    inputs = planar_motion("disc")
    outputs = (
        real_signal("ux", "N", "control force on the disc along x"),
        real_signal("uy", "N", "control force on the disc along y"),
        real_signal("current_delay", "s", "current delay tau(t)"),
    )

    def _check(self, params: dict[str, Any]) -> None:
        self.tau0 = base_delay(params, params["speed"], self.name, f"{self.name}.speed")

    def _initial_state(self) -> dict[str, Any]:
        # rows (t, zx, zy); empty until the first step records a sample
        return {"history": np.zeros((0, 3))}

    def _signal(self) -> tuple[float, float]:
        if self.params["feedback"] == "position":
            return self.u["x"], self.u["y"]
        return self.u["vx"], self.u["vy"]

    def _delay(self, t: float) -> float:
        q = self.params
        return delay_at(t, self.tau0, q["modulation_amplitude"], q["modulation_frequency"])

    def _advance(self, t: float, h: float) -> None:
        hist = self.state["history"]
        zx, zy = self._signal()
        if hist.shape[0] and hist[-1, 0] > t:
            hist = hist[hist[:, 0] <= t]  # stepped again from an earlier time: forget the future
        # Two samples at one time mark a jump: a zero-length step recorded the signal just
        # before an impact reset it.  Both stay, and no interpolation stencil spans them.
        if hist.shape[0] and hist[-1, 0] == t and hist[-1, 1] == zx and hist[-1, 2] == zy:
            hist = hist[:-1]
        keep = t + h - self.tau0 - self.params["modulation_amplitude"]
        # keep three samples before the oldest time still needed, for the stencil
        first = max(int(np.searchsorted(hist[:, 0], keep)) - 3, 0)
        self.state["history"] = np.vstack((hist[first:], [[t, zx, zy]]))

    def _delayed(self, tq: float) -> tuple[float, float]:
        hist = self.state["history"]
        zx, zy = self._signal()
        samples = np.vstack((hist[hist[:, 0] < self.time], [[self.time, zx, zy]]))
        if tq <= samples[0, 0]:
            return samples[0, 1], samples[0, 2]
        ts = samples[:, 0]
        # the continuous piece holding tq: between jumps (two samples at one time)
        jumps = np.flatnonzero(ts[1:] == ts[:-1]) + 1
        k = int(np.searchsorted(jumps, int(np.searchsorted(ts, tq, side="right")), side="right"))
        start = jumps[k - 1] if k > 0 else 0
        stop = jumps[k] if k < jumps.size else ts.size
        piece = samples[start:stop]
        i = int(np.searchsorted(piece[:, 0], tq))
        lo = max(min(i - 2, piece.shape[0] - 4), 0)
        window = piece[lo : lo + 4]
        z = lagrange_cubic(window[:, 0], window[:, 1:], tq)
        return z[0], z[1]

    def _outputs(self) -> dict[str, float]:
        t = self.time
        tau = self._delay(t)
        if t < self.params["t_on"]:
            return {"ux": 0.0, "uy": 0.0, "current_delay": tau}
        zx, zy = self._signal()
        dx, dy = self._delayed(t - tau)
        gain = self.params["gain"]
        return {
            "ux": feedback_force(gain, zx, dx),
            "uy": feedback_force(gain, zy, dy),
            "current_delay": tau,
        }


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
    kernels=(delay_at, feedback_force),
)
