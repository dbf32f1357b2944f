"""Talking to ``station serve`` as a browser does, for the serve tests: the server in a subprocess, a client that
loads the page and opens the session's websocket as textual.js does, and a headless Chromium driven over its
DevTools protocol.

textual.js (textual-serve's page script) opens ``<data-session-websocket-url>?width=W&height=H``, then sends JSON
messages: ``["resize", {"width": W, "height": H}]`` once open, ``["stdin", KEYS]`` for what is typed (xterm.js's
bytes: ``"\\x18"`` is ctrl+x), ``["ping", T]``; the server answers with binary frames, the app's terminal output.
"""

from __future__ import annotations

import asyncio
import base64
import json
import os
import re
import shutil
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import NamedTuple

import aiohttp
import pyte

ROOT = Path(__file__).resolve().parents[2]

#: Escape sequences in the terminal output (CSI with its parameters, OSC, charset and keypad selections).
ESCAPES = re.compile(rb"\x1b\[[0-9;?<>=]*[ -/]*[@-~]|\x1b\][^\x07\x1b]*(?:\x07|\x1b\\)|\x1b[()][A-Z0-9]|\x1b[=>78]")


def terminal_text(output: bytes) -> str:
    """The characters a terminal stream writes, without its escape sequences (cursor moves, colours)."""
    return ESCAPES.sub(b"", output).decode("utf-8", "replace")


def free_port(host: str = "127.0.0.1") -> int:
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET) as probe:
        probe.bind((host, 0))
        return probe.getsockname()[1]


class ServedStation:
    """``station serve`` in a subprocess on ``host``, a free port, and the data folder ``home``.

    ``lines`` collects what it prints (stdout and stderr); :attr:`url` is the first URL it prints.
    """

    def __init__(self, home: Path, host: str = "127.0.0.1", *, extra: tuple[str, ...] = ()) -> None:
        self.home, self.host, self.port = home, host, free_port(host)
        env = dict(os.environ, CHAOS_STATION_HOME=str(home), PYTHONPATH=str(ROOT), PYTHONUNBUFFERED="1")
        self.process = subprocess.Popen(
            [sys.executable, "-m", "station", "serve", "--host", host, "--port", str(self.port), *extra],
            cwd=ROOT, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
            text=True, bufsize=1)
        self.lines: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        self.url = self.wait_for_line("station serve: open ").split("open ", 1)[1].strip()

    def _read(self) -> None:
        for line in self.process.stdout:
            self.lines.append(line.rstrip("\n"))

    def wait_for_line(self, start: str, timeout: float = 30.0) -> str:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for line in list(self.lines):
                if line.startswith(start):
                    return line
            if self.process.poll() is not None and not self._reader.is_alive():
                break
            time.sleep(0.05)
        raise AssertionError(f"station serve never printed {start!r}; it printed:\n" + "\n".join(self.lines))

    def stop(self) -> int:
        """SIGTERM (as Ctrl+C would); the exit code."""
        if self.process.poll() is None:
            self.process.terminate()
        try:
            code = self.process.wait(timeout=40)
        except subprocess.TimeoutExpired:
            self.process.kill()
            code = self.process.wait()
        self._reader.join(timeout=5)
        return code

    def __enter__(self) -> ServedStation:
        return self

    def __exit__(self, *exc) -> None:
        self.stop()


