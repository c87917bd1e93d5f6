"""Metrics of a basins result: basin stability, basin entropy, the boundary's dimension
and uncertainty exponent, and the Wada property.

They take the final-state grid: one outcome per cell (``outcomes[j, i]``, the x' index
``j`` and the x index ``i`` of :mod:`.cellmap`), an attractor's index, or one more for
escape (the sink counts as an outcome, as in Daza et al.).  A pursuit result knows every
sample's fate; a cell whose samples disagree is a boundary cell and takes the fate of
its first sample (the basin entropy uses every sample of a box).

* **Basin stability**: the share of the samples (cells, for cell mapping) going to each
  outcome.
* **Basin entropy** (Daza, Wagemakers, Georgeot, Guery-Odelin & Sanjuan, Sci. Rep. 6,
  31416, 2016): the grid cut into boxes of ``box x box`` cells; a box's entropy is
  ``-sum p_j ln p_j`` over the shares ``p_j`` of its samples' outcomes; ``Sb`` is its mean
  over all boxes, ``Sbb`` over the boxes that hold more than one outcome.  ``Sbb > ln 2``
  is a sufficient condition for a fractal boundary (the ln 2 criterion; with two outcomes
  ``Sbb`` never exceeds ln 2, so the criterion can only fire with three or more).
* **Boundary dimension and uncertainty exponent**: the number ``N(s)`` of boxes of ``s x
  s`` cells that hold more than one outcome, for box sizes over at least a decade; the
  box-counting dimension ``d`` of the boundary is the slope of ``ln N`` against
  ``ln(1/s)``, and the uncertainty exponent ``alpha = 2 - d`` (Grebogi, McDonald, Ott &
  Yorke 1983; the estimate Attractors.jl's ``uncertainty_exponent`` makes on a basins
  grid): 1 for a smooth boundary, below 1 for a fractal one.
* **Wada property by merging** (Daza, Wagemakers & Sanjuan, Sci. Rep. 8, 9954, 2018): for
  each outcome, the other outcomes merged into one; the boundary of that two-colour basin
  is the set of cells with a neighbour of the other colour.  The basin is Wada (at this
  resolution) when every such boundary lies within ``wada_cells`` cells of every other:
  the largest distance from a cell of one boundary to the nearest cell of another (a
  directed Hausdorff distance, in cells) is reported for every pair.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .errors import AnalysisError

DEFAULT_BOX = 5  # cells per side of the basin entropy's boxes (Daza et al. use 5)
DEFAULT_WADA_CELLS = 3.0


def box_entropy(samples: np.ndarray, box: int) -> tuple[float, float, int, int]:
    """``(Sb, Sbb, boxes, boundary boxes)`` of the outcomes ``samples[j, i, k]`` (cell
    ``(j, i)``, its sample ``k``; an int array, one outcome per sample) in boxes of
    ``box x box`` cells (the grid's remainder rows and columns left out)."""
    if not (isinstance(box, int) and box >= 1):
        raise AnalysisError(f"--box {box!r}: must be an integer >= 1")
    nv, nx, per = samples.shape
    bj, bi = nv // box, nx // box
    if bj < 1 or bi < 1:
        raise AnalysisError(f"--box {box}: larger than the grid ({nx} x {nv} cells)")
    cut = samples[: bj * box, : bi * box].reshape(bj, box, bi, box, per)
    flat = cut.transpose(0, 2, 1, 3, 4).reshape(bj * bi, box * box * per)
    n_out = int(samples.max()) + 1
    counts = np.stack([(flat == k).sum(axis=1) for k in range(n_out)], axis=1)
    p = counts / flat.shape[1]
    with np.errstate(divide="ignore", invalid="ignore"):
        h = -np.where(p > 0.0, p * np.log(p), 0.0).sum(axis=1)
    mixed = (counts > 0).sum(axis=1) > 1
    sb = float(h.mean())
    sbb = float(h[mixed].mean()) if mixed.any() else 0.0
    return sb, sbb, int(h.size), int(mixed.sum())


def boundary_boxes(outcomes: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """``N(s)``: the boxes of ``s x s`` cells holding more than one outcome, per size."""
    nv, nx = outcomes.shape
    out = []
    for s in sizes:
        bj, bi = nv // s, nx // s
        cut = outcomes[: bj * s, : bi * s].reshape(bj, s, bi, s)
        lo, hi = cut.min(axis=(1, 3)), cut.max(axis=(1, 3))
        out.append(int(np.sum(lo != hi)))
    return np.array(out)


def boundary_dimension(outcomes: np.ndarray, sizes: np.ndarray | None = None) -> dict[str, Any]:
    """The boundary's box-counting dimension and the uncertainty exponent (see the
    module's docstring), fitted over ``sizes`` (default: 2 cells up to a fifth of the
    grid's shorter side, at least 20, spaced evenly in ``ln s``: at least a decade; a box
    of one cell never holds two outcomes)."""
    short = min(outcomes.shape)
    if sizes is None:
        top = max(20, short // 5)
        sizes = np.unique(np.round(np.geomspace(2, top, 12)).astype(int))
    sizes = np.asarray(sizes, dtype=int)
    if sizes.min() < 2 or sizes.max() < 10 * sizes.min() or sizes.max() > short:
        raise AnalysisError(
            f"the boundary's dimension needs box sizes of 2 cells or more over a decade "
            f"within the grid ({short} cells on its shorter side; at least 20 x 20 cells)"
        )
    n = boundary_boxes(outcomes, sizes)
    if np.any(n == 0):
        return {"sizes": sizes.tolist(), "boundary_boxes": n.tolist(), "dimension": None,
                "uncertainty_exponent": None, "note": "no boundary at some box size"}  # fmt: skip
    slope, _ = np.polyfit(np.log(1.0 / sizes), np.log(n), 1)
    return {
        "sizes": sizes.tolist(),
        "boundary_boxes": n.tolist(),
        "dimension": float(slope),
        "uncertainty_exponent": float(2.0 - slope),
    }


def _boundary(mask: np.ndarray) -> np.ndarray:
    """Cells of ``mask`` (bool) or of its complement with a 4-neighbour of the other."""
    b = np.zeros_like(mask)
    diff_x = mask[:, 1:] != mask[:, :-1]
    diff_v = mask[1:, :] != mask[:-1, :]
    b[:, 1:] |= diff_x
    b[:, :-1] |= diff_x
    b[1:, :] |= diff_v
    b[:-1, :] |= diff_v
    return b


def wada_merging(outcomes: np.ndarray, wada_cells: float = DEFAULT_WADA_CELLS) -> dict[str, Any]:
    """The merging test (see the module's docstring) on the outcomes present."""
    from scipy.ndimage import distance_transform_edt

    present = [int(k) for k in np.unique(outcomes)]
    if len(present) < 3:
        return {"outcomes": len(present), "wada": False, "note": "fewer than three outcomes"}
    bounds = {k: _boundary(outcomes == k) for k in present}
    far = {k: distance_transform_edt(~b) for k, b in bounds.items()}  # cells to boundary k
    distances = {}
    for a in present:
        for b in present:
            if a != b and bounds[a].any():
                distances[f"{a}->{b}"] = float(far[b][bounds[a]].max())
    worst = max(distances.values()) if distances else math.inf
    return {
        "outcomes": len(present),
        "wada": bool(worst <= wada_cells),
        "max_distance_cells": worst,
        "wada_cells": wada_cells,
        "distances_cells": distances,
    }


def basin_metrics(
    outcomes: np.ndarray,
    samples: np.ndarray | None = None,
    names: list[str] | None = None,
    box: int = DEFAULT_BOX,
    wada_cells: float = DEFAULT_WADA_CELLS,
) -> dict[str, Any]:
    """Every metric of the module's docstring for the final-state grid ``outcomes``
    (``(nv, nx)`` ints), with every sample's outcome ``samples`` (``(nv, nx, k)``) when
    known; ``names`` label the outcomes in the basin stability."""
    outcomes = np.asarray(outcomes)
    if outcomes.ndim != 2 or outcomes.size == 0 or outcomes.min() < 0:
        raise AnalysisError("basin metrics need a grid of outcomes >= 0")
    per = outcomes[:, :, None] if samples is None else np.asarray(samples)
    n_out = int(per.max()) + 1
    shares = np.bincount(per.ravel(), minlength=n_out) / per.size
    labels = names or [str(k) for k in range(n_out)]
    metrics: dict[str, Any] = {
        "basin_stability": {labels[k]: float(shares[k]) for k in range(n_out)},
        "wada": wada_merging(outcomes, wada_cells),
    }
    try:
        sb, sbb, boxes, mixed = box_entropy(per, box)
        metrics["basin_entropy"] = {
            "Sb": sb,
            "Sbb": sbb,
            "box_cells": box,
            "boxes": boxes,
            "boundary_boxes": mixed,
            "ln2_criterion_fractal": bool(sbb > math.log(2.0)),
        }
    except AnalysisError as exc:  # a grid smaller than a box
        metrics["basin_entropy"] = {"error": str(exc)}
    try:
        metrics["boundary"] = boundary_dimension(outcomes)
    except AnalysisError as exc:
        metrics["boundary"] = {"error": str(exc)}
    return metrics


def metrics_of(
    basins: Any, box: int = DEFAULT_BOX, wada_cells: float = DEFAULT_WADA_CELLS
) -> dict[str, Any]:
    """:func:`basin_metrics` of a basins result (:class:`.cellmap.Basins`): every sample's
    fate when the method knows it (pursuit, slice), else the cells' labels (cell mapping:
    a boundary cell, whose samples reach several attractors, is an outcome of its own)."""
    g = basins.grid
    n_att = basins.n_attractors
    names = [f"{k}: {m.get('label', '')}".rstrip(": ") for k, m in enumerate(basins.motions)]
    names += [f"{k}" for k in range(len(names), n_att)]
    if basins.fates is not None:
        fates = np.asarray(basins.fates, dtype=np.int64).reshape(g.nv, g.nx, -1)
        found = basin_metrics(fates[:, :, 0], fates, [*names, "escape"], box, wada_cells)
        return {"from": "every sample's fate", **found}
    labels = np.asarray(basins.labels).reshape(g.nv, g.nx)
    out = np.where(labels >= 0, labels, np.where(labels == -1, n_att, n_att + 1))
    found = basin_metrics(out, None, [*names, "escape", "boundary"], box, wada_cells)
    return {"from": "the cells' labels", **found}
