"""The loop's table (bench/loop_table.py) from a small loop database made here: pooled figures, Wilson's interval,
the forecasts as the loop makes them, the ceiling over the same worlds, partial rows, and the station commit each
run stores (station/loopstore.py)."""

from __future__ import annotations

import json
import sqlite3
import subprocess
from pathlib import Path

import pytest

from bench import loop_table
from station import loopstore
from station.loopstore import LoopRow, LoopStore, run_key
from station.services.trials import build_trial, layout_values, load_trial_scenario

SIZES = {"attempts": 2, "baseline": 2, "prediction_weight": 4.0, "world_revision": 2, "budget": None}
A = {"parameters": [{"name": "track.x", "value": -0.06}]}
B = {"parameters": [{"name": "track.x", "value": -0.05}]}


@pytest.fixture(scope="module")
def simple():
    return load_trial_scenario("simple")


def _trial(scenario, success: bool) -> dict:
    outcomes = {"last_stops": "yes"} if success else {"ball_hits_domino": "no"}
    return build_trial(scenario, layout_values(scenario, scenario.layout("success")), outcomes)


def store_run(database, scenario, *, seed: int, jigs: bool, loops: dict, layouts: dict, baseline=(),
              commit: str | None = "abc1234", sizes=SIZES, world_options: str = "") -> int:
    """A run as bench_loop stores it: ``loops`` {loop: [(success, predicted)]}, the baseline's successes."""
    world = f"sim://world?seed={seed}{world_options}"
    settings = {**sizes, "scenario": scenario.content_hash, "scenario_name": scenario.name, "world": world,
                "jigs": jigs}
    with LoopStore(str(database)) as store:
        run, _ = store.run(run_key(settings), scenario=scenario.name, content_hash=scenario.content_hash,
                           world=world, settings=settings, commit=commit)
        for k, layout in layouts.items():
            store.add_loop(run, LoopRow(k, layout, None, None, {}))
        for k, outcomes in loops.items():
            for a, (success, predicted) in enumerate(outcomes, 1):
                store.add_attempt(run, k, a, _trial(scenario, success), predicted=predicted, check_rounds=0)
        for a, success in enumerate(baseline, 1):
            store.add_attempt(run, 0, a, _trial(scenario, success), predicted=None, check_rounds=0)
    return run


@pytest.fixture
def campaign(tmp_path, simple):
    """Worlds 1 and 2 with jigs, world 1 without, world 3 with jigs begun (loop 1 only)."""
    database = tmp_path / "bench_loop.sqlite3"
    store_run(database, simple, seed=1, jigs=True, layouts={1: A, 2: B},
              loops={1: [(False, 0.5), (True, 0.5)], 2: [(True, 0.9), (True, 0.8)]}, baseline=(False, False))
    # world 2 keeps loop 1's layout: loop 2's forecasts carry loop 1's record on
    store_run(database, simple, seed=2, jigs=True, layouts={1: A, 2: A},
              loops={1: [(True, 0.6), (True, 0.7)], 2: [(True, 1.0), (False, 0.5)]}, baseline=(True, False))
    store_run(database, simple, seed=3, jigs=True, layouts={1: A}, loops={1: [(True, 0.6), (True, 0.7)]})
    store_run(database, simple, seed=1, jigs=False, layouts={1: A, 2: B},
              loops={1: [(True, 0.9), (True, 0.9)], 2: [(True, 0.9), (False, 0.9)]}, baseline=(False, False))
    bounds = tmp_path / "rows.jsonl"
    rows = [("simple", True, 1, 30), ("simple", True, 2, 10), ("simple", True, 2, 31), ("simple", True, 3, 32),
            ("simple", False, 1, 20)]
    lines = [{"scenario": s, "jigs": j, "seed": seed, "successes": k, "samples": 32, "success": k / 32,
              "how": {"track.x": "check (top)"}} for s, j, seed, k in rows]
    # every parameter at one error (--precision flat): not the loop's precision, left out
    lines.append({"scenario": "simple", "jigs": False, "seed": 1, "successes": 32, "samples": 32, "success": 1.0,
                  "how": {"track.x": "flat"}})
    bounds.write_text("".join(json.dumps(line) + "\n" for line in lines), encoding="utf-8")
    return database, bounds


def _tables(database, bounds, seeds=(1, 2, 3), scenarios=("simple", "ballrun")):
    return loop_table.tables(loop_table.read_runs([str(database)]), loop_table.read_bounds([str(bounds)]),
                             scenarios=loop_table.scenario_names(scenarios), seeds=list(seeds), loops=2)


