"""Branch switching at a flip onto the period-doubled branch, and period-doubling cascades.

At a flip of an n-periodic orbit (a multiplier -1, eigenvector ``v``) the 2n-periodic
orbits are born: for the map ``P^2n`` the flip is a pitchfork, and the new branch leaves
the flip point along ``v`` with the parameter stationary.  The switch starts from the
flip point moved ``SWITCH_DISTANCE`` (scaled) along ``v`` and corrects onto the
2n-periodic branch with the hyperplane normal to ``v``; the n-periodic orbit, whose
points ``P^n`` leaves in place, is excluded by checking that ``P^n`` maps the new point
to the other side (about ``-v``).  The branch is then continued from there along ``+v``
(its image under ``P^n`` is the same orbit).

A cascade follows the first flip of each new branch in turn: the flip parameters
``mu_1, mu_2, ...`` of the first doublings, and their ratios
``(mu_k - mu_{k-1}) / (mu_{k+1} - mu_k)``, which tend to Feigenbaum's 4.669... for a
smooth unimodal-like cascade.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .bifurcation_points import SpecialPoint
from .continuation import Branch, Continuation
from .errors import AnalysisError
from .orbit_problem import OrbitProblem

SWITCH_DISTANCE = 1e-3  # in state scales, along the flip's eigenvector
FEIGENBAUM = 4.669201609102990


def flip_direction(cont: Continuation, flip: SpecialPoint) -> np.ndarray:
    """The unit eigenvector (scaled state coordinates) of the flip's multiplier -1."""
    problem = cont.problem
    lin = problem.linearize(flip.state, flip.param, with_param=False)
    lam, vecs = np.linalg.eig(lin.monodromy)
    k = int(np.argmin(np.abs(lam + 1.0)))
    v = np.real(vecs[:, k]) / problem.scale
    return v / np.linalg.norm(v)


def switch(
    cont: Continuation,
    flip: SpecialPoint,
    progress: Callable[[float], None] | None = None,
    distance: float = SWITCH_DISTANCE,
) -> Branch:
    """The 2n-periodic branch born at ``flip`` (a special point of ``cont``'s branch),
    continued over ``cont``'s range with its settings."""
    if flip.kind != "flip":
        raise AnalysisError(f"branch switching is at a flip, not at a {flip.kind}")
    v = flip_direction(cont, flip)
    base = cont.problem
    doubled = OrbitProblem(
        base.scenario, base.param, 2 * base.period, mode=base.mode, rtol=base.rtol,
        max_events=base.max_events, mu_scale=base.mu_scale,
    )  # fmt: skip
    new = Continuation(
        doubled, cont.mu0, cont.mu1, step=cont.ds, max_step=cont.max_step,
        min_step=cont.min_step, max_points=cont.max_points, locate_grazing=cont.locate_grazing,
    )  # fmt: skip
    normal = np.append(v, 0.0)
    start = new._u(flip.state, flip.param) + distance * normal
    pt = new.correct(start, normal)
    if pt is None:
        raise AnalysisError(
            f"no {doubled.period}-periodic orbit found {distance:g} state scales from the "
            f"flip at {base.param} = {flip.param:.10g}"
        )
    y, mu = new._split(pt.u)
    image, _ = base.image(y, mu)
    moved = float(np.max(np.abs(image - y) / base.scale))
    if moved < distance:
        raise AnalysisError(
            f"the switch at {base.param} = {flip.param:.10g} found the {base.period}-periodic "
            f"orbit again (P^{base.period} moves the point {moved:.2g} state scales)"
        )
    branch = new.new_branch()
    return new.march(branch, pt, new.tangent(pt.jac, normal), progress)


@dataclass
class Cascade:
    """The branches of a period-doubling cascade (periods n, 2n, 4n, ...) and the flip
    points where each was born (``flips[k]`` on ``branches[k]``)."""

    branches: list[Branch] = field(default_factory=list)
    flips: list[SpecialPoint] = field(default_factory=list)

    @property
    def flip_params(self) -> np.ndarray:
        return np.array([f.param for f in self.flips])

    @property
    def ratios(self) -> np.ndarray:
        """``(mu_k - mu_{k-1}) / (mu_{k+1} - mu_k)`` of the flip parameters."""
        mu = self.flip_params
        if mu.size < 3:
            return np.zeros(0)
        d = np.diff(mu)
        return d[:-1] / d[1:]

    def report(self) -> dict[str, Any]:
        return {
            "periods": [b.period for b in self.branches],
            "flip_params": self.flip_params.tolist(),
            "feigenbaum_ratios": self.ratios.tolist(),
            "feigenbaum_constant": FEIGENBAUM,
        }


def _first_flip(branch: Branch) -> SpecialPoint | None:
    return next(iter(branch.special_of("flip")), None)


def cascade(
    cont: Continuation,
    branch: Branch,
    doublings: int,
    progress: Callable[[float], None] | None = None,
) -> Cascade:
    """From ``branch`` (continued by ``cont``), switch at the first flip of each branch in
    turn, ``doublings`` times at most (fewer when a branch has no flip)."""
    if not (isinstance(doublings, int) and doublings >= 1):
        raise AnalysisError(f"--doublings {doublings!r}: must be an integer >= 1")
    out = Cascade([branch])
    for _ in range(doublings):
        flip = _first_flip(out.branches[-1])
        if flip is None:
            break
        out.flips.append(flip)
        nxt = switch(cont, flip, progress)
        out.branches.append(nxt)
        cont = _continuation_of(cont, nxt)
    last = _first_flip(out.branches[-1])
    if last is not None and len(out.flips) < len(out.branches):
        out.flips.append(last)
    return out


def _continuation_of(cont: Continuation, branch: Branch) -> Continuation:
    """A continuation like ``cont`` for ``branch``'s period."""
    base = cont.problem
    problem = OrbitProblem(
        base.scenario, base.param, branch.period, mode=base.mode, rtol=base.rtol,
        max_events=base.max_events, mu_scale=base.mu_scale,
    )  # fmt: skip
    return Continuation(
        problem, cont.mu0, cont.mu1, step=cont.ds, max_step=cont.max_step,
        min_step=cont.min_step, max_points=cont.max_points, locate_grazing=cont.locate_grazing,
    )  # fmt: skip
