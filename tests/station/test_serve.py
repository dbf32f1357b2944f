"""``station serve`` in process: the token and its file, the guard in front of every route (aiohttp's test server),
the served command, and the keys a browser sends (the served app is the terminal's, key for key)."""

from __future__ import annotations

import importlib
import os
import pkgutil
import re
import shlex
import stat
import sys
from html.parser import HTMLParser
from urllib.parse import urljoin, urlsplit

import pytest
from aiohttp import ClientSession, WSServerHandshakeError
from aiohttp.test_utils import TestServer
from textual._xterm_parser import XTermParser
from textual.events import Key

from station.serve import (
    TOKEN_COOKIE,
    TOKEN_FILE,
    app_command,
    load_or_create_token,
    needs_token,
    origin_matches,
    token_matches,
    url,
)
from station.serve_http import StationServer

from ..conftest import opened

TOKEN = "t" * 43


@pytest.mark.parametrize(("host", "needed"), [
    ("127.0.0.1", False), ("::1", False), ("[::1]", False),
    ("127.0.0.2", True), ("0.0.0.0", True), ("::", True), ("localhost", True), ("192.168.1.5", True),
])
def test_only_127_0_0_1_and_ipv6_loopback_are_served_without_a_token(host, needed):
    assert needs_token(host) is needed


def test_the_token_is_kept_owner_only_reused_and_renewed(tmp_path):
    old_umask = os.umask(0)  # the widest umask: the file must still be 0600
    try:
        token, why = load_or_create_token(tmp_path)
    finally:
        os.umask(old_umask)
    path = tmp_path / TOKEN_FILE
    assert why == "first use" and len(token) >= 43
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert path.read_text().strip() == token
    assert load_or_create_token(tmp_path) == (token, "")  # a tablet's bookmark keeps working
    renewed, why = load_or_create_token(tmp_path, renew=True)
    assert renewed != token and why == "asked for a new one"
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert not [p for p in tmp_path.iterdir() if p.name != TOKEN_FILE]  # no temporary file left


def test_a_token_others_could_read_or_a_broken_file_is_replaced(tmp_path):
    token, _ = load_or_create_token(tmp_path)
    path = tmp_path / TOKEN_FILE
    path.chmod(0o644)
    again, why = load_or_create_token(tmp_path)
    assert again != token and "could be read by other users (mode 0644)" in why
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    path.write_text("short\n")
    path.chmod(0o600)
    third, why = load_or_create_token(tmp_path)
    assert third not in (again, "short") and "did not hold a token" in why


def test_tokens_differ_between_stations(tmp_path):
    for name in "ab":
        (tmp_path / name).mkdir()
    assert load_or_create_token(tmp_path / "a")[0] != load_or_create_token(tmp_path / "b")[0]


def test_token_comparison():
    assert token_matches(TOKEN, TOKEN)
    for wrong in (None, "", TOKEN[:-1], TOKEN + "t", "u" + TOKEN[1:], "é" * 43):
        assert not token_matches(wrong, TOKEN)


def test_websocket_origin_must_be_the_page():
    assert origin_matches("http://127.0.0.1:8000", "127.0.0.1:8000")
    assert origin_matches(None, "127.0.0.1:8000")  # not a browser
    assert not origin_matches("http://evil.example", "127.0.0.1:8000")
    assert not origin_matches("http://127.0.0.1:8001", "127.0.0.1:8000")


def test_printed_url():
    assert url("127.0.0.1", 8000, None) == "http://127.0.0.1:8000/"
    assert url("::1", 8000, None) == "http://[::1]:8000/"
    assert url("127.0.0.2", 8080, TOKEN) == f"http://127.0.0.2:8080/?token={TOKEN}"
    everywhere = url("0.0.0.0", 8000, TOKEN)
    assert everywhere.endswith(f":8000/?token={TOKEN}") and "0.0.0.0" not in everywhere  # no address to open


