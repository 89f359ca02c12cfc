"""Foreground computations (Explorer, Segments) are bounded in number: with every slot
taken, a further request answers at once with a notice and computes nothing.

Budget: WALL = 2 s per refused request. A refusal is a parse, a cache look-up and a
non-blocking semaphore test (milliseconds); 2 s leaves room for two shared, loaded cores,
while the point it refuses would compute for about a second and a waiting request would
wait for as long as the held slot (here: for ever).
"""

from __future__ import annotations

import sys
import threading
import time

import pytest

from dampersim import costs
from dampersim.errors import InputError

WALL = 2.0


@pytest.fixture(scope="module")
def pages():
    import app  # noqa: F401  (Dash loads the page modules)

    return sys.modules["pages.explorer"], sys.modules["pages.segments"]


@pytest.fixture(autouse=True)
def _fresh(cache_dir, monkeypatch):
    for name in (costs.BUDGET_ENV, costs.AUTOSTART_ENV, costs.BYTES_ENV):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv(costs.FOREGROUND_SLOTS_ENV, "1")


def rows(n=6):
    return [2] + [None] * (n - 1), [300] + [None] * (n - 1), [0] + [None] * (n - 1)


def refuse_compute(monkeypatch, module, name):
    def refuse(*a, **k):
        raise AssertionError(f"{name} must not run while the server is busy")
    monkeypatch.setattr(module, name, refuse)


def test_second_request_answers_at_once_when_the_only_slot_is_held(pages, monkeypatch):
    explorer, segments = pages
    refuse_compute(monkeypatch, explorer, "explorer_view")
    refuse_compute(monkeypatch, segments, "segments_view")
    ks, amps, phs = rows()
    params = {"set": None, "overrides": {}}
    with costs.foreground_slot():  # the first request computing
        t0 = time.perf_counter()
        out = explorer.explorer_outputs(1500, 200, ks, amps, phs, 1.2, [], [], "pi", [], params, run=True)
        seg = segments.segments_outputs(1500, 200, ks, amps, phs, 1.2, "outer", 0.2, 0.04, 5, params, run=True)
        wall = time.perf_counter() - t0
        res = explorer.update_explorer(1500, 200, ks, amps, phs, 1.2, [], [], "pi", [], params, "some-key", None)
    assert wall < 2 * WALL
    for o in (out, seg):
        text = " ".join(n["text"] for n in o["notices"])
        assert o["busy"] and o["error"]
        assert "the server is busy with 1 other interactive computation; try again in a moment" in text
        assert costs.FOREGROUND_SLOTS_ENV in text and "previous results are kept" in text
    from dash import no_update
    assert res[0] is no_update  # the previous figures stay


def test_slots_are_released_and_bounded(monkeypatch):
    monkeypatch.setenv(costs.FOREGROUND_SLOTS_ENV, "2")
    with costs.foreground_slot(), costs.foreground_slot():
        with pytest.raises(costs.ServerBusy, match="busy with 2 other interactive computations"):
            with costs.foreground_slot():
                pass
    with costs.foreground_slot():  # released again after use (and after an error)
        pass
    with pytest.raises(RuntimeError):
        with costs.foreground_slot():
            raise RuntimeError("failed")
    held = []

    def hold(ready, done):
        with costs.foreground_slot():
            held.append(1)
            ready.set()
            done.wait(5)

    ready, done = threading.Event(), threading.Event()
    threads = [threading.Thread(target=hold, args=(ready, done))]
    threads[0].start()
    ready.wait(5)
    with costs.foreground_slot():  # one of two taken by another thread: the second is free
        pass
    done.set()
    threads[0].join(5)


def test_default_slots_and_bad_setting(monkeypatch):
    monkeypatch.delenv(costs.FOREGROUND_SLOTS_ENV)
    assert costs.foreground_slots() == 4  # half of app.py's 8 request threads
    for bad in ("0", "-3", "two", "1.5"):
        monkeypatch.setenv(costs.FOREGROUND_SLOTS_ENV, bad)
        with pytest.raises(InputError) as err:
            costs.foreground_slots()
        assert costs.FOREGROUND_SLOTS_ENV in str(err.value) and repr(bad) in str(err.value)
        assert "accepted is a whole number of at least 1" in str(err.value)
