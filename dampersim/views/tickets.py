"""Tickets: the validated request of a background job, kept on the server under an opaque
random id, so that a job never runs on state a browser posts back.

A page's request callback validates its state and :func:`issue` stores it (page, state,
the view key the job will produce) as a small JSON file in the private folder
``tickets`` of the cache (:func:`dampersim.locations.private_dir`: mode 0700, owner
checked); the browser only receives the id. The job callback :func:`redeem` s the id and
validates the state again before any work; the job queue reads the stored work key with
:func:`peek` to share identical requests. Tickets expire after :data:`TICKET_TTL_S`;
an unknown, malformed or expired id gives None (the page says "this request has
expired; press Run").
"""

from __future__ import annotations

import json
import os
import re
import secrets
import tempfile
import time

from dampersim.locations import private_dir

#: Sub-folder of the cache directory holding the tickets.
TICKETS_SUBDIR = "tickets"
#: Lifetime of a ticket [s].
TICKET_TTL_S = 3600.0
#: Largest stored ticket [bytes] (a page state is well under 4 kB).
MAX_TICKET_BYTES = 64 * 1024
#: Most tickets kept; above it the oldest are removed when a new one is issued.
MAX_TICKETS = 5000

_ID = re.compile(r"[0-9a-f]{32}")


def valid_ticket(ticket) -> bool:
    """Whether ``ticket`` has the form of a ticket id (32 hex digits)."""
    return isinstance(ticket, str) and _ID.fullmatch(ticket) is not None


def _folder():
    return private_dir(TICKETS_SUBDIR)


def issue(page: str, state: dict, work: str | None = None) -> str:
    """Store a validated request; returns its ticket id (32 random hex digits).

    page: the page name; state: its validated page state (JSON-ready); work: the key of
    the view the job will produce (identical requests share it)."""
    folder = _folder()
    _prune(folder)
    ticket = secrets.token_hex(16)
    data = json.dumps({"page": str(page), "state": state, "work": work, "created": time.time()},
                      separators=(",", ":"), allow_nan=False).encode("utf-8")
    if len(data) > MAX_TICKET_BYTES:
        raise ValueError(f"a request of {len(data)} bytes cannot be stored: accepted are at most {MAX_TICKET_BYTES}")
    fd, tmp = tempfile.mkstemp(prefix=".ticket-", dir=folder)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.chmod(tmp, 0o600)
        os.replace(tmp, folder / f"{ticket}.json")
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    return ticket


def peek(ticket, page: str | None = None) -> dict | None:
    """The stored request ``{"page", "state", "work"}`` of ``ticket`` (of ``page`` when
    given), or None when the id is malformed, unknown, expired, unreadable or issued for
    another page. The server reads the work key of a posted ticket this way (the job
    queue shares jobs on it, never on a work key the browser posts)."""
    if not valid_ticket(ticket):
        return None
    path = _folder() / f"{ticket}.json"
    try:
        if time.time() - os.stat(path).st_mtime > TICKET_TTL_S:
            _unlink(path)
            return None
        if os.path.getsize(path) > MAX_TICKET_BYTES:
            return None
        with open(path, "rb") as fh:
            data = json.loads(fh.read().decode("utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or not isinstance(data.get("page"), str):
        return None
    if page is not None and data["page"] != page:
        return None
    created = data.get("created")
    if not isinstance(created, (int, float)) or time.time() - created > TICKET_TTL_S:
        return None
    work = data.get("work")
    return {"page": data["page"], "state": data.get("state"), "work": work if isinstance(work, str) else None}


def redeem(ticket, page: str) -> dict | None:
    """The stored request ``{"state", "work"}`` of ``ticket`` for ``page``, or None when the
    id is malformed, unknown, expired, unreadable or issued for another page."""
    entry = peek(ticket, page)
    return None if entry is None else {"state": entry["state"], "work": entry["work"]}


def _unlink(path):
    try:
        os.unlink(path)
    except OSError:
        pass


def _prune(folder) -> None:
    """Remove expired tickets, and the oldest above :data:`MAX_TICKETS`."""
    now = time.time()
    try:
        entries = []
        with os.scandir(folder) as it:
            for e in it:
                if e.name.endswith(".json") or e.name.startswith(".ticket-"):
                    try:
                        entries.append((e.stat().st_mtime, e.path))
                    except OSError:
                        pass
    except OSError:
        return
    keep = []
    for mtime, path in entries:
        if now - mtime > TICKET_TTL_S:
            _unlink(path)
        else:
            keep.append((mtime, path))
    if len(keep) >= MAX_TICKETS:
        keep.sort()
        for _, path in keep[:len(keep) - MAX_TICKETS + 1]:
            _unlink(path)


__all__ = ["TICKETS_SUBDIR", "TICKET_TTL_S", "MAX_TICKET_BYTES", "MAX_TICKETS", "valid_ticket", "issue", "peek",
           "redeem"]
