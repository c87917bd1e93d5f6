"""Where a one-period stroboscopic map of Feng & Yang's oscillator spends its steps.

A diagnostic, not a benchmark of a target: it integrates ``--samples`` random states of
the paper's region over one forcing period each (the cell mapping's kernel: every
period a restart) and over ten periods in one call, with the ``fast`` engine's compiled
``integrate`` at ``--rtol``, and prints per period the wall time, accepted and rejected
steps, right-hand-side calls, events and restarts.  For comparison it prints the same
counts for scipy's ``solve_ivp`` (DOP853, the same controller) on the smooth Duffing
oscillator without the barrier.

    .venv/bin/python benchmarks/profile_strobe_map.py [--samples 20000] [--rtol 1e-7]
"""

from __future__ import annotations

import argparse
import math
import time

import numba as nb
import numpy as np
from scipy.integrate import solve_ivp

from rubcosim.analysis.maps import StroboscopicMap
from rubcosim.reference.core import (
    C_EVENTS,
    C_REJECTED,
    C_RESTARTS,
    C_RHS,
    C_STEPS,
    N_COUNTERS,
    new_event_log,
)
from rubcosim.reference.fast import integrate
from rubcosim.scenario import load_scenario


@nb.njit
def _run(Y, p, ip, period, rtol, atol, n_periods, split, tot):
    n = Y.shape[1]
    evlog = new_event_log(20000, n)
    cnt = np.zeros(N_COUNTERS, dtype=np.int64)
    y_end = np.empty(n)
    out = (np.empty(0), np.empty((0, 0)), evlog, cnt)
    dde = (np.zeros((1, 2)), np.zeros(4, dtype=np.int64))
    for j in range(Y.shape[0]):
        y = Y[j].copy()
        mode = 0
        chunks = n_periods if split else 1
        span = period * (1 if split else n_periods)
        for k in range(chunks):
            cnt[:] = 0
            _, mode = integrate(
                y, mode, k * span, (k + 1) * span, p, ip, (rtol, atol, np.inf), out, None, dde,
                y_end, None,
            )  # fmt: skip
            y[:] = y_end
            for c in range(N_COUNTERS):
                tot[c] += cnt[c]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--samples", type=int, default=20000)
    ap.add_argument("--rtol", type=float, default=1e-7)
    args = ap.parse_args(argv)
    sc = load_scenario("feng_yang_attractors")
    smap = StroboscopicMap(sc.system, rtol=args.rtol)
    rng = np.random.default_rng(0)
    Y = np.column_stack([rng.uniform(-2, 1, args.samples), rng.uniform(-2, 2, args.samples)])
    tot = np.zeros(N_COUNTERS, dtype=np.int64)
    for label, n_periods, split, rows in (
        ("one period from each random state (a cell map)", 1, True, Y),
        ("ten periods, a restart every period", 10, True, Y[: args.samples // 10]),
        ("ten periods in one call", 10, False, Y[: args.samples // 10]),
    ):
        _run(rows[:2], smap._p, smap._ip, smap.period, args.rtol, smap.atol, n_periods, split, tot)
        tot[:] = 0
        start = time.perf_counter()
        _run(rows, smap._p, smap._ip, smap.period, args.rtol, smap.atol, n_periods, split, tot)
        wall = time.perf_counter() - start
        m = rows.shape[0] * n_periods
        print(
            f"{label}: {wall / m * 1e6:.1f} us per period; accepted steps {tot[C_STEPS] / m:.1f}, "
            f"rejected {tot[C_REJECTED] / m:.1f}, rhs calls {tot[C_RHS] / m:.0f}, events "
            f"{tot[C_EVENTS] / m:.2f}, restarts {tot[C_RESTARTS] / m:.2f}"
        )
    w = 0.678
    period = 2.0 * math.pi / w

    def duffing(t, y):
        return [y[1], 0.77 * math.cos(w * t) - 0.02 * y[1] - y[0] - y[0] ** 3]

    r = solve_ivp(duffing, (0.0, 10 * period), [0.5, 0.0], method="DOP853", rtol=args.rtol,
                  atol=args.rtol)  # fmt: skip
    accepted = len(r.t) - 1
    attempts = (r.nfev - 1) / 11.0
    print(
        f"scipy solve_ivp DOP853, smooth Duffing (no barrier), 10 periods: accepted steps "
        f"{accepted / 10:.1f}, rejected {(attempts - accepted) / 10:.1f} per period"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
