"""How often a layout works as the simulated maker sets it: each way the guide may tell the maker to set the heights
and tilts (a ruler, a laser-cut jig), in the same worlds.

For a scenario and a layout: per world seed, the hidden physics drawn (:func:`station.services.world.prepare_world`)
and ``attempts`` attempts placed with the projector's highlight (:func:`station.services.world.place_parts`), no
check, and run (:func:`station.services.world.run_attempt`), once with the guide as ``station guide`` makes it
(heights and tilts with a ruler) and once with its jigs (``--jigs``: the parameters they set on them). It isolates
what the jigs buy from the rest of the loop (no calibration, no choice of layout).

Run: ``python -m bench.bench_world_twin [--scenario causalityswitch_ball] [--layout success] [--seeds 1-5]
[--attempts 10] [--world '&ruler_mm=1'] [--json OUT.json]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path


def _seeds(text: str) -> list[int]:
    seeds: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        seeds += list(range(int(lo), int(hi or lo) + 1))
    return seeds


def measure(scenario: str, layout: str | None, seeds: list[int], attempts: int, world: str = "",
            log=print) -> dict:
    """Successes per way of setting (``"ruler"``: the guide as made; ``"jig"``: with its jigs) over the seeds."""
    from calibration.sim_runs import wilson_interval
    from station.services import world as worlds
    from station.services.guide import GuideRequest, make_guide

    jobs = {"ruler": make_guide(GuideRequest(scenario, layout, tolerances=False)),
            "jig": make_guide(GuideRequest(scenario, layout, tolerances=False, jigs=True))}
    figures: dict = {"scenario": scenario, "layout": layout, "world": world, "attempts_per_seed": attempts,
                     "jigs": [j.id for j in jobs["jig"].guide.jigs]}
    for how, job in jobs.items():
        started, successes, total = time.perf_counter(), 0, 0
        for seed in seeds:
            the_world = worlds.open_world(f"sim://world?seed={seed}{world}")
            worlds.prepare_world(the_world, job.scenario)
            for attempt in range(1, attempts + 1):
                worlds.place_parts(the_world, job.guide, attempt=attempt, highlighted=True, scenario=job.scenario)
                run = worlds.run_attempt(job.scenario, job.layout.x, job.guide, the_world)
                successes += run.success
                total += 1
            the_world.close()
        lo, hi = wilson_interval(successes, total)
        figures[how] = {"successes": successes, "attempts": total, "success_rate": successes / total,
                        "interval": [lo, hi], "seconds": round(time.perf_counter() - started, 1)}
        log(f"{scenario} {how}: {successes}/{total} = {successes / total:.2f} (95 % {lo:.2f}-{hi:.2f})")
    return figures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="causalityswitch_ball")
    parser.add_argument("--layout", default="success", help="a layout named in the scenario, or a LAYOUT.json")
    parser.add_argument("--seeds", default="1-5")
    parser.add_argument("--attempts", type=int, default=10, help="attempts per world seed")
    parser.add_argument("--world", default="", help="more sim://world options, e.g. '&ruler_mm=1'")
    parser.add_argument("--json", default=None)
    args = parser.parse_args([] if argv is None else argv)
    world = args.world if not args.world or args.world.startswith("&") else f"&{args.world}"
    figures = measure(args.scenario, args.layout, _seeds(args.seeds), args.attempts, world,
                      log=lambda line: print(line, flush=True))
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=2) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
