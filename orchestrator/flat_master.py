"""The compiled master: the Python master's algorithm over flat arrays, in numba.

:func:`flat_unsupported` says whether a master's units and protocols all have a
compiled form (the rotors, the stators, the bearings, the hybrid impact
oscillators, the delayed-feedback controller, with the rigid or penalty contact
protocols; not FMUs);
:func:`run_flat` then runs it: the graph and the units' current states are
packed into arrays (:mod:`.flat_layout`), the compiled loop (:mod:`.flat_loop`)
runs in chunks (a progress bar between them) and the recorded rows, events and
counters come back as the Python master's :class:`.cosim_result.CosimResult`.
The algorithm, the decisions and the counters are the Python master's
(``tests/test_flat_master.py`` compares them on every scenario it can run);
only the per-step cost differs.  ``cosim.master`` picks: ``auto`` (compiled when
possible and already compiled, see below), ``compiled`` (an error naming what is not),
``python``.

The loop steps the units and reads their outputs through C functions
(:mod:`rubcosim.components.flat_calls`), so the units' code compiles once, not once per
caller.  It still takes minutes to compile, once for every model (it holds every unit
type), and a short co-simulation, such as ``make run``'s check of the flagship, runs in
seconds on the Python master with the same results.  So ``auto`` takes the compiled
loop only once it is in numba's cache (:func:`flat_ready`: a run of it, or
``rubcosim warm-up``, records it there) and otherwise runs the Python master and says
so on one line.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from rubcosim.compile_notice import is_marked, mark, quiet, write_line
from rubcosim.components import flat_units as fu
from rubcosim.components.delay_history import ROW
from rubcosim.components.flat_calls import unit_calls
from rubcosim.components.flat_hybrid import MAX_MODES, output_map
from rubcosim.components.rigid_protocol import N_STATE
from rubcosim.components.unit import Unit
from rubcosim.progress import watch

from . import flat_layout as L
from .cosim_result import CosimResult
from .flat_loop import EVENT_ROOM, run_loop, start
from .protocols import ElasticContact, RigidContact

CHUNK = 4000  # loop passes between progress updates
COMPILED = "cosim-compiled-master"  # the marker of the compiled loop in numba's cache
HISTORY_ROWS = 4096  # a controller's history buffer to begin with (it grows when full)
_TOLD: set[str] = set()  # the one-line notices this process has printed


def flat_ready(setting: str) -> bool:
    """Whether a master that can run compiled does, under ``cosim.master = setting``:
    ``compiled`` always; ``auto`` once the compiled loop is in numba's cache (a process
    ran it with this cache), else it says on one line (once per process) that the Python
    master runs."""
    if setting == "compiled" or is_marked(COMPILED):
        return True
    if not quiet() and COMPILED not in _TOLD:
        _TOLD.add(COMPILED)
        write_line(
            "rubcosim: the co-simulation's compiled master is not in the cache yet: this run "
            "takes the Python master (the same results, slower per step); 'rubcosim "
            'warm-up\' or cosim.master = "compiled" compiles it once (minutes)'
        )
    return False


def flat_unsupported(master: Any) -> str | None:
    """Why ``master`` cannot run compiled (the first unit or protocol without a compiled
    form), or None when it can."""
    for name, unit in master.units.items():
        if not isinstance(unit, Unit):
            return f"unit {name} is an FMU"
        if fu.flat_type(unit.role, unit.type_name) is None:
            return f"unit {name} ({unit.type_name}) has no compiled form"
    for proto in master.protocols:
        if not isinstance(proto, RigidContact | ElasticContact):
            return f"protocol {type(proto).__name__} has no compiled form"
    for name in master.left_limit_units:  # the controller's zero-length steps at events
        unit = master.units[name]
        if fu.flat_type(unit.role, unit.type_name)[0] != fu.K_CONTROLLER:
            return f"unit {name} records its inputs' left limits"
    return None


def _graph(master: Any, t_end: float, times: np.ndarray, record: list[tuple[str, str]]):
    st = master.settings
    names = list(master.units)
    index = {n: i for i, n in enumerate(names)}
    units = [master.units[n] for n in names]
    n_units = len(units)
    ins = [[s.name for s in u.inputs] for u in units]
    outs = [[s.name for s in u.outputs] for u in units]
    kind = np.zeros(n_units, np.int64)
    ode = np.zeros(n_units, np.int64)
    ode_idx = np.zeros((n_units, 4), np.int64)
    node = np.zeros(n_units, np.int64)
    p = np.zeros((n_units, fu.MAX_PARAMS))
    tol = np.zeros((n_units, 2))
    model = None
    exact = np.zeros(n_units, np.int64)  # 1: the rotor steps exactly (an int for step_c)
    omap = np.zeros((n_units, fu.MAX_OUTPUTS), np.int64)  # hybrid units' output sources
    mval = np.zeros((n_units, fu.MAX_OUTPUTS, MAX_MODES))
    for k, u in enumerate(units):
        kind[k], ode[k], _, ode_inputs = fu.flat_type(u.role, u.type_name)
        if kind[k] == fu.K_HYBRID:
            omap[k], mval[k] = output_map(u)
        p[k] = fu.flat_params(u.role, u.type_name, u.params)
        tol[k] = u.params.get("rtol", 1e-10), u.params.get("atol", 1e-14)
        node[k] = len(ode_inputs)
        ode_idx[k, : len(ode_inputs)] = [ins[k].index(i) for i in ode_inputs]
        exact[k] = u.params.get("integrator") == "exact"
        if exact[k]:
            model = u._linear_model()
    if model is None:
        model = (np.zeros((1, 1)), np.zeros((1, 1)), np.zeros(1), np.zeros(1), np.zeros(1))
    conns = master.connections
    pos = {n: i for i, n in enumerate(master.order)}
    src0, src_unit, src_out = [0], [], []
    for c in conns:
        for u, o in c.pairs:
            src_unit.append(index[u])
            src_out.append(outs[index[u]].index(o))
        src0.append(len(src_unit))
    grouped = [[i for i, c in enumerate(conns) if c.unit == n] for n in names]
    protos = master.protocols
    pr_f = np.zeros((max(len(protos), 1), 2))
    for i, pr in enumerate(protos):
        if isinstance(pr, RigidContact):
            pr_f[i] = pr.v_chat, pr.min_flight
    p_order = st.extrapolation if st.adaptive else 0
    is_ctl = kind == fu.K_CONTROLLER  # each controller's history buffer: S.cbuf[ctl[k]]
    ctl = np.full(n_units, -1, np.int64)
    ctl[is_ctl] = np.arange(np.count_nonzero(is_ctl))
    events = {"locate": L.EVENTS_LOCATE, "step": L.EVENTS_STEP, "off": L.EVENTS_OFF}
    return L.FlatGraph(
        kind=kind, ode=ode, exact=exact,
        ny=np.array([len(u.state.get("y", ())) for u in units], np.int64),
        nin=np.array([len(i) for i in ins], np.int64),
        nout=np.array([len(o) for o in outs], np.int64),
        ode_idx=ode_idx, node=node, p=p, tol=tol,
        feed=np.array([master.feedthrough[n] for n in names], np.bool_),
        in_order=np.array([master.input_orders[n] for n in names], np.int64),
        order=np.array([index[n] for n in master.order], np.int64),
        eval_order=np.array([index[n] for n in master.eval_order], np.int64),
        c_input=np.array([ins[index[c.unit]].index(c.input) for c in conns], np.int64),
        src0=np.array(src0, np.int64), src_unit=np.array(src_unit, np.int64),
        src_out=np.array(src_out, np.int64),
        c_gs=np.array([all(pos[u] < pos[c.unit] for u, _ in c.pairs) for c in conns], np.bool_),
        conn0=np.cumsum([0] + [len(g) for g in grouped]).astype(np.int64),
        conns=np.array([i for g in grouped for i in g], np.int64),
        nominal=np.array([master.nominal.get(c.target, 0.0) for c in conns]),
        bound=np.array([master.bounds.get(c.target, math.inf) for c in conns]),
        pr_kind=np.array([L.PR_RIGID if isinstance(pr, RigidContact) else L.PR_ELASTIC
                          for pr in protos], np.int64),
        pr_stator=np.array([index[pr.stator] for pr in protos], np.int64),
        pr_rotor=np.array([index[getattr(pr, "rotor", pr.stator)] for pr in protos], np.int64),
        pr_f=pr_f,
        rec_unit=np.array([index[u] for u, _ in record], np.int64),
        rec_out=np.array([outs[index[u]].index(o) for u, o in record], np.int64),
        out_times=np.asarray(times, dtype=float),
        model=tuple(np.ascontiguousarray(m) for m in model),
        iset=np.array([st.algorithm == "gauss-seidel", st.adaptive, st.iterations,
                       events[st.events], st.max_events_per_period, p_order + 1,
                       np.count_nonzero(is_ctl)], np.int64),
        fset=np.array([st.rtol, st.iteration_tol, st.min_step, st.max_step, master.t_tol,
                       master.period, t_end]),
        omap=omap, mval=mval, ctl=ctl, calls=unit_calls(),
    )  # fmt: skip


def _state(master: Any, G: L.FlatGraph, t_start: float) -> L.FlatState:
    n_units, n_conn = G.kind.shape[0], G.c_input.shape[0]
    ust = np.array([fu.unit_row(u) for u in master.units.values()])
    n_proto = max(G.pr_kind.shape[0], 1)
    prs = np.zeros((n_proto, N_STATE))  # a penalty protocol keeps no state
    for i, pr in enumerate(master.protocols):
        if isinstance(pr, RigidContact):
            prs[i] = pr.state
    ms = np.zeros(L.MS_SIZE)
    ms[L.MS_TIME], ms[L.MS_H], ms[L.MS_ERR_PREV] = t_start, master.settings.step, 1e-4
    out = np.zeros((n_units, fu.MAX_OUTPUTS))
    hist = np.zeros((n_conn, 7))
    acc = np.full((n_units, fu.MAX_OUTPUTS), np.nan)
    cap = 1024
    cbuf, cscr = _histories(master, G, ust)
    return L.FlatState(
        ust=ust, out=out, hist=hist, scale=np.zeros(n_conn), acc=acc, prs=prs, ms=ms,
        cnt=np.zeros(len(L.COUNTERS), np.int64), given=np.zeros(n_conn), real=np.zeros(n_conn),
        scratch=np.zeros(n_conn),
        rows=np.full((G.out_times.shape[0], G.rec_unit.shape[0]), np.nan),
        ev_t=np.zeros(cap), ev_kind=np.zeros(cap, np.int64), ev_unit=np.zeros(cap, np.int64),
        snap=ust.copy(), ck_ust=ust.copy(), ck_out=out.copy(), ck_hist=hist.copy(),
        ck_scale=np.zeros(n_conn), ck_acc=acc.copy(), ck_prs=prs.copy(),
        ck_ms=np.zeros(L.MS_SAVED), info=np.zeros(3, np.int64), finfo=np.zeros(3),
        cbuf=cbuf, cscr=cscr, ck_cbuf=cbuf.copy(),
    )  # fmt: skip


def _histories(master: Any, G: L.FlatGraph, ust: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The controllers' history buffers, each filled with its unit's history so far (its
    bounds into the unit's row), and their scratch rows."""
    units = list(master.units.values())
    ks = [k for k in range(len(units)) if G.ctl[k] >= 0]
    longest = max((len(units[k].state["history"]) for k in ks), default=0)
    cap = max(HISTORY_ROWS, 2 * longest) if ks else 1
    cbuf = np.zeros((max(len(ks), 1), cap, ROW))
    for k in ks:
        hist = units[k].state["history"]
        cbuf[G.ctl[k], : len(hist)] = hist
        ust[k, fu.Y : fu.Y + 3] = 0.0, len(hist), units[k].state["start"]
    return cbuf, np.zeros((cap + 1, ROW))


