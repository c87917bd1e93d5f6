"""The copy of an inlined callee's IR that rubcosim installs into numba
(``components/numba_inlining.py``): same content, nothing shared with the
original, one scope for all blocks; and inlined code computes what Python does."""

from __future__ import annotations

import copy
import subprocess
import sys
import textwrap

import numba
import pytest
from numba.core import inline_closurecall
from numba.core.compiler import run_frontend

from rubcosim.components import jit  # noqa: F401  (registers the install on first compile)
from rubcosim.components.numba_inlining import BlockGraphCopy, CalleeMemo, install


def _branchy(x, n):
    total = 0.0
    for i in range(n):
        if x > i:
            total += x * i
        else:
            total -= i
    return total


def test_installed_on_this_numba_and_idempotent():
    """Wiring: the installed numba has the structure the patch expects."""
    assert install() is True
    assert install() is True
    wrapper = inline_closurecall.InlineWorker.inline_ir
    assert getattr(wrapper, "_rubcosim_block_graph_copy", False)
    assert not hasattr(wrapper.__wrapped__, "_rubcosim_block_graph_copy")
    assert inline_closurecall.copy is copy  # swapped only during a call


def test_the_patch_waits_for_the_first_compile():
    """Wiring: importing the package does not import numba's inliner (a warm run never
    needs it); the first compilation installs the patch before it inlines."""
    script = textwrap.dedent(
        """
        import sys
        import numba
        from rubcosim.components import jit
        assert "numba.core.inline_closurecall" not in sys.modules

        @numba.njit(inline="always")
        def inner(x):
            return 2.0 * x

        @numba.njit
        def outer(x):
            return inner(x) + 1.0

        assert outer(3.0) == 7.0
        from numba.core.inline_closurecall import InlineWorker
        assert InlineWorker.inline_ir._rubcosim_block_graph_copy
        """
    )
    subprocess.run([sys.executable, "-c", script], check=True, timeout=120)


def test_block_graph_copy_shares_one_new_scope_and_nothing_with_the_original():
    ir = run_frontend(_branchy)
    assert len(ir.blocks) > 3
    copier = BlockGraphCopy()
    copies = {label: copier.deepcopy(block) for label, block in ir.blocks.items()}
    scopes = {id(block.scope) for block in copies.values()}
    assert len(scopes) == 1
    (scope_id,) = scopes
    assert scope_id != id(ir.blocks[min(ir.blocks)].scope)
    for label, block in ir.blocks.items():
        new = copies[label]
        assert [str(s) for s in new.body] == [str(s) for s in block.body]
        for old_stmt, new_stmt in zip(block.body, new.body, strict=True):
            assert new_stmt is not old_stmt
            old_vars = {id(v) for v in old_stmt.list_vars()}
            assert not old_vars & {id(v) for v in new_stmt.list_vars()}
            assert all(v.scope is new.scope for v in new_stmt.list_vars())


def test_a_second_ir_gets_its_own_memo():
    first, second = run_frontend(_branchy), run_frontend(_branchy)
    copier = BlockGraphCopy()
    a = copier.deepcopy(first.blocks[min(first.blocks)])
    b = copier.deepcopy(second.blocks[min(second.blocks)])
    assert a.scope is not b.scope


@numba.njit(inline="always")
def _inner(x, k):
    return x * x + k if x > k else x - k


@numba.njit(inline="always")
def _middle(x, n):
    acc = 0.0
    for k in range(n):
        acc += _inner(x, k) - _inner(-x, k)
    return acc


@numba.njit
def _outer(x, n):
    return _middle(x, n) + _middle(x + 1.0, n) * _inner(x, n)


def _outer_in_python(x, n):
    def inner(x, k):
        return x * x + k if x > k else x - k

    def middle(x, n):
        return sum(inner(x, k) - inner(-x, k) for k in range(n))

    return middle(x, n) + middle(x + 1.0, n) * inner(x, n)


@pytest.mark.parametrize("x", [-2.5, 0.0, 0.75, 3.0])
def test_nested_inlined_code_computes_what_python_computes(x):
    expected = _outer_in_python(x, 5)
    assert _outer(x, 5) == pytest.approx(expected, rel=1e-15, abs=0.0)


@numba.njit(inline="always")
def _leaf(x, k):
    return x * k - 1.0 if x > k else x + k


