"""Compile the engines for one model only: per-model copies of the compiled modules.

The kernels of :mod:`.system` serve every model: they branch on ``ip`` (which
units the system has, where their states are), and numba compiles every branch
of every unit type into each engine, hundreds of times over through the inlined
Runge-Kutta stages.  That is what a first run paid for: minutes of compiling for
a model of two units.

Here a model's engine is compiled from a copy of the compiled modules in which
every structural read ``ip[IP_NAME]`` is the module constant ``M_IP_NAME`` of
that model (a generated ``model`` module).  numba prunes a branch whose condition
is a comparison of constants before it inlines or types anything, so the copy
compiles the model's own units and nothing else.  The copies live in a package
under numba's cache directory named by the hash of their text (the model's
``ip`` and the sources), written once: a second process imports them and loads
the compiled code from numba's cache, a different model gets its own package,
and an edit of a source makes new copies (numba keys its cache on the file).

Which modules are copied follows the imports: :mod:`.system` and every module
of rubcosim that imports a copied module, among the names given by the caller
(an analysis asks for its own kernels; the engines bring the rest).  A module
that does not depend on the model (the Runge-Kutta tableau, the root finders)
is imported from the package as usual, so its compiled code is shared by every
model.
"""

from __future__ import annotations

import ast
import hashlib
import importlib
import importlib.util
import os
import re
import sys
import tempfile
from functools import cache
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from .layout import LAYOUT

ROOT = "rubcosim.reference.system"
# Every module that depends on the model, in an order where a module comes after what it
# imports of these (numba resolves a copy's globals when it compiles, not on import).
MODEL_MODULES = (
    ROOT,
    "rubcosim.reference.history",
    "rubcosim.reference.event_search",
    "rubcosim.reference.core",
    "rubcosim.reference.tangent",
    "rubcosim.reference.fast",
    "rubcosim.reference.accurate",
    "rubcosim.analysis.strobe_kernels",
    "rubcosim.analysis.tangent_kernels",
)
_HYBRID = ("hybrid_rhs", "hybrid_events", "hybrid_apply", "hybrid_outputs")
_IP_READ = re.compile(r"\bip\[(?:S\.)?(IP_\w+)\]")
# Which slots of ``ip`` a copy compiles in as constants: its scope.
#
# ``family`` (the default): the family (the rotor family, or hybrid unit type i) and
# whether a delayed-feedback controller is there.  An impact oscillator's engine holds
# its own kernels only; the rotor family's holds every rotor, stator and bearing type,
# once without the controller and its delay and once with them.  ``model``: every slot
# that says which unit types the model has and where their states are, so an engine
# holds exactly the model's units.  A first run of one rotor model compiles about 1.5
# times faster in ``model`` scope, but each rotor model then compiles its own engine,
# and the engine's machinery (the step loop, the event search, the event handling)
# costs more than the units in it: the whole test suite compiled about 2.5 times as
# long (measured with both scopes, 2026-11-28).  ``RUBCOSIM_COMPILE_SCOPE=model`` picks
# it.  A choice parameter's value (the controller's feedback and modulation shape) stays
# a run-time read in either: one engine serves every choice.
SCOPES = ("family", "model")
_CHOICE_SLOTS = frozenset(LAYOUT.ip_choice.values())
_FAMILY_SLOTS = ("IP_FAMILY", "IP_CONTROLLER")


def scope() -> str:
    """The compile scope in force (``RUBCOSIM_COMPILE_SCOPE``, default ``family``)."""
    value = os.environ.get("RUBCOSIM_COMPILE_SCOPE") or "family"
    if value not in SCOPES:
        raise ValueError(f"RUBCOSIM_COMPILE_SCOPE = {value!r} is not one of {', '.join(SCOPES)}")
    return value


def constant_slots(which: str | None = None) -> dict[str, int]:
    """The slots of ``ip`` compiled in as constants in scope ``which`` (default: in
    force): constant name -> slot."""
    which = which or scope()
    names = _FAMILY_SLOTS if which == "family" else LAYOUT.constants
    return {
        name: LAYOUT.constants[name]
        for name in names
        if name.startswith("IP_") and LAYOUT.constants[name] not in _CHOICE_SLOTS
    }


