"""rubcosim: nonsmooth rotor/stator rub-impact dynamics and its co-simulation."""

from __future__ import annotations

import hashlib
import os
from importlib.util import find_spec
from pathlib import Path

__version__ = "0.1.0"


def _numba_cache_dir() -> Path:
    """A numba cache directory keyed by the source of every compiled module.

    numba invalidates a cached function when its own file changes, not when a
    function it calls in another module does; keying the directory on all the
    sources makes a stale mixture of old and new kernels impossible.
    """
    digest = hashlib.sha256(__version__.encode())
    for package in ("rubcosim.components", "rubcosim.reference"):
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
