"""Hostile links and crafted job data on the Explorer, Segments, Colourmap, Maps and
Hysteresis pages: each answered quickly, within a memory budget, with a notice that says
what was refused; what runs afterwards is only the safe default (the URL contract) within
the autostart budget; no traceback or server path in what the page shows.

Budgets used below, and why:
* WALL = 2 s per request: a page load is a parse and a cache look-up (milliseconds);
  2 s leaves room for a loaded 2-core machine, while any simulation these links ask for
  takes at least tens of seconds (and the protected-off case allocates gigabytes).
* MEM = 20 MB of Python allocations (tracemalloc peak): a notice and a small state; the
  unprotected links allocate 150 MB (40 range lists) to 16 GB (time step 1e-8 s).
"""

from __future__ import annotations

import json
import re
import sys
import time
import tracemalloc

import pytest

from dampersim import costs, default_parameters

WALL = 2.0
MEM = 20e6
PATH = re.compile(r"(?<![\w.])/(?:work|tmp|home|root|usr|var|opt|srv)/")
RANGE = "300:6000:0.05701"  # about 100 000 speeds per item


def text_of(obj) -> str:
    return json.dumps(obj, ensure_ascii=False,
                      default=lambda c: c.to_plotly_json() if hasattr(c, "to_plotly_json") else str(c))


def bounded(fn, *args, **kwargs):
    """Run ``fn`` and assert the wall-time and memory budgets; returns its result and the
    page text (checked for tracebacks and server paths)."""
    tracemalloc.start()
    t0 = time.perf_counter()
    try:
        out = fn(*args, **kwargs)
        wall = time.perf_counter() - t0
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert wall < WALL, f"{fn.__name__} took {wall:.2f} s"
    assert peak < MEM, f"{fn.__name__} allocated {peak / 1e6:.0f} MB"
    text = text_of(out)
    assert "Traceback" not in text and not PATH.search(text), text[:500]
    return out, text


@pytest.fixture(scope="module")
def pages():
    import app  # noqa: F401  (Dash loads the page modules)
    from types import SimpleNamespace

    return SimpleNamespace(**{n: sys.modules[f"pages.{n}"] for n in ("explorer", "segments", "colourmap", "maps", "hysteresis")})


@pytest.fixture(autouse=True)
def _fresh(cache_dir, monkeypatch):
    for name in (costs.BUDGET_ENV, costs.AUTOSTART_ENV, costs.BYTES_ENV):
        monkeypatch.delenv(name, raising=False)


def find(component, cid):
    if getattr(component, "id", None) == cid:
        return component
    children = getattr(component, "children", None)
    for child in children if isinstance(children, (list, tuple)) else [children]:
        if hasattr(child, "to_plotly_json"):
            hit = find(child, cid)
            if hit is not None:
                return hit
    return None


def control_value(component, cid):
    """The ``value`` of the control with id ``cid`` (the first component with both)."""
    if getattr(component, "id", None) == cid and hasattr(component, "value"):
        return component.value
    children = getattr(component, "children", None)
    for child in children if isinstance(children, (list, tuple)) else [children]:
        if hasattr(child, "to_plotly_json"):
            hit = control_value(child, cid)
            if hit is not None:
                return hit
    return None


def recorder(monkeypatch, module, name):
    """Replace ``module.name`` (a view) by one that records the system and state it would
    compute, then stops with a DampersimError (the page reports it and keeps serving)."""
    from dampersim.errors import InputError

    seen = []

    def record(system, state, *a, **k):
        if k.get("cache_only"):
            return None
        seen.append((system, dict(state)))
        raise InputError("stopped by the test")
    monkeypatch.setattr(module, name, record)
    return seen


def rows(n=6):
    return [2] + [None] * (n - 1), [300] + [None] * (n - 1), [0] + [None] * (n - 1)


def no_compute(monkeypatch, module, name):
    """Make ``module.name`` fail if it computes (a cache-only look-up answers None)."""
    def refuse(*a, **k):
        if k.get("cache_only"):
            return None
        raise AssertionError(f"{name} must not run")
    monkeypatch.setattr(module, name, refuse)


