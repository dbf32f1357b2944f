"""The loop's table for the results: every figure from stored ``bench_loop`` runs, next to each scenario's ceiling.

Reads one or more ``bench_loop`` databases (opened read-only, each in one snapshot: a running campaign keeps
writing them; a run stored in several counts once, with the most attempts any of them holds) and the ceilings
``bench_loop_bound --out`` stored (JSON lines; a world measured again: its last row). Nothing is simulated. For each
scenario, with jigs and without, pooled over the world seeds whose runs are complete:

- the success after the first calibration (loops >= 2) with Wilson's 95 % interval, and loop 1's;
- the median number of attempts to the first success (loop 1's first attempt is 1);
- the Brier score of the predicted success and of the forecast (the prediction updated by its layout's record
  before the attempt, :func:`station.services.loop.record_forecasts`, recomputed from the stored attempts);
- the thesis's workflow (the run's baseline) in the same worlds;
- the ceiling at the same placement precision with the physics known (``bench_loop_bound``, the same jigs), pooled
  over the same worlds, and the loop's success after calibration as a fraction of it.

Each row names its world seeds; a row without every asked seed is marked partial, and the jigs-against-no-jigs
comparison (what jigs buy) uses only the worlds run both ways. Runs whose stored settings differ in anything but
the scenario, the world seed and the jigs (sizes, world options, the world's revision) go to separate tables. The
station commit of each run is read from its stored settings (``station_commits``, :mod:`station.loopstore`); a
database whose runs do not store it is said so (``--unstored-commit`` names it as given, not stored). Runs not
complete (running, or stopped) are listed under the table, not counted. ``--per-world`` adds a line per counted
run (each loop's successes and mean prediction, the baseline's, its commits).

Run: ``python -m bench.loop_table [DATABASE ...] [--bounds ROWS.jsonl ...] [--scenarios all] [--seeds 1-5]
[--loops 2] [--unstored-commit COMMIT] [--per-world] [--json OUT.json] [--readme]`` (no database:
``bench_loop``'s default one). ``--readme`` prints the README's short table instead, a row per scenario, rendered
from the same figures as ``--json`` writes them (:func:`readme`), so a test can hold the README to a stored JSON.
"""

from __future__ import annotations

import argparse
import json
import sqlite3
import sys
from collections.abc import Iterable, Sequence
from contextlib import closing
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import parse_qsl, urlencode, urlsplit

import numpy as np

from bench.bench_loop import ALL, FULL, QUICK, _brier, _f, _seeds, first_success
from bench.bench_loop_bound import flat_row
from calibration.sim_runs import wilson_interval
from design.contraption.errors import ScenarioNotFoundError
from station.errors import ServiceError
from station.loopstore import AttemptRow
from station.paths import cache_dir
from station.services.layout_choice import PREDICTION_WEIGHT
from station.services.loop import record_forecasts
from station.services.trials import load_trial_scenario

#: What a run's stored settings hold that varies within one table (the rest must be equal to share a table).
PER_RUN = ("scenario", "scenario_name", "world", "jigs", "side_camera", "station_commits")


class TableError(Exception):
    """Bad input to the table, in one line."""


