"""Compile one model's kernels only: per-model copies of the modules that hold them.

The kernels of :mod:`.system` serve every model: they branch on ``ip`` (which
units the system has, where their states are), and numba would compile every
branch of every unit type into each of them.  The engines' machinery does not
depend on the model (it calls a model through the pointers of its model tuple,
:mod:`.model_calls`); the kernels it calls are :mod:`.model_kernels`' C functions,
compiled here per model.

A model's kernels are compiled from a copy of :mod:`.system` and
:mod:`.model_kernels` in which every structural read ``ip[IP_NAME]`` that the
compile scope names is the module constant ``M_IP_NAME`` of that model (a
generated ``model`` module).  numba prunes a branch whose condition is a
comparison of constants before it inlines or types anything, so the copy compiles
the model's own units and nothing else.  The copies live in a package under
numba's cache directory named by the hash of their text (the model's constants and
the sources), written once: a second process imports them and loads the compiled
code from numba's cache, a different model gets its own package, and an edit of a
source makes new copies (numba keys its cache on the file).  A module that does not
depend on the model (the Runge-Kutta tableau, the unit types' physics) is imported
from the package as usual.
"""

from __future__ import annotations

import ast
import contextlib
import hashlib
import importlib
import importlib.util
import json
import os
import re
import sys
import tempfile
from functools import cache
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from rubcosim.compile_notice import announce_when_slow

from .layout import LAYOUT
from .model_calls import ModelTuple

ROOT = "rubcosim.reference.system"
# The modules copied per model, in an order where a module comes after what it imports
# of these (numba resolves a copy's globals when it compiles, not on import).  The
# engines' machinery is not among them: it calls a model through the pointers of its
# model tuple (:mod:`.model_calls`) and is compiled once for every model.
MODEL_MODULES = (ROOT, "rubcosim.reference.system_outputs", "rubcosim.reference.model_kernels")
_HYBRID = ("hybrid_rhs", "hybrid_events", "hybrid_apply", "hybrid_outputs")
_IP_READ = re.compile(r"\bip\[(?:S\.)?(IP_\w+)\]")
# Which slots of ``ip`` a copy compiles in as constants: its scope.
#
# ``family`` (the default): the family (the rotor family, or hybrid unit type i) and
# whether a delayed-feedback controller is there.  An impact oscillator's kernels hold
# its own physics only; the rotor family's hold every rotor, stator and bearing type,
# once without the controller and its delay and once with them.  ``model``: every slot
# that says which unit types the model has and where their states are, so the kernels
# hold exactly the model's units: a rotor model's first compile is a little shorter
# (9.7 s against 11.0 s before the kernels held a Runge-Kutta step), but every rotor
# model then compiles its own, and the bundled ones are five.
# ``RUBCOSIM_COMPILE_SCOPE=model`` picks it.  A choice parameter's value (the
# controller's feedback and modulation shape) stays a run-time read in either.
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
        if target == "rubcosim.components.hybrid_dispatch":
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


def _sha(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()


def _flattened(files: dict[str, str], names: list[str]) -> dict[str, str]:
    """``files`` with the kernels of modules ``names`` written out at the source level
    (:mod:`rubcosim.components.source_inline`), so that numba builds each kernel's IR
    once instead of inlining its helpers call site by call site.  Writing them out
    takes about 0.3 s, so the result is kept on disk under the hash of ``files``, with
    the hashes of the installed modules it read: a process whose sources are those
    reads it back."""
    if os.environ.get("RUBCOSIM_SOURCE_INLINE", "1") != "1":
        return files
    digest = hashlib.sha256()
    for file, text in sorted(files.items()):
        digest.update(file.encode() + b"\0" + text.encode() + b"\0")
    base = Path(os.environ.get("NUMBA_CACHE_DIR") or tempfile.gettempdir()) / "models"
    memo = base / "flattened" / f"{digest.hexdigest()[:24]}.json"
    with contextlib.suppress(OSError, ValueError, KeyError, AttributeError):
        kept = json.loads(memo.read_text())
        if all(
            _sha(Path(importlib.util.find_spec(m).origin).read_text()) == h
            for m, h in kept["read"].items()
        ):
            return kept["files"]
    from rubcosim.components.source_inline import flatten_module

    texts = {file[:-3]: text for file, text in files.items() if file != "__init__.py"}
    out, read = dict(files), {}
    for name in names:
        others = {k: v for k, v in texts.items() if k != name}
        out[f"{name}.py"] = flatten_module(texts[name], "." + name, others, read=read)
    with contextlib.suppress(OSError):
        _write(json.dumps({"files": out, "read": {m: _sha(t) for m, t in read.items()}}), memo)
    return out


@cache
def _package(key: tuple[int, ...]) -> str:
    which = SCOPES[key[0]]
    model = _model_source(dict(zip(constant_slots(which), key[1:], strict=True)))
    files = {"__init__.py": '"""Generated: one model\'s compiled modules."""\n', "model.py": model}
    for name, text in _template(which):
        files[f"{_flat(name)}.py"] = text
    files = _flattened(files, [_flat(name) for name, _ in _template(which)])
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


def kernels_label(system: Any) -> str:
    """What the kernels compiled for ``system`` serve in the scope in force, for a person:
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


def compiled_model(system: Any) -> tuple[Any, ...]:
    """The model tuple the engines take (:mod:`.model_calls`): ``(ip, rhs, events, apply,
    outputs)``, the kernels compiled for ``system``'s model (on first use, said on the
    terminal; loaded from numba's cache after that)."""
    key = model_key(system.ip)
    if key not in _KERNELS:
        with announce_when_slow(f"the kernels of {kernels_label(system)}"):
            kernels = specialized("rubcosim.reference.model_kernels", system.ip).KERNELS
        _KERNELS[key] = kernels
    return ModelTuple((np.array(system.ip, dtype=np.int64), *_KERNELS[key]))


_KERNELS: dict[tuple[int, ...], tuple[Any, ...]] = {}