def test_a_row_pools_its_worlds_with_wilsons_interval_the_forecasts_and_the_ceiling(campaign):
    (table,) = _tables(*campaign)
    jigs = next(r for r in table.rows if r["scenario"] == "SIMPLE" and r["jigs"])
    assert jigs["seeds"] == [1, 2] and jigs["partial"]  # world 3 is not complete: not counted
    after = jigs["after_calibration"]
    assert (after["successes"], after["attempts"]) == (3, 4)
    assert after["interval"] == pytest.approx([0.3006, 0.9544], abs=1e-4)  # Wilson's 95 % of 3 in 4
    assert (jigs["loop1"]["successes"], jigs["loop1"]["attempts"]) == (3, 4)
    assert jigs["median_attempts_to_first_success"] == 1.5  # world 1 at its 2nd attempt, world 2 at its 1st
    predicted = [(0.5, 0), (0.5, 1), (0.9, 1), (0.8, 1), (0.6, 1), (0.7, 1), (1.0, 1), (0.5, 0)]
    assert jigs["brier"] == pytest.approx(sum((p - s) ** 2 for p, s in predicted) / 8)
    # each forecast: (4 p + successes) / (4 + attempts) of its layout's record before it
    forecast = [(0.5, 0), ((4 * 0.5 + 0) / 5, 1), (0.9, 1), ((4 * 0.8 + 1) / 5, 1),  # world 1: loop 2 a new layout
                (0.6, 1), ((4 * 0.7 + 1) / 5, 1), ((4 * 1.0 + 2) / 6, 1), ((4 * 0.5 + 3) / 7, 0)]  # world 2: the same
    assert jigs["brier_forecast"] == pytest.approx(sum((p - s) ** 2 for p, s in forecast) / 8)
    assert (jigs["baseline"]["successes"], jigs["baseline"]["attempts"]) == (1, 4)
    # the ceiling over the same worlds 1 and 2 (world 2's later row), not world 3's
    bound = jigs["ceiling"]
    assert (bound["seeds"], bound["successes"], bound["simulations"], bound["missing"]) == ([1, 2], 61, 64, [])
    assert jigs["of_ceiling"] == pytest.approx(0.75 / (61 / 64))
    without = next(r for r in table.rows if r["scenario"] == "SIMPLE" and not r["jigs"])
    assert without["seeds"] == [1] and without["partial"]
    assert without["ceiling"]["successes"] == 20  # the flat row of the same world left out
    assert without["of_ceiling"] == pytest.approx(0.5 / (20 / 32))
    assert table.commits == {"abc1234": 3} and table.unstored == 0


def test_partial_rows_are_marked_and_jigs_are_compared_in_the_worlds_run_both_ways(campaign):
    (table,) = _tables(*campaign)
    (simple, ballrun) = table.jigs_buy
    assert simple["seeds"] == [1]  # world 2 ran only with jigs
    assert (simple["with"]["successes"], simple["with"]["attempts"]) == (2, 2)
    assert (simple["without"]["successes"], simple["without"]["attempts"]) == (1, 2)
    assert simple["ceiling_with"]["successes"] == 30 and simple["ceiling_without"]["successes"] == 20
    assert ballrun["seeds"] == []
    text = "\n".join(loop_table.markdown(table))
    assert "| SIMPLE | yes | 1-2 (partial: 3 missing) | 0.75 (3/4; 0.30-0.95) | 3/4 | 1.5 |" in text
    assert "| SIMPLE | no | 1 (partial: 2-3 missing) | 0.50 (1/2;" in text
    assert "| BALLRUN | yes | none | no complete run yet |" in text
    assert "| SIMPLE | 1 | 1.00 (2/2; 0.34-1.00), 0.50 (1/2; 0.09-0.91) |" in text
    assert "SIMPLE, world 3, with jigs (run 3 in" in text and "loop 2 0 of 2" in text
    assert text.startswith("Station commit: abc1234 (3 runs).")
    # asked only the worlds a row has, it is whole
    (whole,) = _tables(*campaign, seeds=(1, 2), scenarios=("simple",))
    assert not whole.rows[0]["partial"] and not whole.incomplete
    assert "| SIMPLE | yes | 1-2 | 0.75" in "\n".join(loop_table.markdown(whole))