def _grow(S: L.FlatState) -> L.FlatState:
    """Room for the loop to go on (it returned NEED_ROOM): for events, else for the
    controllers' histories."""
    n = S.ev_t.shape[0]
    if n - int(S.ms[L.MS_N_EVENTS]) < EVENT_ROOM:
        return S._replace(
            ev_t=np.concatenate([S.ev_t, np.zeros(n)]),
            ev_kind=np.concatenate([S.ev_kind, np.zeros(n, np.int64)]),
            ev_unit=np.concatenate([S.ev_unit, np.zeros(n, np.int64)]),
        )
    n_ctl, cap, _ = S.cbuf.shape
    cbuf = np.zeros((n_ctl, 2 * cap, ROW))
    cbuf[:, :cap] = S.cbuf
    kept = np.zeros_like(cbuf)
    kept[:, :cap] = S.ck_cbuf
    return S._replace(cbuf=cbuf, cscr=np.zeros((2 * cap + 1, ROW)), ck_cbuf=kept)


def _message(master: Any, G: L.FlatGraph, S: L.FlatState) -> str:
    names = list(master.units)
    code, who, detail = (int(v) for v in S.info)
    now = S.ms[L.MS_TIME]
    h, t = S.finfo[L.FI_H], S.finfo[L.FI_TIME]
    if code == L.FAIL_STEP:
        why = fu.failure_reason(detail, S.ust[who], G.p[who], names[who])
        text = f"{names[who]}: step failed: {why}"
        return f"{text} (macro step {h:.3g} s from t = {t:.9g} s)" if h else text
    if code == L.FAIL_OUTPUT:
        why = fu.failure_reason(detail, S.ust[who], G.p[who], names[who])
        text = f"{names[who]}: no outputs at t = {now:.9g} s: {why}"
        return f"{text} (macro step {h:.3g} s)" if h else text
    if code == L.FAIL_NOT_FINITE:
        out = master.units[names[who]].outputs[detail].name
        return f"{names[who]}.{out} = {S.finfo[L.FI_VALUE]} at t = {now:.9g} s"
    if code == L.FAIL_UNSTABLE:
        c = master.connections[who]
        bound = G.bound[who]
        return (
            f"unstable: {' + '.join(c.sources)} = {S.finfo[L.FI_VALUE]:.3g} passed {bound:.3g} "
            f"at t = {now:.9g} s; the coupled model diverges (if the monolithic engines "
            "diverge too, the model itself is unstable)"
        )
    if code == L.FAIL_STALL:
        worst = max(
            range(len(master.connections)),
            key=lambda c: abs(S.given[c] - S.real[c]) / max(S.scale[c], abs(S.real[c]), 1e-300),
        )
        st = master.settings
        return (
            f"the coupling error stayed above cosim.rtol at cosim.min_step = {st.min_step:.3g} s "
            f"for {L.STALL_STEPS} steps before t = {now:.9g} s; the largest is on "
            f"{master.connections[worst].target}"
        )
    return (
        f"{names[who]}: more than {master.settings.max_events_per_period} events within one "
        f"forcing period before t = {now:.9g} s (cosim.max_events_per_period)"
    )


