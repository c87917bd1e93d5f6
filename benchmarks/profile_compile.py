"""Where a cold compile of an engine spends its time: numba's passes and rubcosim's
functions, self time.

A diagnostic for issue 45 (first result in seconds), not a benchmark of a target: it
runs ``rubcosim.simulate`` of a scenario on each ``--engine`` for a moment, in a fresh
process with an empty numba cache (``NUMBA_CACHE_DIR`` a new temporary directory), and
sums the wall time of every compiler pass numba runs (its ``numba:run_pass`` events),
less the passes nested in it (a pass that compiles a callee contains that callee's
passes), by pass and by function.

    .venv/bin/python benchmarks/profile_compile.py [--scenario jeffcott_rigid_stator]
        [--engine fast] [--engine accurate] [--top 20]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

_CHILD = r"""
import collections, json, sys, time
from numba.core import event

args = json.loads(sys.argv[1])
stack, by_pass, by_function = [], collections.Counter(), collections.Counter()


class SelfTime(event.Listener):
    def on_start(self, ev):
        stack.append([time.perf_counter(), 0.0])

    def on_end(self, ev):
        start, nested = stack.pop()
        spent = time.perf_counter() - start
        if stack:
            stack[-1][1] += spent
        name = ev.data["name"].split(" [")[0]
        by_pass[name] += spent - nested
        module = ev.data["module"]
        if module.startswith("rubcosim_model_"):  # a model's copy: the template's name
            module = "(model)." + module.split(".", 1)[1]
        by_function[module + "." + ev.data["qualname"]] += spent - nested


event.register("numba:run_pass", SelfTime())
import rubcosim as rc

sc = rc.load(args["scenario"])
walls = {}
for engine in args["engines"]:
    start = time.perf_counter()
    rc.simulate(sc, engine, set={"sim.t_end": sc.sim["t_start"] + 1e-3 * sc.system.forcing_period})
    walls[engine] = time.perf_counter() - start
print(json.dumps({"walls": walls, "passes": by_pass.most_common(),
                  "functions": by_function.most_common()}))
"""


def profile(scenario: str, engines: list[str]) -> dict:
    """The child's measurements: wall time per engine (s), self time per pass and per
    function (s, largest first)."""
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache, "RUBCOSIM_QUIET_COMPILE": "1"}
        env["RUBCOSIM_COMPILE_AHEAD"] = "0"  # every compile in this process, none in a helper
        arg = json.dumps({"scenario": scenario, "engines": engines})
        out = subprocess.run(
            [sys.executable, "-c", _CHILD, arg], env=env, capture_output=True, text=True
        )
    if out.returncode != 0:
        raise SystemExit(out.stderr)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", default="jeffcott_rigid_stator")
    ap.add_argument("--engine", action="append", choices=("fast", "accurate"))
    ap.add_argument("--top", type=int, default=20, help="functions listed")
    args = ap.parse_args(argv)
    engines = args.engine or ["fast"]
    got = profile(args.scenario, engines)
    walls = ", ".join(f"{e} {s:.1f} s" for e, s in got["walls"].items())
    total = sum(s for _, s in got["passes"])
    print(f"{args.scenario}, empty cache")
    print(f"wall: {walls}; numba's passes {total:.1f} s in all\n")
    print("| pass | self time |\n|---|---:|")
    for name, sec in got["passes"][:12]:
        print(f"| {name} | {sec:.2f} s |")
    print("\n| function | self time |\n|---|---:|")
    for name, sec in got["functions"][: args.top]:
        print(f"| `{name}` | {sec:.2f} s |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
