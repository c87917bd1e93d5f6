"""The statement rewrites of source-level inlining (:mod:`.source_inline`): returns as
assignments, the order in which an expression's calls are evaluated, and replacing a
call by the name of its result."""

from __future__ import annotations

import ast
import copy

_PURE_MODULES = frozenset({"math", "np", "numpy", "nb", "numba"})
_PURE_BUILTINS = frozenset({"abs", "min", "max", "float", "int", "bool", "range", "len"})


def lower(body: list[ast.stmt], target: ast.expr | None) -> list[ast.stmt]:
    """The callee's statements with each ``return v`` an assignment ``target = v``
    (or dropped), the statements after a branch that returns under its ``else``."""
    out: list[ast.stmt] = []
    for i, s in enumerate(body):
        if isinstance(s, ast.Return):
            if target is not None and s.value is not None:
                out.append(ast.Assign([copy.deepcopy(target)], s.value))
            return out
        if isinstance(s, ast.If) and _has_return(s):
            rest = body[i + 1 :]
            new = copy.copy(s)
            new.body = lower(s.body if _ends(s.body) else s.body + rest, target) or [ast.Pass()]
            new.orelse = lower(s.orelse if _ends(s.orelse) else s.orelse + rest, target)
            out.append(new)
            return out
        out.append(s)
    return out


def _has_return(node: ast.AST) -> bool:
    return any(isinstance(n, ast.Return) for n in ast.walk(node))


def _ends(stmts: list[ast.stmt]) -> bool:
    """Whether every path through ``stmts`` returns."""
    if not stmts:
        return False
    last = stmts[-1]
    if isinstance(last, ast.Return):
        return True
    return isinstance(last, ast.If) and _ends(last.body) and _ends(last.orelse)


def evaluation_order(expr: ast.expr) -> list[ast.Call | None]:
    """The calls of ``expr`` in the order they finish; ``None`` for a conditional part
    (``and``, ``or``, ``x if c else y``) that holds a call."""
    out: list[ast.Call | None] = []

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.BoolOp | ast.IfExp):
            if any(isinstance(n, ast.Call) for n in ast.walk(node)):
                out.append(None)
            return
        if isinstance(node, ast.Call):
            visit(node.func)
            for a in node.args:
                visit(a)
            for k in node.keywords:
                visit(k.value)
            out.append(node)
            return
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(expr)
    return out


def pure(call: ast.Call) -> bool:
    f = call.func
    if isinstance(f, ast.Name):
        return f.id in _PURE_BUILTINS
    while isinstance(f, ast.Attribute):
        f = f.value
    return isinstance(f, ast.Name) and f.id in _PURE_MODULES


class Replace(ast.NodeTransformer):
    def __init__(self, old: ast.AST, new: ast.expr) -> None:
        self.old, self.new = old, new

    def generic_visit(self, node: ast.AST) -> ast.AST:
        if node is self.old:
            return self.new
        for name, value in ast.iter_fields(node):
            if isinstance(value, list):
                setattr(node, name, [self.visit(v) if isinstance(v, ast.AST) else v for v in value])
            elif isinstance(value, ast.AST):
                setattr(node, name, self.visit(value))
        return node

    def visit(self, node: ast.AST) -> ast.AST:
        if node is self.old:
            return self.new
        node = copy.copy(node)
        return self.generic_visit(node)
