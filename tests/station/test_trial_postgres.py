"""The trial log on a real PostgreSQL server (pgserver, started by the tests; never a mock): the same schema and
migrations as SQLite, the same API and commands, several stations at once."""

from __future__ import annotations

import json
import sqlite3
import threading

import pytest

from station.db import DATABASE_VARIABLE, POSTGRES_MIGRATIONS, Database
from station.services.trials import build_trial, layout_values, load_trial_scenario
from station.triallog import TrialStore

from .conftest import log_json, run_cli

pytest.importorskip("psycopg", reason="psycopg (dev dependency) talks to PostgreSQL")


def _trial(name="simple", **outcomes):
    scenario = load_trial_scenario(name)
    return build_trial(scenario, layout_values(scenario, scenario.layout("success")), outcomes)


def _sqlite_columns(path) -> dict[str, list[tuple[str, bool]]]:
    connection = sqlite3.connect(path)
    tables = [r[0] for r in connection.execute("SELECT name FROM sqlite_master WHERE type = 'table' AND name NOT "
                                               "LIKE 'sqlite_%' ORDER BY name")]
    result = {t: [(r[1], bool(r[3] or r[5])) for r in connection.execute(f"PRAGMA table_info({t})")]
              for t in tables}
    connection.close()
    return result


def _postgres_columns(database: Database) -> dict[str, list[tuple[str, bool]]]:
    with database.transaction(write=False) as tx:
        rows = tx.all("SELECT table_name, column_name, is_nullable FROM information_schema.columns "
                      "WHERE table_schema = 'public' AND table_name <> 'station_schema' "
                      "ORDER BY table_name, ordinal_position")
    result: dict[str, list[tuple[str, bool]]] = {}
    for table, column, nullable in rows:
        result.setdefault(table, []).append((column, nullable == "NO"))
    return result


def test_the_same_schema_and_migrations_as_sqlite(pg_url, tmp_path):
    with Database(pg_url) as database:
        with database.transaction(write=False) as tx:
            assert tx.one("SELECT version FROM station_schema") == (len(POSTGRES_MIGRATIONS),)
        postgres = _postgres_columns(database)
    with Database(str(tmp_path / "t.sqlite3")):
        pass
    # the same tables, the same columns in the same order, the same NOT NULLs (SQLite's primary keys count)
    assert postgres == _sqlite_columns(tmp_path / "t.sqlite3")
    assert set(postgres) == {"jobs", "scenarios", "trials", "trial_events", "loop_runs", "loop_loops", "loop_attempts",
                             "optimized_layouts"}
    # opening again applies nothing and keeps the data
    with TrialStore(pg_url) as store:
        trial_id = store.add(_trial(last_stops="yes"))
    with TrialStore(pg_url) as store:
        assert store.get(trial_id)["success"] is True


def test_commands_round_trip_between_sqlite_and_postgresql(pg_url, tmp_path, capsys, monkeypatch):
    # a station on its local file logs two trials and exports them ...
    log_json(capsys, "simple", "success", "--outcome", "last_stops=yes", "--time", "last_stops=2.5", "--who", "ann")
    log_json(capsys, "ballrun", "failure", "--outcome", "ball_hits_plank=no")
    local = tmp_path / "local.json"
    run_cli(capsys, "trial", "export", "--out", str(local))
    # ... the makerspace's shared PostgreSQL database imports them, a station logs there directly
    monkeypatch.setenv(DATABASE_VARIABLE, pg_url)
    code, out, err = run_cli(capsys, "trial", "import", str(local), "--json")
    assert code == 0, err
    assert json.loads(out) == {"added": [1, 2], "duplicates": []}
    third = log_json(capsys, "simple", "failure", "--outcome", "ball_hits_domino=no", "--notes", "on postgres")
    assert third == 3
    shared = tmp_path / "shared.json"
    run_cli(capsys, "trial", "export", "--out", str(shared))
    exported = json.loads(shared.read_text())
    assert exported["trials"][:2] == json.loads(local.read_text())["trials"]
    assert exported["trials"][2]["notes"] == "on postgres"
    assert exported["trials"][2]["outcomes"]["first_topples"] == "not-reached"
    code, out, _ = run_cli(capsys, "trial", "list", "--scenario", "simple", "--json")
    assert [t["id"] for t in json.loads(out)] == [1, 3]
    code, out, _ = run_cli(capsys, "trial", "import", str(local))
    assert "0 trial(s) added" in out and "2 refused: already in the log" in out


