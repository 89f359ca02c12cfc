"""Every page's layout and callbacks called directly as plain functions (no browser)."""

from __future__ import annotations

import base64
import json
import os
import subprocess
import sys
import textwrap
from contextvars import copy_context
from pathlib import Path

import pytest
from dash import no_update

from dampersim import default_parameters, views

ROOT = Path(__file__).resolve().parents[2]
SHORT = 1.2


@pytest.fixture(scope="module")
def app_module():
    import app

    return app


@pytest.fixture
def pages(app_module):
    """The page modules as Dash loaded them (Dash executes each page file once)."""
    from types import SimpleNamespace

    names = ("explorer", "colourmap", "hysteresis", "segments", "maps", "parameters")
    return SimpleNamespace(**{n: sys.modules[f"pages.{n}"] for n in names})


def as_json(component) -> str:
    return json.dumps(component, default=lambda c: c.to_plotly_json() if hasattr(c, "to_plotly_json") else str(c))


def find(component, cid):
    """The component with id ``cid`` in a layout tree."""
    if getattr(component, "id", None) == cid:
        return component
    children = getattr(component, "children", None)
    for child in children if isinstance(children, (list, tuple)) else [children]:
        if hasattr(child, "to_plotly_json"):
            hit = find(child, cid)
            if hit is not None:
                return hit
    return None


def with_triggers(fn, prop_ids, *args):
    """Run a callback that reads dash.ctx as if ``prop_ids`` had triggered it."""
    from dash._callback_context import context_value
    from dash._utils import AttributeDict

    def run():
        context_value.set(AttributeDict(triggered_inputs=[{"prop_id": p, "value": None} for p in prop_ids]))
        return fn(*args)

    return copy_context().run(run)


# ----------------------------------------------------------------------------- layouts
@pytest.mark.parametrize("page", ["explorer", "colourmap", "hysteresis", "segments", "maps", "parameters"])
def test_every_layout_renders_with_and_without_a_query(pages, page):
    module = getattr(pages, page)
    assert find(module.layout(), f"{page}-url") is not None  # page-local Location for the URL state
    assert find(module.layout(), f"{page}-link-text") is not None  # copy-link bar
    text = as_json(module.layout(foo="bar"))  # unknown keys: ignored, no notice
    assert "could not be used" not in text


def test_explorer_layout_shows_link_values_and_notices(pages):
    lay = pages.explorer.layout(speed="2100", torque="260", orders="2:250,4:80@90", **{"solver.outer_segments": "12"})
    assert find(lay, "explorer-speed").value == 2100.0
    assert find(lay, "explorer-torque").value == 260.0
    assert find(lay, {"type": "explorer-order", "field": "ph", "row": 1}).value == 90.0
    assert find(lay, {"type": "explorer-param", "name": "solver.outer_segments"}).value == 12
    bad = pages.explorer.layout(speed="fast", torque="1e9")
    text = as_json(find(bad, "explorer-link-notices"))
    assert "speed='fast'" in text and "torque='1e9'" in text and "Using 1500 rpm" in text
    assert find(bad, "explorer-speed").value == 1500.0


@pytest.mark.parametrize("page, query, expect", [
    ("colourmap", {"speeds": "1:2:3"}, "speeds='1:2:3'"),
    ("hysteresis", {"protocol": "full-999"}, "protocol='full-999'"),
    ("segments", {"spring": "middle"}, "spring='middle'"),
    ("maps", {"torques": "a,b"}, "torques='a,b'"),
    ("parameters", {"inertias.primary": "0"}, "Parameter inertias.primary"),
])
def test_bad_link_values_show_a_notice_on_every_page(pages, page, query, expect):
    text = as_json(find(getattr(pages, page).layout(**query), f"{page}-link-notices"))
    assert expect in text and "notice-warning" in text


# ----------------------------------------------------------------------------- explorer
def explorer_args(speed=1600.0, torque=180.0, orders=((2, 300, 0), (4, 80, 90)), duration=SHORT, params=None, **param_values):
    names = ["solver.outer_segments", "solver.inner_segments"]
    sv = default_parameters().solver  # the controls show the default set's counts
    values = [param_values.get("outer", sv.outer_segments), param_values.get("inner", sv.inner_segments)]
    ks = [o[0] for o in orders] + [None] * (6 - len(orders))
    amps = [o[1] for o in orders] + [None] * (6 - len(orders))
    phs = [o[2] for o in orders] + [None] * (6 - len(orders))
    ids = [{"type": "explorer-param", "name": n} for n in names]
    return (speed, torque, ks, amps, phs, duration, values, ["friction.enabled", "hardstops.enabled"], "pi", ids,
            params or {"set": None, "overrides": {}})


