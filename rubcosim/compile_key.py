"""Which sources compiled code depends on: the name of numba's cache directory.

numba invalidates a cached function when its own file changes, not when a function or a
constant it takes from another module does (numba#1833, #9483).  So the cache directory is
named by a hash of every source that compiled code can reach: each module of rubcosim that
uses numba (in ``components/``, ``reference/``, ``orchestrator/``, ``analysis/`` and the
package itself), and every module of rubcosim those import, directly or not, at any depth
and inside functions too.  An edit to a module no compiled code reaches (the Python master,
the FMU master, the CLI, the scenario files' loader, the plots) keeps the compiled code; an
edit anywhere compiled code can see starts a new, empty directory, so a stale mixture of old
and new kernels cannot happen.

The set is found from the import statements, so it sees static imports only.  The
computed imports in the code today do not escape it: the generated modules are keyed by
their own text (:mod:`rubcosim.reference.specialize`), and the engines
``simulate`` imports by name import numba themselves.  A module a kernel module imported
by a computed name, and that itself uses no numba, would escape the key.

Finding that set parses the sources (about 0.5 s).  The answer is kept under the hash of
all the sources (``keys/`` in the cache), so a process finds it with one read of the sources
and one small file, as long as no source changed.

Every process marks the directory it uses (its modification time); when a new state of the
sources is first seen, the directories (and keys) no process has used for
:data:`UNUSED_DAYS` days are removed: each holds about 100 MB of compiled code for sources
that are gone (an older release, an old checkout).
"""

from __future__ import annotations

import contextlib
import hashlib
import os
from importlib.util import find_spec
from pathlib import Path

# the packages whose modules compiled code may import, besides rubcosim itself
SUBPACKAGES = ("components", "reference", "orchestrator", "analysis")
UNUSED_DAYS = 30


def sources() -> dict[str, Path]:
    """Every module of rubcosim and of its subpackages :data:`SUBPACKAGES`: name -> file."""
    found: dict[str, Path] = {}
    for package in ("rubcosim", *(f"rubcosim.{name}" for name in SUBPACKAGES)):
        spec = find_spec(package)
        for folder in spec.submodule_search_locations if spec else ():
            for path in sorted(Path(folder).glob("*.py")):
                module = package if path.stem == "__init__" else f"{package}.{path.stem}"
                found[module] = path
    return found


def reached(texts: dict[str, bytes]) -> set[str]:
    """The modules of ``texts`` (name -> source) that import numba (or rubcosim's ``njit``),
    and every module of ``texts`` they import, transitively."""
    graph: dict[str, tuple[set[str], bool]] = {}

    def parsed(name: str) -> tuple[set[str], bool]:
        if name not in graph:
            graph[name] = _imports(name, texts[name], texts)
        return graph[name]

    # a module that never names numba or njit cannot import them: not parsed to find out
    named = [n for n, text in texts.items() if b"numba" in text or b"njit" in text]
    todo = [name for name in named if parsed(name)[1]]
    seen: set[str] = set()
    while todo:
        name = todo.pop()
        if name not in seen:
            seen.add(name)
            todo.extend(parsed(name)[0])
    return seen


def imported(name: str, text: bytes, known: dict[str, bytes] | set[str]) -> set[str]:
    """The modules among ``known`` that module ``name`` imports anywhere in ``text``, inside
    functions too (``import a.b``, ``from a import b``, relative imports; a package is named
    by its ``__init__``).  Imports under ``if TYPE_CHECKING:`` never run and are left out."""
    return _imports(name, text, known)[0]


