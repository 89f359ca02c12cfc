"""The dashboard through Dash's HTTP endpoints (``app.server.test_client()``), no browser."""

from __future__ import annotations

import base64
import json
import time

import pytest

from dampersim import views

SHORT = 1.2


@pytest.fixture(scope="module")
def dash_app():
    import app

    return app.app


class DashClient:
    """Calls callbacks the way the browser does: POST /_dash-update-component."""

    def __init__(self, app):
        self.client = app.server.test_client()
        assert self.client.get("/").status_code == 200  # the first request sets up the pages router
        self.deps = self.client.get("/_dash-dependencies").get_json()

    def spec(self, output_part):
        hits = [d for d in self.deps if output_part in d["output"]]
        assert hits, f"no callback writes {output_part}"
        return hits[0]

    @staticmethod
    def _outputs(spec):
        out = spec["output"]
        if not out.startswith(".."):  # a single output travels as one object
            return dict(zip(("id", "property"), out.rsplit(".", 1)))
        return [dict(zip(("id", "property"), p.rsplit(".", 1))) for p in out[2:-2].split("...")]

    @staticmethod
    def _items(deps, values):
        items = []
        for dep in deps:
            key = f"{dep['id']}.{dep['property']}"
            if dep["id"].startswith("{"):  # pattern-matching (ALL): a list of concrete items
                items.append([{"id": cid, "property": dep["property"], "value": v} for cid, v in values.get(key, [])])
            else:
                items.append({"id": dep["id"], "property": dep["property"], "value": values.get(key)})
        return items

    def body(self, output_part, values, changed=None):
        spec = self.spec(output_part)
        inputs = self._items(spec["inputs"], values)
        if changed is None:  # a page's first call lists every input
            changed = [f"{d['id']}.{d['property']}" for d in spec["inputs"]]
        return {"output": spec["output"], "outputs": self._outputs(spec), "inputs": inputs,
                "state": self._items(spec["state"], values), "changedPropIds": changed}

    def call(self, output_part, values, changed=None, query=""):
        r = self.client.post("/_dash-update-component" + query, json=self.body(output_part, values, changed))
        return r

    def layout(self, path, search=""):
        r = self.call("_pages_content.children", {"_pages_location.pathname": path, "_pages_location.search": search})
        assert r.status_code == 200, r.data[:500]
        return json.dumps(r.get_json(), ensure_ascii=False, separators=(",", ":"))  # readable text: no \u escapes


@pytest.fixture
def dc(dash_app):
    return DashClient(dash_app)


def rows(prefix, ks, amps, phs):
    def ids(field):
        return [({"field": field, "row": i, "type": f"{prefix}-order"}, v) for i, v in enumerate(list(ks if field == "k" else amps if field == "a" else phs) + [None] * (6 - len(ks)))]

    return {f'{{"field":"{f}","row":["ALL"],"type":"{prefix}-order"}}.value': ids(f) for f in ("k", "a", "ph")}


def explorer_values(speed=1700, torque=150, duration=SHORT, outer=48):
    # the default set's values: 48/16 segments, 0.2 kg m^2 primary inertia
    names = ["solver.outer_segments", "solver.inner_segments", "inertias.primary"]
    vals = [outer, 16, 0.2]
    pid = '{"name":["ALL"],"type":"explorer-param"}'
    v = {
        "explorer-speed.value": speed, "explorer-torque.value": torque, "explorer-duration.value": duration,
        "explorer-switches.value": ["friction.enabled", "hardstops.enabled"], "explorer-motor.value": "pi",
        "explorer-base-params.data": {"set": None, "overrides": {}}, "explorer-last-good.data": None,
        f"{pid}.value": [({"name": n, "type": "explorer-param"}, x) for n, x in zip(names, vals)],
        f"{pid}.id": [({"name": n, "type": "explorer-param"}, {"name": n, "type": "explorer-param"}) for n in names],
    }
    v.update(rows("explorer", [2, 4], [300, 100], [0, 90]))
    return v


