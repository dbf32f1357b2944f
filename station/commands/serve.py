"""``station serve``: the station's UI in a browser (a tablet by the laser, a phone by the plotter)."""

from __future__ import annotations

import socket

from station.errors import StationError, UsageError
from station.paths import data_dir
from station.serve import load_or_create_token, needs_token, tls_context, token_path


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "serve",
        help="the station's UI in a browser (local only unless given --host; then a token guards it)",
        description="Serve the station's terminal UI to web browsers: every browser session runs the same UI as "
        "`station` in a terminal, on the same data folder and devices, with the same keys and questions (a laser "
        "job is started with g, aborted with ctrl+x). Local only by default (127.0.0.1). On any other address "
        "(--host 0.0.0.0 for every network of this computer) a token is required: it is made once, kept in the "
        "data folder (readable by you only) and carried by the printed URL; a request without it gets 403. A "
        "session whose browser goes away (tab closed, Wi-Fi lost) cannot be asked: its running job is aborted (laser "
        "off) and recorded, as ctrl+q's 'abort and quit' does.",
        epilog="examples:\n  station serve\n  station serve --host 0.0.0.0 --port 8000\n"
        "  station serve --host 0.0.0.0 --cert station.pem --key station.key\n"
        "  station serve --host 0.0.0.0 --new-token",
    )
    parser.add_argument("--host", default="127.0.0.1",
                        help="address to listen on (default 127.0.0.1: this computer only; 0.0.0.0 or :: for every "
                        "network, with a token)")
    parser.add_argument("--port", type=int, default=8000, help="port (default 8000)")
    parser.add_argument("--cert", metavar="FILE",
                        help="serve HTTPS with this PEM certificate (with --key): on a shared Wi-Fi, plain HTTP shows "
                        "the token to whoever reads the traffic")
    parser.add_argument("--key", metavar="FILE", help="the certificate's PEM private key (with --cert)")
    parser.add_argument("--new-token", action="store_true",
                        help="replace the stored token (links and bookmarks with the old one stop working)")
    parser.set_defaults(func=run_serve)


def run_serve(args) -> int:
    from station.serve_http import make_server  # deferred: aiohttp and textual-serve, for this command alone

    if not 1 <= args.port <= 65535:
        raise UsageError(f"--port must be an integer in [1, 65535], got {args.port}")
    host = args.host.strip().strip("[]")
    if not host:
        raise UsageError("--host must be an address or a name, e.g. 127.0.0.1 or 0.0.0.0")
    if (args.cert is None) != (args.key is None):
        raise UsageError("--cert and --key go together: the certificate and its private key")
    context = tls_context(args.cert, args.key) if args.cert else None
    try:  # a name or address that is not this computer's is said before a token is made for it
        socket.getaddrinfo(host, args.port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except socket.gaierror as error:
        raise StationError(f"cannot listen on {host}: {error.strerror}; --host must be an address of this "
                           "computer (127.0.0.1, 0.0.0.0, ::, or one of its names)") from None
    token = None
    if needs_token(host):
        token, why = load_or_create_token(data_dir(), renew=args.new_token)
        where = token_path(data_dir())
        print(f"station serve: {host} is not 127.0.0.1 or ::1: every request needs the token "
              f"({'made a new one: ' + why if why else 'kept'} in {where}, readable by you only)")
        if context is None:
            print("station serve: plain HTTP: on a shared Wi-Fi the token can be read from the traffic "
                  "(--cert and --key serve HTTPS)")
    elif args.new_token:
        raise UsageError(f"--new-token is for a served address other than 127.0.0.1 and ::1, got --host {host}")
    server = make_server(host, args.port, token, ssl_context=context)
    try:
        server.serve()
    except OSError as error:  # the port is taken, the address is not this computer's
        raise StationError(f"cannot listen on {host} port {args.port}: {error.strerror or error}") from None
    return 0
