"""Benchmarks that print figures. ``python -m bench`` runs them all; ``python -m bench NAME`` one of them.

Each module ``bench/bench_*.py`` defines ``main() -> None`` and prints its figures. Nothing here asserts on time.
"""

import time
from collections.abc import Callable


def best_time(function: Callable[[], object], repeats: int = 7) -> float:
    """Best wall time of ``repeats`` calls, in seconds (the least disturbed by the other jobs on the machine)."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)