@dataclass(frozen=True)
class StoredRun:
    """One ``bench_loop`` run as its database stores it."""

    key: str
    database: str
    run_id: int
    scenario: str
    content_hash: str
    seed: int | None
    world_options: str  #: the world URL's options other than its seed ("" for none)
    jigs: bool
    settings: dict
    attempts: tuple[AttemptRow, ...]  #: in order (loop, attempt); loop 0 is the baseline
    layouts: dict[int, dict] = field(default_factory=dict)

    @property
    def commits(self) -> tuple[str, ...]:
        return tuple(self.settings.get("station_commits", ()))

    def config(self) -> str:
        """What runs sharing a table must have in common (canonical JSON)."""
        common = {k: v for k, v in self.settings.items() if k not in PER_RUN}
        return json.dumps({**common, "world_options": self.world_options}, sort_keys=True, default=str)

    def logged(self) -> dict[int, int]:
        counts: dict[int, int] = {}
        for attempt in self.attempts:
            counts[attempt.loop] = counts.get(attempt.loop, 0) + 1
        return counts

    def planned(self, loops: int) -> dict[int, int]:
        """Attempts per loop a complete run holds (0: the baseline): ``loops`` loops, or every loop it began."""
        last = max([loops, *self.logged()])
        planned = dict.fromkeys(range(1, last + 1), int(self.settings.get("attempts", 0)))
        if int(self.settings.get("baseline", 0)):
            planned[0] = int(self.settings["baseline"])
        return planned

    def complete(self, loops: int) -> bool:
        logged = self.logged()
        return all(logged.get(k, 0) >= n for k, n in self.planned(loops).items())

    def progress(self, loops: int) -> str:
        logged = self.logged()
        return ", ".join(f"{f'loop {k}' if k else 'baseline'} {logged.get(k, 0)} of {n}"
                         for k, n in sorted(self.planned(loops).items(), key=lambda item: (item[0] == 0, item[0])))

    def forecasts(self) -> list[float | None]:
        """The loop attempts' forecasts, as the loop made them (its prediction weight, its layouts)."""
        placed = [a for a in self.attempts if a.loop >= 1]
        weight = float(self.settings.get("prediction_weight", PREDICTION_WEIGHT))
        return record_forecasts(self.layouts, placed, weight)


def _world(url: str) -> tuple[int | None, str]:
    """``(seed, the other options)`` of a ``sim://world?seed=N&...`` URL."""
    query = parse_qsl(urlsplit(url).query, keep_blank_values=True)
    seeds = [value for name, value in query if name == "seed"]
    others = sorted((name, value) for name, value in query if name != "seed")
    try:
        seed = int(seeds[0]) if seeds else None
    except ValueError:
        seed = None
    return seed, urlencode(others)


def read_runs(databases: Sequence[str]) -> list[StoredRun]:
    """Every run of ``databases``; a run (by its key) stored in several: the copy holding the most attempts."""
    found: dict[str, StoredRun] = {}
    for database in databases:
        for run in _database_runs(database):
            held = found.get(run.key)
            if held is None or len(run.attempts) > len(held.attempts):
                found[run.key] = run
    return sorted(found.values(), key=lambda r: (r.database, r.run_id))


def _database_runs(database: str) -> list[StoredRun]:
    path = Path(database)
    if not path.is_file():
        raise TableError(f"database {database}: no such file (expected a bench_loop database)")
    try:
        with closing(sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True)) as connection:
            connection.execute("BEGIN")  # one snapshot: the campaign may add attempts while this reads
            runs = connection.execute("SELECT id, run_key, scenario_name, content_hash, world, settings "
                                      "FROM loop_runs ORDER BY id").fetchall()
            attempts = connection.execute("SELECT run_id, loop_number, attempt, trial_id, success, predicted, "
                                          "check_rounds FROM loop_attempts ORDER BY run_id, loop_number, "
                                          "attempt").fetchall()
            layouts = connection.execute("SELECT run_id, loop_number, layout FROM loop_loops").fetchall()
    except sqlite3.DatabaseError as error:
        words = "not a bench_loop database (no loop_runs table)" if "no such table" in str(error) else str(error)
        raise TableError(f"database {database}: {words}") from None
    by_run: dict[int, list[AttemptRow]] = {}
    for run_id, loop, attempt, trial, success, predicted, rounds in attempts:
        by_run.setdefault(run_id, []).append(AttemptRow(int(loop), int(attempt), int(trial), bool(success),
                                                        None if predicted is None else float(predicted),
                                                        int(rounds)))
    placed: dict[int, dict[int, dict]] = {}
    for run_id, loop, text in layouts:
        placed.setdefault(run_id, {})[int(loop)] = json.loads(text)
    result = []
    for run_id, key, scenario, content_hash, world, settings in runs:
        stored = json.loads(settings)
        seed, options = _world(world)
        result.append(StoredRun(key, database, int(run_id), scenario, content_hash, seed, options,
                                bool(stored.get("jigs", False)), stored, tuple(by_run.get(run_id, ())),
                                placed.get(run_id, {})))
    return result


