"""The web server of ``station serve``: textual-serve's :class:`~textual_serve.server.Server` with a guard in front
of every route (see :mod:`station.serve` for what it lets through and why).

Kept apart from :mod:`station.serve` (the guard's rules, the token and its file) so that those can be used and tested
without aiohttp; ``station serve`` imports this module only when it starts a server.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import aiohttp_jinja2
from aiohttp import web
from textual_serve.app_service import AppService
from textual_serve.server import Server, to_int

from station.serve import (
    LOCAL_NAMES,
    SESSION_STOP_WAIT,
    TOKEN_COOKIE,
    TOKEN_PARAMETER,
    app_command,
    bare_host,
    log,
    origin_matches,
    token_matches,
    url,
)

#: Headers on every answer: never cached (the page's URL carries the token), never framed by another site (a page
#: could put the station in an invisible frame and have a user tap its buttons), no Referer to anyone.
GUARD_HEADERS = {
    "Cache-Control": "no-store",
    "Referrer-Policy": "no-referrer",
    "X-Frame-Options": "DENY",
    "Content-Security-Policy": "frame-ancestors 'none'",
    "X-Content-Type-Options": "nosniff",
}

#: The page's template: textual-serve's, with every asset it loads (the terminal font too) served by the station
#: itself from textual-serve's static folder, so that the page works on a network without internet and calls no
#: one else.
PAGE_TEMPLATES = Path(__file__).resolve().parent / "serve_page"

REFUSED = ("403 forbidden: this station is served only to who has its token; open the URL that `station serve` "
           "printed (it ends in ?token=...)\n")
REFUSED_LOCAL = "403 forbidden: this station is served on this computer only\n"


class StationServer(Server):
    """textual-serve's server for the station: the guard, the page's URLs taken from the request, sessions logged
    and stopped with the server.

    Parameters
    ----------
    command : str
        The shell command of a session (:func:`station.serve.app_command`).
    host, port
        Where to listen.
    token : str or None
        The token every request must carry; None for a local-only station (loopback names only).
    say : callable
        Prints the start-up lines (the URL with the token is said there once).
    ssl_context : ssl.SSLContext, optional
        Serve HTTPS (and the websocket over TLS) with it (:func:`station.serve.tls_context`).
    """

    def __init__(self, command: str, host: str, port: int, token: str | None, *,
                 say: Callable[[str], Any] = print, ssl_context=None) -> None:
        super().__init__(command, host=host, port=port, title="Crafting Chaos station", templates_path=PAGE_TEMPLATES)
        self.token = token
        self.say = say
        self.ssl_context = ssl_context
        self.scheme = "https" if ssl_context is not None else "http"
        #: The live sessions: their websocket, the browser's address and since when.
        self.sessions: dict[AppService, tuple[web.WebSocketResponse, str | None, str]] = {}

    # ------------------------------------------------------------------ the guard

    def refusal(self, request: web.Request) -> str:
        """Why ``request`` is refused ("" when it is served)."""
        host = request.host
        if self.token is None:
            if bare_host(host).lower() not in LOCAL_NAMES:
                return f"Host {host!r} is not this computer"
        else:
            given = request.query.get(TOKEN_PARAMETER) or request.cookies.get(TOKEN_COOKIE)
            if not given:
                return "no token"
            if not token_matches(given, self.token):
                return "wrong token"
        if request.headers.get("Upgrade", "").lower() == "websocket" and not origin_matches(
                request.headers.get("Origin"), host):
            return f"websocket from another site's page ({request.headers.get('Origin')!r})"
        return ""

    def make_guard(self):
        """The aiohttp middleware in front of every route (the page, static files, downloads, the websocket)."""

        @web.middleware
        async def guard(request: web.Request, handler) -> web.StreamResponse:
            why = self.refusal(request)
            if why:
                log.warning("refused %s %s from %s: %s", request.method, request.path, request.remote, why)
                return web.Response(status=403, text=REFUSED if self.token else REFUSED_LOCAL,
                                    headers=GUARD_HEADERS)
            response = await handler(request)
            if not response.prepared:  # a websocket or a download has sent its headers already
                response.headers.update(GUARD_HEADERS)
                if self.token and request.query.get(TOKEN_PARAMETER):
                    # the page's script, styles and websocket carry the token as a cookie (the websocket URL gets
                    # the size appended by textual.js, so it cannot carry a query of its own); SameSite=Strict:
                    # another site's page cannot make the browser send it
                    response.set_cookie(TOKEN_COOKIE, self.token, httponly=True, samesite="Strict", path="/",
                                        secure=self.ssl_context is not None)
            return response

        return guard

    async def _make_app(self) -> web.Application:
        app = await super()._make_app()
        app.middlewares.append(self.make_guard())
        return app

    # ------------------------------------------------------------------ the page and the sessions

    async def handle_index(self, request: web.Request) -> web.Response:
        """The page, its URLs made from the request's own address (textual-serve makes them from the bound one,
        which for 0.0.0.0 is no address a tablet can reach)."""
        router = request.app.router
        scheme = "https" if request.secure else "http"
        base = f"{scheme}://{request.host}"
        static = base + str(router["static"].url_for(filename="/")).rstrip("/") + "/"
        websocket = ("wss" if scheme == "https" else "ws") + f"://{request.host}" + str(
            router["websocket"].url_for())
        context = {
            "font_size": to_int(request.query.get("fontsize", "16"), 16),
            "app_websocket_url": websocket,
            "config": {"static": {"url": static}},
            "application": {"name": self.title},
        }
        return aiohttp_jinja2.render_template("app_index.html", request, context)

    async def handle_websocket(self, request: web.Request) -> web.WebSocketResponse:
        """One browser session: the station app in its own process for as long as the websocket is open.

        textual-serve's own, with the session kept in :attr:`sessions` (the server stops them when it stops) and its
        start and end logged. When the browser goes away (tab closed, Wi-Fi lost), the app is told to quit with no
        one to ask: a running job is aborted (soft reset, laser off) and recorded
        (:meth:`station.tui.app.StationApp.on_exit_app`).

        One session at a time: each session is a station of its own, and two would each open the machines' ports
        (a serial port is not locked: two processes could interleave G-code on one laser). A second browser is told
        where the station is open and its session closed; a reload waits for the session it replaces to end.
        """
        websocket = web.WebSocketResponse(heartbeat=15)
        width = to_int(request.query.get("width", "80"), 80)
        height = to_int(request.query.get("height", "24"), 24)
        service: AppService | None = None
        try:
            await websocket.prepare(request)
            busy = await self._wait_for_ended_sessions()
            if busy:
                log.warning("refused a second session from %s: %s", request.remote, busy)
                await websocket.send_bytes(f"\r\n  {busy}.\r\n  Close it there, then press Restart here.\r\n"
                                           .encode())
                await websocket.close()
                return websocket
            service = AppService(self.command, write_bytes=websocket.send_bytes, write_str=websocket.send_str,
                                 close=websocket.close, download_manager=self.download_manager, debug=self.debug)
            self.sessions[service] = (websocket, request.remote, time.strftime("%H:%M"))
            log.info("session %s from %s started", service.app_service_id[:8], request.remote)
            await service.start(width, height)
            await self._process_messages(websocket, service)
        except asyncio.CancelledError:
            await websocket.close()
        except Exception as error:  # a session's failure is logged; the server goes on for the others
            log.exception(error)
        finally:
            if service is not None:
                await self._stop_session(service)
                log.info("session %s from %s ended", service.app_service_id[:8], request.remote)
        return websocket

    async def _wait_for_ended_sessions(self) -> str:
        """Wait until the sessions whose browsers have gone have ended (their apps may be aborting a job); "" then,
        or what still holds the station: a session whose browser is still there, or one that did not end in time."""
        deadline = asyncio.get_running_loop().time() + SESSION_STOP_WAIT + 1
        while self.sessions:
            for websocket, remote, since in self.sessions.values():
                if not websocket.closed:
                    return f"The station is open in another browser (from {remote}, since {since})"
            if asyncio.get_running_loop().time() > deadline:
                return "The station's last session has not ended yet"
            await asyncio.sleep(0.1)
        return ""

    async def _stop_session(self, service: AppService) -> None:
        """Ask the session's app to quit; kill its process if it has not within :data:`SESSION_STOP_WAIT`.

        The session ends when its process has (textual-serve stops reading at its output's end): a session the
        server no longer lists has no process left to drive a machine.
        """
        process = service._process
        try:
            await asyncio.wait_for(asyncio.shield(service.stop()), SESSION_STOP_WAIT)
            if process is not None:
                await asyncio.wait_for(process.wait(), SESSION_STOP_WAIT)
        except (asyncio.TimeoutError, OSError):
            if process is not None and process.returncode is None:
                log.warning("session %s did not quit within %g s: killed", service.app_service_id[:8],
                            SESSION_STOP_WAIT)
                process.kill()
                await process.wait()
        finally:
            self.sessions.pop(service, None)

    async def on_startup(self, app: web.Application) -> None:
        """Nothing: the URLs are said once the server listens (:meth:`listening`)."""

    def listening(self, _aiohttp_says: str = "") -> None:
        """Say where to open the station; aiohttp calls it (as its ``print``) once the address is bound."""
        self.say(f"station serve: open {url(self.host, self.port, self.token, self.scheme)}")
        if self.token:
            self.say("station serve: the token is in that URL; whoever has it can run the machines")
        self.say("station serve: Ctrl+C stops the server (and every session: running jobs are aborted)")

    async def on_shutdown(self, app: web.Application) -> None:
        await asyncio.gather(*(self._stop_session(service) for service in list(self.sessions)),
                             return_exceptions=True)

    def serve(self, debug: bool = False) -> None:
        """Serve until Ctrl+C or SIGTERM. No access log: its lines would carry the token."""
        self.debug = debug
        handler = logging.StreamHandler()
        handler.setFormatter(logging.Formatter("station serve: %(message)s"))
        for name in ("station.serve", "textual-serve"):
            logger = logging.getLogger(name)
            logger.setLevel(logging.DEBUG if debug else logging.INFO)
            logger.addHandler(handler)
        web.run_app(self._make_app(), host=self.host, port=self.port, access_log=None, print=self.listening,
                    handle_signals=True, shutdown_timeout=SESSION_STOP_WAIT + 5, ssl_context=self.ssl_context)


def make_server(host: str, port: int, token: str | None, *, command: str | None = None,
                say: Callable[[str], Any] = print, ssl_context=None):
    """A :class:`textual_serve.server.Server` for the station with the guard described in :mod:`station.serve`."""
    return StationServer(command or app_command(), host, port, token, say=say, ssl_context=ssl_context)
