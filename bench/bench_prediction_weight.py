"""What a predicted physical success is worth against a layout's record on the table.

The loop chooses a layout by its expected success ``(w p + successes) / (w + attempts)``: the prediction ``p`` as a
Beta prior worth ``w`` attempts, updated by the layout's record (:mod:`station.services.layout_choice`). This bench
fits ``w`` to the loops already run: each loop of each run is one layout with a mean predicted success ``p`` (the
mean of its attempts' predictions) and ``k`` successes of ``n`` attempts; if the predictions were honest with
strength ``w``, ``k`` would be beta-binomial(``n``, ``w p``, ``w (1 - p)``). It prints the maximum-likelihood ``w``
(over every scenario, and per scenario), the negative log-likelihood at a few values, and how many layouts it saw.
A small ``w`` says the predictions are worth little against a few attempts; a large one that they are as good as
many attempts (``w`` -> infinity: ``k`` binomial(``n``, ``p``)).

The figures come from the bench's loop databases (``bench_loop``'s default, or ``--database``, several allowed;
a run stored in two databases counts once). Nothing is simulated here.

Run: ``python -m bench.bench_prediction_weight [--database DB ...]`` or ``python -m bench prediction_weight``.
"""

from __future__ import annotations

import argparse
import sqlite3
import sys
from pathlib import Path

import numpy as np

# Predictions of exactly 0 or 1 give a degenerate prior: held as far inside as the loop's choice holds them.
from station.services.layout_choice import PREDICTION_EDGE as EDGE

GRID = (1.0, 2.0, 4.0, 8.0, 16.0, 64.0, 1e6)


def loop_records(databases: list[str]) -> list[tuple[str, int, int, float]]:
    """``(scenario, attempts, successes, mean predicted success)`` of every loop with predictions in
    ``databases`` (each run once, by its key)."""
    records: dict[tuple[str, int], tuple[str, int, int, float]] = {}
    query = """SELECT r.run_key, r.scenario_name, a.loop_number, count(*), sum(a.success), avg(a.predicted)
               FROM loop_attempts a JOIN loop_runs r ON r.id = a.run_id
               WHERE a.loop_number > 0 AND a.predicted IS NOT NULL
               GROUP BY r.run_key, a.loop_number"""
    for database in databases:
        if not Path(database).is_file():
            continue
        connection = sqlite3.connect(f"file:{database}?mode=ro", uri=True)
        try:
            for key, scenario, loop, n, k, p in connection.execute(query):
                records[(key, loop)] = (scenario, int(n), int(k), float(p))
        except sqlite3.OperationalError:  # not a loop database
            pass
        finally:
            connection.close()
    return list(records.values())


def negative_log_likelihood(weight: float, n: np.ndarray, k: np.ndarray, p: np.ndarray) -> float:
    """The beta-binomial negative log-likelihood of the records with prior strength ``weight`` (the binomial
    coefficients left out: they do not depend on it)."""
    from scipy.special import betaln

    p = np.clip(p, EDGE, 1 - EDGE)
    a, b = weight * p, weight * (1 - p)
    return float(-np.sum(betaln(k + a, n - k + b) - betaln(a, b)))


def fit_weight(n: np.ndarray, k: np.ndarray, p: np.ndarray) -> float:
    """The maximum-likelihood prior strength, searched over 0.1 .. 1e4 attempts (in log)."""
    from scipy.optimize import minimize_scalar

    result = minimize_scalar(lambda lw: negative_log_likelihood(float(np.exp(lw)), n, k, p),
                             bounds=(np.log(0.1), np.log(1e4)), method="bounded")
    return float(np.exp(result.x))


def main(argv: list[str] | None = None) -> int:
    from station.paths import cache_dir

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--database", action="append", default=None,
                        help="a loop database (default: bench_loop's, full and quick); may be given again")
    args = parser.parse_args([] if argv is None else argv)
    databases = args.database or [str(cache_dir() / f"bench_loop{end}.sqlite3") for end in ("", "_quick")]
    records = loop_records(databases)
    print(f"bench_prediction_weight: {len(records)} layouts (loops of runs) from {', '.join(databases)}")
    if not records:
        print("  no loops with predictions there: run `python -m bench.bench_loop` first")
        return 0
    names = sorted({r[0] for r in records})
    table = np.array([r[1:] for r in records], float)
    n, k, p = table.T
    w = fit_weight(n, k, p)
    print(f"  maximum-likelihood weight over every scenario: {w:.2f} attempts")
    print("  weight    " + "  ".join(f"{g:>8g}" for g in GRID))
    print("  -log L    " + "  ".join(f"{negative_log_likelihood(g, n, k, p):8.1f}" for g in GRID))
    print(f"  {'scenario':<32} {'layouts':>7} {'weight':>8} {'mean |k/n - p|':>15}")
    for name in names:
        rows = np.array([r[1:] for r in records if r[0] == name], float)
        nn, kk, pp = rows.T
        print(f"  {name:<32} {len(rows):>7} {fit_weight(nn, kk, pp):>8.2f} {np.mean(np.abs(kk / nn - pp)):>15.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