# ----------------------------------------------------------------------------- pages and links
@pytest.mark.parametrize("path", ["/", "/explorer?speed=2100&torque=260", "/colourmap", "/hysteresis", "/segments", "/maps",
                                  "/parameters", "/explorer?speed=%ZZ&&&=="])
def test_every_page_is_served(dash_app, path):
    r = dash_app.server.test_client().get(path)
    assert r.status_code == 200 and b"_dash-renderer" in r.data


def test_layout_from_a_good_link(dc):
    text = dc.layout("/explorer", "?speed=2100&torque=260&orders=2:250,4:80@90&solver.outer_segments=12")
    assert '"id":"explorer-speed"' in text and '"value":2100.0' in text and '"value":260.0' in text
    assert "could not be used" not in text
    assert dc.layout("/", "?speed=2100").count('"value":2100.0') >= 1  # "/" is the Explorer too


@pytest.mark.parametrize("path, search, expect", [
    ("/explorer", "?speed=abc&torque=99999&unknown=1", ["speed='abc'", "torque='99999'"]),
    ("/colourmap", "?speeds=900:800:10&db=perhaps", ["STOP (800) is below START (900)", "db='perhaps'"]),
    ("/hysteresis", "?rate=-5", ["rate='-5'"]),
    ("/segments", "?gain=1000", ["gain='1000'"]),
    ("/maps", "?fmin=300&fmax=100", ["fmin < fmax"]),
    ("/parameters", "?inertias.primary=-1&set=nothex", ["Parameter inertias.primary", "not a valid set id"]),
])
def test_bad_query_strings_give_visible_notices(dc, path, search, expect):
    text = dc.layout(path, search)
    assert "notice-warning" in text
    for e in expect:
        assert e in text, e


def test_unknown_page_is_a_404_page_not_an_error(dc):
    assert "404" in dc.layout("/no-such-page")


def ticket_state(job, page):
    """The state a job's ticket stands for (the browser holds only the ticket)."""
    from dampersim.views import tickets

    assert set(job) == {"ticket", "work", "nonce"}
    return tickets.redeem(job["ticket"], page)["state"]


# ----------------------------------------------------------------------------- explorer
def test_explorer_callback_over_http(dc, cache_dir):
    t0 = time.perf_counter()
    r = dc.call("explorer-traces.figure", explorer_values())
    first = time.perf_counter() - t0
    assert r.status_code == 200
    resp = r.get_json()["response"]
    assert resp["explorer-mr"]["figure"]["data"][0]["x"] == ["2", "4"]
    search = resp["explorer-url"]["search"]
    assert "speed=1700" in search and "orders=2:300,4:100@90" in search and "duration=1.2" in search
    assert resp["shared-params"]["data"] == {"set": None, "overrides": {}}
    # the same state again: from the view cache
    t0 = time.perf_counter()
    r = dc.call("explorer-traces.figure", explorer_values(), changed=["explorer-speed.value"])
    again = time.perf_counter() - t0
    assert "from cache" in json.dumps(r.get_json()["response"]["explorer-kpis"])
    assert again < first


def test_explorer_bad_inputs_over_http_and_the_server_keeps_serving(dc, cache_dir):
    r = dc.call("explorer-traces.figure", explorer_values(speed=9000, outer=999), changed=["explorer-speed.value"])
    assert r.status_code == 200
    notices = json.dumps(r.get_json()["response"]["explorer-run-notices"])
    assert "speed=9000" in notices and "solver.outer_segments" in notices
    assert dc.client.get("/_dash-layout").status_code == 200


