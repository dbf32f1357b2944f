"""One code tree's simulations of given layouts, timed: the subprocess half of ``bench_simulation``.

Run as a script with the code tree to measure first on ``sys.path`` (``--root``), so the same probe measures this
tree and an older commit's worktree alike. It uses only what every revision of the simulator offers
(``load_scenario``, ``Simulator(scenario).run(x, early_stop=True)``, ``Simulator.build``) and times the engine by
wrapping ``pybullet.stepSimulation`` in the module itself: a ``BulletClient`` looks its methods up there on every
call, so the wrapper sees every step whichever way the simulator reaches the engine.

Input (JSON file): ``{"scenario": PATH, "layouts": [[...], ...], "engine": {...}, "dynamics": {...},
"bare": true}``, or ``{"scenario": PATH, "parallel": WORKERS, "U": [...], "U2": [...]}`` for the executor's
serial and pooled times; ``engine`` is merged into every ``setPhysicsEngineParameter`` call, ``dynamics`` is applied
with ``changeDynamics`` to every body as it is created (e.g. ``{"sleepThreshold": 0.01}``). Output (JSON on the
path given): per-layout outcomes, wall and engine time, steps, and the bare engine's steps per second.
"""

from __future__ import annotations

import argparse
import json
import sys
import time


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", required=True, help="the code tree to import the simulator from")
    parser.add_argument("--input", required=True)
    parser.add_argument("--output", required=True)
    args = parser.parse_args(argv)
    sys.path.insert(0, args.root)
    spec = json.loads(open(args.input, encoding="utf-8").read())

    # Imported from --root, deliberately after the path is set (this probe measures other trees than its own).
    import numpy as np

    import design
    from design.contraption import Simulator, load_scenario
    from design.contraption.bullet import pybullet

    if spec.get("parallel"):
        out = parallel(spec, np)
        out["code"] = design.__file__
        with open(args.output, "w", encoding="utf-8") as handle:
            json.dump(out, handle)
        return 0

    engine_time = [0.0, 0]
    raw_step = pybullet.stepSimulation
    raw_set = pybullet.setPhysicsEngineParameter
    raw_create = pybullet.createMultiBody
    engine = dict(spec.get("engine") or {})
    dynamics = dict(spec.get("dynamics") or {})

    def timed_step(*a, **kw):
        start = time.perf_counter()
        result = raw_step(*a, **kw)
        engine_time[0] += time.perf_counter() - start
        engine_time[1] += 1
        return result

    def set_parameters(*a, **kw):
        kw.update(engine)
        return raw_set(*a, **kw)

    def create_body(*a, **kw):
        uid = raw_create(*a, **kw)
        if dynamics and kw.get("baseCollisionShapeIndex", 0) != -1:
            pybullet.changeDynamics(uid, -1, physicsClientId=kw.get("physicsClientId", 0), **dynamics)
        return uid

    pybullet.stepSimulation = timed_step
    pybullet.setPhysicsEngineParameter = set_parameters
    pybullet.createMultiBody = create_body

    scenario = load_scenario(spec["scenario"])
    layouts = [np.asarray(x, dtype=float) for x in spec["layouts"]]
    outcomes = []
    with Simulator(scenario) as sim:
        sim.run(layouts[0], early_stop=True)  # warm-up: first-call imports and allocations
        engine_time[:] = [0.0, 0]
        start = time.perf_counter()
        for x in layouts:
            result = sim.run(x, early_stop=True)
            outcomes.append({
                "success": bool(result.success),
                "steps": int(result.steps),
                "events": {k: [o.state, o.time] for k, o in result.events.items()},
            })
        wall = time.perf_counter() - start
        in_engine, engine_steps = engine_time
        bare = None
        if spec.get("bare"):
            # The limit: each layout's scene, the engine stepped as many times as its simulation took, in a bare
            # loop with no station code around it.
            step = raw_step
            cid = sim.client._client
            total_steps, total_time = 0, 0.0
            for x, outcome in zip(layouts, outcomes):
                sim.build(x)
                n = outcome["steps"]
                start = time.perf_counter()
                for _ in range(n):
                    step(physicsClientId=cid)
                total_time += time.perf_counter() - start
                total_steps += n
            bare = total_steps / total_time if total_time else None
    out = {"wall": wall, "engine": in_engine, "engine_steps": engine_steps, "outcomes": outcomes,
           "bare_steps_per_s": bare, "code": design.__file__, "dt": scenario.settings.time_step}
    with open(args.output, "w", encoding="utf-8") as handle:
        json.dump(out, handle)
    return 0


def parallel(spec: dict, np) -> dict:
    """Seconds for the batch ``U`` run by the executor in this process, then by ``parallel`` worker processes (a
    fresh pool: its start-up counted), then a second batch ``U2`` on the same, warm pool."""
    from design.robust import SimulationExecutor
    from design.robust.contraption import load_problem

    problem = load_problem(spec["scenario"])
    U, U2 = np.asarray(spec["U"], dtype=float), np.asarray(spec["U2"], dtype=float)
    start = time.perf_counter()
    with SimulationExecutor(problem, backend="inline", cache_path=None) as executor:
        serial = executor.run(U)
        serial_time = time.perf_counter() - start
        start = time.perf_counter()
        executor.run(U2)
        serial_time2 = time.perf_counter() - start
    with SimulationExecutor(problem, backend="processes", workers=int(spec["parallel"]), cache_path=None) as executor:
        start = time.perf_counter()
        pooled = executor.run(U)
        pooled_time = time.perf_counter() - start
        start = time.perf_counter()
        executor.run(U2)
        pooled_time2 = time.perf_counter() - start
        tasks = getattr(executor, "n_tasks", None)
    return {"serial": serial_time, "serial2": serial_time2, "pooled": pooled_time, "pooled2": pooled_time2,
            "same": bool(np.array_equal(serial, pooled)), "tasks": tasks}


if __name__ == "__main__":
    sys.exit(main())
