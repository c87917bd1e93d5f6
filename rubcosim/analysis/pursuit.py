"""Basins by pursuit: every sample followed to a verified attractor (``--method pursuit``).

1. Every sample point (``samples`` per cell, the cell mapping's points) is
   mapped one forcing period by the compiled event-driven engine, in parallel
   checkpointed tasks: one map per sample, the whole cost of the method.
2. Each image is tied to the nearest sample point (:mod:`.sample_graph`):
   following those ties is following the sample's trajectory at the
   resolution of the sample spacing, so a map close to the identity (a weakly
   damped focus, a weak saddle) does not trap chains in spurious cell classes.
   Chains end in the sink (the image left the region) or in a cycle.
3. Each cycle's fate is decided by direct simulation (:mod:`.attractors`):
   the largest-draining cycles are simulated and classified, which finds and
   verifies the attractors and their neighbourhoods (:mod:`.state_space`);
   every other cycle is pursued with the compiled multi-period map until it
   enters one.
3b. A tie moves the image by up to half a sample spacing, which decides the
   fate of samples near a basin boundary: ties are used only where the
   samples around the image share one fate, and every other sample is tracked
   exactly until its fate is certain (:mod:`.trusted_ties`).
4. Per cell, the share of its samples going to each attractor and to the sink.
   A cell is in the *basin* of attractor k when k is the only attractor its
   samples reach, a *boundary* cell when they reach two or more (mixed), an
   *escape* cell when all of them leave the region.
5. The fixed points of P in the region are located by Newton from the
   samples' smallest displacements, with their multipliers
   (:mod:`.saddles`); those with one multiplier outside the unit circle are the
   saddles.

Attractors are numbered by the share of the samples they receive, largest first.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from .attractors import Attractor, settle
from .cellmap import (
    DEFAULT_CHUNK,
    LABEL_BOUNDARY,
    LABEL_ESCAPE,
    Basins,
    Grid,
    all_samples,
    check_inputs,
)
from .maps import StroboscopicMap
from .parallel import executor, map_in_chunks, parallel_images, part_count
from .saddles import FixedPointSearch
from .sample_graph import map_samples, sample_graph
from .state_space import StateSpace
from .trusted_ties import K_NEAR, settle_samples


def _map_all(
    smap: StroboscopicMap,
    grid: Grid,
    samples: int,
    seed: int,
    workers: int | None,
    scheduler: str | None,
    checkpoint_dir: Any,
    chunk: int,
    progress: bool,
    pool: Any,
) -> tuple[np.ndarray, np.ndarray]:
    """Every sample point and its one-period image, (n_cells * samples, 2) each."""
    chunks = map_in_chunks(
        smap, grid, samples, seed, map_samples, "samples", "pursuit",
        workers, scheduler, checkpoint_dir, chunk, progress, pool,
    )  # fmt: skip
    points = all_samples(grid, samples, seed, chunk)
    images = np.concatenate([r["image"] for r in chunks])
    return points, images


def tally(grid: Grid, samples: int, label: np.ndarray, known: list[Attractor]) -> dict[str, Any]:
    """From each sample's attractor (``label``, rows in cell order, ``samples`` per cell;
    ``len(known)`` for the sink): the attractors numbered by their share of the samples,
    largest first (``known``, ``label`` renumbered), per cell the ``shares`` of its samples
    per attractor and (last column) the sink, ``reach``, the cell ``labels`` (basin k,
    boundary, escape), ``attractor_of`` (cells holding an attractor's points) and the
    ``motions`` with their sample counts."""
    n_att = len(known)
    per_att = np.bincount(label, minlength=n_att + 1)[:n_att]
    rank = np.argsort(-per_att, kind="stable")
    known = [known[r] for r in rank]
    label = np.append(np.argsort(rank), n_att)[label]
    cell = np.repeat(np.arange(grid.n_cells), samples)
    shares = np.bincount(cell * (n_att + 1) + label, minlength=grid.n_cells * (n_att + 1))
    shares = shares.reshape(grid.n_cells, n_att + 1) / samples
    reach = shares[:, :n_att] > 0
    n_reach = reach.sum(axis=1)
    labels = np.where(n_reach == 0, LABEL_ESCAPE, LABEL_BOUNDARY)
    single = n_reach == 1
    if n_att:
        labels[single] = np.argmax(reach[single], axis=1)
    attractor_of = np.full(grid.n_cells, -1)
    for k, a in enumerate(known):
        attractor_of[a.cells] = k
    motions = []
    for k, a in enumerate(known):
        n_k = int(np.sum(label == k))
        where = (
            {"neighbourhood_radius_in_state_scales": a.radius}
            if a.radius
            else {"neighbourhood_cells": int(a.near.sum())}
        )
        motions.append({**a.motion, "samples": n_k, "sample_fraction": n_k / label.size, **where})
    return {
        "known": known,
        "label": label,
        "shares": shares,
        "reach": reach,
        "labels": labels,
        "attractor_of": attractor_of,
        "motions": motions,
    }


def pursuit_basins(
    smap: StroboscopicMap,
    grid: Grid,
    samples: int,
    seed: int = 0,
    workers: int | None = None,
    scheduler: str | None = None,
    checkpoint_dir: Any = None,
    chunk: int = DEFAULT_CHUNK,
    progress: bool = False,
) -> Basins:
    """Basins, attractors and saddles by pursuit of every sample (see the module doc).

    One pool of workers serves the whole analysis; what needs no result of the stage
    in progress runs on it meanwhile (Newton from the winding starts, a chaotic
    attractor's Lyapunov exponent) while this process builds the sample graph and
    classifies the attractors."""
    check_inputs(smap, samples, seed)
    clock = {"start": time.perf_counter()}
    with executor(workers, scheduler) as pool:
        points, images = _map_all(
            smap, grid, samples, seed, workers, scheduler, checkpoint_dir, chunk, progress, pool
        )
        clock["mapped"] = time.perf_counter()
        search = FixedPointSearch(
            smap, grid, points, images, samples, pool, part_count(workers, scheduler)
        )
        g = sample_graph(grid, points, images, k=K_NEAR)
        clock["graph"] = time.perf_counter()
        space = StateSpace(smap, grid, (0, 1), pool)
        heads_fate, known, found = settle(smap, space, points[g["cycles"]])
        clock["attractors"] = time.perf_counter()
        # each sample's fate through trusted ties only, the others tracked exactly
        with parallel_images(smap, workers, scheduler, pool) as mapper:
            label, tied = settle_samples(
                smap, space, grid, points, images, g, heads_fate, known, mapper
            )
        space.lyapunov_done(known)
        clock["ties"] = time.perf_counter()
        t = tally(grid, samples, label, known)
        where = (t["labels"] == LABEL_BOUNDARY) | (t["attractor_of"] >= 0)
        fps = search.result(where)
        clock["saddles"] = time.perf_counter()
    stats = {
        "cycles": found["starts"],
        "cycles_simulated": found["simulated"],
        "cycles_pursued": found["pursued"],
        "pursuit_periods": found["pursuit_periods"],
        "ties": tied,
    }
    n_att = len(known)
    label, labels, attractor_of = t["label"], t["labels"], t["attractor_of"]
    for p in fps:  # where it lies: a saddle on a basin boundary, or inside an attractor
        p["on_boundary"] = bool(labels[p["cell"]] == LABEL_BOUNDARY)
        p["in_attractor"] = int(attractor_of[p["cell"]])
    total = points.shape[0]
    motions = t["motions"]
    image = grid.cell_of(np.nan_to_num(images, nan=np.inf)).reshape(grid.n_cells, samples)
    saddles = [np.array([p["cell"]]) for p in fps if p["saddle"]]
    periods = [int(m.get("period") or 0) for m in motions]
    stats["sink_samples"] = int(np.sum(label == n_att))
    stats["sink_sample_fraction"] = stats["sink_samples"] / total
    stats["seconds"] = {
        k: round(clock[k] - clock[p], 3)
        for p, k in zip(
            ["start", "mapped", "graph", "attractors", "ties"],
            ["mapped", "graph", "attractors", "ties", "saddles"],
            strict=True,
        )
    }
    basins = Basins(
        grid, samples, seed, image, labels, attractor_of, t["reach"], saddles, periods, motions
    )
    basins.method = "pursuit"
    basins.shares = t["shares"]
    basins.fixed_points = fps
    basins.fates = label.reshape(grid.n_cells, samples).astype(np.int16)
    basins.info = {"pursuit": stats}
    return basins
