"""Rotor units: the Jeffcott disc and the journal + disc two-mass rotor.

Inputs are forces from the other units (stator contact, controller, bearing),
held constant over a step.  A rigid stator cannot act through a force: it
resets the disc velocity.  The reset protocol: the master writes the
post-impact velocity to ``reset_vx``/``reset_vy`` and changes the integer
``reset_counter``; at the start of its next step the rotor replaces its disc
velocity by the reset values and reports the counter it has applied in
``resets_applied``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from .declaration import FmuIdentity, Provided, UnitType, Wire, planar_states
from .flat_units import RowOutputs
from .jit import USE_NUMBA
from .linear_propagation import affine_model, exact_step
from .modal_propagation import ModalPropagator
from .parameters import choice
from .propagator_cache import PropagatorCache
from .rotor import (
    JEFFCOTT_PARAMS,
    TWO_MASS_PARAMS,
    jeffcott_force,
    two_mass_disc_force,
)
from .stepping import step_ode
from .unit import INTEGRATOR_PARAMS, Unit, integer_signal, planar_motion, real_signal
from .unit_odes import JEFFCOTT, JEFFCOTT_P, TWO_MASS, TWO_MASS_P, unit_rhs

_DISC_INPUTS = (
    real_signal("fx", "N", "external force on the disc along x (contact + control)"),
    real_signal("fy", "N", "external force on the disc along y (contact + control)"),
    real_signal("reset_vx", "m/s", "disc velocity along x to apply at the next reset"),
    real_signal("reset_vy", "m/s", "disc velocity along y to apply at the next reset"),
    integer_signal("reset_counter", "change it to request a disc velocity reset"),
)

_DISC_OUTPUTS = (
    *planar_motion("disc"),
    integer_signal("resets_applied", "reset_counter value of the last applied reset"),
    real_signal(
        "force_x",
        "N",
        "the rotor's own force on the disc along x (shaft, damping, unbalance, gravity): what "
        "a rigid stator needs to hold the disc on its surface",
    ),
    real_signal("force_y", "N", "the rotor's own force on the disc along y"),
)


# How a linear unit steps its ODE over a macro step (the co-simulation's
# ``cosim.unit_integrator``): exactly, or with the compiled DOP853 at rtol/atol.
LINEAR_INTEGRATOR = choice(
    "integrator",
    "exact",
    "exact: matrix exponential of the affine ODE with polynomial inputs and harmonic "
    "unbalance (round-off only); dop853: the compiled DOP853 at rtol, atol",
    ("exact", "dop853"),
)

RESET_PROTOCOL = (
    "Velocity reset protocol: write the new disc velocity to reset_vx, reset_vy and change "
    "reset_counter; the reset is applied at the start of the next fmi2DoStep and "
    "resets_applied then equals reset_counter"
)


class _Rotor(RowOutputs, Unit):
    role = "rotor"
    protocol = RESET_PROTOCOL
    feedthrough = False

    def _initial_y(self) -> list[float]:
        q = self.params
        return [q["x0"], q["y0"], q["vx0"], q["vy0"]]

    def _initial_state(self) -> dict[str, Any]:
        y = np.array(self._initial_y(), dtype=float)
        return {"y": y, "h": 0.0, "resets_applied": 0, "last_step": 0.0}

    def _apply_reset(self) -> None:
        counter = int(self.u["reset_counter"])
        if counter != self.state["resets_applied"]:
            self.state["y"][2] = self.u["reset_vx"]
            self.state["y"][3] = self.u["reset_vy"]
            self.state["resets_applied"] = counter

    # the ODE (rubcosim.components.unit_odes): its kind, parameters and inputs, in order
    ode_kind: int
    ode_params: tuple[str, ...]
    ode_inputs: tuple[str, ...]

    def _ode_params(self) -> np.ndarray:
        return np.array([self.params[k] for k in self.ode_params], dtype=float)

    def _linear_model(self) -> tuple[np.ndarray, ...]:
        """The affine form of the ODE (:func:`.linear_propagation.affine_model`), read off
        once: the parameters never change after the unit is built."""
        model = getattr(self, "_model", None)
        if model is None:
            n, n_in = len(self._initial_y()), len(self.ode_inputs)
            model = affine_model(self.ode_kind, self._ode_params(), n, n_in, self.params["speed"])
            self._model = model
        return model

    def _propagators(self) -> PropagatorCache:
        """The exact step's propagators per step size (:mod:`.propagator_cache`): not
        state, a function of the parameters and the step size."""
        cache = getattr(self, "_cache_of_steps", None)
        if cache is None:
            cache = PropagatorCache(self._linear_model(), self.params["speed"])
            self._cache_of_steps = cache
        return cache

    def _modal(self) -> ModalPropagator | None:
        """The exact step in modal coordinates (:mod:`.modal_propagation`), None when
        the unit's matrix has no well-conditioned eigenvectors: not state either."""
        if not hasattr(self, "_modal_steps"):
            self._modal_steps = ModalPropagator.build(self._linear_model(), self.params["speed"])
        return self._modal_steps

    def _advance(self, t: float, h: float) -> None:
        self._apply_reset()
        q = self.params
        st = self.state
        u = self.input_rows(self.ode_inputs)
        if q["integrator"] == "exact":
            modal = None if USE_NUMBA or h <= 0.0 else self._modal()
            if h > 0.0 and USE_NUMBA:
                st["y"] = exact_step(t, h, st["y"], self._linear_model(), q["speed"], u)
            elif h > 0.0 and h == st.get("last_step"):
                # plain numpy (an FMU) at a step that recurs: cached propagators
                st["y"] = self._propagators().step(t, h, st["y"], u)
            elif modal is not None:  # plain numpy at a new step: modal coordinates
                st["y"] = modal.step(t, h, st["y"], u)
            elif h > 0.0:  # ... unless A has no well-conditioned eigenvectors
                st["y"] = exact_step(t, h, st["y"], self._linear_model(), q["speed"], u)
            if h > 0.0:
                st["last_step"] = h  # state: a replay from a restore takes the same path
            return
        st["y"], st["h"] = step_ode(
            self.ode_kind, t, t + h, st["y"], st["h"], self._ode_params(), u, q["rtol"], q["atol"]
        )


