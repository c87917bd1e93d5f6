"""numba's cache directory follows the sources compiled code can reach (rubcosim.compile_key):
an edit of the Python master or the CLI keeps every compiled kernel; an edit of a kernel, or
of a module a kernel takes a constant from, starts a new directory."""

from __future__ import annotations

import shutil

from rubcosim import __version__
from rubcosim.compile_key import cache_base, key, reached, sources

TREE = {
    # a kernel module, a constant it imports inside a function, a relative import
    "pkg.kernels": b"from numba import njit\nfrom .consts import N\n"
    b"def f():\n    from pkg.deep import helper\n",
    "pkg.consts": b"N = 3\n",
    "pkg.deep": b"from . import leaf\n",
    "pkg.leaf": b"X = 1\n",
    # the package itself, and a driver that calls the kernels from Python
    "pkg": b"",
    "pkg.driver": b"from .kernels import f\nfrom typing import TYPE_CHECKING\n"
    b"if TYPE_CHECKING:\n    from .cli import Thing\n",
    "pkg.cli": b"from .driver import run  # mentions numba in a comment only\n",
    # rubcosim's own njit wrapper counts as numba
    "pkg.wrapped": b"from pkg.jit import njit\n",
    "pkg.jit": b"import numba\n",
}


def test_what_compiled_code_can_reach_follows_its_imports():
    assert reached(TREE) == {
        "pkg.kernels",
        "pkg.consts",
        "pkg.deep",
        "pkg.leaf",
        "pkg",
        "pkg.wrapped",
        "pkg.jit",
    }


def test_real_sources_kernels_and_what_they_read_are_in_the_python_master_is_not():
    texts = {name: path.read_bytes() for name, path in sources().items()}
    found = reached(texts)
    for name in (
        "rubcosim.components.stator",
        "rubcosim.components.registry",  # the declarations the parameter slots come from
        "rubcosim.reference.system",
        "rubcosim.reference.layout",
        "rubcosim.orchestrator.flat_loop",
        "rubcosim.orchestrator.flat_layout",
        "rubcosim.analysis.tangent_kernels",
    ):
        assert name in found, name
    for name in (
        "rubcosim.orchestrator.master",
        "rubcosim.orchestrator.fmu_unit",
        "rubcosim.cli",
        "rubcosim.api",
        "rubcosim.plots",
    ):
        assert name not in found, name


def test_the_key_changes_with_a_kernel_and_not_with_the_python_master(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    files = {}
    for name, path in sources().items():
        copy = tmp_path / "src" / f"{name}.py"
        copy.parent.mkdir(exist_ok=True)
        shutil.copyfile(path, copy)
        files[name] = copy
    first = key(__version__, files)
    assert (cache_base() / "keys").is_dir()  # the answer is kept for the next process
    assert key(__version__, files) == first

    master = files["rubcosim.orchestrator.master"]
    master.write_bytes(master.read_bytes() + b"\n# an edit of the Python master\n")
    assert key(__version__, files) == first

    stator = files["rubcosim.components.stator"]
    stator.write_bytes(stator.read_bytes() + b"\n# an edit of the stator's kernels\n")
    assert key(__version__, files) != first
    assert key("another version", files) != key(__version__, files)


def test_cache_directories_unused_for_thirty_days_are_removed(tmp_path, monkeypatch):
    import os
    import time

    from rubcosim.compile_key import numba_cache_dir, remove_unused

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    base = cache_base()
    old, recent, current = base / "0123456789abcdef", base / "fedcba9876543210", base / "keys"
    for folder in (old / "sub", recent / "sub", current):
        folder.mkdir(parents=True)
    (current / ("a" * 16)).write_text("0123456789abcdef")
    (base / "not_a_cache").mkdir()
    forty_days_ago = time.time() - 40 * 86400.0
    for path in (old, current / ("a" * 16), base / "not_a_cache"):
        os.utime(path, (forty_days_ago, forty_days_ago))

    removed = remove_unused(keep="fedcba9876543210")
    assert sorted(p.name for p in removed) == ["0123456789abcdef", "a" * 16]
    assert not old.exists() and recent.is_dir() and (base / "not_a_cache").is_dir()

    # the directory a process uses is marked as used, so it is kept however old it was
    used = numba_cache_dir(__version__)
    used.mkdir(parents=True, exist_ok=True)
    os.utime(used, (forty_days_ago, forty_days_ago))
    assert numba_cache_dir(__version__) == used
    assert used.stat().st_mtime > time.time() - 60
    assert used not in remove_unused(keep="none of them")
