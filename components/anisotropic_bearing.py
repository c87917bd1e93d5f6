"""A linear bearing with full stiffness and damping matrices: direct and cross-coupled
coefficients, as a rotordynamics code (ROSS's ``BearingElement``) gives a fluid-film
bearing linearised about its operating point.

The force on the journal is ``F = -K q - C q'`` with ``q = (x, y)`` the journal's
displacement from the bearing centre (m) and

    K = [[kxx, kxy],      C = [[cxx, cxy],
         [kyx, kyy]]           [cyx, cyy]]

(N/m, N s/m; the first index the force's axis, the second the motion's).  A
skew-symmetric part of K (``kxy = -kyx``) feeds energy into forward whirl: it is what
destabilises a rotor on fluid-film bearings above its threshold speed (oil whip), so a
run may grow without bound, as the model does.  With ``kxx = kyy``, ``cxx = cyy`` and
no cross-coupling this is the linear bearing.
"""

from __future__ import annotations

from .bearing_law import BearingLaw
from .bearing_unit import JOURNAL_WIRING, BearingUnit
from .declaration import FmuIdentity, UnitType
from .jit import njit
from .parameters import nonnegative, positive, real


@njit
def anisotropic_bearing_force(
    x: float, y: float, vx: float, vy: float,
    kxx: float, kxy: float, kyx: float, kyy: float,
    cxx: float, cxy: float, cyx: float, cyy: float,
) -> tuple[float, float]:  # fmt: skip
    """Force on the journal, N: ``-K q - C q'`` (see the module's docstring)."""
    fx = -(kxx * x + kxy * y) - (cxx * vx + cxy * vy)
    fy = -(kyx * x + kyy * y) - (cyx * vx + cyy * vy)
    return fx, fy


ANISOTROPIC_PARAMS = (
    positive("kxx", None, "N/m", "direct stiffness along x", example=2e7),
    positive("kyy", None, "N/m", "direct stiffness along y", example=1e7),
    real("kxy", 0.0, "N/m", "cross-coupled stiffness: force along x per displacement along y"),
    real("kyx", 0.0, "N/m", "cross-coupled stiffness: force along y per displacement along x"),
    nonnegative("cxx", 0.0, "N s/m", "direct damping along x"),
    nonnegative("cyy", 0.0, "N s/m", "direct damping along y"),
    real("cxy", 0.0, "N s/m", "cross-coupled damping: force along x per velocity along y"),
    real("cyx", 0.0, "N s/m", "cross-coupled damping: force along y per velocity along x"),
)


class AnisotropicBearingUnit(BearingUnit):
    """Linear bearing with direct and cross-coupled stiffness and damping."""

    type_name = "anisotropic"
    summary = "linear bearing with full 2x2 stiffness and damping matrices (cross-coupled)"
    params_spec = ANISOTROPIC_PARAMS


ANISOTROPIC_BEARING = UnitType(
    AnisotropicBearingUnit,
    ANISOTROPIC_PARAMS,
    FmuIdentity("RubcosimAnisotropicBearing"),
    wiring=JOURNAL_WIRING,
    kernels=(anisotropic_bearing_force,),
    bearing=BearingLaw(
        anisotropic_bearing_force, ("kxx", "kxy", "kyx", "kyy", "cxx", "cxy", "cyx", "cyy")
    ),
)