# ----------------------------------------------------------------------------- colourmap (background)
def colourmap_values(speeds="1400,1600", run=0):
    v = {"colourmap-run.n_clicks": run, "colourmap-speeds.value": speeds, "colourmap-torque.value": 200,
         "colourmap-duration.value": SHORT, "colourmap-window.value": 0.5, "colourmap-fmax.value": 400,
         "colourmap-db.value": [], "colourmap-cuts.value": ["2", "4"],
         "colourmap-base-params.data": {"set": None, "overrides": {}}, "colourmap-autorun.data": False}
    v.update(rows("colourmap", [2, 4], [300, 100], [0, 0]))
    return v


def test_colourmap_request_then_background_job_then_cache_hit(dc, cache_dir):
    r = dc.call("colourmap-url.search", colourmap_values())
    resp = r.get_json()["response"]
    assert "Not computed yet: 2 test points" in json.dumps(resp["colourmap-status"])
    assert "colourmap-job" not in resp
    r = dc.call("colourmap-url.search", colourmap_values(run=1), changed=["colourmap-run.n_clicks"])
    job = r.get_json()["response"]["colourmap-job"]["data"]
    assert ticket_state(job, "colourmap")["speeds"] == "1400,1600"

    # the background callback: Dash forks a job process and the browser polls for the result
    body = dc.body("colourmap-done.data", {"colourmap-job.data": job}, changed=["colourmap-job.data"])
    r = dc.client.post("/_dash-update-component", json=body)
    assert r.status_code == 200, r.data[:300]
    started = r.get_json()
    assert "cacheKey" in started and "job" in started
    query = f"?cacheKey={started['cacheKey']}&job={started['job']}"
    deadline = time.monotonic() + 120
    result = None
    while time.monotonic() < deadline:
        r = dc.client.post("/_dash-update-component" + query, json=body)
        if r.status_code == 200 and "response" in (r.get_json() or {}):
            result = r.get_json()["response"]
            break
        time.sleep(0.3)
    assert result is not None, "the background job did not finish"
    done = result["colourmap-done"]["data"]
    assert "key" in done, done

    r = dc.call("colourmap-graph.figure", {"colourmap-hit.data": None, "colourmap-done.data": done},
                changed=["colourmap-done.data"])
    resp = r.get_json()["response"]
    assert resp["colourmap-graph"]["figure"]["data"][0]["type"] == "heatmap"
    # asking again: a cache hit, answered at once without a job
    r = dc.call("colourmap-url.search", colourmap_values(run=2), changed=["colourmap-run.n_clicks"])
    resp = r.get_json()["response"]
    assert "colourmap-job" not in resp and resp["colourmap-hit"]["data"]["key"] == done["key"]


def test_colourmap_invalid_sweep_is_refused_over_http(dc, cache_dir):
    v = colourmap_values(speeds="400,600", run=1)
    v["colourmap-window.value"] = 0.2
    r = dc.call("colourmap-url.search", v, changed=["colourmap-run.n_clicks"])
    resp = r.get_json()["response"]
    assert "colourmap-job" not in resp and "too short" in json.dumps(resp["colourmap-run-notices"])


# ----------------------------------------------------------------------------- parameters
def _upload(text):
    return "data:application/toml;base64," + base64.b64encode(text.encode()).decode()


def parameters_values(contents=None, filename=None, apply=0):
    return {"parameters-validate.n_clicks": 0, "parameters-apply.n_clicks": apply, "parameters-undo.n_clicks": 0,
            "parameters-reset.n_clicks": 0,
            "parameters-upload-data.data": {"contents": contents, "filename": filename} if contents else None,
            '{"name":["ALL"],"type":"param-value"}.value': [], '{"name":["ALL"],"type":"param-value"}.id': [],
            "parameters-params.data": {"set": None, "overrides": {"inertias.primary": 0.3}}}


