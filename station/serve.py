"""The station's Textual app served to a browser (``station serve``), and who may open it.

:mod:`textual_serve` runs the app's command in a subprocess for every browser session (the page's websocket): the
station seen in a browser is the terminal's own ``station`` (same :class:`station.tui.app.StationApp`, same keys,
same questions before a laser job is quit, same data folder and config, which the subprocess inherits with the
environment). This module adds what a UI that can fire a laser needs before it is put on a network:

- Local only by default: bound to 127.0.0.1 or ::1, only a request whose ``Host`` names the loopback is served (a
  web page elsewhere cannot rebind its own name to 127.0.0.1 and drive the station), and a websocket is only opened
  from the station's own page (its ``Origin``), since browsers let any page open a websocket anywhere.
- Any other address needs a token: made with :mod:`secrets`, kept in the data folder in a file only its owner can
  read (:data:`TOKEN_FILE`, mode 0600), and carried by the URL printed at start (``?token=``). A request without
  it, or with a wrong one, gets 403 and nothing of the app: not the page, not its static files, not the websocket.
  The page's own requests (its script, the websocket) carry the token in a cookie the page's response sets
  (HttpOnly, SameSite=Strict: another site's page does not send it). Compared in constant time.
- The token is printed once when the server starts and never written to the log (no access log: its lines would
  carry the URL); the log names each session's start and end and each refused request instead.
- One browser session at a time: each session is a station process of its own that opens the machines' ports, and
  serial ports are not locked. A second browser is told where the station is open.
- A session whose browser goes away cannot be asked: its running job is aborted and recorded, as the terminal's
  ctrl+q "abort and quit" does; stopping the server does the same for its session.
"""

from __future__ import annotations

import hmac
import ipaddress
import logging
import os
import secrets
import shlex
import socket
import stat
import sys
from pathlib import Path

from station.errors import ConfigError, StationError

#: Hosts served without a token: the loopback addresses the issue names (127.0.0.2 is loopback too, but a station
#: bound there is treated as exposed: only these two are "local").
LOCAL_HOSTS = frozenset({"127.0.0.1", "::1"})

#: Names a local-only station answers to in a request's ``Host`` (anything else is a page using DNS rebinding).
LOCAL_NAMES = frozenset({"127.0.0.1", "::1", "localhost"})

#: The token's file in the data folder.
TOKEN_FILE = "serve-token"

#: The query parameter and the cookie that carry the token.
TOKEN_PARAMETER = "token"
TOKEN_COOKIE = "station_token"

#: Bytes of randomness in a token (256 bits; 43 URL-safe characters).
TOKEN_BYTES = 32

#: Seconds a session's app is given to quit before it is killed: more than the 20 s the app waits for an aborted job
#: to end (:meth:`MachinesScreen.abort_then`), so that the job is recorded as aborted.
SESSION_STOP_WAIT = 25.0

log = logging.getLogger("station.serve")


def needs_token(host: str) -> bool:
    """Whether binding ``host`` exposes the station beyond this machine (anything but 127.0.0.1 and ::1)."""
    return host.strip("[]") not in LOCAL_HOSTS


def token_path(folder: Path) -> Path:
    """Where the token lives in the data folder ``folder``."""
    return folder / TOKEN_FILE


def load_or_create_token(folder: Path, *, renew: bool = False) -> tuple[str, str]:
    """The station's serving token from ``folder``, made there if missing, unreadable, or readable by others.

    A token is kept across restarts so that a tablet's bookmark keeps working; ``renew`` replaces it (every
    bookmark stops working). A token file that other users can read is not trusted: a new one replaces it.

    Returns
    -------
    token : str
    why : str
        "" when the stored token is used, else why a new one was made (said when the server starts).
    """
    path = token_path(folder)
    why = "asked for a new one" if renew else ""
    if not renew:
        try:
            mode = path.stat().st_mode
            text = path.read_text(encoding="ascii").strip()
        except FileNotFoundError:
            why = "first use"
        except (OSError, UnicodeDecodeError) as error:
            why = f"{path} was unreadable ({error.__class__.__name__})"
        else:
            if stat.S_IMODE(mode) & 0o077:
                why = f"{path} could be read by other users (mode {stat.S_IMODE(mode):04o})"
            elif not _looks_like_token(text):
                why = f"{path} did not hold a token"
            else:
                return text, ""
    token = secrets.token_urlsafe(TOKEN_BYTES)
    _write_private(path, token + "\n")
    return token, why


