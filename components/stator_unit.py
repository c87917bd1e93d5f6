"""Stator units: rigid (impact law), elastic (penalty contact), elastic on a moving casing.

Every stator reads the disc state (``x``, ``y``, ``vx``, ``vy``) and publishes
its gap ``gap = d - |p - c|`` (m, positive while the disc is clear) as the
event indicator a master watches.

Rigid stator event protocol: when ``gap`` reaches zero with ``gap_rate < 0``
the master puts every unit on the crossing time, reads ``vx_plus``/``vy_plus``
(the disc velocity after Newton's restitution and the Coulomb impulse,
computed from the disc state the stator sees now), writes them to the rotor's
``reset_vx``/``reset_vy`` and increments the rotor's ``reset_counter``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from .bearing import linear_bearing_force
from .parameters import ParameterError, nonnegative
from .stator import (
    CASING_PARAMS,
    ELASTIC_PARAMS,
    RIGID_PARAMS,
    contact_geometry,
    damping_from_restitution,
    penalty_contact_force,
    rigid_impact,
)
from .stepping import integrate
from .unit import INTEGRATOR_PARAMS, Unit, planar_motion, real_signal

ROTOR_PARAMS = (
    nonnegative("speed", 0.0, "rad/s", "spin speed w of the rotor this stator meets"),
    nonnegative("disc_radius", 0.0, "m", "radius Rd of the rotor's rubbing surface"),
)

IMPACT_MASS = nonnegative(
    "impact_mass",
    0.0,
    "kg",
    "mass of the disc (reduced with the casing's) used to derive contact_damping from "
    "restitution; needed only when contact_damping < 0 and restitution < 1",
)

DISC_INPUTS = planar_motion("disc")

GAP = real_signal("gap", "m", "event indicator: clearance minus disc distance (> 0 while clear)")
GAP_RATE = real_signal("gap_rate", "m/s", "time derivative of gap (< 0 while approaching)")


def _relative(u: Mapping[str, float], cx: float, cy: float, cvx: float, cvy: float):
    return u["x"] - cx, u["y"] - cy, u["vx"] - cvx, u["vy"] - cvy


class RigidStatorUnit(Unit):
    """Rigid stator: publishes the gap and the post-impact disc velocity."""

    role = "stator"
    type_name = "rigid"
    summary = "rigid stator: gap event indicator and post-impact disc velocity (reset protocol)"
    protocol = (
        "Impact protocol: gap is the event indicator (> 0 clear); when it reaches 0 with "
        "gap_rate < 0, step every unit onto the crossing time, then copy vx_plus, vy_plus to "
        "the rotor's reset_vx, reset_vy and increment its reset_counter"
    )
    params_spec = (*RIGID_PARAMS, *ROTOR_PARAMS)
    inputs = DISC_INPUTS
    outputs = (
        GAP,
        GAP_RATE,
        real_signal("vx_plus", "m/s", "disc velocity along x just after an impact now"),
        real_signal("vy_plus", "m/s", "disc velocity along y just after an impact now"),
    )

    def _initial_state(self) -> dict[str, Any]:
        return {}

    def _advance(self, t: float, h: float) -> None:
        """A rigid stator has no dynamics of its own."""

    def _outputs(self) -> dict[str, float]:
        q = self.params
        rx, ry, rvx, rvy = _relative(self.u, q["x_offset"], q["y_offset"], 0.0, 0.0)
        dist, nx, ny = contact_geometry(rx, ry)
        vx, vy = rigid_impact(
            rvx, rvy, nx, ny, q["restitution"], q["friction"], q["disc_radius"], q["speed"]
        )
        return {
            "gap": q["clearance"] - dist,
            "gap_rate": -(rvx * nx + rvy * ny),
            "vx_plus": vx,
            "vy_plus": vy,
        }


class _Penalty(Unit):
    role = "stator"

    def _check(self, params: Mapping[str, Any]) -> None:
        if (
            params["contact_damping"] < 0.0
            and params["restitution"] < 1.0
            and params["impact_mass"] <= 0.0
        ):
            raise ParameterError(
                f"{self.name}.impact_mass is required (> 0) to derive contact_damping from "
                f"restitution = {params['restitution']!r}; or give contact_damping >= 0"
            )

    def _contact_damping(self) -> float:
        q = self.params
        if q["contact_damping"] >= 0.0:
            return q["contact_damping"]
        return damping_from_restitution(q["restitution"], q["contact_stiffness"], q["impact_mass"])

    def _contact(self, cx: float, cy: float, cvx: float, cvy: float):
        """(fx, fy, Fn, gap, gap_rate) on the disc for a stator centred at (cx, cy)."""
        q = self.params
        rx, ry, rvx, rvy = _relative(self.u, cx, cy, cvx, cvy)
        fx, fy, fn = penalty_contact_force(
            rx, ry, rvx, rvy, q["clearance"], q["contact_stiffness"], self._contact_damping(),
            q["friction"], q["disc_radius"], q["speed"],
        )  # fmt: skip
        dist, nx, ny = contact_geometry(rx, ry)
        return fx, fy, fn, q["clearance"] - dist, -(rvx * nx + rvy * ny)


_FORCE_OUTPUTS = (
    real_signal("fx", "N", "contact force on the disc along x"),
    real_signal("fy", "N", "contact force on the disc along y"),
    real_signal("normal_force", "N", "normal contact force (> 0 pushes the disc inward)"),
    GAP,
    GAP_RATE,
)


class ElasticStatorUnit(_Penalty):
    """Massless elastic stator: penalty contact with Coulomb friction."""

    type_name = "elastic"
    summary = "elastic stator: penalty contact force with Coulomb friction on the disc"
    params_spec = (*ELASTIC_PARAMS, *ROTOR_PARAMS, IMPACT_MASS)
    inputs = DISC_INPUTS
    outputs = _FORCE_OUTPUTS

    def _initial_state(self) -> dict[str, Any]:
        return {}

    def _advance(self, t: float, h: float) -> None:
        """A massless stator has no dynamics of its own."""

    def _outputs(self) -> dict[str, float]:
        q = self.params
        fx, fy, fn, gap, rate = self._contact(q["x_offset"], q["y_offset"], 0.0, 0.0)
        return {"fx": fx, "fy": fy, "normal_force": fn, "gap": gap, "gap_rate": rate}


class CasingStatorUnit(_Penalty):
    """Elastic stator on a casing of its own mass, spring-mounted to ground."""

    type_name = "casing"
    summary = "elastic stator on a sprung casing mass; penalty contact with the disc"
    params_spec = (*CASING_PARAMS, *ROTOR_PARAMS, IMPACT_MASS, *INTEGRATOR_PARAMS)
    inputs = DISC_INPUTS
    outputs = (
        *_FORCE_OUTPUTS,
        *planar_motion("casing", "casing_"),
    )

    def _initial_state(self) -> dict[str, Any]:
        q = self.params
        return {"y": np.array([q["x0"], q["y0"], q["vx0"], q["vy0"]], dtype=float), "h": 0.0}

    def _centre(self, c: np.ndarray) -> tuple[float, float, float, float]:
        q = self.params
        return q["x_offset"] + c[0], q["y_offset"] + c[1], c[2], c[3]

    def _rhs(self, t: float, c: np.ndarray) -> np.ndarray:
        q = self.params
        fx, fy, _, _, _ = self._contact(*self._centre(c))
        # the mount is an isotropic spring-damper (the linear bearing's law); the casing
        # feels the opposite of the contact force on the disc
        sx, sy = linear_bearing_force(c[0], c[1], c[2], c[3], q["stiffness"], q["damping"])
        ms = q["mass"]
        return np.array([c[2], c[3], (sx - fx) / ms, (sy - fy) / ms])

    def _advance(self, t: float, h: float) -> None:
        q = self.params
        seg = integrate(self._rhs, t, t + h, self.state["y"], q["rtol"], q["atol"], self.state["h"])
        self.state["y"] = seg.y
        self.state["h"] = seg.h_next

    def _outputs(self) -> dict[str, float]:
        c = self.state["y"]
        fx, fy, fn, gap, rate = self._contact(*self._centre(c))
        return {
            "fx": fx,
            "fy": fy,
            "normal_force": fn,
            "gap": gap,
            "gap_rate": rate,
            "casing_x": c[0],
            "casing_y": c[1],
            "casing_vx": c[2],
            "casing_vy": c[3],
        }
