"""Cost of one ``fmi2DoStep`` of the rotor FMUs, through fmpy, for each unit integrator.

The Jeffcott and two-mass rotor FMUs are built from the current sources, loaded with
fmpy's ``FMU2Slave`` and stepped with macro steps of T/400 (the co-simulation's default
first step), all that long or each a little different, while their force inputs change
every step with first and second derivatives (as our master sets them); each integrator
(``exact``: the matrix exponential of :mod:`rubcosim.components.linear_propagation`, or
the propagators of :mod:`rubcosim.components.propagator_cache` when a step is as long as
the one before; ``dop853``: the units' DOP853, plain Python inside the FMU) is timed
over ``--steps`` steps, ``--repeats`` times; the median per step is reported with its
min-max over the repeats.

Then the cost of each FMI call a master makes on a macro step, through the same
fmpy instances: ``fmi2SetReal`` of the two force inputs, ``fmi2SetRealInputDerivatives``
of their first and second derivatives, ``fmi2DoStep`` of zero length (the call without
integration), ``fmi2GetReal`` of every output, and the rollback calls
``fmi2GetFMUstate``, ``fmi2SetFMUstate`` and ``fmi2FreeFMUstate``, for the Jeffcott
rotor (exact) and the rigid stator; each call ``--calls`` times, median over the repeats.

Run from the repository root::

    .venv/bin/python benchmarks/bench_fmu_step.py [--steps 2000] [--repeats 5]

Writes ``fmu_step.json`` and ``fmu_step.md`` to ``--out`` (default benchmarks/results).
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import tempfile
import time
from pathlib import Path

from stamp import REPO, stamp, stamp_line

from rubcosim.fmus.build import build_fmus

RESULTS = REPO / "benchmarks" / "results"
ROTORS = {
    "RubcosimJeffcottRotor": {"eccentricity": 5e-5, "damping": 316.2},
    "RubcosimTwoMassRotor": {"eccentricity": 5e-5, "damping": 316.2, "shaft_damping": 50.0},
}
SPEED = 379.473319  # rad/s: the FMUs' default speed
CALL_FMUS = {
    "RubcosimJeffcottRotor": ({"eccentricity": 5e-5, "damping": 316.2}, ("fx", "fy")),
    "RubcosimRigidStator": ({"clearance": 1e-4, "restitution": 0.8}, ("x", "y")),
}
CALLS = (
    "fmi2SetReal",
    "fmi2SetRealInputDerivatives",
    "fmi2DoStep (h = 0)",
    "fmi2GetReal (all outputs)",
    "fmi2GetFMUstate",
    "fmi2SetFMUstate",
    "fmi2FreeFMUstate",
)
DERIVATIVES = ("fx_d1", "fx_d2", "fy_d1", "fy_d2")
# (unit integrator, steps): the exact step at a fixed and at a changing step, DOP853 at a
# fixed one
STEPPINGS = (("exact", "fixed"), ("exact", "changing"), ("dop853", "fixed"))


def time_fmu(
    path: Path, params: dict[str, float], integrator: str, steps: int, varying: bool = False
) -> float:
    """Seconds per fmi2DoStep over ``steps`` steps of T/400 (``varying``: each a little
    longer or shorter than the one before, as an adaptive master makes them)."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu = FMU2Slave(
        guid=md.guid,
        unzipDirectory=extract(str(path)),
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName="bench",
    )
    fmu.instantiate()
    fmu.setReal([vr[k] for k in params], list(params.values()))
    fmu.setString([vr["integrator"]], [integrator])
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    h = 2.0 * math.pi / SPEED / 400.0
    inputs = [vr["fx"], vr["fy"]]
    derivs = [vr[k] for k in DERIVATIVES]
    t = 0.0
    wall = 0.0
    for k in range(steps):
        fmu.setReal(inputs, [math.cos(0.01 * k), math.sin(0.01 * k)])
        fmu.setReal(derivs, [3.0, 1e3, -2.0, 5e2])
        start = time.perf_counter()
        hk = h * (1.0 + 0.25 * math.sin(0.7 * k)) if varying else h
        fmu.doStep(t, hk)
        wall += time.perf_counter() - start
        t += hk
    fmu.terminate()
    fmu.freeInstance()
    return wall / steps