def test_parameter_upload_over_http(dc, cache_dir):
    r = dc.call("parameters-params.data", parameters_values(_upload("not = [valid"), "broken.toml"),
                changed=["parameters-upload-data.data"])
    resp = r.get_json()["response"]
    assert "parameters-params" not in resp and "broken.toml" in json.dumps(resp["parameters-run-notices"])
    good = views.parameters_toml(views.resolve_system({"set": None, "overrides": {"solver.inner_segments": 10}}))
    r = dc.call("parameters-params.data", parameters_values(_upload(good), "good.toml"), changed=["parameters-upload-data.data"])
    resp = r.get_json()["response"]
    assert resp["parameters-params"]["data"] == {"set": None, "overrides": {"solver.inner_segments": 10}}
    assert resp["parameters-url"]["search"] == "?solver.inner_segments=10"


def test_navbar_links_carry_the_parameter_set(dc):
    r = dc.call("nav-explorer.href", {"shared-params.data": {"set": None, "overrides": {"inertias.primary": 0.3}}},
                changed=["shared-params.data"])
    resp = r.get_json()["response"]
    assert resp["nav-maps"]["href"] == "/maps?inertias.primary=0.3"


# ----------------------------------------------------------------------------- other pages over HTTP
def test_segments_callback_over_http(dc, cache_dir):
    v = {"segments-speed.value": 1500, "segments-torque.value": 200, "segments-duration.value": SHORT,
         "segments-spring.value": "pair_inner", "segments-window.value": 0.1, "segments-span.value": 0.02,
         "segments-gain.value": 5, "segments-base-params.data": {"set": None, "overrides": {}}}
    v.update(rows("segments", [2], [300], [0]))
    resp = dc.call("segments-animation.figure", v).get_json()["response"]
    assert resp["segments-animation"]["figure"]["frames"]
    assert resp["segments-heatmap"]["figure"]["data"][0]["type"] == "heatmap"
    assert "spring=pair_inner" in resp["segments-url"]["search"]
    v["segments-gain.value"] = -3
    resp = dc.call("segments-animation.figure", v, changed=["segments-gain.value"]).get_json()["response"]
    assert "gain=-3" in json.dumps(resp["segments-run-notices"])


def test_hysteresis_request_over_http(dc, cache_dir):
    v = {"hysteresis-run.n_clicks": 0, "hysteresis-protocol.value": "full-100", "hysteresis-speeds.value": "1500",
         "hysteresis-rate.value": 500, "hysteresis-hold.value": 0.2, "hysteresis-windup.value": "outer",
         "hysteresis-lowpass.value": ["on"], "hysteresis-base-params.data": None, "hysteresis-autorun.data": False}
    resp = dc.call("hysteresis-url.search", v).get_json()["response"]
    assert "Not computed yet: 1 loop" in json.dumps(resp["hysteresis-status"])
    assert resp["hysteresis-url"]["search"] == "?protocol=full-100&speeds=1500&rate=500&hold=0.2&windup=outer&lowpass=true"
    v["hysteresis-run.n_clicks"] = 1
    resp = dc.call("hysteresis-url.search", v, changed=["hysteresis-run.n_clicks"]).get_json()["response"]
    assert ticket_state(resp["hysteresis-job"]["data"], "hysteresis")["windup"] == "outer"


def test_maps_request_over_http(dc, cache_dir):
    v = {"maps-run.n_clicks": 0, "maps-speeds.value": "1200:1600:200", "maps-torques.value": "100,300",
         "maps-duration.value": SHORT, "maps-window.value": 0.5, "maps-map-orders.value": ["2"], "maps-fmin.value": 30,
         "maps-fmax.value": 120, "maps-curve-order.value": 2, "maps-base-params.data": None, "maps-autorun.data": True}
    v.update(rows("maps", [2], [300], [0]))
    resp = dc.call("maps-url.search", v).get_json()["response"]  # a shared link starts the map at once
    assert ticket_state(resp["maps-job"]["data"], "maps")["torques"] == "100,300"
    v["maps-fmin.value"] = 500
    resp = dc.call("maps-url.search", v, changed=["maps-fmin.value"]).get_json()["response"]
    assert "fmin" in json.dumps(resp["maps-run-notices"]) and "maps-job" not in resp
