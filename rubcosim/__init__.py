"""rubcosim: nonsmooth rotor/stator rub-impact dynamics and its co-simulation.

The Python API (:mod:`rubcosim.api`) is re-exported here and loaded on first use, so
``import rubcosim`` stays cheap::

    import rubcosim as rc

    sc = rc.load("jeffcott_rigid_stator", set={"rotor.speed": 400})
    res = rc.simulate(sc, engine="fast")
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ._version import __version__

# name -> the module that defines it; imported on first access (PEP 562)
_API = {
    "load": "api",
    "simulate": "api",
    "cosimulate": "api",
    "check": "api",
    "sweep": "api",
    "basins": "api",
    "lyapunov": "api",
    "control_study": "api",
    "continuation": "api_continuation",
    "bifurcation_curve": "api_continuation",
    "basin_continuation": "api_continuation",
    "scenarios": "api",
    "Scenario": "scenario",
    "ScenarioError": "scenario",
    "SimulationResult": "results",
    "CheckResult": "results",
}
__all__ = [
    "__version__",
    "load",
    "simulate",
    "cosimulate",
    "check",
    "sweep",
    "basins",
    "lyapunov",
    "control_study",
    "continuation",
    "bifurcation_curve",
    "basin_continuation",
    "scenarios",
    "Scenario",
    "ScenarioError",
    "SimulationResult",
    "CheckResult",
]

if TYPE_CHECKING:
    from .api import (
        basins,
        check,
        control_study,
        cosimulate,
        load,
        lyapunov,
        scenarios,
        simulate,
        sweep,
    )
    from .api_continuation import basin_continuation, bifurcation_curve, continuation
    from .results import CheckResult, SimulationResult
    from .scenario import Scenario, ScenarioError


def __getattr__(name: str) -> Any:
    module = _API.get(name)
    if module is None:
        raise AttributeError(f"module 'rubcosim' has no attribute {name!r}")
    from importlib import import_module

    value = getattr(import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_API})


def _numba_cache_dir() -> Path:
    """numba's cache directory, named by the sources compiled code can reach
    (:mod:`.compile_key`): an edit elsewhere keeps the compiled code, an edit there
    starts a new directory (numba does not notice a change in another module)."""
    from .compile_key import numba_cache_dir

    return numba_cache_dir(__version__)


if not os.environ.get("NUMBA_CACHE_DIR"):
    os.environ["NUMBA_CACHE_DIR"] = str(_numba_cache_dir())
    try:  # numba may already be imported by the host program: set its live config too
        import numba.core.config as _numba_config

        _numba_config.CACHE_DIR = os.environ["NUMBA_CACHE_DIR"]
    except ImportError:  # pragma: no cover - numba is a hard dependency
        pass
