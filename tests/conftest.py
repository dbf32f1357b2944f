"""Suite-wide fixtures: the station never writes into the real user's folders during tests.

Also helpers shared by test files in different folders (imported as ``from .conftest import ...`` or
``from ..conftest import ...``, as tests/drivers imports its own conftest)."""

from __future__ import annotations

from contextlib import asynccontextmanager

import pytest

from drivers.grbl import GrblConnection


@pytest.fixture(autouse=True)
def station_home(tmp_path_factory, monkeypatch):
    home = tmp_path_factory.mktemp("station-home")
    monkeypatch.setenv("CHAOS_STATION_HOME", str(home))
    return home


@pytest.fixture
def fresh_twins():
    """No simulated camera or projector shared by name (``sim://...?name=``) before the test, nor left after it."""
    from drivers.sim.camera import forget_cameras
    from drivers.sim.projector import forget_projectors

    forget_cameras()
    forget_projectors()
    yield
    forget_cameras()
    forget_projectors()


async def settle(app, pilot):
    """Let a Textual app under test settle: three rounds of a pause and a wait for all its workers, then a pause."""
    for _ in range(3):
        await pilot.pause()
        await app.workers.wait_for_complete()
    await pilot.pause()


def station_app(tmp_path, *, without: tuple[str, ...] = (), **options):
    """A :class:`station.tui.app.StationApp` with its database in ``tmp_path``; ``without`` leaves those areas out
    (e.g. ``("drawing",)``: an app without the Drawing screen)."""
    from station.tui.app import StationApp
    from station.tui.registry import discover_screens

    if without:
        options["areas"] = [entry for entry in discover_screens() if entry.name not in without]
    return StationApp(database=tmp_path / "t.sqlite3", **options)


@asynccontextmanager
async def opened(tmp_path, key: str | None = None, size: tuple[int, int] = (160, 50), *, wait: bool = True,
                 **options):
    """Run a station app under test (see :func:`station_app`) and press ``key`` on its home screen; yields
    ``(app, pilot)``. ``wait``: :func:`settle` after the key (all workers done), else one pause."""
    app = station_app(tmp_path, **options)
    async with app.run_test(size=size) as pilot:
        if key is not None:
            await pilot.press(key)
            if wait:
                await settle(app, pilot)
            else:
                await pilot.pause()
        yield app, pilot


#: Fast settings for the simulator: motion 50x faster than real time, status at 20 Hz, short watchdogs.
FAST = {"poll_interval": 0.05, "lost_ok_timeout": 0.3, "silence_timeout": 0.6}


@pytest.fixture
def make_connection():
    """Open connections and close them at the end of the test."""
    opened: list[GrblConnection] = []

    def make(url: str, **kwargs) -> GrblConnection:
        options = dict(FAST) if url.startswith("sim://") else {}
        options.update(kwargs)
        conn = GrblConnection(url, **options).open()
        opened.append(conn)
        return conn

    yield make
    for conn in opened:
        conn.close()