# -- the figures ---------------------------------------------------------------------------------------------------
def _rate(successes: Iterable[bool]) -> dict:
    values = [bool(s) for s in successes]
    k, n = sum(values), len(values)
    return {"successes": k, "attempts": n, "success_rate": k / n if n else None,
            "interval": list(wilson_interval(k, n)) if n else None}


def _median(values: list[float]) -> float | None:
    return float(np.median(values)) if values else None


def figures(runs: Sequence[StoredRun]) -> dict:
    """The row's figures over ``runs`` (complete runs, one per world seed)."""
    loop_attempts = [[a for a in r.attempts if a.loop >= 1] for r in runs]
    predicted = [(a.predicted, a.success) for placed in loop_attempts for a in placed if a.predicted is not None]
    forecast = [(f, a.success) for r, placed in zip(runs, loop_attempts) for a, f in zip(placed, r.forecasts())
                if f is not None]
    baselines = [[a.success for a in r.attempts if a.loop == 0] for r in runs]
    return {
        "seeds": sorted(r.seed for r in runs),
        "after_calibration": _rate(a.success for placed in loop_attempts for a in placed if a.loop >= 2),
        "loop1": _rate(a.success for placed in loop_attempts for a in placed if a.loop == 1),
        "median_attempts_to_first_success": _median([first_success([a.success for a in p]) for p in loop_attempts]),
        "brier": _brier(predicted), "brier_forecast": _brier(forecast), "predictions": len(predicted),
        "baseline": {**_rate(s for b in baselines for s in b),
                     "median_attempts_to_first_success": _median([first_success(b) for b in baselines if b])},
        "commits": sorted({c for r in runs for c in r.commits}),
        "runs": [{"database": r.database, "run": r.run_id, "seed": r.seed, "commits": list(r.commits)}
                 for r in runs],
        "scenario_files": sorted({r.content_hash for r in runs}),
    }


def read_bounds(paths: Sequence[str]) -> dict[tuple[str, bool], dict[int, dict]]:
    """``bench_loop_bound --out`` rows at the loop's precision, ``{(example name, jigs): {seed: row}}`` (a world
    measured again: its last row; ``--precision flat`` rows, every parameter at one error, left out)."""
    bounds: dict[tuple[str, bool], dict[int, dict]] = {}
    for path in paths:
        try:
            lines = Path(path).read_text(encoding="utf-8").splitlines()
        except (OSError, UnicodeDecodeError) as error:
            raise TableError(f"--bounds {path}: cannot read ({error})") from None
        for number, line in enumerate(lines, 1):
            if not line.strip():
                continue
            try:
                row = json.loads(line)
                if not flat_row(row):
                    bounds.setdefault((str(row["scenario"]), bool(row["jigs"])), {})[int(row["seed"])] = row
            except (ValueError, KeyError, TypeError, AttributeError) as error:
                raise TableError(f"--bounds {path}: line {number}: expected a row bench_loop_bound --out writes "
                                 f"({error})") from None
    return bounds


def ceiling(rows: dict[int, dict] | None, seeds: Sequence[int]) -> dict | None:
    """The bound pooled over ``seeds``' worlds (those ``rows`` hold): successes of its simulations, Wilson's
    interval, and the worlds it lacks."""
    if not rows or not seeds:
        return None
    held = [s for s in seeds if s in rows]
    if not held:
        return None
    k = sum(int(rows[s]["successes"]) for s in held)
    n = sum(int(rows[s]["samples"]) for s in held)
    return {"seeds": held, "missing": [s for s in seeds if s not in rows], "successes": k, "simulations": n,
            "success_rate": k / n if n else None, "interval": list(wilson_interval(k, n)) if n else None,
            "per_world": {s: rows[s]["success"] for s in held}}


