"""numba's SSA reconstruction, rewriting only the blocks that name each variable.

numba's ``ReconstructSSA`` pass (``numba.core.ssa._run_ssa``) takes the variables
assigned more than once one at a time, and for each rewrites *every* block of the
function twice (fresh names for its definitions, then its uses), though a
statement that does not name the variable comes out unchanged.  The cost is
variables x statements, and the engines inline hundreds of kernels into large
functions: a cold compile of the ``fast`` engine (124 functions) met some six hundred
such variables, and the pass took 5.5 s of that one-minute compile (0.65 s with
:func:`run_ssa`).

:func:`run_ssa` is the same algorithm, with numba's own handlers, visiting per
variable only the blocks that name it (an index built once: a rewrite renames
only the variable at hand, so every other variable keeps its blocks).  Blocks
are visited in the same order and phi nodes made in the same sequence, so the
result is the same IR, names included (``tests/test_numba_ssa.py`` compares the
two on real kernels).  :func:`install` puts it in place of numba's when numba has
the structure it was written against (checked, not assumed).
"""

from __future__ import annotations

from collections import defaultdict
from typing import Any

_NEEDED = (
    "compute_cfg_from_blocks",
    "_iterated_domfronts",
    "_find_defs_violators",
    "_CacheListVars",
    "_make_states",
    "_FreshVarHandler",
    "_FixSSAVars",
    "_compute_phi_locations",
    "_run_ssa_block_pass",
)


def _blocks_naming(blocks: dict[int, Any]) -> defaultdict[str, set[int]]:
    """Variable name -> labels of the blocks whose statements name it."""
    index: defaultdict[str, set[int]] = defaultdict(set)
    for label, block in blocks.items():
        for stmt in block.body:
            for var in stmt.list_vars():
                index[var.name].add(label)
    return index


def _rewrite(blocks: dict[int, Any], labels: set[int], states: dict, handler: Any):
    """numba's ``_run_block_rewrite`` over the blocks in ``labels``; the others as they
    are (the handlers return every statement that does not name the variable)."""
    from numba.core import ir, ssa

    new = {}
    for label, block in blocks.items():
        if label not in labels:
            new[label] = block
            continue
        states["label"] = label
        states["block"] = block
        rewritten = ir.Block(scope=block.scope, loc=block.loc)
        rewritten.body = list(ssa._run_ssa_block_pass(states, block, handler))
        new[label] = rewritten
    return new


def run_ssa(blocks: dict[int, Any]) -> dict[int, Any]:
    """``numba.core.ssa._run_ssa``: the blocks of a function in SSA form."""
    from numba.core import errors, ir, ssa

    if not blocks:
        return {}
    cfg = ssa.compute_cfg_from_blocks(blocks)
    df_plus = ssa._iterated_domfronts(cfg)
    violators = ssa._find_defs_violators(blocks, cfg)
    cache_list_vars = ssa._CacheListVars()
    naming = _blocks_naming(blocks)
    for varname in violators:
        labels = naming[varname]
        # fresh names for the definitions (numba's _fresh_vars)
        states = ssa._make_states(blocks)
        states["varname"] = varname
        states["defmap"] = defmap = defaultdict(list)
        blocks = _rewrite(blocks, labels, states, ssa._FreshVarHandler())
        # the uses to their reaching definitions, phi nodes where needed (_fix_ssa_vars)
        states = ssa._make_states(blocks)
        states["varname"] = varname
        states["defmap"] = defmap
        states["phimap"] = phimap = defaultdict(list)
        states["cfg"] = cfg
        states["phi_locations"] = ssa._compute_phi_locations(df_plus, defmap)
        blocks = _rewrite(blocks, labels, states, ssa._FixSSAVars(cache_list_vars))
        for label, philist in phimap.items():
            # into a new block, as numba's pass does: no block of the input gets a phi
            old = blocks[label]
            blocks[label] = ir.Block(scope=old.scope, loc=old.loc)
            blocks[label].body = philist + old.body
    if ssa.compute_cfg_from_blocks(blocks) != cfg:
        raise errors.CompilerError("CFG mutated in SSA pass")
    return blocks


_NUMBA_RUN_SSA: list[Any] = []  # numba's own function, once replaced


def numba_run_ssa() -> Any:
    """numba's own ``_run_ssa``, installed or not (for comparisons)."""
    if _NUMBA_RUN_SSA:
        return _NUMBA_RUN_SSA[0]
    from numba.core import ssa

    return ssa._run_ssa


def install() -> bool:
    """Put :func:`run_ssa` in place of numba's ``_run_ssa`` (once); True when it is."""
    try:
        from numba.core import ssa
    except ImportError:
        return False
    original = getattr(ssa, "_run_ssa", None)
    if original is run_ssa:
        return True
    if original is None or not all(hasattr(ssa, name) for name in _NEEDED):
        return False
    # the algorithm this restates: one variable at a time, two whole-function rewrites
    names = set(original.__code__.co_names)
    if not {"_find_defs_violators", "_fresh_vars", "_fix_ssa_vars"} <= names:
        return False
    if ssa.reconstruct_ssa.__code__.co_names.count("_run_ssa") != 1:
        return False
    _NUMBA_RUN_SSA.append(original)
    ssa._run_ssa = run_ssa
    return True
