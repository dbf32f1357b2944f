"""A database URL's form: which database it names (:func:`parse_url`) and how to show it without its password
(:func:`redact`). Read by the station's config (``[database] url``) as well as by the database itself.

A URL is ``postgresql://USER:PASSWORD@HOST:PORT/DB`` (libpq's form; ``postgres://`` and SQLAlchemy's
``postgresql+psycopg://`` are accepted), ``sqlite:///PATH`` or a plain file path.
"""

from __future__ import annotations

from pathlib import Path
from urllib.parse import urlsplit, urlunsplit

from station.errors import StationError

__all__ = ["parse_url", "redact"]


def redact(url: str) -> str:
    """``url`` without its password, for messages and listings."""
    parts = urlsplit(url)
    if parts.password is None:
        return url
    host = parts.hostname or ""
    if parts.port is not None:
        host += f":{parts.port}"
    return urlunsplit(parts._replace(netloc=f"{parts.username or ''}:***@{host}"))


def parse_url(url: str) -> tuple[str, str]:
    """``(dialect, target)``: ``("sqlite", file path)`` or ``("postgresql", a libpq URI)``.

    Raises
    ------
    StationError
        A URL of another database (``mysql://``), naming what is accepted.
    """
    text = url.strip()
    scheme, sep, rest = text.partition("://")
    if not sep or len(scheme) < 2:  # a plain path (C:\\... has a one-letter "scheme")
        return "sqlite", str(Path(text).expanduser())
    scheme = scheme.lower()
    if scheme == "sqlite":
        if not rest.startswith("/") or rest == "/":
            raise StationError(f"database URL {text!r}: expected sqlite:///PATH (three slashes, then the file)")
        return "sqlite", str(Path(rest[1:]).expanduser())
    if scheme.split("+")[0] in ("postgresql", "postgres"):
        return "postgresql", "postgresql://" + rest
    raise StationError(f"database URL {redact(text)!r}: expected postgresql://USER:PASSWORD@HOST/DB, "
                       "sqlite:///PATH or a file path")