def test_two_stations_importing_the_same_file_at_once_add_each_trial_once(pg_url):
    records = [_trial(last_stops="yes") for _ in range(20)]
    results, errors = [], []

    def station():
        try:
            with TrialStore(pg_url) as store:
                results.append(store.import_trials(records))
        except Exception as error:  # noqa: BLE001 - reported below
            errors.append(error)

    threads = [threading.Thread(target=station) for _ in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(30)
    assert not errors
    assert sorted(len(added) for added, _ in results) == [0, 20]
    assert sorted(len(duplicates) for _, duplicates in results) == [0, 20]
    with TrialStore(pg_url) as store:
        assert store.count() == 20
        assert sorted(t["uid"] for t in store.trials()) == sorted(r["uid"] for r in records)


@pytest.mark.parametrize("where", ["sqlite", "postgresql"])
def test_the_loop_store_on_both_databases(where, request, tmp_path):
    # station loop's tables (migration 4): a run found again by its key, a loop kept once, an attempt logged with its
    # trial in one transaction and never twice, the optimized-layout cache
    from station.loopstore import LoopRow, LoopStore, run_key

    url = request.getfixturevalue("pg_url") if where == "postgresql" else str(tmp_path / "t.sqlite3")
    key = run_key({"scenario": "SIMPLE", "world": "sim://world?seed=1"})
    with LoopStore(url) as store:
        run, made = store.run(key, scenario="SIMPLE", content_hash="h", world="sim://world?seed=1", settings={"a": 1})
        assert made and store.run(key, scenario="SIMPLE", content_hash="h", world="w", settings={}) == (run, False)
        assert store.loop(run, 1) is None
        row = LoopRow(1, {"x": [1.0]}, None, None, {"wood.friction": 0.5})
        store.add_loop(run, row)
        store.add_loop(run, LoopRow(1, {"x": [2.0]}, "other", "text", {}))
        assert store.loop(run, 1) == row
        first = store.add_attempt(run, 1, 1, _trial(last_stops="yes"), predicted=0.75, check_rounds=2)
        again = store.add_attempt(run, 1, 1, _trial(ball_hits_domino="no"), predicted=0.1, check_rounds=0)
        assert first == again and (first.success, first.predicted, first.check_rounds) == (True, 0.75, 2)
        assert store.trials.count() == 1 and store.trial(first.trial_id)["success"] is True
        assert [a.attempt for a in store.attempts(run)] == [1] and store.attempts(run, 2) == []
        assert store.cached_layout("k") is None
        store.cache_layout("k", {"x": [3.0]})
        assert store.cached_layout("k") == {"x": [3.0]}


def test_a_transaction_postgresql_aborts_for_another_ones_sake_is_run_again(pg_url):
    # PostgreSQL aborts one of two conflicting transactions (serialization_failure, deadlock_detected) and expects it
    # to be run again: here the server itself aborts the first two attempts to store the trial
    with TrialStore(pg_url) as store:
        store.add(_trial(last_stops="yes"))  # the schema is there
        with store.database.transaction() as tx:
            tx.execute("CREATE SEQUENCE attempts")
            tx.execute("CREATE FUNCTION abort_twice() RETURNS trigger LANGUAGE plpgsql AS $$ BEGIN "
                       "IF nextval('attempts') = 1 THEN RAISE EXCEPTION 'could not serialize access' USING "
                       "ERRCODE = 'serialization_failure'; END IF; IF currval('attempts') = 2 THEN RAISE EXCEPTION "
                       "'deadlock detected' USING ERRCODE = 'deadlock_detected'; END IF; RETURN NEW; END $$")
            tx.execute("CREATE TRIGGER abort_twice BEFORE INSERT ON trials FOR EACH ROW EXECUTE FUNCTION "
                       "abort_twice()")
        waits = []
        record = _trial(ball_hits_domino="no")
        trial_id = store.add(record, on_wait=waits.append)
        assert store.get(trial_id)["uid"] == record["uid"] and store.count() == 2
        assert len(waits) == 1 and "is busy" in waits[0]
        with store.database.transaction(write=False) as tx:
            assert tx.one("SELECT last_value FROM attempts") == (3,)  # two aborted attempts, then the one kept
            # the aborted attempts left nothing: one row per event of the one trial
            assert tx.one("SELECT count(*) FROM trial_events WHERE trial_id = ?", (trial_id,)) == (5,)