@numba.njit(inline="always")
def _branch(x, n):
    acc = 0.0
    for k in range(n):
        acc += _leaf(x, k) * _leaf(x - 1.0, k)
    return acc


@numba.njit
def _root(x, n):
    return _branch(x, n) - _branch(2.0 * x, n) + _leaf(x, n)


@numba.njit(_nrt=False)
def _other_root(x, n):
    return _branch(x + 0.5, n) * _leaf(x, n)


def _root_in_python(x, n, other=False):
    def leaf(x, k):
        return x * k - 1.0 if x > k else x + k

    def branch(x, n):
        return sum(leaf(x, k) * leaf(x - 1.0, k) for k in range(n))

    if other:
        return branch(x + 0.5, n) * leaf(x, n)
    return branch(x, n) - branch(2.0 * x, n) + leaf(x, n)


@numba.njit
def _host_root(x, n):
    return _leaf(x, n) + _leaf(-x, n)


def _memo():
    cells = inline_closurecall.InlineWorker.inline_function.__closure__
    (memo,) = [c.cell_contents for c in cells if isinstance(c.cell_contents, CalleeMemo)]
    return memo


def _count_builds(monkeypatch):
    built = []
    original = inline_closurecall.InlineWorker.run_untyped_passes

    def counting(self, func, enable_ssa=False):
        built.append(func.__name__)
        return original(self, func, enable_ssa)

    monkeypatch.setattr(inline_closurecall.InlineWorker, "run_untyped_passes", counting)
    return built


def test_a_host_programs_callees_are_built_as_numba_builds_them(monkeypatch):
    """Functions outside rubcosim (this test module's) are built at every call site."""
    assert install() is True
    assert _memo().covers(install) and not _memo().covers(_leaf.py_func)
    built = _count_builds(monkeypatch)
    assert _host_root(0.5, 2) == (0.5 + 2) + (-0.5 + 2)
    assert built == ["_leaf", "_leaf"]


def test_each_inlined_callee_is_built_once(monkeypatch):
    """Five call sites of _leaf and three of _branch over two callers (one compiled
    without reference counting, a flag the untyped pipeline does not read): numba
    would build the callees' IR eight times (more, nested); the memo builds each once,
    and the stored IR is the same after every inlining (it is copied, not changed)."""
    assert install() is True
    store = _memo()
    # these test kernels stand for rubcosim's own
    monkeypatch.setattr(
        store, "packages", store.packages | {_leaf.py_func.__module__.partition(".")[0]}
    )
    built = _count_builds(monkeypatch)
    assert _root(1.5, 4) == pytest.approx(_root_in_python(1.5, 4), rel=1e-15, abs=0.0)
    assert sorted(built) == ["_branch", "_leaf"]
    stored = _stored_ir(store)
    expected = _root_in_python(0.25, 3, other=True)
    assert _other_root(0.25, 3) == pytest.approx(expected, rel=1e-15, abs=0.0)
    assert sorted(built) == ["_branch", "_leaf"]
    assert _stored_ir(store) == stored


def _stored_ir(store):
    return {
        function.__name__: [
            [(label, [str(stmt) for stmt in block.body]) for label, block in ir.blocks.items()]
            for _, ir in entries
        ]
        for function, entries in store._built.items()
        if function in (_leaf.py_func, _branch.py_func)
    }


def test_numba_is_the_release_pyproject_pins():
    """The patch of numba's inlining pass (tested here) and the private
    names rubcosim/reference/stack_arrays.py uses were written against one numba
    release; pyproject pins it.  Another numba in this environment (installed by hand)
    fails here first, by name, rather than as wrong IR somewhere in a kernel."""
    import tomllib
    from pathlib import Path

    import numba
    from packaging.requirements import Requirement

    pyproject = Path(__file__).resolve().parents[1] / "pyproject.toml"
    deps = tomllib.loads(pyproject.read_text())["project"]["dependencies"]
    pin = next(Requirement(d) for d in deps if Requirement(d).name == "numba")
    assert pin.specifier.contains(numba.__version__), (
        f"numba {numba.__version__} is not the release pyproject pins ({pin.specifier})"
    )
    assert pin.specifier.contains("0.68.1") and not pin.specifier.contains("0.69.0")
