"""Batches split into interleaved parts and put back in row order (analysis.parallel):
the same rows, in the same order, whatever the number of parts or where they run."""

from __future__ import annotations

import numpy as np
import pytest

from rubcosim.analysis.parallel import (
    InlineExecutor,
    executor,
    gather_interleaved,
    submit_interleaved,
)


def _square_rows(offset: float, rows: np.ndarray) -> np.ndarray:
    return rows**2 + offset


@pytest.mark.parametrize("parts", [1, 2, 3, 7])
def test_parts_come_back_in_row_order(parts):
    rows = np.arange(20.0).reshape(10, 2)
    futures = submit_interleaved(InlineExecutor(), parts, _square_rows, 1.0, rows)
    assert len(futures) == parts
    out = gather_interleaved(futures, np.empty_like(rows))
    assert np.array_equal(out, rows**2 + 1.0)


def test_parts_on_worker_processes_into_a_list():
    rows = list(range(9))
    with executor(2) as pool:
        futures = submit_interleaved(pool, 2, _double, 0, rows)
        assert gather_interleaved(futures, [None] * len(rows)) == [2 * r for r in rows]


def _double(_: int, rows: list[int]) -> list[int]:
    return [2 * r for r in rows]