@dataclass
class Table:
    """One table: runs sharing their settings but the scenario, the world seed and the jigs."""

    config: dict
    rows: list[dict]
    jigs_buy: list[dict]
    incomplete: list[str]
    commits: dict[str, int]  #: commit -> complete runs counted
    unstored: int  #: complete runs counted whose database stores no commit
    counted: list[StoredRun] = field(default_factory=list)  #: the runs the rows pool


def tables(runs: Sequence[StoredRun], bounds: dict[tuple[str, bool], dict[int, dict]], *,
           scenarios: Sequence[tuple[str, str]], seeds: Sequence[int], loops: int) -> list[Table]:
    """The tables of ``runs``: one per configuration, a row per scenario (``(example name, scenario name)``, in
    order) with jigs and without, over the complete runs of ``seeds``."""
    names = {name for _, name in scenarios}
    wanted = [r for r in runs if r.scenario in names and r.seed in seeds]
    configs: dict[str, list[StoredRun]] = {}
    for run in wanted:
        configs.setdefault(run.config(), []).append(run)
    result = []
    for config, found in configs.items():
        complete = [r for r in found if r.complete(loops)]
        rows, buy, notes, counted = [], [], [], []
        # the ceilings are measured in the world's default options: a table in other ones has none beside it
        known = bounds if not json.loads(config).get("world_options") else {}
        for example, name in scenarios:
            by_jigs = {}
            for jigs in (True, False):
                chosen, dropped = _one_per_seed([r for r in complete if r.scenario == name and r.jigs == jigs])
                counted += chosen
                notes += [f"{r.scenario}, world {r.seed}, {'with' if r.jigs else 'without'} jigs (run {r.run_id} in "
                          f"{r.database}): an earlier scenario file ({r.content_hash[:12]}) than the run counted"
                          for r in dropped]
                row = {"scenario": name, "example": example, "jigs": jigs, "asked_seeds": list(seeds),
                       "partial": sorted(r.seed for r in chosen) != sorted(seeds)}
                if chosen:
                    row.update(figures(chosen))
                    row["ceiling"] = ceiling(known.get((example, jigs)), row["seeds"])
                    after, bound = row["after_calibration"]["success_rate"], row["ceiling"]
                    row["of_ceiling"] = (after / bound["success_rate"]
                                         if bound and after is not None and bound["success_rate"] else None)
                else:
                    row["seeds"] = []
                rows.append(row)
                by_jigs[jigs] = chosen
            buy.append(_jigs_buy(name, example, by_jigs, known))
        commits: dict[str, int] = {}
        for run in counted:
            for commit in run.commits:
                commits[commit] = commits.get(commit, 0) + 1
        incomplete = [f"{r.scenario}, world {r.seed}, {'with' if r.jigs else 'without'} jigs (run {r.run_id} in "
                      f"{r.database}): not complete ({r.progress(loops)})" for r in found if not r.complete(loops)]
        result.append(Table(json.loads(config), rows, buy, incomplete + notes, commits,
                            sum(1 for r in counted if not r.commits), counted))
    return result


def _one_per_seed(runs: list[StoredRun]) -> tuple[list[StoredRun], list[StoredRun]]:
    """``(one run per world seed, the others)``: two complete runs of one world in one configuration differ only
    in their scenario file (its content hash); the later one is counted, the earlier said."""
    chosen: dict[int, StoredRun] = {}
    dropped = []
    for run in runs:
        if run.seed in chosen:
            dropped.append(chosen[run.seed])
        chosen[run.seed] = run
    return [chosen[s] for s in sorted(chosen)], dropped


def _jigs_buy(name: str, example: str, by_jigs: dict[bool, list[StoredRun]], bounds) -> dict:
    """With jigs against without, over the worlds run both ways only."""
    both = sorted({r.seed for r in by_jigs[True]} & {r.seed for r in by_jigs[False]})
    entry: dict = {"scenario": name, "seeds": both}
    for jigs, word in ((True, "with"), (False, "without")):
        runs = [r for r in by_jigs[jigs] if r.seed in both]
        entry[word] = _rate(a.success for r in runs for a in r.attempts if a.loop >= 2)
        entry[f"ceiling_{word}"] = ceiling(bounds.get((example, jigs)), both)
    return entry


