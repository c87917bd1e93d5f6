"""Source-level inlining (components/source_inline.py): a module with its inlinable calls
written out computes what the original computes, and no longer calls them.

The modules here are plain Python (``njit`` a decorator that does nothing), so the
original and the written-out functions run side by side on the same inputs."""

from __future__ import annotations

import ast
import importlib
import random
import sys
import textwrap

import pytest

from rubcosim.components.source_inline import flatten_module

HELPERS = textwrap.dedent(
    '''
    import math

    SCALE = 3.0


    def njit(function=None, **options):
        return (lambda f: f) if function is None else function


    @njit(inline="always")
    def clamp(x, lo=-1.0, hi=1.0):
        """An early return in each branch."""
        if x < lo:
            return lo
        if x > hi:
            return hi
        return x


    @njit(inline="always")
    def polar(x, y):
        r = math.sqrt(x * x + y * y)
        if r == 0.0:
            return 0.0, 1.0, 0.0
        return r, x / r, y / r


    @njit(inline="always")
    def scaled(x):
        return SCALE * clamp(x, hi=2.0)


    @njit(inline="always")
    def fill(out, x):
        for i in range(out.shape[0] if hasattr(out, "shape") else len(out)):
            out[i] = scaled(x + i)


    @njit(inline="always")
    def stages(evaluate, ctx, x, out):
        for s in range(3):
            evaluate(ctx, x + s, out, s)


    @njit(inline="always")
    def first_positive(values):
        for v in values:
            if v > 0:
                return v
        return 0.0
    '''
)

MAIN = textwrap.dedent(
    """
    from .helpers import clamp, first_positive, njit, polar, scaled, stages, fill


    @njit(inline="always")
    def _slot(ctx, x, out, s):
        out[s] = ctx * scaled(x)


    def kernel(x, y, out):
        r, nx, ny = polar(x, y)
        total = clamp(x) + 2.0 * scaled(y)
        total += scaled(r)
        if clamp(nx - ny, lo=-0.5) > 0.0:
            total -= 1.0
        elif scaled(ny) < 0.0:
            total += 0.5
        fill(out, x)
        stages(_slot, 0.5, y, out)
        ok = x > 0 and clamp(y) > 0
        return total + first_positive([x, y]) + (1.0 if ok else 0.0)
    """
)


@pytest.fixture
def package(tmp_path, monkeypatch):
    """Import ``orig`` (the modules as written) and ``flat`` (``kernel`` written out)."""
    flat = flatten_module(MAIN, ".main", {"helpers": HELPERS})
    for name, main in (("orig", MAIN), ("flat", flat)):
        (tmp_path / name).mkdir()
        (tmp_path / name / "__init__.py").write_text("")
        (tmp_path / name / "helpers.py").write_text(HELPERS)
        (tmp_path / name / "main.py").write_text(main)
    monkeypatch.syspath_prepend(str(tmp_path))
    yield importlib.import_module("orig.main"), importlib.import_module("flat.main"), flat
    for name in ("orig", "orig.main", "orig.helpers", "flat", "flat.main", "flat.helpers"):
        sys.modules.pop(name, None)


def test_written_out_kernel_computes_what_the_original_computes(package):
    orig, flat, _ = package
    rng = random.Random(45)
    for _ in range(400):
        x, y = rng.uniform(-3, 3), rng.uniform(-3, 3)
        if rng.random() < 0.05:
            x = y = 0.0  # the early return of polar
        a, b = [0.0] * 4, [0.0] * 4
        assert flat.kernel(x, y, b) == orig.kernel(x, y, a)
        assert a == b


def test_inlinable_calls_are_written_out_where_the_evaluation_order_allows(package):
    _, _, text = package
    tree = ast.parse(text)
    kernel = next(n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "kernel")
    called = {
        n.func.id
        for n in ast.walk(kernel)
        if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)
    }
    # written out: every call in a statement, an unconditional expression or a test, and
    # the right-hand side passed into the stage loop; left: the one inside `and` and the
    # callee whose return is inside a loop
    assert called == {"clamp", "first_positive", "hasattr", "len", "range"}


def test_a_callee_from_another_module_reads_its_globals_through_aliases(package):
    _, _, text = package
    aliases = text.splitlines()[2]
    assert aliases.startswith("from .helpers import ")
    assert "math as _i1_math" in aliases and "SCALE as _i2_SCALE" in aliases
    assert "_i2_SCALE * " in text  # scaled's global, read through its alias