class JeffcottRotorUnit(_Rotor):
    """Jeffcott rotor: one unbalanced disc on a massless elastic shaft."""

    type_name = "jeffcott"
    summary = "Jeffcott rotor (single disc) with unbalance; velocity reset input for rigid impacts"
    params_spec = (*JEFFCOTT_PARAMS, LINEAR_INTEGRATOR, *INTEGRATOR_PARAMS)
    inputs = _DISC_INPUTS
    outputs = _DISC_OUTPUTS
    ode_kind, ode_params, ode_inputs = JEFFCOTT, JEFFCOTT_P, ("fx", "fy")


class TwoMassRotorUnit(_Rotor):
    """Two-mass rotor: a journal in the bearing and an unbalanced disc, joined by the shaft."""

    type_name = "two_mass"
    summary = "two-mass rotor (journal + disc); bearing force input on the journal"
    params_spec = (*TWO_MASS_PARAMS, LINEAR_INTEGRATOR, *INTEGRATOR_PARAMS)
    inputs = (
        *_DISC_INPUTS,
        real_signal("journal_fx", "N", "bearing force on the journal along x"),
        real_signal("journal_fy", "N", "bearing force on the journal along y"),
    )
    outputs = (
        *_DISC_OUTPUTS,
        *planar_motion("journal", "journal_"),
    )
    ode_kind, ode_params = TWO_MASS, TWO_MASS_P
    ode_inputs = ("fx", "fy", "journal_fx", "journal_fy")

    def _initial_y(self) -> list[float]:
        q = self.params
        journal = [q["journal_x0"], q["journal_y0"], q["journal_vx0"], q["journal_vy0"]]
        return [*super()._initial_y(), *journal]


def rotor_clock(q: Mapping[str, Any]) -> tuple[float, float]:
    """The rotor drives the model: forcing at the spin speed (at the natural frequency
    sqrt(k / m) when it does not spin), frequency scale the faster of the two, rad/s."""
    wn = math.sqrt(q["stiffness"] / q["mass"])
    return (q["speed"] if q["speed"] > 0.0 else wn), max(q["speed"], wn)


def constraint_rate(q: Mapping[str, Any]) -> float:
    """Rate (rad/s) at which a constraint on the disc pulls drift back: the faster of the
    spin speed and the shaft's natural frequency sqrt(k / m), the rotor's own time scale."""
    return max(q["speed"], math.sqrt(q["stiffness"] / q["mass"]))


# What a stator, bearing or controller takes from the rotor (see their ``needs``).
ROTOR_PROVIDES = (
    Provided("speed", "rad/s", "spin speed w", lambda q: q["speed"]),
    Provided("disc_radius", "m", "radius Rd of the rubbing surface", lambda q: q["disc_radius"]),
    Provided("disc_mass", "kg", "disc mass m", lambda q: q["mass"]),
    Provided("constraint_rate", "rad/s", "Baumgarte rate of a contact constraint", constraint_rate),
)

# The disc's forces: contact (stator) plus control (controller), in this order.
DISC_WIRING = (
    Wire("fx", ("stator.fx", "controller.ux")),
    Wire("fy", ("stator.fy", "controller.uy")),
)

JEFFCOTT_ROTOR = UnitType(
    JeffcottRotorUnit,
    JEFFCOTT_PARAMS,
    FmuIdentity("RubcosimJeffcottRotor"),
    states=planar_states(),
    provides=ROTOR_PROVIDES,
    wiring=DISC_WIRING,
    kernels=(jeffcott_force, unit_rhs),
    mass_scale="mass",
    length_scale=lambda q: q["eccentricity"],
    clock=rotor_clock,
)

TWO_MASS_ROTOR = UnitType(
    TwoMassRotorUnit,
    TWO_MASS_PARAMS,
    FmuIdentity("RubcosimTwoMassRotor"),
    states=(*planar_states(), *planar_states("journal_")),
    provides=ROTOR_PROVIDES,
    wiring=(
        *DISC_WIRING,
        Wire("journal_fx", ("bearing.fx",)),
        Wire("journal_fy", ("bearing.fy",)),
    ),
    kernels=(two_mass_disc_force, unit_rhs),
    mass_scale="mass",
    length_scale=lambda q: q["eccentricity"],
    clock=rotor_clock,
)