# ------------------------------------------------------------------------ explorer / segments
def test_explorer_time_step_link_falls_back_to_the_safe_default(pages, monkeypatch):
    E = pages.explorer
    lay, text = bounded(E.layout, **{"solver.time_step": "1e-8", "duration": "20"})
    notices = text_of(find(lay, "explorer-link-notices"))
    assert "solver.time_step" in notices and "'1e-8'" in notices and "1e-07 to 0.0001" in notices
    # the URL contract: the page goes on with the default step; what runs is that cheap point
    seen = recorder(monkeypatch, E, "explorer_view")
    ks, amps, phs = rows()
    out, text = bounded(E.explorer_outputs, 1500, 200, ks, amps, phs, 20.0, [], [], "pi", [], {"set": None, "overrides": {}},
                        initial=True)
    (system, state), = seen
    assert system.solver.time_step == pytest.approx(default_parameters().solver.time_step) and state["duration"] == 20.0
    assert costs.admit(costs.point_cost(system, 20.0)) == "run"


def test_explorer_refuses_points_too_large_to_compute_while_the_browser_waits(pages, monkeypatch):
    E = pages.explorer
    monkeypatch.setenv(costs.BUDGET_ENV, "1e12")  # a generous server: the foreground limit still holds
    monkeypatch.setenv(costs.BYTES_ENV, str(64 * 2**30))
    no_compute(monkeypatch, E, "explorer_view")
    ks, amps, phs = rows()
    # 2e8 steps of 86 DOFs: about 19 minutes of one core at costs.STEP_DOF_PER_SECOND
    params = {"set": None, "overrides": {"solver.time_step": 1e-7}}
    out, text = bounded(E.explorer_outputs, 1500, 200, ks, amps, phs, 20.0, [], [], "pi", [], params, run=True)
    assert out["error"] and "dampersim simulate" in text


@pytest.mark.parametrize("page", ["explorer", "segments"])
def test_point_above_the_memory_budget_is_refused(pages, monkeypatch, page):
    module = getattr(pages, page)
    no_compute(monkeypatch, module, f"{page}_view")
    ks, amps, phs = rows()
    params = {"set": None, "overrides": {"solver.time_step": 1e-7}}  # in range: 2e8 steps, a 1.6 GB torque grid
    if page == "explorer":
        out, text = bounded(module.explorer_outputs, 1500, 200, ks, amps, phs, 20.0, [], [], "pi", [], params, run=True)
    else:
        out, text = bounded(module.segments_outputs, 1500, 200, ks, amps, phs, 20.0, "outer", 0.2, 0.04, 5, params, run=True)
    assert out["error"] and "Refused" in text and "GB" in text and costs.BYTES_ENV in text


def test_explorer_waits_for_run_above_the_autostart_budget(pages, monkeypatch):
    E = pages.explorer
    monkeypatch.setenv(costs.AUTOSTART_ENV, "1e6")  # below one 1.2 s point (1.2e7 step·DOF)
    ks, amps, phs = rows()
    args = (1500, 200, ks, amps, phs, 1.2, [], [], "pi", [], {"set": None, "overrides": {}})
    out = E.explorer_outputs(*args)
    assert out["pending"] and "DAMPERSIM_AUTOSTART_BUDGET" in text_of(out["notices"])
    res = E.update_explorer(*args, None)  # the callback shows the Run button
    assert res[-1] == {"display": "block"}
    out = E.explorer_outputs(*args, run=True)  # Run computes it
    assert out["figures"] and not out["pending"]


def test_explorer_posted_junk_gets_notices(pages, monkeypatch):
    E = pages.explorer
    ks, amps, phs = rows()
    junk = {"set": "../../etc", "overrides": {"solver.time_step": [1, 2], "solver.duration": "1e400"}}
    seen = recorder(monkeypatch, E, "explorer_view")
    out, text = bounded(E.explorer_outputs, 1500, 200, ks, amps, phs, 1e9, [], [], "pi", [], junk, initial=True)
    assert "duration" in text and "solver.time_step" in text
    (system, state), = seen  # what would run is the safe default
    assert state["duration"] == system.solver.duration and system.solver.time_step == pytest.approx(default_parameters().solver.time_step)


# ------------------------------------------------------------------------ range lists and maps
@pytest.mark.parametrize("page, key", [("colourmap", "speeds"), ("maps", "speeds"), ("maps", "torques"),
                                       ("hysteresis", "speeds")])
