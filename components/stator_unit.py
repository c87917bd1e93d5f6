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

from .contact_law import ContactLaw
from .declaration import Derived, FmuIdentity, Need, UnitType, Wire, planar_states
from .flat_units import RowOutputs, flat_params
from .parameters import ParameterError, nonnegative
from .stator import (
    CASING_PARAMS,
    ELASTIC_PARAMS,
    RIGID_PARAMS,
    constraint_normal_force,
    contact_geometry,
    penalty_damping,
    penalty_normal,
    rigid_impact,
    slip_speed,
    sticking_friction,
)
from .stepping import step_ode
from .unit import INTEGRATOR_PARAMS, Unit, integer_signal, planar_motion, real_signal
from .unit_odes import CASING, row_contact_force, unit_rhs

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
NORMAL_FORCE = real_signal("normal_force", "N", "normal contact force (> 0 pushes the disc inward)")
CONTACT = real_signal("contact", "1", "contact state: 0 free, 1 in contact or sliding, 2 sticking")
SLIP = real_signal(
    "slip", "m/s", "slip speed of the disc surface over the stator, v.t + Rd w (t = z x n)"
)


class RigidStatorUnit(RowOutputs, Unit):
    """Rigid stator: the gap, the post-impact disc velocity and, in sustained contact,
    the constraint force that holds the disc on its surface."""

    role = "stator"
    type_name = "rigid"
    summary = (
        "rigid stator: gap event indicator, post-impact disc velocity (reset protocol), "
        "constraint and friction force in sustained contact"
    )
    protocol = (
        "Impact protocol: gap is the event indicator (> 0 clear); when it reaches 0 with "
        "gap_rate < 0, step every unit onto the crossing time, then copy vx_plus, vy_plus to "
        "the rotor's reset_vx, reset_vy and increment its reset_counter. Sustained contact: "
        "set contact_mode (1 sliding with slip > 0, 2 sliding with slip < 0, 3 sticking) and "
        "feed the rotor's own force plus any other disc force to other_fx, other_fy; fx, fy "
        "then hold the disc on the stator; leave contact when normal_force falls through 0, "
        "change the sliding mode when slip crosses 0 and leave sticking when hold_margin "
        "falls through 0"
    )
    params_spec = (
        *RIGID_PARAMS,
        *ROTOR_PARAMS,
        nonnegative("disc_mass", 0.0, "kg", "disc mass; needed (> 0) only for sustained contact"),
        nonnegative(
            "constraint_rate",
            0.0,
            "rad/s",
            "Baumgarte rate pulling drift in sustained contact back onto the surface",
        ),
    )
    inputs = (
        *DISC_INPUTS,
        real_signal("other_fx", "N", "every force on the disc along x but the stator's"),
        real_signal("other_fy", "N", "every force on the disc along y but the stator's"),
        integer_signal(
            "contact_mode", "0 free (impacts), 1 sliding slip > 0, 2 sliding slip < 0, 3 sticking"
        ),
    )
    outputs = (
        GAP,
        GAP_RATE,
        real_signal("vx_plus", "m/s", "disc velocity along x just after an impact now"),
        real_signal("vy_plus", "m/s", "disc velocity along y just after an impact now"),
        real_signal("fx", "N", "contact force on the disc along x (sustained contact only)"),
        real_signal("fy", "N", "contact force on the disc along y (sustained contact only)"),
        NORMAL_FORCE,
        CONTACT,
        SLIP,
        real_signal(
            "hold_margin",
            "N",
            "friction reserve mu N - |F_hold| of a sticking contact (< 0: it starts to slide)",
        ),
        real_signal(
            "hold_force",
            "N",
            "tangential force (along t = z x n) that would keep the slip speed constant",
        ),
    )

    def _initial_state(self) -> dict[str, Any]:
        return {}

    def _advance(self, t: float, h: float) -> None:
        """A rigid stator has no dynamics of its own."""


class _Penalty(RowOutputs, Unit):
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


PENALTY_OUTPUTS = (
    real_signal("fx", "N", "contact force on the disc along x"),
    real_signal("fy", "N", "contact force on the disc along y"),
    NORMAL_FORCE,
    GAP,
    GAP_RATE,
    CONTACT,
)


