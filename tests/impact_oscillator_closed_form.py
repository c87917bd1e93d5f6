"""The period-1 single-impact orbits of the linear impact oscillator in closed form
(Shaw & Holmes 1983), apart from rubcosim's code: numpy and scipy's matrix exponential.

``x'' + b x' + a x = f cos(w t)`` with a rigid stop at ``x = d`` (the motion stays in
``x <= d``) and Newton's law ``v+ = -r v-``.  Between impacts the motion is the forced
response ``x_p(t) = R cos(w t - psi)`` plus a free one, ``e(t) = exp(A (t - t_i)) e(t_i)``.
An orbit leaving the stop at ``t_i`` with speed ``-r v`` returns one forcing period
later with ``v``; with ``Phi = exp(A T)`` that is ``(I - Phi) u = -v (r Phi + I) e_2`` for
``u = (d - x_p(t_i), -x_p'(t_i))``, so ``u = v w`` with a fixed vector ``w``, and
``(d - v w_1)^2 + (v w_2 / w)^2 = R^2``: a quadratic in v whose two roots are the two
orbits (they meet at a fold, where its discriminant vanishes).  The multipliers are those
of ``S Phi``, ``S`` the saltation matrix of the impact.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm


def _parts(w: float, a: float, b: float, f: float, r: float):
    T = 2.0 * math.pi / w
    A = np.array([[0.0, 1.0], [-a, -b]])
    Phi = expm(A * T)
    vec = -np.linalg.solve(np.eye(2) - Phi, (r * Phi + np.eye(2)) @ np.array([0.0, 1.0]))
    D = (a - w * w) ** 2 + (b * w) ** 2
    return T, A, Phi, vec, f / math.sqrt(D), math.atan2(b * w, a - w * w)


def discriminant(w: float, a: float, b: float, f: float, d: float, r: float) -> float:
    """The quadratic's discriminant: zero at a fold of the period-1 orbits."""
    T, A, Phi, vec, R, psi = _parts(w, a, b, f, r)
    qa, qb, qc = vec[0] ** 2 + (vec[1] / w) ** 2, -2.0 * d * vec[0], d * d - R * R
    return qb * qb - 4.0 * qa * qc


def orbits(w: float, a: float, b: float, f: float, d: float, r: float) -> list[dict]:
    """Each period-1 orbit: impact speed ``v``, impact time ``t_impact`` in [0, T), the
    state on the section t = kT (``section``) and the multipliers ``S Phi``."""
    T, A, Phi, vec, R, psi = _parts(w, a, b, f, r)
    qa, qb, qc = vec[0] ** 2 + (vec[1] / w) ** 2, -2.0 * d * vec[0], d * d - R * R
    disc = qb * qb - 4.0 * qa * qc
    out = []
    if disc < 0.0:
        return out
    for sign in (1.0, -1.0):
        v = (-qb + sign * math.sqrt(disc)) / (2.0 * qa)
        if v <= 0.0:
            continue
        theta = math.atan2(v * vec[1] / (R * w), (d - v * vec[0]) / R)
        ti = ((theta + psi) / w) % T
        xp = np.array([R * math.cos(w * ti - psi), -R * w * math.sin(w * ti - psi)])
        e = expm(A * (T - ti)) @ (np.array([d, -r * v]) - xp)
        section = np.array([R * math.cos(-psi), -R * w * math.sin(-psi)]) + e
        S = np.array([[-r, 0.0], [(1.0 + r) * (f * math.cos(w * ti) - a * d) / v, -r]])
        lam = np.linalg.eigvals(S @ Phi)
        out.append({"v": v, "t_impact": ti, "section": section, "multipliers": lam,
                    "monodromy": S @ Phi})  # fmt: skip
    return out


def flip_test(w: float, a: float, b: float, f: float, d: float, r: float, branch: int = 0):
    """``det(S Phi + I)`` of orbit ``branch``: zero at a flip."""
    o = orbits(w, a, b, f, d, r)[branch]
    return float(np.linalg.det(o["monodromy"] + np.eye(2)))
