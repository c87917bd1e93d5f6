"""Single-DOF impact oscillator unit: the impacts happen inside its own steps.

Between impacts the oscillator is integrated with DOP853 and the barrier
crossing is located as a terminal event; Newton's law ``v+ = -R v-`` is
applied there and integration restarts.  A rebound slower than
``chatter_tol * |D| w`` ends a chattering sequence: the mass then sticks to
the barrier while the free acceleration pushes it into the barrier and is
released when that acceleration changes sign (located as an event too).
Elastic stops are integrated through (their force is continuous).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .declaration import FmuIdentity, State, UnitType
from .oscillator import (
    OSCILLATOR_PARAMS,
    barrier_gap,
    check_oscillator,
    elastic_stop_force,
    free_acceleration,
    pressing,
    stop_impact,
)
from .oscillator import STOP_KINDS as _STOPS
from .parameters import positive
from .stepping import event, integrate
from .unit import INTEGRATOR_PARAMS, Unit, integer_signal, real_signal

FREE, STUCK_UPPER, STUCK_LOWER = 0, 1, -1
MAX_EVENTS_PER_STEP = 100_000

CHATTER_TOL = positive(
    "chatter_tol",
    1e-10,
    "1",
    "rebound speed, in units of |barrier| * forcing_frequency, below which the mass sticks",
)


class ImpactOscillatorUnit(Unit):
    """``x'' + b x' + a x + c3 x^3 = f cos(w t) + force + F_stop`` with rigid or elastic stops."""

    role = "oscillator"
    type_name = "impact_oscillator"
    summary = "single-DOF (Duffing) impact oscillator with rigid or elastic stops"
    params_spec = (*OSCILLATOR_PARAMS, *INTEGRATOR_PARAMS, CHATTER_TOL)
    feedthrough = False
    inputs = (real_signal("force", "m/s^2", "external force per unit mass"),)
    outputs = (
        real_signal("x", "m", "displacement"),
        real_signal("v", "m/s", "velocity"),
        integer_signal("impacts", "number of impacts on a rigid stop so far"),
        integer_signal("stuck", "1 stuck on the barrier +D, -1 on -D, 0 free"),
        real_signal("contact", "1", "0 free, 1 in an elastic stop, 2 stuck on a barrier"),
    )

    def _check(self, params: dict[str, Any]) -> None:
        check_oscillator(params, self.name)
        self.stop = _STOPS.index(params["stop"])
        self.rigid = params["stop"].startswith("rigid")
        self.two_sided = params["stop"].endswith("two_sided")
        length = abs(params["barrier"]) or 1.0
        self.v_chatter = params["chatter_tol"] * length * params["forcing_frequency"]

    def _initial_state(self) -> dict[str, Any]:
        q = self.params
        return {"y": np.array([q["x0"], q["v0"]]), "h": 0.0, "mode": FREE, "impacts": 0}

    def _free_acc(self, t: float, x: float, v: float) -> float:
        q = self.params
        acc = free_acceleration(
            t, x, v, q["linear_stiffness"], q["damping"], q["cubic_stiffness"],
            q["forcing_amplitude"], q["forcing_frequency"],
        )  # fmt: skip
        return acc + self.input_at("force", t)

    def _rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        q = self.params
        acc = self._free_acc(t, y[0], y[1])
        acc += elastic_stop_force(y[0], self.stop, q["barrier"], q["stop_stiffness"])
        return np.array([y[1], acc])

    def _free_events(self):
        D = self.params["barrier"]
        events = [event(lambda t, y: barrier_gap(y[0], D, 1), -1.0)]
        if self.two_sided:
            events.append(event(lambda t, y: barrier_gap(y[0], D, -1), -1.0))
        return events

    def _release_event(self, side: int):
        D = self.params["barrier"] * side
        # stuck while pushed into the barrier
        return [event(lambda t, y: pressing(side, self._free_acc(t, D, 0.0)), -1.0)]

    def _advance(self, t: float, h: float) -> None:
        q = self.params
        t_end = t + h
        st = self.state
        for _ in range(MAX_EVENTS_PER_STEP):
            if t >= t_end:
                return
            if st["mode"] == FREE:
                events = self._free_events() if self.rigid else ()
                rhs = self._rhs
            else:
                events = self._release_event(st["mode"])
                rhs = _at_rest
            seg = integrate(rhs, t, t_end, st["y"], q["rtol"], q["atol"], st["h"], events)
            t, st["y"], st["h"] = seg.t, seg.y, seg.h_next
            if seg.event < 0:
                return
            if st["mode"] != FREE:
                st["mode"] = FREE
                continue
            self._impact(t, 1 if seg.event == 0 else -1)
        raise RuntimeError(f"more than {MAX_EVENTS_PER_STEP} impacts in one step")

    def _impact(self, t: float, side: int) -> None:
        st = self.state
        D = self.params["barrier"] * side
        y = st["y"]
        y[0] = D  # the locator leaves the mass within round-off of the barrier
        y[1], stuck = stop_impact(
            y[1], self.params["restitution"], self.v_chatter, side, self._free_acc(t, D, 0.0)
        )
        st["impacts"] += 1
        if stuck:
            st["mode"] = STUCK_UPPER if side > 0 else STUCK_LOWER

    def _outputs(self) -> dict[str, float]:
        y = self.state["y"]
        mode = self.state["mode"]
        D = self.params["barrier"]
        elastic = self.params["stop"].startswith("elastic")
        pressing = elastic and (y[0] > D or (self.two_sided and y[0] < -D))
        contact = 2.0 if mode != FREE else (1.0 if pressing else 0.0)
        return {
            "x": y[0],
            "v": y[1],
            "impacts": self.state["impacts"],
            "stuck": mode,
            "contact": contact,
        }


def _at_rest(t: float, y: np.ndarray) -> np.ndarray:
    return np.zeros(2)


IMPACT_OSCILLATOR = UnitType(
    ImpactOscillatorUnit,
    OSCILLATOR_PARAMS,
    FmuIdentity("RubcosimImpactOscillator"),
    states=(State("x", "m", "length"), State("v", "m/s", "velocity")),
    # the barrier's distance, or 1 (a nondimensional oscillator) when it is at 0
    length_scale=lambda q: abs(q["barrier"]) if q["barrier"] != 0.0 else 1.0,
    clock=lambda q: (q["forcing_frequency"], q["forcing_frequency"]),
    kernels=(free_acceleration, elastic_stop_force, barrier_gap, pressing, stop_impact),
)
