"""Inline kernels at the source level: a module's functions with the calls of their
``inline="always"`` callees written out, before numba sees them.

numba inlines an ``inline="always"`` callee at its IR level: at every call site it
builds the callee's IR again (running the untyped pipeline over it, and so inlining the
callee's own callees the same way), then copies it into the caller, block by block,
each copy taking the function's whole scope with it.  Both costs grow faster than the
code inlined, and the engines' stage loops inline a model's right-hand side through
four or five levels of helpers.  Written out here, the same code reaches numba as one
function: it builds one IR, once.

What is written out is what numba would have inlined, with the same semantics:

* the arguments are bound to fresh names first (an array is bound, not copied, as a
  call passes it), a compiled function passed as an argument (the stage loop's
  right-hand side) is put in place of its parameter, so that it is written out too;
* the callee's locals are renamed apart, its globals read through aliases imported from
  its own module (a module constant stays a global, which numba compiles in);
* a ``return`` becomes an assignment to the call's target, the statements after it an
  ``else``.

A call is written out where it is a statement, the value of an assignment or a return,
or part of one evaluated unconditionally before any other call that is not a known pure
one; a callee with a ``return`` inside a loop, a nested function or a comprehension is
left to numba.  Anything left is still correct: numba inlines it as before.
"""

from __future__ import annotations

import ast
import builtins
import copy
import importlib.util
import itertools
from dataclasses import dataclass, field
from pathlib import Path

from .source_inline_rewrites import Replace, evaluation_order, lower, pure

_BUILTINS = frozenset(dir(builtins))
_MAX_EXPANSIONS = 5000


@dataclass
class Source:
    """One module's parsed source and how a generated module imports from it:
    ``ref`` is ``"rubcosim.components.stator"``, or ``".reference_system"`` for a module
    of the same generated package."""

    ref: str
    tree: ast.Module
    is_package: bool = False
    text: str = ""
    functions: dict[str, ast.FunctionDef] = field(default_factory=dict)
    bound: dict[str, ast.stmt] = field(default_factory=dict)  # module-level names

    @classmethod
    def parse(cls, ref: str, text: str, is_package: bool = False) -> Source:
        tree = ast.parse(text)
        src = cls(ref, tree, is_package, text)
        for node in tree.body:
            if isinstance(node, ast.FunctionDef):
                src.functions[node.name] = node
                src.bound[node.name] = node
            elif isinstance(node, ast.Import | ast.ImportFrom):
                for alias in node.names:
                    if alias.name != "*":
                        src.bound[alias.asname or alias.name.split(".")[0]] = node
            elif isinstance(node, ast.Assign | ast.AnnAssign):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                for target in targets:
                    for name in ast.walk(target):
                        if isinstance(name, ast.Name):
                            src.bound[name.id] = node
        return src

    def absolute(self, node: ast.ImportFrom) -> str:
        """The absolute module of a relative import in an installed module."""
        if node.level == 0:
            return node.module or ""
        level = node.level - 1 if self.is_package else node.level
        base = self.ref.rsplit(".", level)[0] if level else self.ref
        return f"{base}.{node.module}" if node.module else base


def inlinable(fn: ast.FunctionDef) -> bool:
    """Whether ``fn`` is decorated ``njit(..., inline="always")`` and can be written out."""
    marked = any(
        isinstance(d, ast.Call)
        and any(
            k.arg == "inline" and isinstance(k.value, ast.Constant) and k.value.value == "always"
            for k in d.keywords
        )
        for d in fn.decorator_list
    )
    if not marked or fn.args.vararg or fn.args.kwarg or fn.args.kwonlyargs:
        return False
    for node in ast.walk(fn):
        if node is not fn and isinstance(
            node,
            ast.FunctionDef | ast.Lambda | ast.ListComp | ast.SetComp | ast.DictComp
            | ast.GeneratorExp | ast.Global | ast.Nonlocal | ast.Try | ast.With | ast.Yield
            | ast.YieldFrom | ast.AsyncFunctionDef,
        ):  # fmt: skip
            return False
    return not any(_returns_inside_loop(s, False) for s in fn.body)


def _returns_inside_loop(node: ast.AST, in_loop: bool) -> bool:
    if isinstance(node, ast.Return):
        return in_loop
    loop = in_loop or isinstance(node, ast.For | ast.While)
    return any(_returns_inside_loop(child, loop) for child in ast.iter_child_nodes(node))


