"""Hunt-Crossley stator: a massless stator whose contact force is nonlinear in the
penetration and never pulls.

Normal force on the disc (N, > 0 pushes it inward), with ``delta = dist - d`` the
penetration (m) and ``delta' = vn`` its rate (m/s, the disc's outward normal speed)::

    Fn = max(0, k delta^n (1 + 3 (1 - e) / 2 * delta' / v0))      for delta > 0

(Hunt & Crossley 1975, with the damping of Lankarani & Nikravesh 1990):
``n = 3/2`` is Hertz's exponent.  The damping factor is written with a fixed
``v0``, Hunt and Crossley's material constant ``lambda = 3 k (1 - e) / (2 v0)``:
an impact at normal speed ``v0`` rebounds with restitution close to ``e`` (for
``e`` near 1), a slower one with less loss, a faster one with more, as
measured.  The force is zero at first touch (no jump at contact onset, unlike
the Kelvin-Voigt law of the elastic stator) and it never becomes tension: the
disc leaves the surface when the force would pull.  Coulomb friction acts on it
as on every penalty stator (:func:`.stator.penalty_force_components`).
"""

from __future__ import annotations

from .contact_law import ContactLaw
from .declaration import FmuIdentity, UnitType
from .jit import njit
from .parameters import positive, real
from .stator import CONTACT_GEOMETRY, contact_geometry
from .stator_unit import DISC_WIRING, ROTOR_NEEDS, ROTOR_PARAMS, MasslessPenaltyStator
from .unit_odes import row_contact_force


@njit
def hunt_crossley_normal(
    dist: float, vn: float, d: float, k: float, n: float, e: float, v0: float
) -> float:
    """Normal force ``max(0, k delta^n (1 + 1.5 (1 - e) vn / v0))`` (N) for the
    penetration ``delta = dist - d`` (m) and its rate ``vn`` (m/s); 0 while clear."""
    penetration = dist - d
    if penetration <= 0.0:
        return 0.0
    return max(k * penetration**n * (1.0 + 1.5 * (1.0 - e) * vn / v0), 0.0)


HUNT_CROSSLEY_PARAMS = (
    *CONTACT_GEOMETRY,
    positive(
        "contact_stiffness", None, "N/m^n", "k in Fn = k delta^n (N/m^1.5 for Hertz)", example=1e9
    ),
    positive("exponent", 1.5, "1", "exponent n of the penetration (3/2: Hertz)"),
    real("restitution", 0.9, "1", "restitution e of an impact at normal speed v0", 0.0, 1.0),
    positive(
        "impact_speed",
        None,
        "m/s",
        "normal impact speed v0 at which the restitution is e",
        example=0.05,
    ),  # fmt: skip
)


class HuntCrossleyStatorUnit(MasslessPenaltyStator):
    """Massless stator with Hunt-Crossley contact: nonlinear, dissipative, no tension."""

    type_name = "hunt_crossley"
    summary = (
        "Hunt-Crossley stator: contact force k delta^n (1 + 3(1-e)/2 delta'/v0), no tension, "
        "with Coulomb friction on the disc"
    )
    params_spec = (*HUNT_CROSSLEY_PARAMS, *ROTOR_PARAMS)


HUNT_CROSSLEY_STATOR = UnitType(
    HuntCrossleyStatorUnit,
    HUNT_CROSSLEY_PARAMS,
    FmuIdentity("RubcosimHuntCrossleyStator"),
    needs=ROTOR_NEEDS,
    wiring=DISC_WIRING,
    length_scale=lambda q: q["clearance"],
    kernels=(contact_geometry, row_contact_force, hunt_crossley_normal),
    contact=ContactLaw(
        "penalty",
        hunt_crossley_normal,
        ("clearance", "contact_stiffness", "exponent", "restitution", "impact_speed"),
    ),
)