class MasslessPenaltyStator(RowOutputs, Unit):
    """A massless stator with a penalty contact law (its type's :mod:`.contact_law`):
    the contact force on the disc from the disc state alone."""

    role = "stator"
    inputs = DISC_INPUTS
    outputs = PENALTY_OUTPUTS

    def _initial_state(self) -> dict[str, Any]:
        return {}

    def _advance(self, t: float, h: float) -> None:
        """A massless stator has no dynamics of its own."""


class ElasticStatorUnit(_Penalty, MasslessPenaltyStator):
    """Massless elastic stator: penalty contact with Coulomb friction."""

    type_name = "elastic"
    summary = "elastic stator: penalty contact force with Coulomb friction on the disc"
    params_spec = (*ELASTIC_PARAMS, *ROTOR_PARAMS, IMPACT_MASS)


class CasingStatorUnit(_Penalty):
    """Elastic stator on a casing of its own mass, spring-mounted to ground."""

    type_name = "casing"
    summary = "elastic stator on a sprung casing mass; penalty contact with the disc"
    params_spec = (*CASING_PARAMS, *ROTOR_PARAMS, IMPACT_MASS, *INTEGRATOR_PARAMS)
    inputs = DISC_INPUTS
    outputs = (
        *PENALTY_OUTPUTS,
        *planar_motion("casing", "casing_"),
    )

    def _initial_state(self) -> dict[str, Any]:
        q = self.params
        return {"y": np.array([q["x0"], q["y0"], q["vx0"], q["vy0"]], dtype=float), "h": 0.0}

    def _advance(self, t: float, h: float) -> None:
        q, st = self.params, self.state
        p = flat_params(self.role, self.type_name, q)  # its row: the compiled master's
        st["y"], st["h"] = step_ode(
            CASING, t, t + h, st["y"], st["h"], p, self.input_rows(("x", "y", "vx", "vy")),
            q["rtol"], q["atol"],
        )  # fmt: skip


# What every stator takes from the rotor it meets, and the disc state it reads.
ROTOR_NEEDS = (Need("speed", "rotor.speed"), Need("disc_radius", "rotor.disc_radius"))
DISC_WIRING = tuple(Wire(s, (f"rotor.{s}",)) for s in ("x", "y", "vx", "vy"))
PENALTY_DAMPING = Derived(
    "penalty_damping", "N s/m", "contact damping of the penalty law", penalty_damping
)

RIGID_STATOR = UnitType(
    RigidStatorUnit,
    RIGID_PARAMS,
    FmuIdentity("RubcosimRigidStator"),
    needs=(
        *ROTOR_NEEDS,
        Need("disc_mass", "rotor.disc_mass"),
        Need("constraint_rate", "rotor.constraint_rate"),
    ),
    # every disc force but the stator's own: the rotor's, then the controller's
    wiring=(
        *DISC_WIRING,
        Wire("other_fx", ("rotor.force_x", "controller.ux")),
        Wire("other_fy", ("rotor.force_y", "controller.uy")),
    ),
    length_scale=lambda q: q["clearance"],
    kernels=(
        contact_geometry,
        rigid_impact,
        slip_speed,
        constraint_normal_force,
        sticking_friction,
    ),
    contact=ContactLaw("rigid"),
)

# The Kelvin-Voigt law of the brief: Fn = kc (dist - d) + cc vn.
KELVIN_VOIGT = ContactLaw(
    "penalty", penalty_normal, ("clearance", "contact_stiffness", "penalty_damping")
)

ELASTIC_STATOR = UnitType(
    ElasticStatorUnit,
    ELASTIC_PARAMS,
    FmuIdentity("RubcosimElasticStator"),
    needs=(*ROTOR_NEEDS, Need("impact_mass", "rotor.disc_mass")),
    derived=(PENALTY_DAMPING,),
    wiring=DISC_WIRING,
    length_scale=lambda q: q["clearance"],
    kernels=(contact_geometry, row_contact_force, penalty_normal),
    contact=KELVIN_VOIGT,
)

CASING_STATOR = UnitType(
    CasingStatorUnit,
    CASING_PARAMS,
    FmuIdentity("RubcosimCasingStator"),
    states=planar_states("casing_", initial=""),
    # the disc meets the casing: the impact sees their reduced mass
    needs=(*ROTOR_NEEDS, Need("impact_mass", "rotor.disc_mass", reduced_with="mass")),
    derived=(PENALTY_DAMPING,),
    wiring=DISC_WIRING,
    length_scale=lambda q: q["clearance"],
    kernels=(contact_geometry, row_contact_force, penalty_normal, unit_rhs),
    contact=KELVIN_VOIGT,
)
