"""rubcosim: nonsmooth rotor/stator rub-impact dynamics and its co-simulation.

The Python API (:mod:`rubcosim.api`) is re-exported here and loaded on first use, so
``import rubcosim`` stays cheap::

    import rubcosim as rc

    sc = rc.load("jeffcott_rigid_stator", set={"rotor.speed": 400})
    res = rc.simulate(sc, engine="fast")
"""

from __future__ import annotations

import hashlib
import os
from importlib.util import find_spec
from pathlib import Path
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

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
    """A numba cache directory keyed by the source of every compiled module.

    numba invalidates a cached function when its own file changes, not when a
    function it calls in another module does; keying the directory on all the
    sources makes a stale mixture of old and new kernels impossible.
    """
    digest = hashlib.sha256(__version__.encode())
    for package in ("rubcosim.components", "rubcosim.reference", "rubcosim.orchestrator"):
        spec = find_spec(package)
        for folder in spec.submodule_search_locations if spec else ():
            for path in sorted(Path(folder).glob("*.py")):
                digest.update(path.name.encode())
                digest.update(path.read_bytes())
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "rubcosim" / "numba" / digest.hexdigest()[:16]


if not os.environ.get("NUMBA_CACHE_DIR"):
    os.environ["NUMBA_CACHE_DIR"] = str(_numba_cache_dir())
    try:  # numba may already be imported by the host program: set its live config too
        import numba.core.config as _numba_config

        _numba_config.CACHE_DIR = os.environ["NUMBA_CACHE_DIR"]
    except ImportError:  # pragma: no cover - numba is a hard dependency
        pass