def test_repeated_range_lists_are_refused_before_expansion(pages, page, key):
    module = getattr(pages, page)
    long = ",".join([RANGE] * 40)  # the issue's 700-byte link: capped by its length
    lay, text = bounded(module.layout, **{key: long})
    assert "679 characters" in text_of(find(lay, f"{page}-link-notices"))
    short = ",".join([RANGE] * 25)  # 424 characters: counted from its numbers, never expanded
    lay, text = bounded(module.layout, **{key: short})
    notices = text_of(find(lay, f"{page}-link-notices"))
    assert "expands to 2499" in notices and "at most" in notices
    from dampersim.views.state import field

    assert control_value(lay, f"{page}-{key}") == field(page, key).default  # the safe default is what runs


def test_forty_million_point_map_starts_nothing(pages, monkeypatch):
    M = pages.maps
    link = {"speeds": "300:6000:14.3", "torques": "-500:1000:0.01501"}
    lay, text = bounded(M.layout, **link)
    notices = text_of(find(lay, "maps-link-notices"))
    assert "99934 torques" in notices and "3192 test points" in notices
    assert control_value(lay, "maps-torques") == "50:400:50"  # the default map (within autostart) replaces it
    no_compute(monkeypatch, M, "maps_view")
    ks, amps, phs = rows()
    values = [link["speeds"], link["torques"], ks, amps, phs, 2.6, 1.25, ["2"], 30, 200, 2]
    out, text = bounded(M.request, False, True, values, None, True)  # posted straight, autorun forced on
    assert "job" not in out and "99934 torques" in text


def test_map_over_the_point_limit_is_refused_even_when_each_list_is_small(pages):
    from dampersim.views.state import parse_query

    state, notices = parse_query("maps", {"speeds": "1000:4990:10", "torques": "50:100:50"})  # 400 x 2 points
    assert "800 test points" in notices[0]["text"] and state["speeds"] == "1000:2800:200"


# ------------------------------------------------------------------------ budgets on the background pages
def test_sweep_above_the_budget_is_refused_and_below_autostart_waits(pages, monkeypatch):
    C = pages.colourmap
    no_compute(monkeypatch, C, "colourmap_view")
    ks, amps, phs = rows()
    values = ["900:2800:50", 200, ks, amps, phs, 2.6, 1.25, 500, ["db"], ["2"]]
    monkeypatch.setenv(costs.BUDGET_ENV, "1e8")
    out, text = bounded(C.request, True, False, values, None, True)
    assert "job" not in out and "Refused" in text and "DAMPERSIM_BUDGET" in text
    estimate = float(re.search(r"(\d\.\de\d+) step·DOF", text).group(1))  # the refusal quotes the estimate
    assert 1e8 < estimate < 1e10  # above the budget that refused it, below the one that will admit it
    monkeypatch.setenv(costs.BUDGET_ENV, "1e10")
    monkeypatch.setenv(costs.AUTOSTART_ENV, "1e8")
    monkeypatch.setattr(C, "colourmap_view", lambda *a, **k: None)  # nothing cached
    out, text = bounded(C.request, False, True, values, None, True)  # a link: waits
    assert "job" not in out and "Press Run sweep" in text and "DAMPERSIM_AUTOSTART_BUDGET" in text
    out = C.request(True, False, values, None, True)  # Run starts it
    assert out["job"]["work"]


def test_hysteresis_ramps_are_counted(pages, monkeypatch):
    H = pages.hysteresis
    monkeypatch.setenv(costs.AUTOSTART_ENV, "1e7")
    monkeypatch.setattr(H, "hysteresis_view", lambda *a, **k: None)
    values = ["full-450", "1000,1500,2000,2500,3000,3500", 50, 2, "total", []]  # six ramps of 30 s
    out, text = bounded(H.request, False, True, values, None, True)
    assert "job" not in out and "6 loops of 30 s simulated time" in text and "Press Run ramps" in text
    values[2:4] = [5, 10]  # six ramps of 273 s: about 2 GB of records at 10 kHz
    out, text = bounded(H.request, True, False, values, None, True)
    assert "job" not in out and "Refused" in text and "DAMPERSIM_MEMORY_BUDGET" in text


