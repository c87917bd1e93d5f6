"""Basin fractions continued over a parameter (``rubcosim basins --continue``): matching
of attractors between values, checkpoints, and the fractions of a single basins run."""

from __future__ import annotations

import json

import numpy as np
import pytest

import rubcosim as rc
from rubcosim.analysis.basin_continuation import Step, continue_basins, match
from rubcosim.cli import main

SCALE = np.array([1.0, 1.0])


def _step(value, labels, points, fractions, cells):
    return Step(value, labels, [np.atleast_2d(p) for p in points], np.asarray(fractions),
                np.asarray(cells), None)  # fmt: skip


def test_matching_keeps_moved_attractors_and_names_births_deaths_and_merges():
    """A moves a little, B is gone and its cells went to A's basin (a merge), C is new
    far from both; D of another kind beside A is not taken for A."""
    prev = _step(0.0, ["1-0", "2-1"], [[0.0, 0.0], [1.0, 1.0]], [0.4, 0.6, 0.0],
                 [0, 0, 1, 1, 1])  # fmt: skip
    prev.ids = [7, 8]
    cur = _step(0.1, ["1-1", "1-0", "3-1"], [[0.01, 0.0], [0.02, 0.0], [5.0, 5.0]],
                [0.1, 0.7, 0.2, 0.0], [1, 1, 1, 1, 2])  # fmt: skip
    ids, events = match(prev, cur, SCALE, next_id=9)
    assert ids == [9, 7, 10]
    kinds = {(e["event"], e["attractor"]) for e in events}
    assert kinds == {("born", 9), ("born", 10), ("merged", 8)}
    merged = next(e for e in events if e["event"] == "merged")
    assert merged["into"] == 7


def test_a_continuation_resumes_from_its_checkpoint(tmp_path):
    calls = []

    class Fake:
        def __init__(self, v):
            self.n_attractors, self.fates = 1, np.zeros((4, 2), dtype=int)
            self.motions = [{"label": "1-0", "poincare_points": [[v, 0.0]]}]
            self.labels, self.info = np.zeros(4, dtype=int), {}

    def run(v):
        calls.append(v)
        return Fake(v)

    first = continue_basins(run, "p", np.array([0.0, 0.1, 0.2]), SCALE, tmp_path)
    assert calls == [0.0, 0.1, 0.2] and first.n_ids == 1
    again = continue_basins(lambda v: pytest.fail("recomputed"), "p",
                            np.array([0.0, 0.1, 0.2]), SCALE, tmp_path)  # fmt: skip
    assert np.array_equal(again.fractions, first.fractions)


def test_the_fractions_at_a_value_are_those_of_a_single_basins_run(tmp_path):
    """Feng & Yang's case: the continuation's fractions at f = 0.77 are those a single
    `basins` run at 0.77 finds (the same grid, samples and seed); the command writes its
    table, report and figure, and every value's fates were checked."""
    settings = {"grid": (24, 24), "samples": 2, "check": 10}
    out = tmp_path / "bc"
    code = main(["basins", "feng_yang_attractors", "--continue",
                 "oscillator.forcing_amplitude=0.76:0.78:3", "--grid", "24x24", "--samples",
                 "2", "--check", "10", "--out", str(out), "--no-progress"])  # fmt: skip
    assert code == 0
    report = json.loads((out / "report.json").read_text())
    at_077 = rc.load("feng_yang_attractors", set={"oscillator.forcing_amplitude": 0.77})
    single = rc.basins(at_077, **settings)
    n = single.n_attractors
    shares = np.bincount(single.fates.ravel(), minlength=n + 1) / single.fates.size
    at = report["per_value"][1]
    row = np.array(report["fractions"][1])
    assert sorted(row[at["ids"]]) == pytest.approx(sorted(shares[:n]), abs=1e-15)
    assert row[-1] == pytest.approx(shares[n], abs=1e-15)
    assert report["fates_checked"] == 30
    assert (out / "basin_fractions.png").is_file() and (out / "fractions.csv").is_file()
