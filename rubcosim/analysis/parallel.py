"""Running an analysis' tasks in parallel, with progress and a checkpoint to resume from.

Tasks go to local worker processes by default, or to a Dask cluster when a
scheduler address is given (``dask.distributed``, through its
``concurrent.futures`` executor), or run inline with one worker.  Each
finished task's result is saved at once in the checkpoint directory, so an
interrupted analysis started again with the same settings and output skips
what is done.  A task may have a follow-up that needs its result (a sweep's
continuation from the last state): it is submitted as soon as the result
arrives.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import hashlib
import json
import multiprocessing
import os
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .errors import AnalysisError, CheckpointError

Task = tuple[str, tuple[Any, ...]]  # (key, arguments)


class Checkpoint:
    """Finished task results of one analysis, one ``.npz`` file per task key.

    ``spec`` is everything that determines the results (JSON-able); a checkpoint
    written with another spec is refused, never mixed in.
    """

    def __init__(self, directory: str | Path, spec: Mapping[str, Any]) -> None:
        self.directory = Path(directory)
        text = json.dumps(spec, sort_keys=True, default=str)
        self.digest = hashlib.sha256(text.encode()).hexdigest()[:16]
        stamp = self.directory / "spec.json"
        if stamp.is_file():
            old = json.loads(stamp.read_text(encoding="utf-8"))
            if old.get("digest") != self.digest:
                raise CheckpointError(
                    f"{self.directory}: holds the checkpoint of an analysis with other "
                    "settings; choose another --out, or delete that directory to start over"
                )
        else:
            self.directory.mkdir(parents=True, exist_ok=True)
            stamp.write_text(json.dumps({"digest": self.digest, "spec": json.loads(text)}))

    def _path(self, key: str) -> Path:
        return self.directory / f"{key}.npz"

    def done(self) -> set[str]:
        return {p.stem for p in self.directory.glob("*.npz")}

    def load(self, key: str) -> dict[str, np.ndarray]:
        with np.load(self._path(key)) as data:
            return {k: data[k] for k in data.files}

    def save(self, key: str, result: Mapping[str, np.ndarray]) -> None:
        # write then rename: a killed run never leaves a half-written result
        tmp = self.directory / f".{key}.tmp.npz"
        np.savez(tmp, **result)
        os.replace(tmp, self._path(key))


class InlineExecutor(cf.Executor):
    """Runs each task at submission, in this process (one worker: no process overhead)."""

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> cf.Future:
        future: cf.Future = cf.Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # handed to the caller through the future
            future.set_exception(exc)
        return future


def default_workers() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 1)


@contextlib.contextmanager
def executor(workers: int | None = None, scheduler: str | None = None) -> Iterator[cf.Executor]:
    """Where tasks run: a Dask cluster at ``scheduler`` (an address such as
    ``tcp://host:8786``), else ``workers`` local processes (default: the usable
    cores), inline when that is 1."""
    if workers is not None and (isinstance(workers, bool) or workers < 1):
        raise AnalysisError(f"--workers = {workers!r} must be >= 1")
    if scheduler is not None:
        try:
            from dask.distributed import Client
        except ImportError as exc:  # pragma: no cover - dask is a declared dependency
            raise RuntimeError("--scheduler needs dask.distributed installed") from exc
        try:
            client = Client(scheduler, timeout=5)
        except (OSError, TimeoutError) as exc:
            raise AnalysisError(
                f"--scheduler {scheduler}: no Dask scheduler there ({exc})"
            ) from None
        try:
            yield client.get_executor()
        finally:
            client.close()
        return
    n = workers or default_workers()
    if n == 1:
        yield InlineExecutor()
        return
    # fork: workers inherit the compiled kernels the parent has loaded
    methods = multiprocessing.get_all_start_methods()
    context = multiprocessing.get_context("fork" if "fork" in methods else "spawn")
    with cf.ProcessPoolExecutor(max_workers=n, mp_context=context) as pool:
        yield pool


@contextlib.contextmanager
def _given_or_new(
    pool: cf.Executor | None, workers: int | None, scheduler: str | None
) -> Iterator[cf.Executor]:
    """``pool`` itself (left open: its owner closes it), else a new :func:`executor`."""
    if pool is not None:
        yield pool
        return
    with executor(workers, scheduler) as new:
        yield new


SPLIT_MIN = 500  # rows: fewer are mapped in this process (a task costs more than it saves)


def part_count(workers: int | None = None, scheduler: str | None = None) -> int:
    """Into how many parts a batch is split for :func:`submit_interleaved`: one per worker (at
    least two on a pool or a cluster), one when it runs inline."""
    return 1 if scheduler is None and workers == 1 else max(2, workers or default_workers())


def submit_interleaved(
    pool: cf.Executor, n: int, fn: Callable[..., Any], head: Any, rows: Any
) -> list[cf.Future]:
    """``fn(head, rows[i::n])`` for each of the ``n`` parts, submitted to ``pool``.
    Interleaved rows, not contiguous blocks: neighbouring rows of a batch (often sorted
    by position) cost alike, so each part gets its share of the dear ones."""
    return [pool.submit(fn, head, rows[i::n]) for i in range(n)]


def gather_interleaved(parts: list[cf.Future], out: Any) -> Any:
    """The parts' results (rows of :func:`submit_interleaved`'s parts, in order) put back
    in row order into ``out`` (an array or a list of the batch's length)."""
    for i, part in enumerate(parts):
        out[i :: len(parts)] = part.result()
    return out


def _images(smap: Any, states: np.ndarray) -> np.ndarray:
    return smap.map(states)[0]


@contextlib.contextmanager
def parallel_images(
    smap: Any,
    workers: int | None = None,
    scheduler: str | None = None,
    pool: cf.Executor | None = None,
) -> Iterator[Callable[[np.ndarray], np.ndarray]]:
    """A function giving the one-period images of many states (rows; NaN where the run
    failed) of ``smap`` (a :class:`.maps.StroboscopicMap`), the rows split over the
    executor's workers (``pool`` when given: an analysis' own, else a new one); for
    analyses that map many small batches in turn."""
    n = part_count(workers, scheduler)
    with _given_or_new(pool, workers, scheduler) as pool:

        def images(states: np.ndarray) -> np.ndarray:
            if n == 1 or states.shape[0] < SPLIT_MIN:
                return _images(smap, states)
            parts = submit_interleaved(pool, n, _images, smap, states)
            return gather_interleaved(parts, np.empty_like(states))

        yield images


def run_tasks(
    fn: Callable[..., dict[str, np.ndarray]],
    tasks: list[Task],
    pool: cf.Executor,
    checkpoint: Checkpoint | None = None,
    follow_up: Callable[[str, dict[str, np.ndarray]], Task | None] | None = None,
    total: int | None = None,
    desc: str = "",
    progress: bool = True,
) -> dict[str, dict[str, np.ndarray]]:
    """Run ``fn(*args)`` for every task (and the follow-ups their results ask for),
    saving each result in ``checkpoint`` as it arrives; returns results by key."""
    from tqdm import tqdm

    results: dict[str, dict[str, np.ndarray]] = {}
    bar = tqdm(total=total or len(tasks), desc=desc, disable=not progress, unit="task")
    pending = {pool.submit(fn, *args): key for key, args in tasks}
    try:
        while pending:
            finished, _ = cf.wait(pending, return_when=cf.FIRST_COMPLETED)
            for future in finished:
                key = pending.pop(future)
                result = future.result()
                results[key] = result
                if checkpoint is not None:
                    checkpoint.save(key, result)
                bar.update(1)
                nxt = follow_up(key, result) if follow_up is not None else None
                if nxt is not None:
                    pending[pool.submit(fn, *nxt[1])] = nxt[0]
    finally:
        for future in pending:
            future.cancel()
        bar.close()
    return results


def map_in_chunks(
    smap: Any,
    grid: Any,
    samples: int,
    seed: int,
    function: Any,
    kind: str,
    analysis: str,
    workers: int | None,
    scheduler: str | None,
    checkpoint_dir: Any,
    chunk: int,
    progress: bool,
    pool: cf.Executor | None = None,
) -> list[dict[str, np.ndarray]]:
    """Run ``function(smap, grid, first, last, samples, seed)`` over the cells of ``grid``
    (a :class:`.cellmap.Grid`; ``smap`` a :class:`.maps.StroboscopicMap`) in chunks
    of ``chunk``, in parallel (on ``pool`` when given, else a new :func:`executor`) and
    checkpointed (a checkpoint is tied to ``analysis``, the grid, the sampling and the
    system); the chunks' results in cell order."""
    starts = list(range(0, grid.n_cells, chunk))
    keys = [f"{kind}_{a:09d}" for a in starts]
    tasks = [
        (k, (smap, grid, a, min(a + chunk, grid.n_cells), samples, seed))
        for k, a in zip(keys, starts, strict=True)
    ]
    checkpoint = None
    results: dict[str, dict[str, np.ndarray]] = {}
    if checkpoint_dir is not None:
        spec = {
            "analysis": analysis,
            "grid": [grid.nx, grid.nv, grid.x0, grid.x1, grid.v0, grid.v1],
            "samples": samples,
            "seed": seed,
            "chunk": chunk,
            "rtol": smap.rtol,
            "p": smap.system.p.tolist(),
            "ip": smap.system.ip.tolist(),
        }
        checkpoint = Checkpoint(checkpoint_dir, spec)
        done = checkpoint.done()
        results = {k: checkpoint.load(k) for k, _ in tasks if k in done}
        tasks = [t for t in tasks if t[0] not in done]
    if tasks:
        smap.map(smap.system.y0[None, :])  # load the kernels once: forked workers share them
        with _given_or_new(pool, workers, scheduler) as pool:
            results.update(
                run_tasks(function, tasks, pool, checkpoint, desc=kind, progress=progress)
            )
    return [results[k] for k in keys]
