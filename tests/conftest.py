"""Suite-wide fixtures: the station never writes into the real user's folders during tests."""

from __future__ import annotations

import pytest


@pytest.fixture(autouse=True)
def station_home(tmp_path_factory, monkeypatch):
    home = tmp_path_factory.mktemp("station-home")
    monkeypatch.setenv("CHAOS_STATION_HOME", str(home))
    return home