# -- words ---------------------------------------------------------------------------------------------------------
def seed_words(seeds: Sequence[int]) -> str:
    """``[1, 2, 3, 5]`` -> ``"1-3, 5"``."""
    parts: list[str] = []
    ordered = sorted(set(seeds))
    i = 0
    while i < len(ordered):
        j = i
        while j + 1 < len(ordered) and ordered[j + 1] == ordered[j] + 1:
            j += 1
        parts.append(str(ordered[i]) if i == j else f"{ordered[i]}-{ordered[j]}")
        i = j + 1
    return ", ".join(parts)


def _rate_words(rate: dict) -> str:
    if not rate["attempts"]:
        return "-"
    low, high = rate["interval"]
    return f"{_f(rate['success_rate'])} ({rate['successes']}/{rate['attempts']}; {_f(low)}-{_f(high)})"


def _ceiling_words(bound: dict | None) -> str:
    if bound is None:
        return "not measured"
    low, high = bound["interval"]
    words = f"{_f(bound['success_rate'])} ({_f(low)}-{_f(high)})"
    if bound["missing"]:
        words += f", worlds {seed_words(bound['seeds'])} only"
    return words


def sizes_words(config: dict) -> str:
    """The table's sizes: ``bench_loop``'s FULL or QUICK when they match, else the settings that set them."""
    for label, sizes in (("full sizes", FULL), ("quick sizes", QUICK)):
        if all(config.get(k) == v for k, v in sizes.items() if k != "loops"):
            return label
    return "sizes " + ", ".join(f"{k} {config.get(k)}" for k in FULL if k != "loops")


def commit_words(table: Table, unstored_commit: str | None) -> str:
    parts = [f"{commit} ({count} run{'s' if count != 1 else ''})" for commit, count in sorted(table.commits.items())]
    if table.unstored:
        runs = f"{table.unstored} run{'s' if table.unstored != 1 else ''}"
        parts.append(f"{unstored_commit} for {runs} (as given: their database does not store it)" if unstored_commit
                     else f"not stored for {runs} (made by a station that did not store its commit)")
    return "; ".join(parts) or "no complete run"