def test_explorer_outputs_good_state(pages, cache_dir):
    out = pages.explorer.explorer_outputs(*explorer_args())
    assert out["error"] is None and out["notices"] == []
    assert set(out["figures"]) == {"traces", "spectrum", "mr", "windup", "energy"}
    q = dict(p.split("=", 1) for p in out["search"][1:].split("&"))
    assert q["speed"] == "1600" and q["torque"] == "180" and q["orders"] == "2:300,4:80@90" and q["duration"] == "1.2"
    mr = out["figures"]["mr"]["data"][0]
    assert list(mr["x"]) == ["2", "4"] and all(0 < y < 1 for y in mr["y"])


def test_explorer_control_changes_go_into_the_url(pages, cache_dir):
    out = pages.explorer.explorer_outputs(*explorer_args(outer=12))
    assert "solver.outer_segments=12" in out["search"]
    assert out["params"]["overrides"] == {"solver.outer_segments": 12}
    # a control still showing the link's (rounded) value keeps the exact link value
    base = {"set": None, "overrides": {"inertias.primary": 0.2234567891}}
    names = ["inertias.primary"]
    args = list(explorer_args(params=base))
    args[6], args[9] = [0.2234568], [{"type": "explorer-param", "name": n} for n in names]
    out = pages.explorer.explorer_outputs(*args)
    assert out["params"]["overrides"]["inertias.primary"] == 0.2234567891


def test_explorer_refused_values_keep_the_previous_results(pages, cache_dir):
    out = pages.explorer.explorer_outputs(*explorer_args(speed=None, outer=500))
    assert out["error"] is None
    text = " ".join(n["text"] for n in out["notices"])
    assert "Speed (speed) is empty" not in text  # an empty slider value is "default", said once
    assert "solver.outer_segments" in text and "from 4 to 64" in text  # the page range of segment counts
    # a parameter set that cannot be simulated: an error notice, figures unchanged
    res = pages.explorer.update_explorer(*explorer_args(orders=((2, 300, 0),), params={"set": None, "overrides": {}}),
                                         "previous-key")
    assert res[0] is not no_update  # valid: new figures
    args = list(explorer_args())
    args[6] = [4, 4]
    args[2] = [2.0, None, None, None, None, None]
    args[3] = [5000.0, None, None, None, None, None]  # amplitude above the accepted 1000 N m
    res = pages.explorer.update_explorer(*args, "previous-key")
    notices = as_json(res[7])
    assert "1000 N m" in notices


def test_explorer_callback_keeps_figures_when_the_simulation_fails(pages, cache_dir, monkeypatch):
    from dampersim.errors import SimulationDiverged

    def boom(*a, **k):
        raise SimulationDiverged(0.5, "runaway speed", 2e-5)

    monkeypatch.setattr(pages.explorer, "explorer_view", boom)
    res = pages.explorer.update_explorer(*explorer_args(), "previous-key")
    assert res[:5] == (no_update,) * 5  # previous figures stay
    assert "diverged at t = 0.5" in as_json(res[7]) and "notice-error" in as_json(res[7])
    assert res[8] is no_update  # the URL keeps the last good state
    res = pages.explorer.update_explorer(*explorer_args(), None)  # nothing shown yet: an explicit error state
    assert "No result" in json.dumps(res[0])


def test_order_rows_to_text():
    from dampersim.views.state import orders_text_from_rows

    text, notes = orders_text_from_rows([2, None, 4.5, 6], [300, 50, None, 10], [0, None, 0, -30])
    assert text == "2:300,6:10@-30"
    assert "no amplitude" in notes[0]["text"]


# ----------------------------------------------------------------------------- background pages
def colourmap_values(speeds="1400,1600", cuts=("2", "4")):
    return [speeds, 200, [2, 4, None, None, None, None], [300, 100, None, None, None, None], [0, 0, None, None, None, None],
            SHORT, 0.5, 400, [], list(cuts)]