def model_key(ip: np.ndarray) -> tuple[int, ...]:
    """What the compiled engine of a system depends on in the scope in force: the scope,
    then the values of the slots it compiles in as constants."""
    which = scope()
    return (SCOPES.index(which), *(int(ip[s]) for s in constant_slots(which).values()))


def _flat(name: str) -> str:
    """The copy's module name inside its package: ``reference_fast``."""
    return name.removeprefix("rubcosim.").replace(".", "_")


def _source(name: str) -> str:
    spec = importlib.util.find_spec(name)
    if spec is None or spec.origin is None:
        raise ImportError(f"cannot find the source of {name}")
    return Path(spec.origin).read_text()


def _absolute(module: str, node: ast.ImportFrom) -> str:
    if node.level == 0:
        return node.module or ""
    base = module.rsplit(".", node.level)[0]
    return f"{base}.{node.module}" if node.module else base


def _rewrite_imports(module: str, text: str, constants: dict[str, int]) -> str:
    """``module``'s source with its imports pointing at the copies where there are
    copies and at the package elsewhere, and every read of a slot in ``constants`` a
    constant of the model."""
    tree = ast.parse(text)
    lines = text.splitlines()
    edits: list[tuple[int, int, str]] = []
    for node in tree.body:
        if not isinstance(node, ast.ImportFrom) or node.module == "__future__":
            continue
        target = _absolute(module, node)
        names = node.names
        if target == "rubcosim.components.hybrid_dispatch" and module == ROOT:
            model = [a for a in names if a.name in _HYBRID]
            rest = [a for a in names if a.name not in _HYBRID]
            new = [ast.ImportFrom("model", model, 1)]
            if rest:
                new.append(ast.ImportFrom(target, rest, 0))
        elif target in MODEL_MODULES:
            new = [ast.ImportFrom(_flat(target), names, 1)]
        elif node.module is None and f"{target}.{names[0].name}" in MODEL_MODULES:
            aliases = [ast.alias(_flat(f"{target}.{a.name}"), a.asname or a.name) for a in names]
            new = [ast.ImportFrom(None, aliases, 1)]
        else:
            new = [ast.ImportFrom(target, names, 0)]
        text = "\n".join(map(ast.unparse, new))
        edits.append((node.lineno, node.end_lineno or node.lineno, text))
    for first, last, replacement in sorted(edits, reverse=True):
        lines[first - 1 : last] = [replacement]
    futures = [n for n in tree.body if isinstance(n, ast.ImportFrom) and n.module == "__future__"]
    future = futures[-1].end_lineno if futures else 0
    lines.insert(future, "from .model import *  # noqa: F403  (generated: this model's constants)")

    def constant(match: re.Match) -> str:
        name = match.group(1)
        return f"M_{name}" if name in constants else match.group(0)

    return _IP_READ.sub(constant, "\n".join(lines)) + "\n"


def _model_source(values: dict[str, int]) -> str:
    """The generated ``model`` module: the model's constants (slot name -> value) and
    its hybrid unit type's kernels under the names :mod:`.system` calls."""
    from rubcosim.components.hybrid_dispatch import hybrid_types

    lines = ['"""Generated by rubcosim.reference.specialize; do not edit."""', ""]
    lines.append("from rubcosim.components.jit import njit")
    lines.append(f"__all__ = {[f'M_{name}' for name in values]!r}")
    for name, value in values.items():
        lines.append(f"M_{name} = {value}")
    family = values["IP_FAMILY"]
    types = hybrid_types()
    args = {
        "hybrid_rhs": "t, y, mode, p, dy",
        "hybrid_events": "t, y, mode, p, g, dirs, rates",
        "hybrid_apply": "k, t, y, mode, p",
        "hybrid_outputs": "t, y, mode, p, out",
    }
    fields = {"hybrid_rhs": "rhs", "hybrid_events": "events", "hybrid_apply": "apply",
              "hybrid_outputs": "output"}  # fmt: skip
    index = family - 1  # FAMILY_HYBRID = 1: hybrid type i is family 1 + i
    for function in _HYBRID:
        lines += ["", "", '@njit(inline="always")', f"def {function}(i, {args[function]}):"]
        if 0 <= index < len(types):
            kernel = getattr(types[index].hybrid, fields[function])
            py = getattr(kernel, "py_func", kernel)
            lines.insert(3, f"from {py.__module__} import {py.__name__} as _{fields[function]}")
            call = f"_{fields[function]}({args[function]})"
            lines.append(f"    return {call}" if function == "hybrid_apply" else f"    {call}")
        else:  # a rotor-family model: never called (its branch is pruned)
            lines.append("    return mode, 0" if function == "hybrid_apply" else "    pass")
    return "\n".join(lines) + "\n"


