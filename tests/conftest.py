"""Suite-wide fixtures: the station never writes into the real user's folders during tests.

Also helpers shared by test files in different folders (imported as ``from .conftest import ...`` or
``from ..conftest import ...``, as tests/grbl imports its own conftest)."""

from __future__ import annotations

import pytest


@pytest.fixture(autouse=True)
def station_home(tmp_path_factory, monkeypatch):
    home = tmp_path_factory.mktemp("station-home")
    monkeypatch.setenv("CHAOS_STATION_HOME", str(home))
    return home


async def settle(app, pilot):
    """Let a Textual app under test settle: three rounds of a pause and a wait for all its workers, then a pause."""
    for _ in range(3):
        await pilot.pause()
        await app.workers.wait_for_complete()
    await pilot.pause()
