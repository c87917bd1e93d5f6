"""The order in which a master evaluates units: sources before the units that read them."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from rubcosim.components.wiring import Connection

from .cosim_result import CosimError


def evaluation_order(
    names: Sequence[str], connections: Sequence[Connection], feedthrough: Mapping[str, bool]
) -> list[str]:
    """Units whose outputs do not depend on their inputs first, then the others after
    every unit they read from (a direct-feedthrough cycle is an algebraic loop)."""
    deps = {n: set() for n in names}
    for c in connections:
        for s in c.sources:
            src = s.split(".", 1)[0]
            if feedthrough[c.unit] and feedthrough[src] and src != c.unit:
                deps[c.unit].add(src)
    order = [n for n in names if not feedthrough[n]]
    pending = [n for n in names if feedthrough[n]]
    while pending:
        ready = [n for n in pending if deps[n] <= set(order)]
        if not ready:
            raise CosimError(f"algebraic loop between units {', '.join(pending)}")
        order += ready
        pending = [n for n in pending if n not in ready]
    return order