def test_the_served_command_is_this_python_running_station(monkeypatch):
    words = shlex.split(app_command())
    assert words[-3:] == [sys.executable, "-m", "station"]
    assert words[0].startswith("PYTHONPATH=")
    # `station` without a command is what the session runs: the terminal's StationApp, on the configured devices
    from station import cli
    from station.tui.app import StationApp

    ran = []
    monkeypatch.setattr(StationApp, "run", lambda self, **kw: ran.append(self))
    assert cli.main([]) == 0
    assert [type(app) for app in ran] == [StationApp]
    ran[0].database.close()


# ---------------------------------------------------------------------------------------------------- the guard

class Served:
    """A :class:`StationServer` on aiohttp's test server (no session is opened: its command is never run)."""

    def __init__(self, token):
        self.server = StationServer("false", "127.0.0.1", 0, token, say=lambda line: None)

    async def __aenter__(self):
        self.test_server = TestServer(await self.server._make_app())
        await self.test_server.start_server()
        self.base = f"http://127.0.0.1:{self.test_server.port}"
        return self

    async def __aexit__(self, *exc):
        await self.test_server.close()


ROUTES = ("/", "/static/js/textual.js", "/static/css/xterm.css", "/static/", "/ws", "/download/abc", "/nothing")


async def test_without_the_token_nothing_of_the_app_is_served(caplog):
    async with Served(TOKEN) as served, ClientSession() as client:
        for path in ROUTES:
            for query in ("", "?token=", f"?token={TOKEN[:-1]}", f"?token={TOKEN}x"):
                async with client.get(served.base + path + query) as response:
                    assert response.status == 403, path + query
                    body = await response.text()
                    assert "textual" not in body.lower() and "<" not in body
        async with client.get(served.base + "/", cookies={TOKEN_COOKIE: "wrong"}) as response:
            assert response.status == 403
        with pytest.raises(WSServerHandshakeError) as refused:
            await client.ws_connect(served.base + "/ws")
        assert refused.value.status == 403
    assert TOKEN not in caplog.text  # refusals are logged, the token never


async def test_the_token_opens_the_page_and_its_cookie_the_rest():
    async with Served(TOKEN) as served, ClientSession() as client:
        async with client.get(f"{served.base}/?token={TOKEN}", headers={"Host": "192.168.1.5:8000"}) as response:
            assert response.status == 200
            page = await response.text()
            cookie = response.cookies[TOKEN_COOKIE]
            assert cookie.value == TOKEN and cookie["httponly"] and cookie["samesite"] == "Strict"
            assert response.headers["Referrer-Policy"] == "no-referrer"
            assert response.headers["X-Frame-Options"] == "DENY"
        # the page's URLs are the address the tablet used, not the bound one
        assert 'data-session-websocket-url="ws://192.168.1.5:8000/ws"' in page
        assert 'src="http://192.168.1.5:8000/static/js/textual.js"' in page
        for path in ROUTES[1:3]:
            async with client.get(served.base + path, cookies={TOKEN_COOKIE: TOKEN}) as response:
                assert response.status == 200, path
        # another site's page cannot open the session, even where the browser would send the cookie
        with pytest.raises(WSServerHandshakeError) as refused:
            await client.ws_connect(f"{served.base}/ws?token={TOKEN}", headers={"Origin": "http://evil.example"})
        assert refused.value.status == 403


@pytest.mark.parametrize(("host", "status"), [
    ("127.0.0.1:8000", 200), ("localhost:8000", 200), ("[::1]:8000", 200), ("LOCALHOST", 200),
    ("evil.example:8000", 403), ("127.0.0.2:8000", 403), ("192.168.1.5", 403),
])
async def test_a_local_station_answers_only_to_loopback_names(host, status):
    # a page that rebinds its own name to 127.0.0.1 still says its name in Host: it gets nothing
    async with Served(None) as served, ClientSession() as client:
        for path in ROUTES[:2]:
            async with client.get(served.base + path, headers={"Host": host}) as response:
                assert response.status == status, (host, path)


async def test_a_local_station_refuses_a_websocket_from_another_sites_page():
    async with Served(None) as served, ClientSession() as client:
        with pytest.raises(WSServerHandshakeError) as refused:
            await client.ws_connect(served.base + "/ws", headers={"Origin": "http://evil.example"})
        assert refused.value.status == 403


