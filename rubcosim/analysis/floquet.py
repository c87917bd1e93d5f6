"""Floquet multipliers of periodic motions, through impacts.

The monodromy matrix of an n-periodic motion is the Jacobian of the n-fold
stroboscopic map at its fixed point: the tangent matrix of the variational
equations over n forcing periods from the identity, with the saltation matrix
``S = DG + (f+ - DG f-) grad_h^T / (grad_h . f-)`` applied at every event
(:func:`.lyapunov.monodromy`, on the ``fast`` engine).  It is valid while
every nearby orbit has the impacts of this one (no grazing within the
perturbation): that is checked by mapping the states ``FD_STEP`` scales away
along each axis, and the result refused when one of them changes its impacts.

The fixed point is first refined by Newton's method on ``P^n(y) - y``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import MapError
from .lyapunov import monodromy
from .maps import StroboscopicMap

FLOQUET_RTOL = 1e-12  # the map's tolerance (the fixed point by Newton to 1e-10)
FD_STEP = 1e-6  # perturbation of the grazing check, in state scales


@dataclass(frozen=True)
class Floquet:
    """Multipliers of an n-periodic motion at its stroboscopic fixed point ``state``.

    ``stable``: every multiplier inside the unit circle.  ``kind`` names how
    the largest one leaves (or is nearest to leaving) the circle: ``"fold"``
    (real, near +1: saddle-node or symmetry breaking), ``"flip"`` (real,
    near -1: period doubling), ``"neimark-sacker"`` (a complex pair).
    """

    multipliers: np.ndarray
    monodromy: np.ndarray
    state: np.ndarray
    period: int
    impacts: int
    residual: float  # |P^n(y) - y| at the fixed point, in state scales

    @property
    def spectral_radius(self) -> float:
        return float(np.max(np.abs(self.multipliers)))

    @property
    def stable(self) -> bool:
        return self.spectral_radius < 1.0

    @property
    def kind(self) -> str:
        lam = self.multipliers[np.argmax(np.abs(self.multipliers))]
        if abs(lam.imag) > 1e-6 * max(1.0, abs(lam)):
            return "neimark-sacker"
        return "fold" if lam.real > 0 else "flip"


def _image(smap: StroboscopicMap, y: np.ndarray, n: int, mode: int) -> tuple[np.ndarray, int]:
    orbit = smap.orbit(y, keep=n, mode=mode)
    if not orbit.ok:
        raise MapError(f"the map failed near the periodic orbit: {orbit.message}")
    return orbit.final_state, int(orbit.impacts.sum())


def jacobian(
    smap: StroboscopicMap, y: np.ndarray, n: int, mode: int, step: float = FD_STEP
) -> tuple[np.ndarray, int]:
    """Jacobian of the n-fold map at ``y`` (the variational equations' monodromy
    matrix) and the impacts of the orbit; refuses when an orbit started ``step``
    scales away along an axis changes its impacts (grazing)."""
    J, m, _, _ = monodromy(smap.system, y, n, mode, smap.rtol, smap.max_events)
    offsets = np.diag(step * smap.scale)
    starts = np.concatenate((y + offsets, y - offsets))
    _, _, impacts, status = smap.map(starts, n, np.full(2 * y.size, mode, dtype=np.int64))
    if np.any(status != 0):
        raise MapError("the map failed near the periodic orbit")
    if np.any(impacts != m):
        lo, hi = int(impacts.min()), int(impacts.max())
        raise MapError(
            f"a perturbation of {step:g} scales changes the impacts per {n} period(s) "
            f"({lo}..{hi}, not {m}): the orbit is at grazing and its map is not smooth"
        )
    return J, m


def floquet(
    smap: StroboscopicMap,
    y_guess: np.ndarray,
    period: int,
    mode: int | None = None,
    tol: float = 1e-10,
    max_iter: int = 20,
    box: tuple[np.ndarray, np.ndarray] | None = None,
) -> Floquet:
    """Refine the n-periodic fixed point near ``y_guess`` and return its multipliers.

    ``smap`` should be built with a tight tolerance (``FLOQUET_RTOL``).  ``tol`` is
    the Newton tolerance on ``|P^n(y) - y|`` in state scales.  ``box = (lo, hi)``: a
    Newton iterate outside it ends the search with a :class:`MapError` (a search for
    the fixed points of a region: an iterate that leaves it has diverged, and
    integrating from far out, where a stiffening spring is very fast, costs many steps).
    """
    if not (isinstance(period, int) and period >= 1):
        raise MapError(f"period = {period!r} must be an integer >= 1")
    m0 = smap.system.mode0 if mode is None else mode
    y = smap._state(y_guess).copy()
    scale = smap.scale
    residual = np.inf
    for _ in range(max_iter):
        image, _ = _image(smap, y, period, m0)
        r = image - y
        residual = float(np.max(np.abs(r) / scale))
        if residual < tol:
            break
        J, _ = jacobian(smap, y, period, m0)
        y = y - np.linalg.solve(J - np.eye(y.size), r)
        if box is not None and not np.all((box[0] <= y) & (y <= box[1])):
            raise MapError(f"Newton left the box {box[0]} .. {box[1]} at {y}")
    J, m = jacobian(smap, y, period, m0)
    return Floquet(multipliers_of(J), J, y, period, m, residual)


def multipliers_of(monodromy: np.ndarray) -> np.ndarray:
    """The Floquet multipliers (the monodromy matrix's eigenvalues), largest modulus
    first (ties in their eigvals order)."""
    lam = np.linalg.eigvals(monodromy)
    return lam[np.argsort(-np.abs(lam), kind="stable")]


def floquet_report(f: Floquet) -> dict:
    """JSON-able summary: multipliers as [re, im] pairs, largest first."""
    return {
        "multipliers": [[float(z.real), float(z.imag)] for z in f.multipliers],
        "spectral_radius": f.spectral_radius,
        "stable": bool(f.stable),
        "kind": f.kind,
        "residual": f.residual,
    }


def floquet_along(
    systems: list, points: np.ndarray, modes: np.ndarray, periods: list[int], max_period: int = 8
) -> list[dict | None]:
    """Multipliers of each periodic motion of a sweep (``periods[i]`` its period, 0 when
    not periodic), from its last stroboscopic point; ``None`` where not periodic or
    longer than ``max_period``, ``{"error": ...}`` where not feasible (grazing)."""
    out: list[dict | None] = []
    for system, pts, md, n in zip(systems, points, modes, periods, strict=True):
        if not n or n > max_period or not np.all(np.isfinite(pts[-1])):
            out.append(None)
            continue
        try:
            f = floquet(StroboscopicMap(system, FLOQUET_RTOL), pts[-1], n, int(md[-1]))
            out.append(floquet_report(f))
        except (MapError, np.linalg.LinAlgError) as exc:
            out.append({"error": str(exc)})
    return out


def sweep_floquet(scenario: Any, result: Any, max_period: int = 8) -> dict[str, list[dict | None]]:
    """Per direction of a sweep (``SweepResult``) of ``scenario``: the multipliers of
    each value's periodic motion (see :func:`floquet_along`)."""
    from .sweep import sweep_systems

    systems = sweep_systems(scenario, result.param, result.values)
    out = {}
    for d in result.points:
        periods = [c.get("period", 0) for c in result.classify(d)]
        out[d] = floquet_along(systems, result.points[d], result.modes[d], periods, max_period)
    return out