class Flattener:
    """Writes out the inlinable calls of functions of module ``target``.

    ``package`` maps the names of the generated package's modules (``"model"``,
    ``"reference_system"``) to their sources, read for relative imports; installed
    modules are read from their files."""

    def __init__(self, target: Source, package: dict[str, Source] | None = None) -> None:
        self.target = target
        self.package = package or {}
        self._installed: dict[str, Source | None] = {}
        self.aliases: dict[str, tuple[Source, str]] = {}  # alias -> (module, name there)
        self._alias_of: dict[tuple[str, str], str] = {}
        self._counter = itertools.count(1)
        self.expansions = 0

    # -- finding what a name refers to ---------------------------------------------
    def _module(self, importer: Source, node: ast.ImportFrom | None, name: str) -> Source | None:
        if node is not None and node.level and importer.ref.startswith("."):
            return self.package.get(node.module or "")
        module = importer.absolute(node) if node is not None else name
        if not module.startswith("rubcosim"):
            return None
        if module not in self._installed:
            spec = importlib.util.find_spec(module)
            origin = spec.origin if spec is not None else None
            ok = origin is not None and origin.endswith(".py")
            self._installed[module] = (
                Source.parse(module, Path(origin).read_text(), origin.endswith("__init__.py"))
                if ok
                else None
            )
        return self._installed[module]

    def _resolve(self, src: Source, name: str, depth: int = 0) -> tuple[str, Source, str] | None:
        """``("function" | "module", source, name)`` for ``name`` in module ``src``."""
        if depth > 20:
            return None
        if src is self.target and name in self.aliases:
            src, name = self.aliases[name]
        if name in src.functions:
            return "function", src, name
        node = src.bound.get(name)
        if isinstance(node, ast.ImportFrom):
            attr = next(a.name for a in node.names if (a.asname or a.name) == name)
            module = self._module(src, node, "") if node.module or not node.level else None
            if module is not None and attr in module.bound:
                return self._resolve(module, attr, depth + 1)
            if src.ref.startswith(".") and node.level:  # from . import a module of the package
                found = self.package.get(attr) if node.module is None else None
            else:
                found = self._module(src, None, f"{src.absolute(node)}.{attr}")
            if found is not None:
                return "module", found, ""
        elif isinstance(node, ast.Import):
            alias = next(a for a in node.names if (a.asname or a.name.split(".")[0]) == name)
            found = self._module(src, None, alias.name)
            if found is not None and alias.asname:
                return "module", found, ""
        return None

    def _callee(self, func: ast.expr) -> tuple[Source, ast.FunctionDef] | None:
        found = None
        if isinstance(func, ast.Name):
            found = self._resolve(self.target, func.id)
        elif isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name):
            module = self._resolve(self.target, func.value.id)
            if module is not None and module[0] == "module":
                found = self._resolve(module[1], func.attr)
        if found is None or found[0] != "function":
            return None
        fn = found[1].functions[found[2]]
        return (found[1], fn) if inlinable(fn) else None

    def _is_function(self, expr: ast.expr) -> bool:
        if not isinstance(expr, ast.Name):
            return False
        found = self._resolve(self.target, expr.id)
        return found is not None and found[0] == "function"

    def _alias(self, src: Source, name: str) -> str:
        key = (src.ref, name)
        if key not in self._alias_of:
            alias = f"_i{len(self._alias_of) + 1}_{name}"
            self._alias_of[key] = alias
            self.aliases[alias] = (src, name)
        return self._alias_of[key]

    def read(self) -> dict[str, str]:
        """The installed modules read so far: name -> source text."""
        return {name: src.text for name, src in self._installed.items() if src is not None}

    def imports(self) -> list[str]:
        """The import lines the aliases need, one per module."""
        by_module: dict[str, list[str]] = {}
        for alias, (src, name) in self.aliases.items():
            by_module.setdefault(src.ref, []).append(f"{name} as {alias}")
        return [f"from {ref} import {', '.join(names)}" for ref, names in by_module.items()]

    # -- writing a call out ----------------------------------------------------------
    def _body(self, src: Source, fn: ast.FunctionDef, call: ast.Call) -> tuple[list, dict]:
        """The callee's statements for this call: arguments bound, locals renamed,
        globals aliased; and the renaming of its parameters."""
        k = next(self._counter)
        params = [a.arg for a in fn.args.posonlyargs + fn.args.args]
        defaults = fn.args.defaults
        given: dict[str, ast.expr] = dict(zip(params, call.args, strict=False))
        for kw in call.keywords:
            given[kw.arg] = kw.value
        for name, default in zip(params[len(params) - len(defaults) :], defaults, strict=True):
            given.setdefault(name, default)
        local = set(params)
        for node in ast.walk(fn):
            if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
                local.add(node.id)
        substitute: dict[str, str] = {}
        bind: list[ast.stmt] = []
        for name in params:
            arg = given[name]
            if self._is_function(arg):  # a compiled function passed in: put in its place
                substitute[name] = arg.id
                local.discard(name)
            else:
                new = f"{name}__{k}"
                bind.append(ast.Assign([ast.Name(new, ast.Store())], copy.deepcopy(arg)))
        rename = {name: f"{name}__{k}" for name in local}
        same = src is self.target
        flat = self

        class Rename(ast.NodeTransformer):
            def visit_Name(self, node: ast.Name) -> ast.Name:
                if node.id in rename:
                    return ast.Name(rename[node.id], node.ctx)
                if node.id in substitute:
                    return ast.Name(substitute[node.id], node.ctx)
                if same or (node.id in _BUILTINS and node.id not in src.bound):
                    return node
                return ast.Name(flat._alias(src, node.id), node.ctx)

        body = [copy.deepcopy(s) for s in fn.body]
        if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
            body = body[1:]  # the docstring
        body = [Rename().visit(s) for s in body]
        return bind + body, rename

    def _expand(self, call: ast.Call, target: ast.expr | None, aug: ast.AugAssign | None):
        src, fn = self._callee(call.func)
        self.expansions += 1
        if self.expansions > _MAX_EXPANSIONS:
            raise RecursionError("source inlining does not end (a recursive kernel?)")
        body, _ = self._body(src, fn, call)
        if aug is not None:
            result = ast.Name(f"_r{next(self._counter)}", ast.Store())
            tail = [ast.AugAssign(aug.target, aug.op, ast.Name(result.id, ast.Load()))]
            return lower(body, result) + tail
        return lower(body, target)

    def _hoist(self, expr: ast.expr) -> tuple[list[ast.stmt], ast.expr] | None:
        """Write out the first call of ``expr`` that can be, before the statement that
        holds it: ``(statements, expr with a name in its place)``."""
        order = evaluation_order(expr)
        for node in order:
            if node is None:
                return None  # a conditional part with a call: evaluation order unknown
            if self._callee(node.func) is not None:
                name = f"_r{next(self._counter)}"
                stmts = self._expand(node, ast.Name(name, ast.Store()), None)
                replaced = Replace(node, ast.Name(name, ast.Load())).visit(copy.copy(expr))
                return stmts, replaced
            if not pure(node):
                return None
        return None

    def statements(self, stmts: list[ast.stmt]) -> list[ast.stmt]:
        """``stmts`` with every call that can be written out written out."""
        out: list[ast.stmt] = []
        work = list(stmts)
        while work:
            s = work.pop(0)
            new = self._statement(s)
            if new is None:
                out.append(self._nested(s))
            else:
                work[:0] = new
        return out

    def _statement(self, s: ast.stmt) -> list[ast.stmt] | None:
        value = getattr(s, "value", None)
        if isinstance(value, ast.Call) and self._callee(value.func) is not None:
            if isinstance(s, ast.Expr):
                return self._expand(value, None, None)
            if isinstance(s, ast.Assign) and len(s.targets) == 1:
                return self._expand(value, s.targets[0], None)
            if isinstance(s, ast.AugAssign):
                return self._expand(value, None, s)
            if isinstance(s, ast.Return):
                name = f"_r{next(self._counter)}"
                stmts = self._expand(value, ast.Name(name, ast.Store()), None)
                return [*stmts, ast.Return(ast.Name(name, ast.Load()))]
        slot = "test" if isinstance(s, ast.If) else None
        if isinstance(s, ast.Expr | ast.Assign | ast.AugAssign | ast.Return) and value is not None:
            slot = "value"
        if slot is None:
            return None
        hoisted = self._hoist(getattr(s, slot))
        if hoisted is None:
            return None
        before, expr = hoisted
        s = copy.copy(s)
        setattr(s, slot, expr)
        return [*before, s]

    def _nested(self, s: ast.stmt) -> ast.stmt:
        if isinstance(s, ast.If | ast.For | ast.While):
            s = copy.copy(s)
            s.body = self.statements(s.body)
            s.orelse = self.statements(s.orelse)
        return s

    def function(self, fn: ast.FunctionDef) -> ast.FunctionDef:
        """``fn`` with its calls written out."""
        new = copy.copy(fn)
        new.body = self.statements(fn.body)
        return new