def test_a_run_in_two_databases_counts_once_with_its_most_attempts(tmp_path, simple):
    begun, done = tmp_path / "begun.sqlite3", tmp_path / "done.sqlite3"
    store_run(begun, simple, seed=1, jigs=True, layouts={1: A}, loops={1: [(True, 0.5)]})
    store_run(done, simple, seed=1, jigs=True, layouts={1: A, 2: A}, loops={1: [(True, 0.5)] * 2,
              2: [(True, 0.5)] * 2}, baseline=(True, True))
    runs = loop_table.read_runs([str(begun), str(done)])
    assert len(runs) == 1 and runs[0].database == str(done) and runs[0].complete(2)


def test_runs_in_other_sizes_or_worlds_go_to_their_own_table(tmp_path, simple):
    database = tmp_path / "bench_loop.sqlite3"
    full = dict(loops={1: [(True, 0.9)] * 2, 2: [(True, 0.9)] * 2}, baseline=(True, True), layouts={1: A, 2: A})
    store_run(database, simple, seed=1, jigs=True, **full)
    store_run(database, simple, seed=2, jigs=True, sizes={**SIZES, "budget": 120}, **full)
    store_run(database, simple, seed=3, jigs=True, world_options="&ruler_mm=1", **full)
    bounds = tmp_path / "rows.jsonl"
    bounds.write_text(json.dumps({"scenario": "simple", "jigs": True, "seed": 3, "successes": 32, "samples": 32,
                                  "success": 1.0, "how": {}}) + "\n", encoding="utf-8")
    found = _tables(database, bounds, scenarios=("simple",))
    assert sorted(t.rows[0]["seeds"][0] for t in found) == [1, 2, 3]
    other_world = next(t for t in found if t.config["world_options"])
    assert other_world.rows[0]["ceiling"] is None  # the ceilings are measured in the default world only
    assert "world options `ruler_mm=1`" in loop_table.markdown(other_world)[0]


def test_a_database_that_stores_no_commit_says_so(campaign):
    database, bounds = campaign
    with sqlite3.connect(database) as connection:  # as a station that stored no commit left it
        for run_id, settings in connection.execute("SELECT id, settings FROM loop_runs").fetchall():
            stored = json.loads(settings)
            stored.pop("station_commits")
            connection.execute("UPDATE loop_runs SET settings = ? WHERE id = ?", (json.dumps(stored), run_id))
    (table,) = _tables(database, bounds)
    assert table.commits == {} and table.unstored == 3
    assert "not stored for 3 runs" in loop_table.markdown(table)[0]
    assert "a12fa16 for 3 runs (as given" in loop_table.markdown(table, unstored_commit="a12fa16")[0]


@pytest.mark.parametrize("where", ["sqlite", "postgresql"])
def test_a_run_stores_the_commit_of_every_station_code_that_worked_on_it(where, request, tmp_path):
    url = request.getfixturevalue("pg_url") if where == "postgresql" else str(tmp_path / "s.sqlite3")
    key = run_key({"scenario": "SIMPLE"})
    with LoopStore(url) as store:
        run, made = store.run(key, scenario="SIMPLE", content_hash="h", world="w", settings={"a": 1}, commit="c1")
        assert made and store.commits(run) == ["c1"]
        assert store.run(key, scenario="SIMPLE", content_hash="h", world="w", settings={"a": 1},
                         commit="c2+changes") == (run, False)
        store.run(key, scenario="SIMPLE", content_hash="h", world="w", settings={"a": 1}, commit="c2+changes")
        assert store.commits(run) == ["c1", "c2+changes"]  # carried on by newer code: the same run, both said
        other, _ = store.run(run_key({"scenario": "BALLRUN"}), scenario="BALLRUN", content_hash="h", world="w",
                             settings={})
        assert store.commits(other) == ([loopstore.station_commit()] if loopstore.station_commit() else [])


def test_the_station_commit_is_its_own_checkouts_or_none(monkeypatch):
    loopstore.station_commit.cache_clear()
    try:
        head = subprocess.run(["git", "-C", str(Path(loopstore.__file__).parents[1]), "rev-parse", "--short", "HEAD"],
                              capture_output=True, text=True)
        if head.returncode == 0:  # the tests run in the station's checkout: its commit
            assert loopstore.station_commit().split("+")[0] == head.stdout.strip()
        loopstore.station_commit.cache_clear()
        answers = {"rev-parse": "/somewhere/else"}  # an installed copy inside another repository
        monkeypatch.setattr(loopstore, "_git", lambda root, *words: answers.get(words[0], "x"))
        assert loopstore.station_commit() is None
    finally:
        loopstore.station_commit.cache_clear()


