"""The performance figures the documents quote are current and copied, not retyped.

Every benchmark of ``benchmarks/catalog.py`` must have been measured at a commit no
older than the last change to the code it measures, and every results block of
README.md and BENCHMARKS.md must be its results file verbatim.  ``make bench`` re-runs
the benchmarks and rewrites the blocks.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "benchmarks"))
import catalog  # noqa: E402
import readme_tables  # noqa: E402


def _has_history() -> bool:
    """A git checkout with its history (a shallow clone cannot date the figures)."""
    try:
        out = subprocess.run(
            ["git", "rev-parse", "--is-shallow-repository"],
            cwd=REPO, capture_output=True, text=True, check=True,
        ).stdout.strip()  # fmt: skip
    except (OSError, subprocess.CalledProcessError):
        return False
    return out == "false"


IN_GIT = _has_history()


def _git(*args: str) -> str:
    return subprocess.run(
        ["git", *args], cwd=REPO, capture_output=True, text=True, check=True
    ).stdout.strip()


@pytest.mark.skipif(not IN_GIT, reason="needs the git history the figures are stamped with")
@pytest.mark.parametrize("bench", catalog.BENCHMARKS, ids=lambda b: b.name)
def test_benchmark_was_measured_after_the_last_change_to_what_it_measures(bench):
    reasons = catalog.staleness(bench)
    assert not reasons, (
        "; ".join(reasons) + f" -- re-run: python benchmarks/catalog.py run {bench.name}"
    )


@pytest.mark.skipif(not IN_GIT, reason="needs the git history")
def test_staleness_sees_a_commit_followed_by_a_change_to_the_measured_code(tmp_path):
    # the parent of the last commit that changed components/ is, by the history, stale
    # for a benchmark of components/ and current for one of a folder that commit left
    last = _git("log", "-1", "--format=%H", "--", "components")
    parent = _git("rev-parse", f"{last}^")
    (tmp_path / "engines.json").write_text(json.dumps({"runs": [{"git_commit": parent}]}))
    stale = catalog.Benchmark("engines", ("x.py",), ("components",))
    assert any("later commit" in r for r in catalog.staleness(stale, tmp_path))
    untouched = [
        d
        for d in ("docs", "examples", "scenarios", "tests", "benchmarks", "fmus")
        if not _git("rev-list", f"{parent}..HEAD", "--", d)
    ]
    if untouched:
        fresh = catalog.Benchmark("engines", ("x.py",), (untouched[0],))
        assert catalog.staleness(fresh, tmp_path) == []
    (tmp_path / "engines.json").write_text(json.dumps({"cases": {}}))
    assert catalog.staleness(stale, tmp_path) == ["engines.json records no git_commit"]


def test_every_results_block_in_the_documents_is_its_results_file():
    for doc in readme_tables.DOCUMENTS:
        text = doc.read_text(encoding="utf-8")
        for name, body in readme_tables.blocks(text):
            assert body == readme_tables.generated(name), (
                f"{doc.name}: the block of {name} differs from benchmarks/results/{name}; "
                "run python benchmarks/readme_tables.py"
            )


def test_every_catalogued_benchmark_is_quoted_from_its_results_file():
    quoted = {
        name
        for doc in readme_tables.DOCUMENTS
        for name, _ in readme_tables.blocks(doc.read_text(encoding="utf-8"))
    }
    missing = [b.name for b in catalog.BENCHMARKS if f"{b.name}.md" not in quoted]
    assert not missing, f"no results block quotes {missing}"


def test_a_block_is_rewritten_from_its_file_and_the_title_dropped(tmp_path):
    (tmp_path / "x.md").write_text("# Title\n\n| a |\n|---|\n| 1 |\n")
    text = "before\n<!-- results: x.md -->\n| a |\n| 9 |\n<!-- end results -->\nafter\n"
    new = readme_tables.refresh(text, tmp_path)
    table = "| a |\n|---|\n| 1 |\n"
    assert new == f"before\n<!-- results: x.md -->\n{table}<!-- end results -->\nafter\n"
