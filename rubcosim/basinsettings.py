"""The ``[basins]`` table of a scenario: defaults for ``rubcosim basins`` / ``rc.basins``.

::

    [basins]
    method = "pursuit"          # "gcm", "pursuit" or "slice"
    grid = [200, 200]           # cells in x and x' (or "200x200")
    samples = 16                # random points per cell, >= 1
    region = [-2.0, 1.0, -2.0, 2.0]   # x0, x1, v0, v1 in the state's units (or "-2:1,-2:2")
    seed = 0                    # seed of the sample points, >= 0
    slice = ["oscillator.x2", "oscillator.v2"]   # the two state names the grid spans

Every key is optional; the command line's flags (and ``rc.basins``' arguments)
override them.  A bad value raises :class:`ScenarioError` naming the key.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from .errors import ScenarioError

BASIN_METHODS = ("gcm", "pursuit", "slice")  # generalized cell mapping; pursuit; slices
BASIN_KEYS = ("method", "grid", "samples", "region", "seed", "slice")


def _int(key: str, value: Any, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise ScenarioError(f"basins.{key} = {value!r} must be an integer >= {low}")
    return value


def _numbers(key: str, value: Any, count: int, form: str) -> list[Any]:
    if isinstance(value, str):
        try:
            parts = value.lower().replace(",", ":").replace("x", ":").split(":")
            return [float(p) if key == "region" else int(p) for p in parts if p != ""]
        except ValueError:
            raise ScenarioError(f"basins.{key} = {value!r}: expected {form}") from None
    if not isinstance(value, list | tuple) or len(value) != count:
        raise ScenarioError(f"basins.{key} = {value!r}: expected {form}")
    return list(value)


def basin_settings(raw: Mapping[str, Any]) -> dict[str, Any]:
    """The keys of ``[basins]`` that are given, checked: ``method`` (one of
    :data:`BASIN_METHODS`), ``grid`` ``(nx, nv)``, ``samples``, ``region`` ``(x0, x1,
    v0, v1)`` (floats, x0 < x1, v0 < v1), ``seed``, ``slice`` (two state names)."""
    unknown = sorted(set(raw) - set(BASIN_KEYS))
    if unknown:
        raise ScenarioError(
            f"basins.{unknown[0]} is not a setting (known: {', '.join(BASIN_KEYS)})"
        )
    out: dict[str, Any] = {}
    if "method" in raw:
        if raw["method"] not in BASIN_METHODS:
            raise ScenarioError(
                f"basins.method = {raw['method']!r}: one of {', '.join(BASIN_METHODS)}"
            )
        out["method"] = raw["method"]
    if "grid" in raw:
        g = _numbers("grid", raw["grid"], 2, '[NX, NV] or "NXxNV", e.g. [200, 200]')
        if len(g) != 2:
            raise ScenarioError(f"basins.grid = {raw['grid']!r}: expected [NX, NV]")
        out["grid"] = tuple(_int("grid", n, 1) for n in g)
    if "samples" in raw:
        out["samples"] = _int("samples", raw["samples"], 1)
    if "seed" in raw:
        out["seed"] = _int("seed", raw["seed"], 0)
    if "region" in raw:
        form = '[X0, X1, V0, V1] or "X0:X1,V0:V1", e.g. [-2, 1, -2, 2]'
        r = _numbers("region", raw["region"], 4, form)
        ok = len(r) == 4 and all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in r
        )
        if not ok or not (r[0] < r[1] and r[2] < r[3]):
            raise ScenarioError(
                f"basins.region = {raw['region']!r}: needs finite x0 < x1 and v0 < v1 ({form})"
            )
        out["region"] = tuple(float(v) for v in r)
    if "slice" in raw:
        s = raw["slice"]
        names = s.split(",") if isinstance(s, str) else s
        if not (isinstance(names, list | tuple) and len(names) == 2):
            raise ScenarioError(f"basins.slice = {s!r}: expected two state names")
        if not all(isinstance(n, str) and n.strip() for n in names):
            raise ScenarioError(f"basins.slice = {s!r}: expected two state names")
        out["slice"] = tuple(n.strip() for n in names)
    return out