def markdown(table: Table, *, unstored_commit: str | None = None) -> list[str]:
    """The table in markdown, with its header lines and the runs not counted."""
    config = table.config
    options = f", world options `{config['world_options']}`" if config.get("world_options") else ""
    lines = [f"Station commit: {commit_words(table, unstored_commit)}. {sizes_words(config).capitalize()}"
             f"{options}, world revision {config.get('world_revision', '-')}; world seeds asked "
             f"{seed_words(table.rows[0]['asked_seeds']) if table.rows else '-'}.", "",
             "| scenario | jigs | worlds | success after the first calibration (95 %) | loop 1 | median attempts to "
             "the first success | Brier: predicted, forecast | thesis's workflow, same worlds | ceiling, same worlds "
             "(95 %) | loop / ceiling |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for row in table.rows:
        jigs = "yes" if row["jigs"] else "no"
        if not row["seeds"]:
            lines.append(f"| {row['scenario']} | {jigs} | none | no complete run yet | | | | | | |")
            continue
        worlds = seed_words(row["seeds"])
        if row["partial"]:
            missing = sorted(set(row["asked_seeds"]) - set(row["seeds"]))
            worlds += f" (partial: {seed_words(missing)} missing)"
        if len(row["scenario_files"]) > 1:
            worlds += f" ({len(row['scenario_files'])} scenario files)"
        loop1 = row["loop1"]
        baseline = row["baseline"]
        lines.append(
            f"| {row['scenario']} | {jigs} | {worlds} | {_rate_words(row['after_calibration'])} | "
            f"{loop1['successes']}/{loop1['attempts']} | {_f(row['median_attempts_to_first_success'], 1)} | "
            f"{_f(row['brier'], 3)}, {_f(row['brier_forecast'], 3)} | "
            f"{_f(baseline['success_rate'])} ({baseline['successes']}/{baseline['attempts']}) | "
            f"{_ceiling_words(row['ceiling'])} | {_f(row['of_ceiling'])} |")
    lines += ["", "What jigs buy, in the worlds run both ways:", "",
              "| scenario | worlds | success after the first calibration: with jigs, without | ceiling: with jigs, "
              "without |", "| --- | --- | --- | --- |"]
    for entry in table.jigs_buy:
        if not entry["seeds"]:
            lines.append(f"| {entry['scenario']} | none yet | | |")
            continue
        lines.append(f"| {entry['scenario']} | {seed_words(entry['seeds'])} | {_rate_words(entry['with'])}, "
                     f"{_rate_words(entry['without'])} | {_ceiling_words(entry['ceiling_with'])}, "
                     f"{_ceiling_words(entry['ceiling_without'])} |")
    if table.incomplete:
        lines += ["", "Not counted:", *(f"- {line}" for line in table.incomplete)]
    return lines


def per_world(table: Table, *, unstored_commit: str | None = None) -> list[str]:
    """Each counted run in a line, world by world: each loop's successes and mean prediction, the baseline's, and
    the station commits that made it."""
    runs = sorted(table.counted, key=lambda r: (r.seed, not r.jigs))
    loops = sorted({a.loop for r in runs for a in r.attempts if a.loop >= 1})
    lines = [f"| world | scenario | jigs | {' | '.join(f'loop {k}' for k in loops)} | predicted, loop "
             f"{' / '.join(map(str, loops))} | thesis's workflow | station commit |",
             "| " + " | ".join(["---"] * (len(loops) + 6)) + " |"]
    for run in runs:
        cells = []
        means = []
        for k in loops:
            placed = [a for a in run.attempts if a.loop == k]
            cells.append(f"{sum(a.success for a in placed)}/{len(placed)}")
            known = [a.predicted for a in placed if a.predicted is not None]
            means.append(_f(float(np.mean(known))) if known else "-")
        baseline = [a.success for a in run.attempts if a.loop == 0]
        commit = ", ".join(run.commits) or (f"{unstored_commit} (as given)" if unstored_commit else "not stored")
        lines.append(f"| {run.seed} | {run.scenario} | {'yes' if run.jigs else 'no'} | {' | '.join(cells)} | "
                     f"{' / '.join(means)} | {sum(baseline)}/{len(baseline)} | {commit} |")
    return lines


def _short_rate(rate: dict | None) -> str:
    if not rate or not rate.get("attempts"):
        return "-"
    return f"{_f(rate['success_rate'])} ({rate['successes']}/{rate['attempts']})"


def _short_worlds(row: dict) -> str:
    """``""`` for a row with every asked world, else ``" (worlds 1-3)"``."""
    if not row.get("partial") or not row.get("seeds"):
        return ""
    return f" (world{'s' if len(row['seeds']) > 1 else ''} {seed_words(row['seeds'])})"


def readme(table: dict) -> list[str]:
    """The README's short table from one table of :func:`to_json`'s output (``data["tables"][i]``): per scenario,
    the success after the first calibration with jigs and without, the thesis's workflow in the jigs runs' worlds,
    the median attempts to the first success and the forecasts' Brier score with jigs, and the ceiling with jigs
    with the loop's share of it."""
    rows: dict[str, dict[bool, dict]] = {}
    for row in table["rows"]:
        rows.setdefault(row["scenario"], {})[bool(row["jigs"])] = row
    lines = ["| scenario | after the first calibration, with jigs | without jigs | thesis's workflow, same worlds | "
             "median attempts to the first success | Brier of the forecasts | ceiling with jigs (loop / ceiling) |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for name, by_jigs in rows.items():
        jigs, plain = by_jigs.get(True, {}), by_jigs.get(False, {})
        if not jigs.get("seeds"):
            lines.append(f"| {name} | no complete run yet | {_short_rate(plain.get('after_calibration'))}"
                         f"{_short_worlds(plain)} | | | | |")
            continue
        bound = jigs.get("ceiling")
        ceiling_words = "not measured" if not bound else (f"{_f(bound['success_rate'])} "
                                                          f"({_f(jigs.get('of_ceiling'))})")
        lines.append(f"| {name} | {_short_rate(jigs['after_calibration'])}{_short_worlds(jigs)} | "
                     f"{_short_rate(plain.get('after_calibration'))}{_short_worlds(plain)} | "
                     f"{_short_rate(jigs['baseline'])} | {_f(jigs['median_attempts_to_first_success'], 1)} | "
                     f"{_f(jigs['brier_forecast'], 3)} | {ceiling_words} |")
    return lines


def to_json(found: Sequence[Table], databases: Sequence[str], bounds: Sequence[str]) -> dict:
    return {"databases": list(databases), "bounds": list(bounds),
            "tables": [{"config": t.config, "commits": t.commits, "runs_without_commit": t.unstored,
                        "rows": t.rows, "jigs_buy": t.jigs_buy, "incomplete": t.incomplete} for t in found]}


def scenario_names(examples: Sequence[str]) -> list[tuple[str, str]]:
    """``(example name, the scenario's own name)`` of each example (the loop stores the latter)."""
    result = []
    for example in examples:
        try:
            result.append((example, load_trial_scenario(example).name))
        except (ServiceError, ScenarioNotFoundError) as error:
            raise TableError(f"--scenarios: {example!r}: {error}") from None
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("databases", nargs="*", metavar="DATABASE",
                        help="bench_loop databases (SQLite files; default: bench_loop's own)")
    parser.add_argument("--bounds", action="append", default=[], metavar="ROWS.jsonl",
                        help="rows bench_loop_bound --out wrote (may be given again; a later row of a world wins)")
    parser.add_argument("--scenarios", default="all", help=f"comma-separated example names (all: {','.join(ALL)})")
    parser.add_argument("--seeds", default="1-5", help="the world seeds asked, e.g. 1-5 or 1,3,7")
    parser.add_argument("--loops", type=int, default=2, help="loops a complete run holds (at least 2)")
    parser.add_argument("--unstored-commit", default=None, metavar="COMMIT",
                        help="the commit to name for runs whose database does not store one (said as given)")
    parser.add_argument("--per-world", action="store_true",
                        help="also a line per counted run: each loop's successes and mean prediction")
    parser.add_argument("--json", default=None, metavar="OUT.json", help="also write the figures there")
    parser.add_argument("--readme", action="store_true",
                        help="print the README's short table (a row per scenario) instead of the full one")
    args = parser.parse_args([] if argv is None else argv)
    try:
        try:
            seeds = _seeds(args.seeds)
        except ValueError:
            raise TableError(f"--seeds: expected seeds like 1-5 or 1,3,7, got {args.seeds!r}") from None
        if args.loops < 2:
            raise TableError(f"--loops: expected at least 2 (loop 2 is the first after a calibration), "
                             f"got {args.loops}")
        examples = ALL if args.scenarios == "all" else [s.strip() for s in args.scenarios.split(",") if s.strip()]
        databases = args.databases or [str(cache_dir() / "bench_loop.sqlite3")]
        found = tables(read_runs(databases), read_bounds(args.bounds), scenarios=scenario_names(examples),
                       seeds=seeds, loops=args.loops)
    except TableError as error:
        print(f"loop_table: {error}", file=sys.stderr)
        return 2
    if not found:
        print(f"loop_table: no run of {', '.join(examples)} in world seeds {seed_words(seeds)} in "
              f"{', '.join(databases)}")
    data = to_json(found, databases, args.bounds)
    for i, table in enumerate(found):
        if i:
            print()
        if args.readme:
            print("\n".join(readme(data["tables"][i])))
            continue
        print("\n".join(markdown(table, unstored_commit=args.unstored_commit)))
        if args.per_world:
            print("\nPer world:\n")
            print("\n".join(per_world(table, unstored_commit=args.unstored_commit)))
    if args.json:
        try:
            Path(args.json).write_text(json.dumps(data, indent=2, default=str)
                                       + "\n", encoding="utf-8")
        except OSError as error:
            print(f"loop_table: --json {args.json}: cannot write ({error})", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