def test_colourmap_request_job_show(pages, cache_dir):
    cm = pages.colourmap
    base = {"set": None, "overrides": {}}
    out = cm.request(False, True, colourmap_values(), base, False)
    assert "job" not in out and "Not computed yet: 2 test points" in as_json(out["status"])
    assert out["search"].startswith("?speeds=1400,1600&torque=200")
    out = cm.request(True, False, colourmap_values(), base, False)
    assert out["job"]["state"]["speeds"] == "1400,1600"
    progress = []
    done = cm.job(out["job"], lambda d, t, text: progress.append((d, t, text)))
    assert "key" in done and progress[-1][0] == 2 and "2 / 2 test points" in progress[-1][2]
    shown = cm.show({**done, "nonce": "x"})
    assert shown[0]["data"][0]["type"] == "heatmap" and "Done in" in as_json(shown[-2])
    again = cm.request(False, True, colourmap_values(), base, True)  # a cache hit returns at once, no job
    assert again["hit"]["key"] == done["key"] and "job" not in again
    assert "Shown from the cache" in as_json(cm.show({**again["hit"], "nonce": "y"})[-2])


def test_colourmap_refuses_a_window_too_short_for_the_speeds(pages, cache_dir):
    vals = colourmap_values(speeds="400,600")
    vals[6] = 0.2
    out = pages.colourmap.request(True, False, vals, None, False)
    assert "job" not in out and "too short" in as_json(out["notices"])


def test_background_job_errors_are_reported_not_raised(pages, cache_dir, monkeypatch):
    from dampersim.sweeps.executor import SweepPointFailed

    def fail(*a, **k):
        raise SweepPointFailed(1500, 200, "SimulationDiverged", "simulation diverged at t = 0.4 s")

    state, _ = views.parse_query("colourmap", {"speeds": "1500", "duration": "1.2", "window": "0.5"})
    monkeypatch.setattr(pages.colourmap, "colourmap_view", fail)
    out = pages.colourmap.job({"state": state}, lambda *a: None)
    assert "1500 rpm" in out["error"] and "diverged" in out["error"]
    shown = pages.colourmap.show(out)
    assert all(v is no_update for v in shown[:4]) and "previous colourmaps are kept" in as_json(shown[-1])


def test_request_callback_through_dash_context(pages, cache_dir):
    cb = pages.colourmap.callbacks.request
    vals = colourmap_values()
    ids = ["colourmap-run.n_clicks", "colourmap-speeds.value", "colourmap-torque.value"]
    res = with_triggers(cb, ids, 0, *vals, {"set": None, "overrides": {}}, False)  # page load: every input listed
    assert res[5] is no_update and "Not computed yet" in as_json(res[3])
    res = with_triggers(cb, ["colourmap-run.n_clicks"], 1, *vals, {"set": None, "overrides": {}}, False)
    # the browser gets an opaque ticket, the view key and a nonce; the state stays on the server
    assert set(res[5]) == {"ticket", "work", "nonce"} and res[5]["nonce"]
    from dampersim.views import tickets

    assert tickets.redeem(res[5]["ticket"], "colourmap")["state"]["speeds"] == "1400,1600"
    res = with_triggers(cb, ["colourmap-speeds.value"], 1, *vals, {"set": None, "overrides": {}}, False)
    assert res[5] is no_update  # editing a control does not start a sweep
    assert "Cancelled" in as_json(pages.colourmap.callbacks.cancel(1))


def test_hysteresis_request_job_show(pages, cache_dir):
    h = pages.hysteresis
    values = ["full-100", "1500", 500, 0.2, "total", []]
    out = h.request(True, False, values, None, False)
    assert out["job"]["state"]["protocol"] == "full-100"
    progress = []
    done = h.job(out["job"], lambda d, t, text: progress.append(text))
    assert "key" in done and "1 / 1 speeds" in progress[-1]
    shown = h.show(done)
    assert shown[0]["data"] and "Knee" in as_json(shown[4])
    bad = h.request(False, False, ["full-100", "1500", 0, 0.2, "sideways", []], None, False)
    assert "rate=0" in as_json(bad["notices"]) and "windup='sideways'" in as_json(bad["notices"])


def test_maps_request_job_show(pages, cache_dir):
    m = pages.maps
    values = ["1500", "100,300", [2, 4, None, None, None, None], [300, 100, None, None, None, None],
              [0, 0, None, None, None, None], SHORT, 0.5, ["2", "4"], 30, 150, 2]  # 2 test points, 4 map points
    out = m.request(True, False, values, None, False)
    assert "job" in out
    done = m.job(out["job"], lambda *a: None)
    assert "key" in done, done
    shown = m.show(done)
    assert shown[0]["data"][0]["type"] == "heatmap" and "Largest MR" in as_json(shown[2])


