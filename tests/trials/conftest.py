"""Shared pieces of the trial-log tests: scenario texts, a CLI runner, a real PostgreSQL server."""

from __future__ import annotations

import json
import uuid
from pathlib import Path

import pytest

from station.cli import main

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "scenarios"


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    """``station ARGV`` in this process: (exit code, stdout, stderr)."""
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def log_json(capsys, *argv: str) -> int:
    """``station trial log ARGV --json`` that must succeed; the new trial's id."""
    code, out, err = run_cli(capsys, "trial", "log", *argv, "--json")
    assert code == 0, err
    return json.loads(out)["id"]


@pytest.fixture(scope="module")
def pg_server(tmp_path_factory):
    """One real PostgreSQL server for the module (pgserver: PostgreSQL in a wheel, a dev dependency; ~0.6 s to
    initialize and start). Stopped and deleted at the module's end."""
    pgserver = pytest.importorskip("pgserver", reason="pgserver (dev dependency) runs the PostgreSQL tests")
    import psycopg

    server = pgserver.get_server(tmp_path_factory.mktemp("pg") / "data", cleanup_mode="delete")
    # a throw-away server: no fsync (CREATE DATABASE and the shutdown checkpoint took seconds of disk flushes)
    with psycopg.connect(server.get_uri(), autocommit=True) as admin:
        for setting in ("fsync = off", "synchronous_commit = off", "full_page_writes = off"):
            admin.execute(f"ALTER SYSTEM SET {setting}")
        admin.execute("SELECT pg_reload_conf()")
    yield server
    server.cleanup()


@pytest.fixture
def pg_url(pg_server):
    """A new, empty database on the module's server, as a postgresql:// URL."""
    import psycopg

    name = f"t_{uuid.uuid4().hex[:12]}"
    with psycopg.connect(pg_server.get_uri(), autocommit=True) as admin:
        admin.execute(f"CREATE DATABASE {name}")
    return pg_server.get_uri(database=name)
