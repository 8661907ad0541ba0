"""Whether an MLflow tracking server answers, asked before any work: MLflow itself retries a server that does not
answer for minutes (its HTTP backoff, over four minutes as measured) and then fails the run with a long
traceback, after its directory is made."""

from __future__ import annotations

import socket
from urllib.parse import urlsplit, urlunsplit

from hybrid_sysid.core.checks import ConfigError, Shown

ANSWER_SECONDS = 5.0  # a server on a busy network answers a connection well within this


def without_password(uri: str) -> str:
    """The URI with any password in it replaced by ***."""
    parts = urlsplit(uri)
    if parts.password is None:
        return uri
    netloc = parts.netloc.replace(f":{parts.password}@", ":***@", 1)
    return urlunsplit(parts._replace(netloc=netloc))


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