def _looks_like_token(text: str) -> bool:
    return len(text) >= 32 and all(c.isascii() and (c.isalnum() or c in "-_") for c in text)


def _write_private(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` readable by its owner only: a fresh file made with mode 0600 (never a moment with
    wider rights), then renamed over the old one."""
    temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        temporary.unlink(missing_ok=True)
        descriptor = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(descriptor, "w", encoding="ascii") as file:
            file.write(text)
        os.chmod(temporary, 0o600)  # the umask can only narrow a mode; say it anyway
        os.replace(temporary, path)
    except OSError as error:
        temporary.unlink(missing_ok=True)
        raise ConfigError(f"cannot write the serving token {str(path)!r}: {error.strerror}; the data folder must "
                          "be writable") from None


def token_matches(given: str | None, token: str) -> bool:
    """Whether ``given`` is ``token``, compared in constant time (a wrong guess takes as long whatever it shares)."""
    if not given:
        return False
    return hmac.compare_digest(given.encode("utf-8", "surrogateescape"), token.encode("ascii"))


def app_command() -> str:
    """The shell command textual-serve runs for each browser session: this Python running ``station`` (the terminal
    UI, as ``station`` without a command starts it), with this very ``station`` package first on its path.

    The environment is inherited (``CHAOS_STATION_HOME``, ``CHAOS_STATION_CONFIG``), so the session opens the same
    data folder and config as the server; textual-serve adds only its web driver's variables.
    """
    root = str(Path(__file__).resolve().parents[1])
    path = os.pathsep.join([root, *filter(None, [os.environ.get("PYTHONPATH", "")])])
    return f"PYTHONPATH={shlex.quote(path)} exec {shlex.quote(sys.executable)} -m station"


def bare_host(host_header: str) -> str:
    """The host name of a ``Host`` header value (``[::1]:8000`` -> ``::1``, ``localhost:8000`` -> ``localhost``)."""
    if host_header.startswith("["):
        return host_header[1:].split("]", 1)[0]
    return host_header.rsplit(":", 1)[0] if host_header.count(":") == 1 else host_header


def origin_matches(origin: str | None, host_header: str) -> bool:
    """Whether a websocket's ``Origin`` is the station's own page (``http://`` + the ``Host`` it was asked by)."""
    if origin is None:  # not a browser (a browser always says where the page came from)
        return True
    return origin in (f"http://{host_header}", f"https://{host_header}")


def tls_context(cert: str, key: str):
    """An :class:`ssl.SSLContext` serving the certificate ``cert`` with its private key ``key`` (PEM files).

    On another address the token crosses the network with every request: over plain HTTP, anyone who can read the
    Wi-Fi's traffic (an open network, or a shared WPA2 password) can read it. With a certificate it does not.

    Raises
    ------
    StationError
        A file that is missing, unreadable, or not a certificate and its key (one line naming the file).
    """
    import ssl

    context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    context.minimum_version = ssl.TLSVersion.TLSv1_2
    try:
        context.load_cert_chain(cert, key)
    except FileNotFoundError as error:
        raise StationError(f"--cert/--key: no such file: {error.filename or cert}") from None
    except (ssl.SSLError, OSError) as error:
        reason = getattr(error, "reason", None) or error.strerror or ""
        raise StationError(f"--cert {cert!r} / --key {key!r}: cannot be used{f' ({reason})' if reason else ''}; "
                           "expected a PEM certificate and its matching PEM private key") from None
    return context


def url(host: str, port: int, token: str | None, scheme: str = "http") -> str:
    """The URL to print (once): the bound address, or for a wildcard (0.0.0.0, ::) this machine's address on its
    default route (a tablet may not resolve the machine's name), else its name."""
    name = host
    if host in ("0.0.0.0", "::", ""):
        name = _outward_address() or socket.gethostname()
    try:
        literal = ipaddress.ip_address(name)
    except ValueError:
        literal = None
    shown = f"[{name}]" if literal is not None and literal.version == 6 else name
    return f"{scheme}://{shown}:{port}/" + (f"?{TOKEN_PARAMETER}={token}" if token else "")


def _outward_address() -> str:
    """This machine's address on its default route (a UDP socket 'connected' sends nothing); "" when offline."""
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            probe.connect(("192.0.2.1", 9))  # TEST-NET-1: never routed anywhere, only used to pick the interface
            return probe.getsockname()[0]
    except OSError:
        return ""