def test_segments_callback(pages, cache_dir):
    s = pages.segments
    ks, amps, phs = [2, None, None, None, None, None], [300, None, None, None, None, None], [0, None, None, None, None, None]
    res = s.update_segments(1500, 200, ks, amps, phs, SHORT, "outer", 0.2, 0.02, 5, None, None)
    assert res[0]["frames"] and res[1]["data"][0]["type"] == "heatmap"
    assert "spring=outer" in res[5] and "span=0.02" in res[5]
    res = s.update_segments(1500, 200, ks, amps, phs, SHORT, "outer", 0.2, 99, 5, None, "k")
    assert "span=99" in as_json(res[4]) and "Using 0.04 s" in as_json(res[4])


# ----------------------------------------------------------------------------- parameters
def _upload(text):
    return "data:application/toml;base64," + base64.b64encode(text.encode()).decode()


def test_parameters_actions(pages, cache_dir):
    p = pages.parameters
    rows = p.table_rows(views.resolve_system(None))
    edited = [dict(r, value="0.3") if r["name"] == "inertias.primary" else r for r in rows]
    out = p.parameters_action("validate", edited, None)
    assert out["params"] is None and "Valid" in out["status"]["text"]
    out = p.parameters_action("apply", edited, None)
    assert out["params"]["overrides"] == {"inertias.primary": 0.3}
    bad = [dict(r, value="-2") if r["name"] == "outer.spring.stiffness" else r for r in out["rows"]]
    refused = p.parameters_action("apply", bad, out["params"])
    assert refused["params"] is None and "outer.spring.stiffness" in refused["notices"][0]["text"]
    up = p.parameters_action("upload", None, out["params"], _upload("[inertias]\nprimary = 'heavy'\n"), "x.toml")
    assert up["params"] is None and "x.toml" in up["notices"][0]["text"] and "unchanged" in up["notices"][0]["text"]
    good = views.parameters_toml(views.resolve_system({"set": None, "overrides": {"friction.outer.alpha": 0.4}}))
    up = p.parameters_action("upload", None, out["params"], _upload(good), "good.toml")
    assert up["params"] == {"set": None, "overrides": {"friction.outer.alpha": 0.4}}
    assert p.parameters_action("reset", None, up["params"])["params"] == {"set": None, "overrides": {}}


def test_parameters_callback_and_download(pages, cache_dir):
    p = pages.parameters
    params = {"set": None, "overrides": {"inertias.primary": 0.3}}
    res = with_triggers(p.on_action, ["parameters-validate.n_clicks", "parameters-apply.n_clicks"], 0, 0, 0, 0, None, [], [], params)
    assert res[4] == "?inertias.primary=0.3"  # page load mirrors the link state
    rows = p.table_rows(views.resolve_system(params))
    values = ["7" if r["name"] == "solver.outer_segments" else r["value"] for r in rows]
    ids = [{"type": "param-value", "name": r["name"]} for r in rows]
    res = with_triggers(p.on_action, ["parameters-apply.n_clicks"], 0, 1, 0, 0, None, values, ids, params)
    assert res[0]["overrides"] == {"inertias.primary": 0.3, "solver.outer_segments": 7}
    assert "solver.outer_segments=7" in res[4]
    dl = p.download(1, params)
    assert dl["filename"].endswith(".toml") and "primary = 0.3" in dl["content"]


# ----------------------------------------------------------------------------- fork safety
def test_numba_threading_layer_is_fork_safe_under_background_callbacks(tmp_path):
    """After the app is imported, a process that ran a parallel numba kernel can still fork
    a background job that runs parallel code (the default OpenMP layer kills the child)."""
    script = textwrap.dedent(
        """
        import sys
        sys.path.insert(0, %r)
        import app  # sets the threading layer before numba starts threads
        import numba, multiprocess
        from numba import njit, prange

        @njit(parallel=True)
        def total(n):
            s = 0.0
            for i in prange(n):
                s += i
            return s

        total(100000)
        def child(q):
            q.put(total(1000))
        q = multiprocess.Queue()
        p = multiprocess.Process(target=child, args=(q,))
        p.start(); p.join(60)
        print("LAYER", numba.threading_layer(), "EXIT", p.exitcode, "RESULT", q.get(timeout=5) if p.exitcode == 0 else None)
        """
        % str(ROOT)
    )
    env = {**os.environ, "DAMPERSIM_CACHE_DIR": str(tmp_path)}
    env.pop("NUMBA_THREADING_LAYER", None)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=180, env=env, cwd=tmp_path)
    assert "EXIT 0 RESULT 499500.0" in out.stdout, out.stdout + out.stderr
    assert "LAYER omp" not in out.stdout
