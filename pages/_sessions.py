"""Browser sessions of the dashboard, for the job queue's per-session limits and caps.

A session is a random id signed with a server secret (HMAC-SHA256) in an HttpOnly,
SameSite=Strict cookie set by :func:`install_sessions`. The secret is a 0600 file in the
job registry's 0700 folder, created once and shared by every server process on it. A
request without a cookie, or with an unsigned or forged one, belongs to the one anonymous
session (so a made-up cookie gains no limit of its own) and receives a new signed cookie.
"""

from __future__ import annotations

import hashlib
import hmac
import os
import re
import secrets

#: Name of the session cookie.
SESSION_COOKIE = "dampersim_session"
#: Session of requests without a (valid) session cookie, and of calls outside a request.
ANONYMOUS = "anonymous"
_SESSION_RE = re.compile(r"^([0-9a-f]{32})\.([0-9a-f]{64})$")
#: File of the session-signing secret, in the registry's folder.
SECRET_FILE = "session.key"
_SECRETS: dict = {}


def _registry_folder(folder):
    if folder is not None:
        return os.fspath(folder)
    from dampersim.locations import private_dir

    return os.fspath(private_dir("jobs"))


def session_secret(folder=None) -> bytes:
    """The server's session-signing secret, ``SECRET_FILE`` in ``folder`` (default: the
    registry's folder ``private_dir("jobs")``), created once (0600) and shared by every
    server process on that folder."""
    folder = _registry_folder(folder)
    secret = _SECRETS.get(folder)
    if secret is None:
        os.makedirs(folder, mode=0o700, exist_ok=True)
        path = os.path.join(folder, SECRET_FILE)
        if not os.path.exists(path):
            tmp = os.path.join(folder, f".{SECRET_FILE}-{secrets.token_hex(8)}")
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
            with os.fdopen(fd, "wb") as fh:
                fh.write(secrets.token_bytes(32))
            try:
                os.link(tmp, path)  # atomic: another process's secret, once there, wins
            except FileExistsError:
                pass
            finally:
                os.unlink(tmp)
        with open(path, "rb") as fh:
            secret = fh.read()
        if len(secret) < 32:
            raise OSError(f"the session secret {SECRET_FILE} is too short; remove it to create a new one")
        _SECRETS[folder] = secret
    return secret


def sign_session(sid: str, folder=None) -> str:
    """Cookie value of session ``sid`` (32 hex digits): ``sid.hmac``."""
    return f"{sid}.{hmac.new(session_secret(folder), sid.encode(), hashlib.sha256).hexdigest()}"


def verified_session(cookie, folder=None) -> str | None:
    """The session id of a cookie value signed by this server, None otherwise."""
    m = _SESSION_RE.match(cookie) if isinstance(cookie, str) else None
    if m is None:
        return None
    return m.group(1) if hmac.compare_digest(sign_session(m.group(1), folder), cookie) else None


def install_sessions(flask_server, folder=None) -> None:
    """Give every browser a random, signed session id in the ``dampersim_session`` cookie
    (HttpOnly, SameSite=Strict), set on the first response that finds it missing, unsigned
    or forged. ``folder``: the job registry's folder (holds the secret)."""
    from flask import g, request

    folder = _registry_folder(folder)

    @flask_server.before_request
    def _dampersim_session():
        if verified_session(request.cookies.get(SESSION_COOKIE, ""), folder) is None:
            g.dampersim_new_session = sign_session(secrets.token_hex(16), folder)

    @flask_server.after_request
    def _dampersim_session_cookie(response):
        value = g.get("dampersim_new_session")
        if value:
            response.set_cookie(SESSION_COOKIE, value, httponly=True, samesite="Strict", path="/")
        return response


def current_session(folder=None) -> str:
    """Session id of the current request's signed cookie; :data:`ANONYMOUS` without a
    valid one or outside a request. ``folder``: the job registry's folder."""
    try:
        from flask import has_request_context, request
    except ImportError:  # pragma: no cover - flask comes with dash
        return ANONYMOUS
    if not has_request_context():
        return ANONYMOUS
    return verified_session(request.cookies.get(SESSION_COOKIE, ""), folder) or ANONYMOUS


__all__ = ["SESSION_COOKIE", "ANONYMOUS", "SECRET_FILE", "session_secret", "sign_session", "verified_session",
           "install_sessions", "current_session"]