# ---------------------------------------------------------------------------------------------------- the page

#: What a style sheet makes the browser fetch: ``url(...)`` and ``@import "..."``.
CSS_REFERENCES = re.compile(r"""url\(\s*['"]?([^'")\s]+)|@import\s+(?:url\()?['"]([^'"]+)""")

#: An absolute URL written out in a script or a page (a script can fetch what it names).
ABSOLUTE_URL = re.compile(r"""\b(?:https?|wss?)://[^\s'"`<>)]*""", re.IGNORECASE)


class PageReferences(HTMLParser):
    """The URLs a page makes a browser load: ``href``/``src`` attributes, ``data-*`` attributes that hold a URL (the
    session's websocket, textual-serve's ping), and what its ``<style>`` blocks and ``style=`` attributes name."""

    def __init__(self) -> None:
        super().__init__()
        self.found: list[str] = []
        self._in_style = False

    def handle_starttag(self, tag, attrs):
        self._in_style = tag == "style"
        for name, value in attrs:
            if not value:
                continue
            if name in ("href", "src") or (name.startswith("data-") and name.endswith("url")):
                self.found.append(value)
            elif name == "style":
                self.found.extend(css_references(value))

    def handle_endtag(self, tag):
        self._in_style = False

    def handle_data(self, data):
        if self._in_style:
            self.found.extend(css_references(data))


def css_references(text: str) -> list[str]:
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.DOTALL)  # a licence's URLs in a comment are never fetched
    return [a or b for a, b in CSS_REFERENCES.findall(text)]


async def test_the_page_and_every_asset_it_names_come_from_the_station():
    # A station on a makerspace network without internet: the page, its script, styles, images and the terminal's
    # font all come from the station itself, and nothing the page or its script names points off the machine.
    async with Served(TOKEN) as served, ClientSession() as client:
        station = urlsplit(served.base).netloc
        async with client.get(f"{served.base}/?token={TOKEN}") as response:
            assert response.status == 200
            page = await response.text()
        parser = PageReferences()
        parser.feed(page)
        queue = [urljoin(served.base + "/", found) for found in parser.found]
        queue += ABSOLUTE_URL.findall(page)
        fetched: dict[str, bytes] = {}
        while queue:
            address = queue.pop()
            assert urlsplit(address).netloc == station, f"the page loads {address} from off the station"
            if address in fetched or urlsplit(address).scheme in ("ws", "wss"):  # the session: tested elsewhere
                continue
            async with client.get(address, cookies={TOKEN_COOKIE: TOKEN}) as response:
                assert response.status == 200, address
                fetched[address] = body = await response.read()
                kind = response.content_type
            if kind == "text/css":
                queue += [urljoin(address, found) for found in css_references(body.decode())]
            elif "javascript" in kind:
                queue += ABSOLUTE_URL.findall(body.decode())
    paths = {urlsplit(address).path for address in fetched}
    assert {"/static/js/textual.js", "/static/css/xterm.css"} <= paths
    # textual.js draws the terminal in 'Roboto Mono': the page gets it from the station, and it is a TrueType font
    fonts = [body for address, body in fetched.items() if "RobotoMono" in address]
    assert fonts and all(body[:4] == b"\x00\x01\x00\x00" for body in fonts), sorted(paths)


# ---------------------------------------------------------------------------------------------------- the keys

#: What xterm.js sends for a key (textual.js passes it on as a ["stdin", ...] message).
XTERM_SEQUENCES = {
    "escape": "\x1b", "enter": "\r", "tab": "\t", "shift+tab": "\x1b[Z", "space": " ", "backspace": "\x7f",
    "delete": "\x1b[3~",
    "up": "\x1b[A", "down": "\x1b[B", "right": "\x1b[C", "left": "\x1b[D", "home": "\x1b[H", "end": "\x1b[F",
    "pageup": "\x1b[5~", "pagedown": "\x1b[6~",
    "colon": ":", "left_square_bracket": "[", "right_square_bracket": "]", "plus": "+", "minus": "-",
    "equals_sign": "=", "full_stop": ".", "comma": ",", "slash": "/", "question_mark": "?",
}

