"""Notices for the pages, and the two readings of a query value every view module shares:
a number, and the first of a repeated key.

A notice is a plain dict ``{"level": "warning"|"error"|"info"|"success", "text": ...}``;
the pages render it, tests read its text.
"""

from __future__ import annotations

import math

import numpy as np


def notice(text: str, level: str = "warning") -> dict:
    """A notice for the page: ``{"level": "warning"|"error"|"info", "text": ...}``."""
    return {"level": level, "text": str(text)}


def parse_number(raw) -> float:
    """A finite float from a number or its text; raises ValueError with the reason
    ("is empty", "is not a number", "is not a finite number")."""
    if isinstance(raw, bool):
        raise ValueError("is not a number")
    if isinstance(raw, (int, float, np.integer, np.floating)):
        v = float(raw)
    else:
        text = str(raw).strip()
        if not text:
            raise ValueError("is empty")
        try:
            v = float(text)
        except ValueError:
            raise ValueError("is not a number") from None
    if not math.isfinite(v):
        raise ValueError("is not a finite number")
    return v


def query_value(query: dict, key: str, notices: list, label: str):
    """The query value of ``key``; a repeated key keeps its first value, with a notice."""
    raw = query[key]
    if isinstance(raw, (list, tuple)):
        if not raw:
            return ""
        notices.append(notice(f"{label} ({key}) is given {len(raw)} times in the link; using the first value {raw[0]!r}."))
        raw = raw[0]
    return raw


__all__ = ["notice", "parse_number", "query_value"]
