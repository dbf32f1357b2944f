"""Fixtures of the GRBL suite: the machine under test is the simulator, or a real controller whose port URL is in
CHAOS_STATION_GRBL_PORT (those runs are skipped when it is unset)."""

from __future__ import annotations

import os
import time

import pytest

REAL_PORT = os.environ.get("CHAOS_STATION_GRBL_PORT", "")


def sim_url(profile: str = "laser", **query) -> str:
    query.setdefault("time_scale", 0.02)
    return f"sim://grbl?profile={profile}&" + "&".join(f"{k}={v}" for k, v in query.items())


def start_until_acked(runner, lines: int, timeout: float = 10.0) -> None:
    """Start ``runner``'s job in its thread and return once the machine confirmed ``lines`` of it with ``ok`` (or
    after ``timeout`` s): the machine is then in the middle of the job."""
    runner.start()
    deadline = time.monotonic() + timeout
    while runner.progress.lines_acked < lines and time.monotonic() < deadline:
        time.sleep(0.01)


@pytest.fixture(params=["sim", "real"])
def machine_url(request) -> str:
    """The same tests against the simulated GRBL and, when CHAOS_STATION_GRBL_PORT is set, a real one."""
    if request.param == "real":
        if not REAL_PORT:
            pytest.skip("set CHAOS_STATION_GRBL_PORT to a GRBL 1.1 port URL to run against a real machine")
        return REAL_PORT
    return sim_url("laser")