def _imports(name: str, text: bytes, known: dict[str, bytes] | set[str]) -> tuple[set[str], bool]:
    """:func:`imported`, and whether the module imports numba or an ``njit``."""
    import ast

    package = name if _is_package(name, known) else name.rpartition(".")[0]
    found: set[str] = set()
    numba = False
    todo = list(ast.parse(text).body)
    while todo:
        node = todo.pop()
        if isinstance(node, ast.If) and _type_checking(node.test):
            todo.extend(node.orelse)
            continue
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
            numba |= any(alias.name.split(".")[0] == "numba" for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                parts = parts[: len(parts) - (node.level - 1)]
                base = ".".join([*parts, node.module] if node.module else parts)
            found.add(base)
            found.update(f"{base}.{alias.name}" for alias in node.names)
            numba |= base.split(".")[0] == "numba" or any(a.name == "njit" for a in node.names)
        todo.extend(ast.iter_child_nodes(node))
    return {module for module in found if module in known}, numba


def _type_checking(test: object) -> bool:
    import ast

    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _is_package(name: str, known: dict[str, bytes] | set[str]) -> bool:
    return any(other.startswith(name + ".") for other in known)


def key(version: str, files: dict[str, Path] | None = None) -> str:
    """The hash (16 hex digits) of ``version`` and of the sources compiled code can reach
    (:func:`reached`), looked up in ``keys/`` of the cache by the hash of all sources."""
    files = sources() if files is None else files
    texts = {name: path.read_bytes() for name, path in files.items()}
    everything = _digest(version, texts, texts)
    note = cache_base() / "keys" / everything
    try:
        return note.read_text().strip()
    except OSError:
        pass
    found = _digest(version, texts, reached(texts))
    remove_unused(keep=found)
    try:
        note.parent.mkdir(parents=True, exist_ok=True)
        scratch = note.with_name(f".{everything}.{os.getpid()}")
        scratch.write_text(found)
        os.replace(scratch, note)
    except OSError:
        pass  # an unwritable cache: found again by the next process
    return found


def _digest(version: str, texts: dict[str, bytes], names: set[str] | dict[str, bytes]) -> str:
    digest = hashlib.sha256(version.encode())
    for name in sorted(names):
        digest.update(name.encode())
        digest.update(texts[name])
    return digest.hexdigest()[:16]


def cache_base() -> Path:
    """``$XDG_CACHE_HOME/rubcosim/numba`` (``~/.cache`` without it)."""
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "rubcosim" / "numba"


def numba_cache_dir(version: str) -> Path:
    """numba's cache directory for these sources (:func:`cache_base` / :func:`key`),
    marked as used now."""
    folder = cache_base() / key(version)
    with contextlib.suppress(OSError):  # not made yet: numba makes it at its first write
        os.utime(folder)
    return folder


def remove_unused(keep: str, days: float = UNUSED_DAYS) -> list[Path]:
    """Remove the cache directories other than ``keep``, and the keys, that no process has
    used for ``days`` days; returns what was removed."""
    base = cache_base()
    return [
        *remove_unused_entries(base, r"[0-9a-f]{16}", keep, days),
        *remove_unused_entries(base / "keys", r".+", keep, days),
    ]


def remove_unused_entries(folder: Path, names: str, keep: str, days: float) -> list[Path]:
    """Remove the entries of ``folder`` whose name matches the regular expression ``names``,
    other than ``keep``, not modified for ``days`` days (a user marks an entry by touching
    it): directories with what they hold.  Used for every cache rubcosim keeps per version
    of its sources (numba's, the fmu backend's FMU builds); returns what was removed."""
    import re
    import shutil
    import time

    old = time.time() - days * 86400.0
    removed = []
    for path in _entries(folder):
        try:
            unused = (
                path.name != keep
                and re.fullmatch(names, path.name) is not None
                and path.stat().st_mtime < old
            )
        except OSError:
            continue
        if unused:
            if path.is_dir():
                shutil.rmtree(path, ignore_errors=True)
            else:
                path.unlink(missing_ok=True)
            removed.append(path)
    return removed


def _entries(folder: Path) -> list[Path]:
    try:
        return list(folder.iterdir())
    except OSError:
        return []