@cache
def _template(which: str) -> tuple[tuple[str, str], ...]:
    """The copies' sources in scope ``which``, as read once per process."""
    constants = constant_slots(which)
    return tuple((name, _rewrite_imports(name, _source(name), constants)) for name in MODEL_MODULES)


def _write(text: str, path: Path) -> None:
    if path.is_file() and path.read_text() == text:
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")  # then rename: atomic
    with os.fdopen(fd, "w") as f:
        f.write(text)
    os.replace(tmp, path)


@cache
def _package(key: tuple[int, ...]) -> str:
    which = SCOPES[key[0]]
    model = _model_source(dict(zip(constant_slots(which), key[1:], strict=True)))
    files = {"__init__.py": '"""Generated: one model\'s compiled modules."""\n', "model.py": model}
    for name, text in _template(which):
        files[f"{_flat(name)}.py"] = text
    digest = hashlib.sha256()
    for file, text in sorted(files.items()):
        digest.update(file.encode() + b"\0" + text.encode() + b"\0")
    tag = digest.hexdigest()[:16]
    package = f"rubcosim_model_{tag}"
    if package in sys.modules:
        return package
    base = Path(os.environ.get("NUMBA_CACHE_DIR") or tempfile.gettempdir()) / "models" / tag
    try:
        for file, text in files.items():
            _write(text, base / package / file)
    except OSError as exc:
        raise OSError(
            f"cannot write the model's compiled modules under {base} ({exc.strerror}); "
            "set NUMBA_CACHE_DIR to a writable directory"
        ) from exc
    spec = importlib.util.spec_from_file_location(
        package, base / package / "__init__.py", submodule_search_locations=[str(base / package)]
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules[package] = module
    spec.loader.exec_module(module)
    return package


def model_label(system: Any) -> str:
    """The model's units, for a person: ``rotor.jeffcott + stator.rigid``."""
    units = getattr(system, "units", {}) or {}
    return " + ".join(f"{role}.{u.type}" for role, u in units.items()) or "this model"


def engine_label(system: Any) -> str:
    """What an engine compiled for ``system`` serves in the scope in force, for a person:
    ``the rotor family without a controller (here rotor.jeffcott + stator.rigid)``."""
    which, units = scope(), model_label(system)
    if which == "model":
        return units
    from .system import CONTROLLER_NONE, FAMILY_ROTOR, IP_CONTROLLER, IP_FAMILY

    if system.ip[IP_FAMILY] != FAMILY_ROTOR:
        return units
    with_controller = system.ip[IP_CONTROLLER] != CONTROLLER_NONE
    family = "with the delayed-feedback controller" if with_controller else "without a controller"
    return f"the rotor family {family} (here {units})"


def specialized(name: str, ip: np.ndarray) -> ModuleType:
    """The copy of module ``name`` (one of :data:`MODEL_MODULES`) for the model whose
    integer array is ``ip``."""
    if name not in MODEL_MODULES:
        raise ValueError(f"{name} does not depend on the model")
    return importlib.import_module(f"{_package(model_key(ip))}.{_flat(name)}")
