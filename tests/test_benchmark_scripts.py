"""The benchmark scripts run end to end on a small selection (their numbers are not
checked here: they go to BENCHMARKS.md from full runs)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
import bench_cosim  # noqa: E402
import stress_cosim  # noqa: E402


def test_work_precision_benchmark_writes_its_table(tmp_path, capsys):
    args = [
        "--quick",
        "--cases",
        "rigid",
        "--methods",
        "fast",
        "fixed+events",
        "--repeats",
        "1",
        "--target",
        "1e-3",
        "--out",
        str(tmp_path),
    ]
    assert bench_cosim.main(args) == 0
    data = json.loads((tmp_path / "cosim_wp.json").read_text())
    points = data["cases"]["rigid"]["methods"]["fixed+events"]
    assert len(points) == 2 and points[1]["error"] < points[0]["error"]
    assert "| rigid | fast |" in (tmp_path / "cosim_wp.md").read_text()
    assert (tmp_path / "cosim_wp.png").stat().st_size > 0
    # --merge keeps what is there and adds the new method
    assert bench_cosim.main([*args[:4], "accurate", *args[6:], "--merge"]) == 0
    merged = json.loads((tmp_path / "cosim_wp.json").read_text())["cases"]["rigid"]
    assert sorted(merged["methods"]) == ["accurate", "fast", "fixed+events"]
    with pytest.raises(SystemExit):
        bench_cosim.main(["--repeats", "0"])


def test_cost_at_equal_error_takes_the_cheapest_run_below_the_target():
    points = [
        {"error": 1e-3, "wall_s": 0.1},
        {"error": 1e-7, "wall_s": 3.0},
        {"error": 5e-7, "wall_s": 2.0},
        {"failed": "x"},
    ]
    assert bench_cosim.cost_at(points, 1e-6)["wall_s"] == 2.0
    assert bench_cosim.cost_at(points, 1e-9) is None


def test_stress_script_runs_a_case_and_says_whether_it_behaved(tmp_path):
    assert stress_cosim.main(["--only", "speed=2 wn", "--out", str(tmp_path)]) == 0
    rows = json.loads((tmp_path / "stress.json").read_text())
    assert rows[0]["passed"] and rows[0]["status"] == "ok" and rows[0]["rel_error"] < 1e-5
    assert "| speed=2 wn |" in (tmp_path / "stress.md").read_text()
    # --merge adds a case and keeps the one run before, in the script's order
    assert stress_cosim.main(["--only", "kc/k=10", "--merge", "--out", str(tmp_path)]) == 0
    rows = json.loads((tmp_path / "stress.json").read_text())
    assert [r["case"] for r in rows] == ["kc/k=10", "speed=2 wn"]


def test_analysis_benchmark_runs_quick(tmp_path, monkeypatch):
    import bench_analysis

    # a smaller smoke problem than --quick: the script's plumbing, not its figures
    monkeypatch.setattr(bench_analysis, "bench_cells", _shrunk(bench_analysis.bench_cells, 3))
    monkeypatch.setattr(bench_analysis, "bench_sweep", _shrunk(bench_analysis.bench_sweep, 3))
    assert (
        bench_analysis.main(["--quick", "--repeats", "1", "--workers", "1", "--out", str(tmp_path)])
        == 0
    )
    data = json.loads((tmp_path / "analysis.json").read_text())
    assert data["cell_mapping"]["detail"]["attractors"] and data["bifurcation"]["median_s"] > 0
    assert "| cell_mapping |" in (tmp_path / "analysis.md").read_text()


def _shrunk(fn, n):
    def run(first, *rest):
        return fn(min(first, n), *(min(r, n) if i < 2 else r for i, r in enumerate(rest)))

    return run


def test_basins_benchmark_times_the_process_and_writes_its_table(tmp_path):
    import bench_basins

    assert (
        bench_basins.main(["--quick", "--repeats", "1", "--warmup", "0", "--out", str(tmp_path)])
        == 0
    )
    data = json.loads((tmp_path / "basins_feng_yang_quick.json").read_text())
    assert len(data["wall_s"]) == 1 and data["wall_s"][0] > 0 and not data["met"]
    assert data["meta"]["git_commit"] and data["report"]["samples"]["total"] == 20 * 20 * 2
    assert "| P4 |" in (tmp_path / "basins_feng_yang_quick.md").read_text()


def test_continuation_benchmark_writes_its_table(tmp_path):
    import bench_continuation

    args = ["--repeats", "1", "--basin-repeats", "0", "--out", str(tmp_path)]
    assert bench_continuation.main(args) == 0
    data = json.loads((tmp_path / "continuation.json").read_text())
    assert data["branch"]["points"] == 200 and data["flip_curve"]["points"] == 50
    assert [k for k, _ in data["branch"]["special"]] == ["fold"]
    assert "| impact Duffing" in (tmp_path / "continuation.md").read_text()