def time_calls(path: Path, params: dict[str, float], inputs: tuple[str, ...], n: int):
    """Seconds per call of each of :data:`CALLS` on one instance, ``n`` calls each."""
    from rubcosim.orchestrator.fmu_unit import FmuUnit

    unit = FmuUnit(path, name="bench", params=params)
    fmu = unit._fmu
    refs = [unit.variables[k].valueReference for k in inputs]
    out_refs = [unit.variables[k].valueReference for k in unit.outputs
                if unit.variables[k].type == "Real"]  # fmt: skip
    drefs, orders = [r for r in refs for _ in (1, 2)], [o for _ in refs for o in (1, 2)]
    dvals = [1.0] * len(drefs)
    vals = [0.0] * len(refs)
    state = fmu.getFMUState()
    states = []

    def free() -> None:
        fmu.freeFMUState(states.pop())

    calls = {
        "fmi2SetReal": lambda: fmu.setReal(refs, vals),
        "fmi2SetRealInputDerivatives": lambda: fmu.setRealInputDerivatives(drefs, orders, dvals),
        "fmi2DoStep (h = 0)": lambda: fmu.doStep(0.0, 0.0),
        "fmi2GetReal (all outputs)": lambda: fmu.getReal(out_refs),
        "fmi2GetFMUstate": lambda: states.append(fmu.getFMUState()),
        "fmi2SetFMUstate": lambda: fmu.setFMUState(state),
        "fmi2FreeFMUstate": free,
    }
    cost = {}
    for name in CALLS:
        call = calls[name]
        start = time.perf_counter()
        for _ in range(n):
            call()
        cost[name] = (time.perf_counter() - start) / n
    for s in states:
        fmu.freeFMUState(s)
    fmu.freeFMUState(state)
    unit.close()
    return cost


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--calls", type=int, default=2000, help="calls of each FMI function")
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    if args.steps < 1 or args.repeats < 1 or args.calls < 1:
        parser.error("--steps, --repeats and --calls must be >= 1")
    with tempfile.TemporaryDirectory(prefix="bench_fmu_step_") as tmp:
        built = {p.stem: p for p in build_fmus(tmp, only=[*ROTORS, *CALL_FMUS])}
        per_call = []
        for name, (params, inputs) in CALL_FMUS.items():
            time_calls(built[name], params, inputs, 50)  # load, first calls
            runs = [time_calls(built[name], params, inputs, args.calls)
                    for _ in range(args.repeats)]  # fmt: skip
            for call in CALLS:
                times = [r[call] for r in runs]
                per_call.append({"fmu": name, "call": call, "median_s": statistics.median(times),
                                 "runs_s": times})  # fmt: skip
                print(f"{name:24s} {call:30s} {statistics.median(times) * 1e6:8.1f} us/call")
        rows = []
        for name, params in ROTORS.items():
            for integrator, steps in STEPPINGS:
                varying = steps == "changing"
                time_fmu(built[name], params, integrator, 50, varying)  # load, first calls
                runs = [
                    time_fmu(built[name], params, integrator, args.steps, varying)
                    for _ in range(args.repeats)
                ]
                rows.append(
                    {
                        "fmu": name,
                        "integrator": integrator,
                        "steps": steps,
                        "median_s": statistics.median(runs),
                        "runs_s": runs,
                    }  # fmt: skip
                )
                print(f"{name:24s} {integrator:7s} {steps:8s} "
                      f"{statistics.median(runs) * 1e6:8.1f} us/step")  # fmt: skip
    meta = stamp(steps=args.steps, repeats=args.repeats, step="T/400", calls=args.calls)
    args.out.mkdir(parents=True, exist_ok=True)
    data = {"meta": meta, "rows": rows, "per_call": per_call}
    (args.out / "fmu_step.json").write_text(json.dumps(data, indent=1))
    lines = [
        "# Rotor FMUs: cost of one fmi2DoStep",
        "",
        "| FMU | unit integrator | step | fmi2DoStep, median | min - max |",
        "|---|---|---|---:|---:|",
    ]
    for r in rows:
        lo, hi = min(r["runs_s"]) * 1e6, max(r["runs_s"]) * 1e6
        lines.append(
            f"| {r['fmu']} | {r['integrator']} | {r['steps']} | {r['median_s'] * 1e6:.0f} us | "
            f"{lo:.0f} - {hi:.0f} us |"
        )
    lines += [
        "",
        f"Through fmpy, steps of T/400 (fixed: every step that long, as a tool at a fixed "
        f"communication step makes them; changing: T/400 times 1 + 0.25 sin(0.7 k), as an "
        f"adaptive master makes them) with changing inputs and input derivatives; median "
        f"over {args.repeats} runs of {args.steps} steps. The exact step takes propagators "
        f"cached per step size when a step has the length of the one before "
        f"(components/propagator_cache.py), modal coordinates otherwise "
        f"(components/modal_propagation.py). " + stamp_line(meta),
        "",
        "| FMU | FMI call | per call, median | min - max |",
        "|---|---|---:|---:|",
    ]
    for r in per_call:
        lo, hi = min(r["runs_s"]) * 1e6, max(r["runs_s"]) * 1e6
        lines.append(
            f"| {r['fmu']} | {r['call']} | {r['median_s'] * 1e6:.1f} us | {lo:.1f} - {hi:.1f} us |"
        )
    lines += [
        "",
        f"Each call {args.calls} times on one instance through fmpy (a zero-length "
        f"fmi2DoStep is the call without integration); median over {args.repeats} runs.",
    ]
    (args.out / "fmu_step.md").write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