# ------------------------------------------------------------------------ job data and tickets
@pytest.mark.parametrize("page", ["colourmap", "maps", "hysteresis"])
def test_crafted_job_data_never_runs(pages, monkeypatch, page):
    module = getattr(pages, page)
    no_compute(monkeypatch, module, f"{page}_view")
    crafted = {"state": {"speeds": "300:6000:14.3", "duration": 1e9, "torque": 200, "rate": 1e-9,
                         "params": {"overrides": {"solver.time_step": 1e-8}}}, "nonce": "x"}
    # the job callback as Dash calls it: without a ticket nothing of the posted data is used
    out, text = bounded(module.callbacks.job, lambda *a: None, crafted)
    assert out["error"] == "this request has expired; press Run"
    for ticket in ("0" * 32, "../../x", 12, None):
        out, _ = bounded(module.callbacks.job, lambda *a: None, {**crafted, "ticket": ticket})
        assert out["error"] == "this request has expired; press Run"
    # the page's job re-parses a state whatever its origin
    out, text = bounded(module.job, crafted, lambda *a: None)
    assert "not valid any more" in out["error"] and "press Run" in out["error"]


def test_ticket_round_trip_rechecks_the_budget(pages, monkeypatch):
    from dampersim.views import tickets
    from dampersim.views.state import parse_query

    C = pages.colourmap
    state, _ = parse_query("colourmap", {"speeds": "1400,1600", "duration": "1.2", "window": "0.5"})
    ticket = tickets.issue("colourmap", state, "k")
    assert tickets.redeem(ticket, "maps") is None  # a ticket is for its page only
    monkeypatch.setenv(costs.BUDGET_ENV, "1e5")  # the server's budget dropped since the request
    no_compute(monkeypatch, C, "colourmap_view")
    out, text = bounded(C.callbacks.job, lambda *a: None, {"ticket": ticket, "work": "k", "nonce": "n"})
    assert "Refused" not in text and "DAMPERSIM_BUDGET" in out["error"] and out["nonce"] == "n"
    monkeypatch.setattr(tickets, "TICKET_TTL_S", -1.0)  # expired
    out = C.callbacks.job(lambda *a: None, {"ticket": ticket, "work": "k", "nonce": "n"})
    assert out["error"] == "this request has expired; press Run"


def test_errors_reach_the_page_without_traceback_or_path(pages, monkeypatch):
    C = pages.colourmap
    from dampersim.views import tickets
    from dampersim.views.state import parse_query

    def boom(*a, **k):
        raise RuntimeError("failed at /srv/secret/server/file.py line 3")

    state, _ = parse_query("colourmap", {"speeds": "1500", "duration": "1.2", "window": "0.5"})
    monkeypatch.setattr(C, "colourmap_view", boom)
    out, text = bounded(C.callbacks.job, lambda *a: None, {"ticket": tickets.issue("colourmap", state), "nonce": "n"})
    assert "incident" in out["error"] and "secret" not in text
    shown, text = bounded(C.show, out)
    assert "incident" in text and "secret" not in text
    monkeypatch.setattr(C, "render", boom)
    monkeypatch.setattr("pages._jobs.load_view", lambda key: {"summary": {}})
    shown, text = bounded(C.show, {"key": "abc"})
    assert "incident" in text and "secret" not in text
    shown, text = bounded(C.show, {"key": ["not", "a", "key"], "status": {"x": 1}})
    assert "no longer in the cache" in text


def test_query_length_is_capped(pages):
    lay, text = bounded(pages.explorer.layout, **{f"k{i}.x": "1" * 100 for i in range(50)}, speed="2000")
    notices = text_of(find(lay, "explorer-link-notices"))
    assert "accepted are at most 4096" in notices and find(lay, "explorer-speed").value == 1500.0


def test_stored_parameter_set_is_validated_once(pages, monkeypatch):
    import dampersim.views.params as P
    from dampersim.parameters import default_parameters, with_updates
    from dampersim.views.state import parse_query
    from dampersim.views.store import store_parameter_set

    set_id = store_parameter_set(with_updates(default_parameters(), {"inertias.primary": 0.3}))
    calls = []
    real = P.time_step_note
    monkeypatch.setattr(P, "time_step_note", lambda s: calls.append(1) or real(s))
    real_load = P.loads_toml
    monkeypatch.setattr(P, "loads_toml", lambda t: calls.append(2) or real_load(t))
    query = {"set": set_id, "inertias.secondary": "0.05"}
    parse_query("explorer", query)
    first = len(calls)
    for _ in range(3):
        parse_query("explorer", query)
    assert first >= 1 and len(calls) == first  # later page loads reuse the validated set
