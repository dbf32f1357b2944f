"""``station serve`` as a browser meets it: the server in a subprocess, the page, its websocket session, the token,
and a real headless Chromium (when installed)."""

from __future__ import annotations

import json
import os
import shutil
import ssl
import stat
import subprocess
import sys
from urllib.parse import urlsplit

import aiohttp
import numpy as np
import pytest
from PIL import Image

from station.serve import TOKEN_COOKIE, TOKEN_FILE

from .serve_client import ROOT, BrowserSession, ServedStation, chromium, chromium_screenshot

HOME_TEXT = ("Areas", "Recent machine jobs", "Database: ")


def jobs(home) -> list[dict]:
    """``station jobs --json`` on the data folder ``home`` (a separate process: what the served session recorded)."""
    done = subprocess.run([sys.executable, "-m", "station", "jobs", "--json"], cwd=ROOT, capture_output=True,
                          text=True, env=dict(os.environ, CHAOS_STATION_HOME=str(home), PYTHONPATH=str(ROOT)),
                          check=True)
    return json.loads(done.stdout)["jobs"]


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    """One local server for the module's browser sessions (each session is an app process of its own); stopping
    it (SIGTERM) ends it cleanly."""
    station = ServedStation(tmp_path_factory.mktemp("served") / "home")
    yield station
    assert station.stop() in (0, 130), station.lines


def newest_laser_job(home) -> dict:
    return next(job for job in jobs(home) if job["device"] == "laser")


IDLE_ABORT = "abort: soft reset sent (no job was running)"


async def start_laser_job(session: BrowserSession, *, abort_keys: bool = False) -> None:
    """From the home screen: the Machines screen, the laser, the current design queued as a laser job, started.

    ``abort_keys``: first, on the idle plotter, abort with ctrl+x and with a tap on the footer's "^x Abort".
    """
    await session.press("m", "Abort", "plotter: GRBL")  # the simulated plotter, connected on arrival
    if abort_keys:
        # each abort says so under the queue and adds a console line: 2 lines, then one more (the same message)
        await session.key("\x18")  # ctrl+x, as xterm.js sends it
        await session.until(IDLE_ABORT, more_than={IDLE_ABORT: 1})
        # a tablet has no ctrl key: a tap on the footer's first key (^x Abort, bottom-left), xterm.js's SGR click
        height = session.size[1]
        await session.key(f"\x1b[<0;2;{height}M\x1b[<0;2;{height}m")
        await session.until(IDLE_ABORT, more_than={IDLE_ABORT: 2})
    await session.press("v", "laser (laser")
    await session.press("n", "queued")
    await session.until("laser: GRBL")  # connected to the simulated laser (g says "not connected" before)
    await session.press("g", "running")


async def test_a_browser_session_is_the_terminals_station_and_a_browser_gone_aborts_its_job(served):
    async with aiohttp.ClientSession() as client:
        session = BrowserSession(client, served.url)
        page = await session.open()
        assert "Crafting Chaos station" in page
        text = await session.until(*HOME_TEXT)
        # the session's app opened the server's data folder
        assert f"Database: {served.home / 'station.sqlite3'}" in text.replace("\n", "")
        await start_laser_job(session, abort_keys=True)
        # ctrl+q: the terminal's question, in the browser ('a' aborts and quits there as in the terminal:
        # tests/station/tui/test_machines.py); k keeps the job running
        await session.press("\x11", "Quitting now aborts it", "the laser is switched off", "Abort and quit (a)")
        await session.key("k")
        await session.until("running", gone=("Quitting now aborts it",))
        # then the tablet's tab is closed (or its Wi-Fi lost) while the laser runs: no one to ask, so the job is
        # aborted as 'abort and quit' does, and recorded as aborted (not cut off: 'interrupted')
        await session.websocket.close()
    started = [line for line in served.lines if line.endswith("started")][-1]
    served.wait_for_line(started.replace("started", "ended"), timeout=40)
    job = newest_laser_job(served.home)
    assert job["status"] == "aborted" and "laser off" in job["message"], job
    assert jobs(served.home).index(job) == 0


async def test_on_another_address_every_request_needs_the_token(tmp_path):
    home = tmp_path / "home"
    with ServedStation(home, "127.0.0.2") as station:
        token_file = home / TOKEN_FILE
        token = token_file.read_text().strip()
        assert stat.S_IMODE(token_file.stat().st_mode) == 0o600
        assert station.url == f"http://127.0.0.2:{station.port}/?token={token}"
        base = f"http://127.0.0.2:{station.port}"
        # unsafe: aiohttp keeps no cookie from an IP address unless told to (browsers do)
        async with aiohttp.ClientSession(cookie_jar=aiohttp.CookieJar(unsafe=True)) as client:
            for path in ("/", "/static/js/textual.js", "/ws", "/?token=" + "x" * len(token), "/download/x"):
                async with client.get(base + path) as response:
                    assert response.status == 403, path
                    body = await response.text()
                    assert "textual" not in body.lower() and "Crafting" not in body, body
            async with client.get(f"{base}/?token={token}") as response:
                assert response.status == 200
                assert "Crafting Chaos station" in await response.text()
                assert response.cookies[TOKEN_COOKIE]["httponly"]
            # the page's own requests carry the cookie: its websocket session shows the home screen
            session = BrowserSession(client, station.url)
            await session.open()
            await session.until(*HOME_TEXT)
            # one session at a time (each would open the machines' ports): a second browser is told, and closed
            second = BrowserSession(client, station.url)
            await second.open()
            await second.until("The station is open in another browser (from 127.0.0.1, since")
            assert await second.closed(timeout=10)
            await session.websocket.close()
    printed = "\n".join(station.lines)
    assert printed.count(token) == 1, printed  # printed once, never in the log of refused requests
    assert printed.count("refused GET") >= 4


