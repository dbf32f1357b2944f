"""The trial log's database: where it is, how it is opened and migrated, and the Python API calibration reads."""

from __future__ import annotations

import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from station.config import load_config
from station.db import DATABASE_VARIABLE, MIGRATIONS, database_url, open_database, statements
from station.db_url import parse_url, redact
from station.errors import ConfigError, ServiceError, StationError
from station.services.trials import build_trial, layout_values, load_trial_scenario
from station.triallog import TrialStore

ROOT = Path(__file__).resolve().parents[3]


def _trial(name="simple", **outcomes):
    scenario = load_trial_scenario(name)
    return build_trial(scenario, layout_values(scenario, scenario.layout("success")), outcomes)


def test_the_database_url_comes_from_the_environment_else_the_config_else_the_data_folder(
        station_home, monkeypatch, tmp_path):
    assert database_url() == f"sqlite:///{station_home / 'station.sqlite3'}"
    config = station_home / "station.toml"
    config.write_text('[[devices]]\nname = "plotter"\nkind = "plotter"\nurl = "sim://grbl?profile=plotter"\n'
                      '[database]\nurl = "trials/shared.sqlite3"\n')
    assert load_config().database == str(station_home / "trials" / "shared.sqlite3")
    assert database_url() == str(station_home / "trials" / "shared.sqlite3")
    monkeypatch.setenv(DATABASE_VARIABLE, "postgresql://ann:secret@db.example:5433/makerspace")
    assert database_url() == "postgresql://ann:secret@db.example:5433/makerspace"
    assert redact(database_url()) == "postgresql://ann:***@db.example:5433/makerspace"
    assert parse_url("postgresql+psycopg://h/db") == ("postgresql", "postgresql://h/db")
    assert parse_url("sqlite:////var/t.sqlite3") == ("sqlite", "/var/t.sqlite3")
    with pytest.raises(StationError, match=r"database URL 'mysql://ann:\*\*\*@h/db': expected postgresql://"):
        parse_url("mysql://ann:pw@h/db")
    config.write_text(config.read_text().replace('url = "trials/', 'uri = "trials/'))
    with pytest.raises(ConfigError, match=r"station.toml: database.uri: unknown field"):
        load_config()


def test_an_unreachable_postgresql_server_is_one_line(monkeypatch):
    with pytest.raises(StationError, match=r"^database 'postgresql://ann:\*\*\*@127.0.0.1:9/x': cannot connect"):
        TrialStore("postgresql://ann:pw@127.0.0.1:9/x")


def test_a_version_2_database_gains_the_trial_log_and_keeps_its_jobs(tmp_path):
    path = tmp_path / "old.sqlite3"
    old = sqlite3.connect(path)
    for number in range(2):
        old.executescript(MIGRATIONS[number])
    old.execute("PRAGMA user_version = 2")
    old.execute("INSERT INTO jobs (kind, device, status) VALUES ('run', 'laser', 'done')")
    old.commit()
    old.close()
    with TrialStore(str(path)) as store:
        trial_id = store.add(_trial(last_stops="yes"))
        assert store.get(trial_id)["success"] is True
    connection = open_database(path)
    assert connection.execute("SELECT kind, device FROM jobs").fetchall() == [("run", "laser")]
    assert connection.execute("PRAGMA user_version").fetchone() == (len(MIGRATIONS),)
    assert connection.execute("PRAGMA journal_mode").fetchone() == ("wal",)
    assert connection.execute("PRAGMA foreign_keys").fetchone() == (1,)
    with pytest.raises(sqlite3.IntegrityError, match="FOREIGN KEY"):
        connection.execute("INSERT INTO trial_events (trial_id, ordinal, event, outcome) VALUES (999, 0, 'a', 'yes')")
    connection.close()


def test_a_migration_is_one_transaction(tmp_path, monkeypatch):
    # a migration that fails half way (as a killed process would stop it) leaves the old version whole
    path = tmp_path / "t.sqlite3"
    open_database(tmp_path / "t.sqlite3").close()
    import station.db as db

    monkeypatch.setattr(db, "MIGRATIONS", [*MIGRATIONS, "CREATE TABLE extra (a INTEGER); CREATE TABLE extra (b);"])
    with pytest.raises(StationError, match="already exists"):
        db.open_database(path)
    connection = sqlite3.connect(path)
    assert connection.execute("PRAGMA user_version").fetchone() == (len(MIGRATIONS),)
    assert connection.execute("SELECT name FROM sqlite_master WHERE name = 'extra'").fetchall() == []
    connection.close()
    assert statements("CREATE TRIGGER t AFTER INSERT ON a BEGIN SELECT 1; SELECT 2; END; DROP TABLE b;") == [
        "CREATE TRIGGER t AFTER INSERT ON a BEGIN SELECT 1; SELECT 2; END;", "DROP TABLE b;"]


def test_processes_opening_a_new_database_at_once_migrate_it_once(tmp_path):
    path = tmp_path / "new.sqlite3"
    code = ("import sys; from station.triallog import TrialStore; "
            f"TrialStore({str(path)!r}).close(); print('ok')")
    processes = [subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, env={"PYTHONPATH": str(ROOT)},
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(4)]
    results = [p.communicate(timeout=60) for p in processes]
    assert [r[0].strip() for r in results] == ["ok"] * 4, [r[1] for r in results]
    connection = sqlite3.connect(path)
    assert connection.execute("PRAGMA user_version").fetchone() == (len(MIGRATIONS),)
    connection.close()


def test_the_python_api_gives_the_export_form_filtered_by_scenario_hash(tmp_path):
    with TrialStore(str(tmp_path / "t.sqlite3")) as store:
        a = store.add(_trial(last_stops="yes"))
        b = store.add(_trial("ballrun", ball_hits_plank="no"))
        c = store.add(_trial(ball_hits_domino="no"))
        simple_hash = load_trial_scenario("simple").content_hash
        trials = store.trials(scenario_hash=simple_hash)
        assert [t["id"] for t in trials] == [a, c]
        assert [t["id"] for t in store.trials()] == [a, b, c]
        assert [t["id"] for t in store.trials(success=False)] == [b, c]
        assert [t["id"] for t in store.trials(limit=2)] == [b, c]
        assert [t["id"] for t in store.trials(scenario="ballrun")] == [b]
        assert set(trials[0]) == {"id", "uid", "scenario", "layout", "as_built", "check", "physics", "outcomes",
                                  "times", "success", "who", "created_at", "notes", "photos"}
        assert store.count() == 3
        with pytest.raises(ServiceError, match="uid: the trial .* is already in the log"):
            store.add(store.get(a))
        with pytest.raises(ServiceError, match="^id: no trial 99"):
            store.get(99)