class BrowserSession:
    """A page and its websocket session, as textual.js opens them (with the page's cookies and ``Origin``).

    The session's output is played on a terminal emulator (pyte) the size xterm.js said, so that :meth:`screen`
    is what the browser shows now (Textual redraws changed regions: the raw stream repeats old text).
    """

    def __init__(self, client: aiohttp.ClientSession, url: str, size: tuple[int, int] = (120, 40)) -> None:
        self.client, self.url, self.size = client, url, size
        self.terminal = pyte.Screen(*size)
        self.stream = pyte.ByteStream(self.terminal)
        self.websocket: aiohttp.ClientWebSocketResponse | None = None

    async def open(self) -> str:
        """Load the page and what it loads, open the session; the page's HTML."""
        async with self.client.get(self.url) as response:
            assert response.status == 200, f"GET {self.url}: {response.status}"
            page = await response.text()
        script = re.search(r'<script src="([^"]+)"', page).group(1)
        async with self.client.get(script) as response:
            assert response.status == 200, f"GET {script}: {response.status}"
        socket_url = re.search(r'data-session-websocket-url="([^"]+)"', page).group(1)
        width, height = self.size
        origin = re.match(r"https?://[^/]+", self.url).group(0)
        self.websocket = await self.client.ws_connect(f"{socket_url}?width={width}&height={height}",
                                                      headers={"Origin": origin})
        await self.websocket.send_json(["resize", {"width": width, "height": height}])
        return page

    def screen(self) -> str:
        """What the browser's terminal shows now, one line per row."""
        return "\n".join(line.rstrip() for line in self.terminal.display)

    async def key(self, keys: str) -> None:
        await self.websocket.send_json(["stdin", keys])

    async def until(self, *needles: str, more_than: dict[str, int] | None = None, gone: tuple[str, ...] = (),
                    timeout: float = 30.0) -> str:
        """Read the session until the screen shows every one of ``needles`` (more times than ``more_than`` says,
        when given) and none of ``gone``; the screen then."""
        more_than = more_than or {}
        deadline = time.monotonic() + timeout
        while True:
            shown = self.screen()
            if all(shown.count(needle) > more_than.get(needle, 0) for needle in needles) and not any(
                    text in shown for text in gone):
                return shown
            try:
                message = await self.websocket.receive(timeout=max(deadline - time.monotonic(), 0.01))
            except asyncio.TimeoutError:
                raise AssertionError(f"no {needles} on the screen within {timeout} s:\n{shown}") from None
            if message.type == aiohttp.WSMsgType.BINARY:
                self.stream.feed(message.data)
            elif message.type in (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED, aiohttp.WSMsgType.CLOSING):
                raise AssertionError(f"the session closed before showing {needles}:\n{shown}")

    async def press(self, keys: str, *needles: str, timeout: float = 30.0) -> str:
        """Send ``keys`` and wait until the screen shows each of ``needles`` once more than it did before."""
        before = self.screen()
        await self.key(keys)
        return await self.until(*needles, more_than={n: before.count(n) for n in needles}, timeout=timeout)

    async def closed(self, timeout: float = 40.0) -> bool:
        """Wait until the server closes the session (the app exited)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            message = await self.websocket.receive(timeout=max(deadline - time.monotonic(), 0.01))
            if message.type == aiohttp.WSMsgType.BINARY:
                self.stream.feed(message.data)
            elif message.type in (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED, aiohttp.WSMsgType.CLOSING):
                return True
        return False


def chromium() -> str | None:
    """The Chromium (or Chrome) on this machine, or None."""
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        found = shutil.which(name)
        if found:
            return found
    return None


class BrowserShot(NamedTuple):
    """What headless Chromium saw of a page (:func:`chromium_screenshot`)."""

    png: bytes
    #: The session's text so far.
    text: str
    #: Every URL the page made the browser request (the page, its assets, the websocket), in order.
    requested: list[str]
    #: The page's web fonts: (family, style, status) of each ``FontFace`` (status "loaded" once fetched and used).
    fonts: list[tuple[str, str, str]]


async def chromium_screenshot(url: str, needle: str, profile: Path, *, size: tuple[int, int] = (1280, 800),
                              timeout: float = 45.0) -> BrowserShot:
    """Open ``url`` in headless Chromium, wait until its session's websocket has brought ``needle`` (read from the
    frames Chromium itself received, over the DevTools protocol) and the page shows the terminal; the screenshot
    (PNG), the session's text so far, what the page requested and its fonts.

    ``chromium --headless --screenshot URL`` alone takes its picture at the page's load event, before the session
    has sent anything (it shows textual-serve's start dialog): the DevTools protocol lets the test wait for it.
    """
    browser = subprocess.Popen(
        [chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", "--no-first-run",
         "--remote-debugging-port=0", f"--user-data-dir={profile}", f"--window-size={size[0]},{size[1]}",
         "about:blank"],
        stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        endpoint = _devtools_endpoint(browser, timeout=20.0)
        async with aiohttp.ClientSession() as client:
            async with client.get(f"http://{endpoint}/json/list") as response:
                targets = await response.json(content_type=None)
            page_socket = next(t["webSocketDebuggerUrl"] for t in targets if t.get("type") == "page")
            async with client.ws_connect(page_socket, max_msg_size=0) as devtools:
                return await _load_and_shoot(devtools, url, needle, timeout)
    finally:
        browser.terminate()
        try:
            browser.wait(timeout=10)
        except subprocess.TimeoutExpired:
            browser.kill()
            browser.wait()


def _devtools_endpoint(browser: subprocess.Popen, timeout: float) -> str:
    found: list[str] = []

    def read() -> None:
        for line in browser.stderr:
            match = re.search(r"DevTools listening on ws://([^/]+)/", line)
            if match:
                found.append(match.group(1))
                return

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    reader.join(timeout)
    if not found:
        raise AssertionError("chromium did not start its DevTools endpoint")
    threading.Thread(target=lambda: [None for _ in browser.stderr], daemon=True).start()  # keep its pipe drained
    return found[0]


async def _load_and_shoot(devtools, url: str, needle: str, timeout: float) -> BrowserShot:
    ids = iter(range(1, 1_000_000))
    answers: dict[int, dict] = {}
    frames: list[bytes] = []
    requested: list[str] = []

    async def call(method: str, **params) -> dict:
        number = next(ids)
        await devtools.send_str(json.dumps({"id": number, "method": method, "params": params}))
        while number not in answers:
            await receive()
        return answers.pop(number)

    async def receive() -> None:
        message = json.loads((await devtools.receive(timeout=timeout)).data)
        if "id" in message:
            answers[message["id"]] = message.get("result", message)
        elif message.get("method") in ("Network.requestWillBeSent", "Network.webSocketCreated"):
            requested.append(message["params"].get("request", message["params"]).get("url", ""))
        elif message.get("method") == "Network.webSocketFrameReceived":
            frame = message["params"]["response"]
            if frame.get("opcode") == 2:
                frames.append(base64.b64decode(frame["payloadData"]))

    await call("Network.enable")
    await call("Page.enable")
    await call("Page.navigate", url=url)
    deadline = time.monotonic() + timeout
    while needle not in terminal_text(b"".join(frames)):
        if time.monotonic() > deadline:
            raise AssertionError(f"chromium's session never showed {needle!r}:\n{terminal_text(b''.join(frames))}")
        await receive()
    # the page draws what has arrived on its next frames; wait until it has shown the terminal
    while True:
        state = await call("Runtime.evaluate", expression="document.body.className", returnByValue=True)
        if "-first-byte" in state["result"].get("value", ""):
            break
        if time.monotonic() > deadline:
            raise AssertionError(f"chromium's page never showed the terminal: body class {state}")
        await asyncio.sleep(0.1)
    await asyncio.sleep(1.0)  # the opacity transition (0.3 s) and the app's last frames
    shot = await call("Page.captureScreenshot", format="png")
    fonts = await call("Runtime.evaluate", returnByValue=True,
                       expression="[...document.fonts].map(f => [f.family.replace(/[\"']/g, ''), f.style, f.status])")
    return BrowserShot(base64.b64decode(shot["data"]), terminal_text(b"".join(frames)), requested,
                       [tuple(face) for face in fonts["result"].get("value", [])])