def flatten_module(
    text: str,
    ref: str,
    package: dict[str, str] | None = None,
    only: set[str] | None = None,
    read: dict[str, str] | None = None,
) -> str:
    """Module source ``text`` (imported as ``ref``) with the inlinable calls of its
    functions written out: those named in ``only``, by default every function that is
    not itself inlinable.  ``package``: the generated package's other modules' texts;
    ``read``, if given, receives the installed modules read (name -> source text)."""
    sources = {name: Source.parse(f".{name}", t) for name, t in (package or {}).items()}
    target = Source.parse(ref, text)
    flat = Flattener(target, sources)
    lines = text.splitlines()
    edits: list[tuple[int, int, str]] = []
    for node in target.tree.body:
        if not isinstance(node, ast.FunctionDef):
            continue
        if (node.name not in only) if only is not None else inlinable(node):
            continue
        before = flat.expansions
        new = flat.function(node)
        if flat.expansions > before:
            first = min([d.lineno for d in node.decorator_list] + [node.lineno])
            ast.fix_missing_locations(new)
            edits.append((first, node.end_lineno or node.lineno, ast.unparse(new)))
    for first, last, replacement in sorted(edits, reverse=True):
        lines[first - 1 : last] = replacement.splitlines()
    if read is not None:
        read.update(flat.read())
    imports = flat.imports()
    if imports:
        last_import = max(
            n.end_lineno or n.lineno
            for n in target.tree.body
            if isinstance(n, ast.Import | ast.ImportFrom)
        )
        lines[last_import:last_import] = imports
    return "\n".join(lines) + "\n"
