"""Notices for the pages, and the two readings of a query value every view module shares:
a number, and the first of a repeated key.

A notice is a plain dict ``{"level": "warning"|"error"|"info"|"success", "text": ...}``;
the pages render it, tests read its text.
"""

from __future__ import annotations




def notice(text: str, level: str = "warning") -> dict:
    """A notice for the page: ``{"level": "warning"|"error"|"info", "text": ...}``."""
    return {"level": level, "text": str(text)}


def query_value(query: dict, key: str, notices: list, label: str):
    """The query value of ``key``; a repeated key keeps its first value, with a notice."""
    raw = query[key]
    if isinstance(raw, (list, tuple)):
        if not raw:
            return ""
        notices.append(notice(f"{label} ({key}) is given {len(raw)} times in the link; using the first value {raw[0]!r}."))
        raw = raw[0]
    return raw


__all__ = ["notice", "query_value"]
