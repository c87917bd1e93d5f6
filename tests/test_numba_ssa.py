"""rubcosim's SSA reconstruction for numba (``components/numba_ssa.py``) against
numba's own (``numba.core.ssa._run_ssa``):
the same IR, names included, on the pre-SSA IR of every compiled kernel of the
engines, the units and the master."""

from __future__ import annotations

import copy
import importlib
import subprocess
import sys
import textwrap

import pytest
from numba.core.compiler import run_frontend
from numba.core.registry import CPUDispatcher

from rubcosim.components import numba_ssa

MODULES = (
    "rubcosim.reference.fast",
    "rubcosim.reference.core",
    "rubcosim.reference.event_search",
    "rubcosim.reference.history",
    "rubcosim.reference.system",
    "rubcosim.reference.tangent",
    "rubcosim.components.stepping",
    "rubcosim.components.flat_controller",
    "rubcosim.components.delay_history",
    "rubcosim.orchestrator.flat_events",
    "rubcosim.orchestrator.flat_round",
)


def _kernels():
    seen = {}
    for name in MODULES:
        module = importlib.import_module(name)
        for value in vars(module).values():
            if isinstance(value, CPUDispatcher):
                seen.setdefault(value.py_func, f"{name}.{value.py_func.__name__}")
    return sorted(seen.items(), key=lambda item: item[1])


KERNELS = _kernels()


def _dump(blocks):
    return [(label, [str(stmt) for stmt in block.body]) for label, block in blocks.items()]


def test_the_kernels_are_found():
    """Wiring: the comparison below runs over the kernels of every listed module."""
    assert len(KERNELS) > 60


@pytest.mark.parametrize("function", [f for f, _ in KERNELS], ids=[n for _, n in KERNELS])
def test_same_ssa_form_as_numbas_own(function):
    ir = run_frontend(function)
    # two independent copies (each with its own scope, so the same fresh names)
    ours, numbas = copy.deepcopy(ir.blocks), copy.deepcopy(ir.blocks)
    numbas_own = numba_ssa.numba_run_ssa()
    assert numbas_own is not numba_ssa.run_ssa
    expected = numbas_own(numbas)
    got = numba_ssa.run_ssa(ours)
    assert _dump(got) == _dump(expected)
    # the same side effects on the input (numba's rewrite changes some statements of
    # its input through the expressions it copies shallowly, and adds no phi nodes)
    assert _dump(ours) == _dump(numbas)


def test_installed_at_the_first_compile_of_a_process():
    """Wiring: numba's pass calls rubcosim's function once the first compile starts."""
    script = textwrap.dedent(
        """
        import numba
        from numba.core import ssa
        from rubcosim.components import jit, numba_ssa
        assert ssa._run_ssa is not numba_ssa.run_ssa

        @numba.njit
        def f(x):
            y = 0.0
            for i in range(3):
                y = y + x * i
            return y

        assert f(2.0) == 6.0
        assert ssa._run_ssa is numba_ssa.run_ssa
        """
    )
    subprocess.run([sys.executable, "-c", script], check=True, timeout=120)