#: Keys a browser keeps for itself (no page can have them): a binding on one of these never fires in a browser.
BROWSER_KEYS = {"ctrl+w", "ctrl+t", "ctrl+n", "ctrl+tab", "ctrl+shift+tab", "ctrl+shift+w", "ctrl+shift+t",
                "ctrl+shift+n", "f11", "f12", "ctrl+pageup", "ctrl+pagedown"}


#: xterm's codes for a key with modifiers: ``ESC [ 1 ; M letter`` (arrows, home, end), ``ESC [ n ; M ~`` (pages).
MODIFIED = {"up": "1;{}A", "down": "1;{}B", "right": "1;{}C", "left": "1;{}D", "home": "1;{}H", "end": "1;{}F",
            "pageup": "5;{}~", "pagedown": "6;{}~", "delete": "3;{}~"}
MODIFIER_BITS = {"shift": 1, "alt": 2, "ctrl": 4}


def xterm_bytes(key: str) -> str:
    if key in XTERM_SEQUENCES:
        return XTERM_SEQUENCES[key]
    *modifiers, name = key.split("+")
    if modifiers and name in MODIFIED and set(modifiers) <= set(MODIFIER_BITS):
        return "\x1b[" + MODIFIED[name].format(1 + sum(MODIFIER_BITS[m] for m in modifiers))
    if key.startswith("ctrl+") and len(key) == 6 and key[-1].isalpha():
        return chr(ord(key[-1]) - ord("a") + 1)
    if len(key) == 1:
        return key
    raise AssertionError(f"no xterm.js sequence known for {key!r}: add it to XTERM_SEQUENCES")


def parsed_keys(data: str) -> list[str]:
    """The keys Textual's web driver makes of ``data`` (the same XTermParser as the terminal's driver)."""
    parser = XTermParser()
    events = [*parser.feed(data), *parser.feed("")]
    return [event.key for event in events if isinstance(event, Key)]


async def test_every_binding_reaches_the_served_app_as_in_the_terminal(tmp_path):
    import station.tui.widgets as widgets
    from station.tui.screens.confirm_quit import ConfirmQuitScreen

    def station_keys(cls, extra=()) -> set[str]:
        """The keys bound by ``cls`` and its station base classes (not Textual's own: super+c copies)."""
        bindings = [*extra, *(binding for base in cls.__mro__ if base.__module__.startswith("station.")
                              for binding in base.__dict__.get("BINDINGS", []))]
        return {key.strip() for binding in bindings for key in binding.key.split(",")}

    keys: dict[str, set[str]] = {}
    async with opened(tmp_path, wait=False) as (app, pilot):
        keys["app"] = station_keys(type(app))
        for name in ["home", *(entry.name for entry in app.areas)]:
            screen = app.get_screen(name)
            keys[name] = station_keys(type(screen), getattr(screen, "bindings_for_areas", []))
    for module in pkgutil.iter_modules(widgets.__path__):
        for cls in vars(importlib.import_module(f"{widgets.__name__}.{module.name}")).values():
            if isinstance(cls, type) and cls.__module__.startswith("station."):
                keys[cls.__name__] = station_keys(cls)
    keys["confirm_quit"] = station_keys(ConfirmQuitScreen)
    assert "ctrl+x" in keys["machines"] and "ctrl+q" in keys["app"]
    for name, bound in keys.items():
        for key in sorted(bound):
            assert key not in BROWSER_KEYS, f"{name}: {key} is kept by browsers: bind another key"
            assert parsed_keys(xterm_bytes(key)) == [key], f"{name}: {key!r} does not arrive from a browser"


def test_a_certificate_that_cannot_be_used_is_one_line(tmp_path):
    from station.errors import StationError
    from station.serve import tls_context

    with pytest.raises(StationError, match=r"^--cert/--key: no such file: .*missing\.pem$"):
        tls_context(str(tmp_path / "missing.pem"), str(tmp_path / "missing.key"))
    not_pem = tmp_path / "notes.txt"
    not_pem.write_text("not a certificate\n")
    with pytest.raises(StationError, match="expected a PEM certificate and its matching PEM private key"):
        tls_context(str(not_pem), str(not_pem))
