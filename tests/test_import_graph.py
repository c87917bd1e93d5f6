"""The package's import graph, read from the sources (imports inside functions
included): the components import nothing above them, and among themselves form no
cycle; the whole package's modules (every folder pyproject installs) form no cycle."""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
COMPONENTS = "rubcosim.components"


def _modules(folder: Path, package: str) -> dict[str, Path]:
    out = {}
    for f in folder.glob("*.py"):
        out[package if f.stem == "__init__" else f"{package}.{f.stem}"] = f
    return out


def _imports(module: str, path: Path, known: dict[str, Path]) -> set[str]:
    """Every module of ``known``, or absolute name, that ``module`` imports anywhere in its
    source; ``from . import x`` of a submodule x is an import of x, not of the package."""
    found: set[str] = set()
    parts = module.split(".")
    base = parts if path.stem == "__init__" else parts[:-1]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                target = ".".join(base[: len(base) - node.level + 1] + [node.module or ""])
            else:
                target = node.module or ""
            target = target.rstrip(".")
            subs = [f"{target}.{a.name}" for a in node.names if f"{target}.{a.name}" in known]
            found.update(subs if len(subs) == len(node.names) else [target, *subs])
    found.discard(module)
    return found


def _cycle(edges: dict[str, set[str]]) -> list[str]:
    """One import cycle of ``edges`` (module -> modules it imports), [] if there is none."""
    state: dict[str, int] = {}
    path: list[str] = []

    def visit(v: str) -> list[str]:
        state[v] = 1
        path.append(v)
        for w in sorted(edges[v]):
            if state.get(w) == 1:
                return path[path.index(w) :] + [w]
            if w not in state and (found := visit(w)):
                return found
        state[v] = 2
        path.pop()
        return []

    for v in sorted(edges):
        if v not in state and (found := visit(v)):
            return found
    return []


@pytest.fixture(scope="module")
def components() -> dict[str, set[str]]:
    known = _modules(ROOT / "components", COMPONENTS)
    return {m: _imports(m, p, known) for m, p in known.items()}


def test_the_components_import_no_module_of_rubcosim_above_them(components):
    above = {
        (m, i)
        for m, imported in components.items()
        for i in imported
        if i.startswith("rubcosim.") and not i.startswith(COMPONENTS)
    }
    assert not above


def test_the_components_import_one_another_without_a_cycle(components):
    edges = {m: {i for i in imported if i in components} for m, imported in components.items()}
    assert _cycle(edges) == []
    # the check finds a cycle where there is one
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]


def _package_folders() -> dict[str, Path]:
    """Every package pyproject installs -> its folder (package-dir maps a package and,
    below it, its subpackages: ``rubcosim.fmus.loader`` is ``fmus/loader``)."""
    setup = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    where = setup["package-dir"]
    folders = {}
    for package in setup["packages"]:
        parent = max((p for p in where if package == p or package.startswith(p + ".")), key=len)
        rest = package[len(parent) :].lstrip(".").split(".") if package != parent else []
        folders[package] = ROOT.joinpath(where[parent], *rest)
    return folders


def test_the_whole_package_imports_itself_without_a_cycle():
    known: dict[str, Path] = {}
    for package, folder in _package_folders().items():
        assert folder.is_dir(), folder
        known.update(_modules(folder, package))
    # the graph holds every layer: the package, the reference, the co-simulation, the FMUs
    for module in (
        "rubcosim",
        "rubcosim.api",
        "rubcosim.reference.simulate",
        "rubcosim.analysis.sweep",
        "rubcosim.orchestrator.assembly",
        "rubcosim.fmus.build",
        COMPONENTS,
    ):
        assert module in known
    edges = {m: {i for i in _imports(m, p, known) if i in known} for m, p in known.items()}
    assert _cycle(edges) == []
