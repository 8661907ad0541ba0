"""Whether MLflow's tracking store can be used, asked before any work: a server that does not answer (MLflow
itself retries it for minutes, its HTTP backoff, over four minutes as measured) or a local SQLite store that is
no database would otherwise fail the run with a long traceback, after its directory is made."""

from __future__ import annotations

import socket
from pathlib import Path
from urllib.parse import urlsplit, urlunsplit

from hybrid_sysid.core.checks import ConfigError, Shown

ANSWER_SECONDS = 5.0  # a server on a busy network answers a connection well within this
SQLITE_HEADER = b"SQLite format 3\x00"  # the first 16 bytes of every SQLite database file


def without_password(uri: str) -> str:
    """The URI with any password in it replaced by ***."""
    parts = urlsplit(uri)
    if parts.password is None:
        return uri
    netloc = parts.netloc.replace(f":{parts.password}@", ":***@", 1)
    return urlunsplit((parts.scheme, netloc, parts.path, parts.query, parts.fragment))


def check_server(uri: str, key: str, timeout: float = ANSWER_SECONDS) -> None:
    """An http(s) tracking URI names a host and port that accept a connection within ``timeout`` seconds; any
    other URI (a local store, a database) is the tracker's own to open."""
    parts = urlsplit(uri)
    if parts.scheme not in ("http", "https"):
        return
    shown = Shown(without_password(uri))
    try:
        host, port = parts.hostname, parts.port or (443 if parts.scheme == "https" else 80)
    except ValueError as exc:  # a port that is no number
        raise ConfigError(key, shown, f"a tracking server's URL: {exc}") from None
    if not host:
        raise ConfigError(key, shown, "a tracking server's URL names its host: http://HOST:PORT")
    try:
        with socket.create_connection((host, port), timeout=timeout):
            pass
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        allowed = f"no server answers at {host}:{port} ({reason}); start it, or use a local store (sqlite:///...)"
        raise ConfigError(key, shown, allowed) from None


def check_store(uri: str, key: str) -> None:
    """A tracking URI's store can be opened: a server answers (``check_server``), or an SQLite file that exists
    is a regular file holding a database (an empty one SQLite fills)."""
    if not uri.startswith("sqlite:///"):
        check_server(uri, key)
        return
    path = Path(uri.removeprefix("sqlite:///"))
    if not path.exists():
        return
    if not path.is_file():
        raise ConfigError(key, Shown(uri), "an SQLite database file; this path is no regular file")
    with path.open("rb") as f:
        head = f.read(len(SQLITE_HEADER))
    if head and head != SQLITE_HEADER:
        raise ConfigError(key, Shown(uri), "an SQLite database file; this file holds something else")
