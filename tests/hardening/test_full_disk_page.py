"""A sweep that could not store its points (full disk) says so on the page, next to the
results it still shows."""

from __future__ import annotations

from pages._jobs import status_line


def test_status_line_carries_the_cache_notice():
    view = {"summary": {"points": 4, "computed": 4, "from_cache": 0, "compute_time_s": 1.0,
                        "cache_notice": "4 of 4 test points were computed but not cached: disk is full."}}
    text = str(status_line(view, {}))
    assert "not cached" in text and "Done in" in text


def test_status_line_without_notice_is_unchanged():
    view = {"summary": {"points": 4, "computed": 4, "from_cache": 0, "compute_time_s": 1.0, "cache_notice": None}}
    assert "not cached" not in str(status_line(view, {}))