@pytest.mark.skipif(chromium() is None, reason="no chromium on this machine (apt-get install chromium)")
async def test_headless_chromium_shows_the_home_screen(served, tmp_path):
    png, text, requested, fonts = await chromium_screenshot(served.url, "Recent machine jobs", tmp_path / "profile")
    assert all(needle in text for needle in HOME_TEXT), text
    # everything the browser fetched came from the station (a makerspace network may have no internet), and the
    # terminal's font is the station's Roboto Mono, loaded, not a fallback
    station = urlsplit(served.url).netloc
    assert requested and all(urlsplit(address).netloc == station for address in requested), requested
    assert ("Roboto Mono", "normal", "loaded") in fonts, fonts
    path = tmp_path / "home.png"
    path.write_bytes(png)
    if os.environ.get("STATION_SERVE_SCREENSHOT"):  # how docs/station-serve-home.png is made
        Image.open(path).save(os.environ["STATION_SERVE_SCREENSHOT"], optimize=True)
    picture = np.asarray(Image.open(path).convert("RGB")).astype(int)
    # the terminal filled the window (not textual-serve's start dialog on its dotted background): the top rows left
    # of the title are the Textual header, one colour; the start dialog's background there is #0c181f
    header = picture[3:14, 40:380].reshape(-1, 3)
    assert np.ptp(header, axis=0).max() <= 8, "the header rows are not one colour"
    assert np.abs(header.mean(axis=0) - (0x0C, 0x18, 0x1F)).max() > 6, "the page still shows its start dialog"
    # and it has text on it: the home screen's lines are lighter than their background
    body = picture[80:400, 20:600]
    assert (body.max(axis=2) > 150).mean() > 0.01


@pytest.mark.slow  # the same abort as a browser gone (the server tells each session's app to quit), one more app
async def test_stopping_the_server_aborts_a_running_job_and_leaves_no_process(tmp_path):
    station = ServedStation(tmp_path / "home")
    try:
        async with aiohttp.ClientSession() as client:
            session = BrowserSession(client, station.url)
            await session.open()
            await session.until(*HOME_TEXT)
            await start_laser_job(session)
            children = subprocess.run(["pgrep", "-P", str(station.process.pid)], capture_output=True,
                                      text=True).stdout.split()
            assert children, "no session process"
            assert station.stop() == 0  # SIGTERM, as kill or a service manager sends it
    finally:
        station.stop()
    assert not [pid for pid in children if os.path.exists(f"/proc/{pid}")], "a session outlived its server"
    job = newest_laser_job(station.home)
    assert job["status"] in ("aborted", "refused") and "reset" in job["message"], job


@pytest.mark.skipif(shutil.which("openssl") is None, reason="no openssl to make a test certificate")
async def test_with_a_certificate_the_token_travels_encrypted(tmp_path):
    cert, key = tmp_path / "station.pem", tmp_path / "station.key"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", str(key), "-out",
                    str(cert), "-days", "2", "-subj", "/CN=127.0.0.2", "-addext", "subjectAltName=IP:127.0.0.2"],
                   check=True, capture_output=True)
    home = tmp_path / "home"
    with ServedStation(home, "127.0.0.2", extra=("--cert", str(cert), "--key", str(key))) as station:
        token = (home / TOKEN_FILE).read_text().strip()
        assert station.url == f"https://127.0.0.2:{station.port}/?token={token}"
        trusted = ssl.create_default_context(cafile=str(cert))
        async with aiohttp.ClientSession(cookie_jar=aiohttp.CookieJar(unsafe=True)) as client:
            async with client.get(f"https://127.0.0.2:{station.port}/", ssl=trusted) as response:
                assert response.status == 403
            async with client.get(station.url, ssl=trusted) as response:
                assert response.status == 200
                assert f'data-session-websocket-url="wss://127.0.0.2:{station.port}/ws"' in await response.text()
                assert response.cookies[TOKEN_COOKIE]["secure"]
            with pytest.raises(aiohttp.ClientError):  # no plain HTTP on that port
                async with client.get(f"http://127.0.0.2:{station.port}/?token={token}") as response:
                    await response.read()
