"""How much of a check's difference chaos accounts for.

``rubcosim check`` compares a co-simulation with the ``accurate`` engine run to a
tolerance far tighter than the co-simulation's.  On a chaotic motion two correct
integrations separate whatever the coupling does: a difference of the size of their
local errors grows by a factor e every 1/lambda seconds (lambda the largest Lyapunov
exponent) until it is as large as the attractor.  A plain error figure then reads as a
coupling defect.  :func:`assess` measures the separation two ways:

- **the peer**: the ``accurate`` engine again, at the co-simulation's tolerance
  (``cosim.rtol``, for ``sim.rtol`` and ``sim.atol``), compared with the reference
  exactly as the co-simulation is.  It is how far a correct integration at that
  tolerance strays from the reference over the same window;
- **the rate**: when the peer strays more than :data:`SENSITIVE` times its tolerance,
  the largest Lyapunov exponent over the checked window from the scenario's initial
  state (:func:`rubcosim.analysis.lyapunov.lyapunov_spectrum`; delay-free models only).
  A regular motion (such as ``make run``'s check) computes no exponent and compiles
  nothing for it.

A motion is *sensitive* when the peer strays more than :data:`SENSITIVE` times its
tolerance, and *chaotic over the check* when, besides, lambda times the window exceeds
1 (more than one e-folding of a difference).  A sensitive motion need not be chaotic:
an impact a little earlier or later moves every output that jumps there, and a
chattering sequence may end one impact sooner.  Past the *horizon*, the first output
time at which the peer strays more than :data:`HORIZON` (relative), nothing tells a
coupling error from chaos: both differences are as large as the motion.  Before it they
can be told apart: the co-simulation is *within the peer* when its worst relative
difference before the horizon is at most :data:`PEER_FACTOR` times the peer's there
(and its tolerance), and *beyond the peer* otherwise, which points at the coupling.
Past the horizon the trajectories are compared in statistics instead
(``beyond_horizon``): the impact rate, and the distribution of every output's values
on the output grid (the two-sample Kolmogorov-Smirnov distance), of the co-simulation
and of the peer against the reference's.  The co-simulation's statistics *agree* when
each figure is within :data:`STAT_FACTOR` times the peer's (or :data:`STAT_FLOOR`): two
correct integrations of the same chaotic motion differ that much in their statistics
over the same window.  The Lyapunov exponent is the reference model's: a
co-simulation has no variational equations to give its own.
Every figure is in ``report.json``'s ``chaos`` block.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

PEER_FACTOR = 10.0  # the co-simulation may stray this much more than the peer
HORIZON = 1e-2  # the peer's relative difference at which the comparison stops
SENSITIVE = 100.0  # the peer straying this many times its tolerance: compute lambda
STAT_FACTOR = 3.0  # past the horizon, statistics may differ this much more than the peer's
STAT_FLOOR = 0.05  # ... or this much (the peer's own may be close to 0 by chance)
MIN_BEYOND = 20  # output times past the horizon needed to compare statistics


def output_errors(ref: Any, other: Any, names: list[str], rows: np.ndarray) -> dict[str, dict]:
    """Per output: the largest absolute difference of ``other`` from ``ref`` over the grid
    ``rows``, and that difference relative to the largest magnitude ``ref`` reaches
    (``max_rel_error``).  Both take ``output(name)`` (an array over the same times)."""
    errors = {}
    for name in names:
        a = ref.output(name)[rows]
        b = other.output(name)[rows]
        err = float(np.max(np.abs(a - b))) if rows.size else float("nan")
        scale = float(np.max(np.abs(a))) if rows.size else float("nan")
        errors[name] = {
            "max_abs_error": err,
            "max_rel_error": err / scale if scale > 0.0 else (0.0 if err == 0.0 else float("inf")),
            "reference_max_abs": scale,
        }
    return errors


def separation(ref: Any, other: Any, names: list[str], rows: np.ndarray) -> np.ndarray:
    """At every grid row, the largest difference over the outputs, each relative to the
    largest magnitude ``ref`` reaches (as ``max_rel_error``)."""
    curve = np.zeros(rows.size)
    for name in names:
        a = ref.output(name)[rows]
        scale = float(np.max(np.abs(a))) if rows.size else 0.0
        d = np.abs(a - other.output(name)[rows])
        curve = np.maximum(curve, d / scale if scale > 0.0 else np.where(d > 0.0, np.inf, 0.0))
    return curve


def worst(errors: dict[str, dict]) -> float:
    """The largest ``max_rel_error`` of :func:`output_errors` (0 without outputs)."""
    return max((e["max_rel_error"] for e in errors.values()), default=0.0)


def impacts_after(result: Any, t: float) -> int:
    """Impacts of a run after time ``t`` (s): a monolithic result's impact events, a
    co-simulation's master events, or the growth of a hybrid unit's own count
    (``oscillator.impacts``, whose impacts the master does not see)."""
    events = getattr(result, "events", None)
    if events is not None and hasattr(events, "of_kind"):
        return int(np.count_nonzero(events.t[events.of_kind("impact")] > t))
    if "oscillator.impacts" in result.names:
        counts = result.output("oscillator.impacts")
        if counts.size == 0:
            return 0
        k = int(np.searchsorted(result.t, t, side="right"))
        return int(counts[-1] - counts[k - 1]) if k else int(counts[-1])
    return int(np.count_nonzero(result.events_of_kind("impact") > t))


def distribution_distance(a: np.ndarray, b: np.ndarray) -> float:
    """The two-sample Kolmogorov-Smirnov statistic: the largest difference of the
    empirical distribution functions of ``a`` and ``b`` (0 to 1; scipy's ``ks_2samp``)."""
    from scipy.stats import ks_2samp

    return float(ks_2samp(a, b).statistic)


def statistics_beyond(
    ref: Any, other: Any, names: list[str], rows: np.ndarray, t_h: float, t_end: float
) -> dict:
    """How ``other``'s motion after ``t_h`` compares with ``ref``'s in statistics: the
    impact rate (1/s) of each and their relative difference, and per output the
    distance of the distributions of the values on the grid ``rows``
    (:func:`distribution_distance`), the largest as ``distribution``."""
    span = t_end - t_h
    rate_ref, rate = impacts_after(ref, t_h) / span, impacts_after(other, t_h) / span
    per_output = {
        name: distribution_distance(ref.output(name)[rows], other.output(name)[rows])
        for name in names
    }
    if rate_ref > 0.0:
        rate_diff = abs(rate - rate_ref) / rate_ref
    else:
        rate_diff = 0.0 if rate == 0.0 else float("inf")
    return {
        "impact_rate": rate,
        "reference_impact_rate": rate_ref,
        "impact_rate_rel_diff": rate_diff,
        "distribution": max(per_output.values(), default=0.0),
        "distribution_per_output": per_output,
    }


def _beyond_horizon(ref: Any, peer: Any, cosim: Any, names: list[str], rows: np.ndarray,
                    h: int, t_end: float) -> dict:  # fmt: skip
    """The ``beyond_horizon`` block: the statistics of the peer and of the co-simulation
    after the horizon (rows ``rows[h:]``), and whether the co-simulation's agree with the
    reference's as well as a correct integration's do (each figure within
    :data:`STAT_FACTOR` times the peer's, or :data:`STAT_FLOOR`)."""
    after = rows[h:]
    if after.size < MIN_BEYOND:
        return {"compared": False, "why": f"fewer than {MIN_BEYOND} output times past it"}
    t_h = float(ref.result.t[after[0]])
    peer_stats = statistics_beyond(ref.result, peer, names, after, t_h, t_end)
    co_stats = statistics_beyond(ref.result, cosim, names, after, t_h, t_end)
    agree = all(
        co_stats[k] <= max(STAT_FACTOR * peer_stats[k], STAT_FLOOR)
        for k in ("impact_rate_rel_diff", "distribution")
    )
    return {"compared": True, "from_s": t_h, "to_s": t_end, "output_times": int(after.size),
            "peer": peer_stats, "cosim": co_stats, "agree": agree}  # fmt: skip


def _largest_exponent(scenario: Any, duration: float) -> tuple[float | None, str]:
    """lambda (1/s) over the window from the initial state, or None and why not."""
    from .analysis.errors import AnalysisError
    from .analysis.lyapunov import lyapunov_spectrum

    system = scenario.system
    periods = int(duration / system.forcing_period)
    if periods < 1:
        return None, "the check is shorter than one forcing period"
    try:
        spectrum = lyapunov_spectrum(system, periods, 0, count=1)
    except AnalysisError as exc:
        return None, str(exc).split(";")[0]
    return float(spectrum.exponents[0]), f"over {periods} forcing periods from the initial state"


def assess(scenario: Any, ref: Any, cosim: Any, rows: np.ndarray, rtol: float) -> dict:
    """The ``chaos`` block of a check's report: the peer at ``rtol`` (the co-simulation's
    tolerance), lambda when the motion is sensitive, the horizon, and the verdict:
    ``regular``, or ``sensitive`` or ``chaotic``, then ``within the peer`` or ``beyond the
    peer``."""
    from .runner import run_scenario

    sim = scenario.sim
    names = list(scenario.outputs)
    duration = float(sim["t_end"] - sim["t_start"])
    peer_scenario = replace(scenario, sim={**sim, "rtol": rtol, "atol": rtol})
    peer = run_scenario(peer_scenario, engine="accurate").result
    rows = rows[rows < peer.t.size]  # a failed peer: the times it reached
    peer_curve = separation(ref.result, peer, names, rows)
    co_curve = separation(ref.result, cosim, names, rows)
    peer_worst = float(peer_curve.max(initial=0.0))
    block: dict[str, Any] = {
        "peer": {
            "engine": "accurate",
            "rtol": rtol,
            "worst_rel_error": peer_worst,
            "status": "ok" if peer.ok else f"failed: {peer.message}",
        },
        "largest_lyapunov_exponent": None,
        "lyapunov_note": f"not computed: the peer strays less than {SENSITIVE:g} x its tolerance",
        "verdict": "regular",
    }
    if peer_worst <= SENSITIVE * rtol:
        return block
    lam, note = _largest_exponent(scenario, duration)
    block["largest_lyapunov_exponent"], block["lyapunov_note"] = lam, note
    block["e_foldings"] = lam * duration if lam is not None else None
    kind = "chaotic" if lam is not None and lam * duration > 1.0 else "sensitive"
    past = np.flatnonzero(peer_curve > HORIZON)
    h = int(past[0]) if past.size else rows.size
    block["horizon_s"] = float(ref.result.t[rows[h]]) if h < rows.size else None
    co_before = float(co_curve[:h].max(initial=0.0))
    peer_before = max(float(peer_curve[:h].max(initial=0.0)), rtol)
    block["before_horizon"] = {"cosim": co_before, "peer": peer_before}
    block["cosim_over_peer"] = co_before / peer_before
    within = co_before <= PEER_FACTOR * peer_before
    block["verdict"] = f"{kind}, {'within' if within else 'beyond'} the peer"
    if h < rows.size:
        t_end = float(min(ref.result.t_reached, getattr(cosim, "t_reached", np.inf)))
        beyond = _beyond_horizon(ref, peer, cosim, names, rows, h, t_end)
        block["beyond_horizon"] = beyond
    return block


def summary(block: dict) -> str | None:
    """One line for the terminal when the motion is sensitive, else None."""
    if block["verdict"] == "regular":
        return None
    lam, peer, before = block["largest_lyapunov_exponent"], block["peer"], block["before_horizon"]
    if lam is None:
        rate = block["lyapunov_note"]
    else:
        chaotic = "chaotic" if block["verdict"].startswith("chaotic") else "not chaotic"
        folds = block["e_foldings"]
        rate = f"largest Lyapunov exponent {lam:.3g} 1/s, {folds:.3g} e-foldings: {chaotic}"
    horizon = block["horizon_s"]
    until = f" until t = {horizon:.4g} s, while below {HORIZON:g}" if horizon is not None else ""
    head = (
        f"the motion is sensitive ({rate}): the accurate engine at the co-simulation's "
        f"tolerance ({peer['rtol']:.3g}) differs from the reference by "
        f"{peer['worst_rel_error']:.3g} too; the co-simulation differs by {before['cosim']:.3g} "
        f"against its {before['peer']:.3g}{until}"
    )
    if block["verdict"].endswith("within the peer"):
        line = f"{head}: what a correct integration does, not a coupling error"
    else:
        over = block["cosim_over_peer"]
        line = f"{head}: {over:.3g}x, more than a correct integration (the coupling?)"
    beyond = block.get("beyond_horizon")
    if beyond and beyond["compared"]:
        co, peer = beyond["cosim"], beyond["peer"]
        line += (
            f"; beyond t = {beyond['from_s']:.4g} s the statistics "
            f"{'agree' if beyond['agree'] else 'DISAGREE'}: impact rate "
            f"{co['impact_rate']:.4g} 1/s against {co['reference_impact_rate']:.4g} "
            f"({co['impact_rate_rel_diff']:.2g}; the peer {peer['impact_rate_rel_diff']:.2g}), "
            f"distributions of the outputs {co['distribution']:.2g} apart "
            f"(Kolmogorov-Smirnov; the peer {peer['distribution']:.2g})"
        )
    return line
