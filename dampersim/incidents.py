"""Incidents: an unexpected error is logged in full on the server and shown to the browser
as one short line with an id, never as a traceback or a server path.

:func:`report` logs the traceback under a fresh incident id (8 hex digits) and returns the
id; :func:`public_message` turns any exception into the text a page or a JSON response may
show: the message of a deliberate :class:`~dampersim.errors.DampersimError` (absolute paths
replaced by their last component), or "unexpected error (incident …)" for anything else.
"""

from __future__ import annotations

import logging
import re
import secrets

from dampersim.errors import DampersimError

#: Logger the incidents go to (the server's log).
LOGGER = logging.getLogger("dampersim.incidents")

# an absolute POSIX path (two components at least) or a Windows drive path
_PATH = re.compile(r"(?<![\w.:/])(?:/[^\s'\"/:,;()]+){2,}/?|[A-Za-z]:\\[^\s'\"]+")


def new_id() -> str:
    """A fresh incident id (8 hex digits)."""
    return secrets.token_hex(4)


def redact_paths(text: str) -> str:
    """``text`` with every absolute path replaced by ``…/<last component>``."""
    def short(match):
        parts = [p for p in re.split(r"[/\\]", match.group(0)) if p]
        return "…/" + (parts[-1] if parts else "")
    return _PATH.sub(short, str(text))


def report(exc: BaseException, where: str = "") -> str:
    """Log ``exc`` with its traceback under a new incident id; returns the id."""
    incident = new_id()
    LOGGER.error("incident %s%s: %s", incident, f" in {where}" if where else "", exc,
                 exc_info=(type(exc), exc, exc.__traceback__))
    return incident


def public_message(exc: BaseException, where: str = "") -> str:
    """What a browser may be told about ``exc``.

    A :class:`DampersimError` says what was wrong and what is accepted: its message is
    shown (paths redacted). Anything else is a defect: it is logged with
    :func:`report` and the text names only the incident id.
    """
    if isinstance(exc, DampersimError):
        return redact_paths(str(exc))
    incident = report(exc, where)
    return f"unexpected error (incident {incident}; the server log has the details)"


__all__ = ["LOGGER", "new_id", "redact_paths", "report", "public_message"]