def test_the_command_prints_the_table_and_writes_its_json(campaign, tmp_path, capsys):
    database, bounds = campaign
    out = tmp_path / "table.json"
    assert loop_table.main([str(database), "--bounds", str(bounds), "--scenarios", "simple", "--seeds", "1-3",
                            "--json", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "| SIMPLE | yes | 1-2 (partial: 3 missing) |" in printed
    data = json.loads(out.read_text(encoding="utf-8"))
    (table,) = data["tables"]
    assert table["commits"] == {"abc1234": 3}
    assert [r["seeds"] for r in table["rows"]] == [[1, 2], [1]]


@pytest.mark.parametrize("arguments, words", [
    (["{missing}"], "database {missing}: no such file"),
    (["{not_loop}"], "not a bench_loop database"),
    (["{database}", "--bounds", "{bad_bounds}"], "line 1: expected a row bench_loop_bound --out writes"),
    (["{database}", "--seeds", "one"], "--seeds: expected seeds like 1-5"),
    (["{database}", "--loops", "1"], "--loops: expected at least 2"),
    (["{database}", "--scenarios", "nosuch"], "--scenarios: 'nosuch'"),
])
def test_bad_input_is_one_line(campaign, tmp_path, capsys, arguments, words):
    database, _ = campaign
    not_loop = tmp_path / "other.sqlite3"
    sqlite3.connect(not_loop).close()
    bad_bounds = tmp_path / "bad.jsonl"
    bad_bounds.write_text("{\"scenario\": 1}\n", encoding="utf-8")
    paths = {"missing": str(tmp_path / "none.sqlite3"), "not_loop": str(not_loop), "database": str(database),
             "bad_bounds": str(bad_bounds)}
    assert loop_table.main([a.format(**paths) for a in arguments]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("loop_table: ") and words.format(**paths) in err


def test_per_world_a_line_per_counted_run(campaign):
    (table,) = _tables(*campaign)
    lines = loop_table.per_world(table)
    assert lines[0].startswith("| world | scenario | jigs | loop 1 | loop 2 | predicted, loop 1 / 2 |")
    assert lines[2:] == ["| 1 | SIMPLE | yes | 1/2 | 2/2 | 0.50 / 0.85 | 0/2 | abc1234 |",
                         "| 1 | SIMPLE | no | 2/2 | 1/2 | 0.90 / 0.90 | 0/2 | abc1234 |",
                         "| 2 | SIMPLE | yes | 2/2 | 1/2 | 0.65 / 0.75 | 1/2 | abc1234 |"]


def test_the_readme_table_a_row_per_scenario_the_same_from_its_json(campaign, tmp_path, capsys):
    database, bounds = campaign
    out = tmp_path / "table.json"
    assert loop_table.main([str(database), "--bounds", str(bounds), "--scenarios", "simple,ballrun", "--seeds",
                            "1-3", "--json", str(out), "--readme"]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].startswith("| scenario | after the first calibration, with jigs | without jigs |")
    # with jigs worlds 1-2 of 1-3 (world 3 not complete), without jigs world 1; the thesis's workflow and the
    # ceiling from the jigs runs' worlds
    brier = _tables(*campaign)[0].rows[0]["brier_forecast"]  # the full table's, checked above
    assert printed[2] == (f"| SIMPLE | 0.75 (3/4) (worlds 1-2) | 0.50 (1/2) (world 1) | 0.25 (1/4) | 1.5 | "
                          f"{brier:.3f} | {61 / 64:.2f} ({0.75 / (61 / 64):.2f}) |")
    assert printed[3] == "| BALLRUN | no complete run yet | - | | | | |"
    # the stored JSON renders the same lines
    (table,) = json.loads(out.read_text(encoding="utf-8"))["tables"]
    assert loop_table.readme(table) == printed


README_TABLE = Path(__file__).resolve().parents[2] / "docs" / "results" / "2026-12-05-loop-table.json"


def test_the_readmes_loop_table_is_the_stored_campaigns():
    """The README's table is rendered from the campaign's stored figures, row for row (it cannot drift from them)."""
    readme = (README_TABLE.parents[2] / "README.md").read_text(encoding="utf-8")
    data = json.loads(README_TABLE.read_text(encoding="utf-8"))
    lines = [line for table in data["tables"] for line in loop_table.readme(table)]
    assert "\n".join(lines) in readme