def run_flat(
    master: Any,
    t_start: float,
    t_end: float,
    output_times: np.ndarray,
    record: list[str],
    progress: bool = False,
) -> CosimResult:
    """Run ``master`` (checked by :func:`flat_unsupported`) on the compiled loop; the
    same arguments and result as :meth:`.master.Master.run`.  The Python units are
    read, not advanced: after the run they are still at the start."""
    wall = time.perf_counter()
    rec = [tuple(n.split(".", 1)) for n in record]
    G = _graph(master, float(t_end), np.asarray(output_times, dtype=float), rec)
    S = _state(master, G, float(t_start))
    graph, ref = L.refs(G, S)
    code = L.FAILED if start(graph, ref) else L.RUNNING
    with watch("co-simulation", t_start, t_end, lambda: S.ms[L.MS_TIME], enabled=progress):
        while code != L.FAILED:
            code = run_loop(graph, ref, CHUNK)
            if code == L.NEED_ROOM:
                S = _grow(S)
                _, ref = L.refs(G, S)
            elif code == L.DONE:
                break
    mark(COMPILED)
    n = int(S.ms[L.MS_K_OUT])
    n_ev = int(S.ms[L.MS_N_EVENTS])
    names = list(master.units)
    return CosimResult(
        t=G.out_times[:n].copy(),
        names=[".".join(r) for r in rec],
        values=S.rows[:n].copy(),
        event_t=S.ev_t[:n_ev].copy(),
        event_kind=[L.EVENT_KINDS[k] for k in S.ev_kind[:n_ev]],
        event_unit=[names[u] for u in S.ev_unit[:n_ev]],
        counters={k: int(v) for k, v in zip(L.COUNTERS, S.cnt, strict=True) if v > 0},
        status="failed" if code == L.FAILED else "ok",
        message=_message(master, G, S) if code == L.FAILED else "",
        t_reached=float(S.ms[L.MS_TIME]),
        wall_time_s=time.perf_counter() - wall,
        settings=master.settings,
        input_orders=dict(master.input_orders),
        master="compiled",
    )
