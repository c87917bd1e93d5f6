"""Bearing units: the journal state in, the bearing force on the journal out."""

from __future__ import annotations

from typing import Any

from .bearing import (
    LINEAR_PARAMS,
    OILFILM_PARAMS,
    film_scale,
    linear_bearing_force,
    oilfilm_force,
)
from .bearing_law import BearingLaw
from .declaration import Derived, FmuIdentity, Need, UnitType, Wire
from .flat_units import RowOutputs
from .parameters import positive
from .unit import Unit, planar_motion, real_signal

JOURNAL_INPUTS = planar_motion("journal")

FORCE_OUTPUTS = (
    real_signal("fx", "N", "bearing force on the journal along x"),
    real_signal("fy", "N", "bearing force on the journal along y"),
)


class BearingUnit(RowOutputs, Unit):
    """Base of the bearing unit classes: the journal state in, the force of the type's
    declared law (:mod:`.bearing_law`) out; nothing to integrate."""

    role = "bearing"
    inputs = JOURNAL_INPUTS
    outputs = FORCE_OUTPUTS

    def _initial_state(self) -> dict[str, Any]:
        return {}

    def _advance(self, t: float, h: float) -> None:
        """The bearing force is algebraic in the journal state: nothing to integrate."""


class OilFilmBearingUnit(BearingUnit):
    """Capone short-bearing oil film."""

    type_name = "oilfilm"
    summary = "nonlinear oil-film bearing (Capone short-bearing model)"
    params_spec = (
        *OILFILM_PARAMS,
        positive("speed", None, "rad/s", "journal spin speed w", example=700.0),
    )


class LinearBearingUnit(BearingUnit):
    """Isotropic spring-damper bearing."""

    type_name = "linear"
    summary = "linear isotropic spring-damper bearing"
    params_spec = LINEAR_PARAMS


# The bearing holds the journal of a two-mass rotor.
JOURNAL_WIRING = tuple(Wire(s, (f"rotor.journal_{s}",)) for s in ("x", "y", "vx", "vy"))

OILFILM_BEARING = UnitType(
    OilFilmBearingUnit,
    OILFILM_PARAMS,
    FmuIdentity("RubcosimOilFilmBearing"),
    needs=(Need("speed", "rotor.speed"),),
    derived=(
        Derived(
            "sigma",
            "N",
            "Capone's force scale sigma = mu w R L (R/c)^2 (L/(2R))^2",
            film_scale,
        ),
    ),
    wiring=JOURNAL_WIRING,
    length_scale=lambda q: q["clearance"],
    kernels=(oilfilm_force,),
    bearing=BearingLaw(
        oilfilm_force,
        ("speed", "clearance", "sigma"),
        wall="clearance",
        model="the oil-film model",
        positive=("speed",),  # the film's pressure comes from the journal's spin
    ),
)

LINEAR_BEARING = UnitType(
    LinearBearingUnit,
    LINEAR_PARAMS,
    FmuIdentity("RubcosimLinearBearing"),
    wiring=JOURNAL_WIRING,
    kernels=(linear_bearing_force,),
    bearing=BearingLaw(linear_bearing_force, ("stiffness", "damping")),
)
