"""The URL contract of the Pulsation generator and Studies pages: a bad query value gives a
notice naming the key, the value, what is accepted and the default used, never an error
page; checked through the layout functions, through Dash's page callback over HTTP, and
with GET requests of a corpus of bad values on every page path.

Budgets: a layout call is pure validation (0.5 s); an HTTP request is answered from the
test client without running a simulation (5 s covers a loaded 2-core machine).
"""

from __future__ import annotations

import json
import re
import time
from urllib.parse import quote

import pytest

import app  # noqa: F401  (registers the pages)
from pages import pulsation, studies

LAYOUT_BUDGET_S = 0.5
REQUEST_BUDGET_S = 5.0
ABSOLUTE_PATH = re.compile(r"(?<![\w.:/])/(?:home|root|tmp|work|usr|var|opt|srv)/")
PATHS = ["/", "/explorer", "/colourmap", "/hysteresis", "/segments", "/maps", "/parameters", "/pulsation", "/studies",
         "/discrepancy"]
#: bad values for any key: text, empty, non-finite, huge, negative, markup, a path, control bytes
CORPUS = ["abc", "", "nan", "inf", "-inf", "1e309", "-1", "1e9", "0x10", "<script>alert(1)</script>",
          "/etc/passwd", "%00", "9" * 400, "1,2", "true", "🙂"]


def texts(component) -> str:
    data = component.to_plotly_json() if hasattr(component, "to_plotly_json") else component
    return json.dumps(data, default=lambda o: o.to_plotly_json(), ensure_ascii=False)


def notices_of(layout) -> str:
    return texts(layout.children[1].children)  # the link-notices area


def timed_layout(fn, **query):
    t0 = time.perf_counter()
    out = fn(**query)
    assert time.perf_counter() - t0 < LAYOUT_BUDGET_S
    return out


# --------------------------------------------------------------------------- layout functions
@pytest.mark.parametrize("key, value, accepted, default", [
    ("pressure", "abc", "a number from 0.5 to 4 bar abs", "Using 2.5 bar"),
    ("pressure", "9", "a number from 0.5 to 4 bar abs", "Using 2.5 bar"),
    ("pressure", "nan", "a number from 0.5 to 4 bar abs", "Using 2.5 bar"),
    ("speed", "-1", "a number from 500 to 4000 rpm", "Using 1500 rpm"),
    ("speed", "1e309", "a number from 500 to 4000 rpm", "Using 1500 rpm"),
    ("coupled", "perhaps", "true or false (1/0)", "Using 0"),
])
def test_pulsation_bad_value_notice(key, value, accepted, default):
    layout = timed_layout(pulsation.layout, **{key: value})
    text = notices_of(layout)
    assert f"{key}={value!r}" in text and f"accepted is {accepted}" in text and default in text


def test_pulsation_good_link_is_used_without_notice():
    layout = timed_layout(pulsation.layout, pressure="3.1", speed="2200", coupled="1")
    text = texts(layout)
    assert notices_of(layout) == "[]"
    assert '"value": 3.1' in text and '"value": 2200.0' in text and '"value": ["1"]' in text


def test_pulsation_repeated_key_and_long_value():
    layout = timed_layout(pulsation.layout, pressure=["3", "abc"], speed="9" * 5000)
    text = notices_of(layout)
    assert "given 2 times" in text and "…" in text and len(text) < 2000  # a long value is quoted cut short


@pytest.mark.parametrize("query, expect", [
    ({"study": "nope"}, ["study='nope'", "accepted is one of", "Using order-rule"]),
    ({"study": "../../etc"}, ["study='../../etc'", "Using order-rule"]),
    ({"quick": "maybe"}, ["quick='maybe'", "true or false (1/0)", "Using 1"]),
])
def test_studies_bad_value_notice(query, expect):
    text = notices_of(timed_layout(studies.layout, **query))
    for part in expect:
        assert part in text


def test_studies_good_link():
    from dampersim.views.studies import STUDY_NAMES

    layout = timed_layout(studies.layout, study=STUDY_NAMES[-1], quick="0")
    assert notices_of(layout) == "[]" and f'"value": "{STUDY_NAMES[-1]}"' in texts(layout)


@pytest.mark.parametrize("value", CORPUS)
@pytest.mark.parametrize("fn, keys", [(pulsation.layout, ("pressure", "speed", "coupled")),
                                      (studies.layout, ("study", "quick"))])
def test_layouts_never_raise(fn, keys, value):
    for key in keys:
        timed_layout(fn, **{key: value})


# --------------------------------------------------------------------------- callbacks with posted state
def _plain(f):
    return getattr(f, "__wrapped__", f)


@pytest.mark.parametrize("pressure, speed, coupled", [("abc", 1500, []), (2.5, None, []), (2.5, "1e400", []),
                                                       ({"x": 1}, 1500, []), (2.5, 1500, "maybe")])
def test_pulsation_run_refuses_posted_nonsense(pressure, speed, coupled):
    *_, message = _plain(pulsation.run)(1, pressure, speed, coupled)
    assert message and "Traceback" not in message and not ABSOLUTE_PATH.search(message)
    assert "accepted" in message


def test_pulsation_sweep_refuses_posted_nonsense():
    fig, message = _plain(pulsation.sweep)(lambda p: None, 1, "abc", [])
    assert "accepted" in message and "Traceback" not in message


@pytest.mark.parametrize("name", ["nope", ["order-rule"], None, {"a": 1}])
def test_study_run_refuses_posted_nonsense(name):
    figs, checks, doc = _plain(studies.run)(lambda p: None, 1, name, ["1"])
    text = texts(checks)
    assert figs == [] and doc == "" and "accepted is one of" in text and "Traceback" not in text


# --------------------------------------------------------------------------- HTTP
@pytest.fixture(scope="module")
def client():
    c = app.server.test_client()
    assert c.get("/").status_code == 200
    deps = c.get("/_dash-dependencies").get_json()
    spec = next(d for d in deps if "_pages_content.children" in d["output"])
    return c, spec


def page_layout_over_http(client, path, search):
    c, spec = client
    out = spec["output"]
    outputs = ([dict(zip(("id", "property"), p.rsplit(".", 1))) for p in out[2:-2].split("...")]
               if out.startswith("..") else dict(zip(("id", "property"), out.rsplit(".", 1))))
    values = {"_pages_location.pathname": path, "_pages_location.search": search}
    inputs = [{"id": d["id"], "property": d["property"], "value": values.get(f"{d['id']}.{d['property']}")}
              for d in spec["inputs"]]
    state = [{"id": d["id"], "property": d["property"], "value": values.get(f"{d['id']}.{d['property']}")}
             for d in spec["state"]]
    body = {"output": out, "outputs": outputs, "inputs": inputs, "state": state,
            "changedPropIds": [f"{d['id']}.{d['property']}" for d in spec["inputs"]]}
    t0 = time.perf_counter()
    r = c.post("/_dash-update-component", json=body)
    assert time.perf_counter() - t0 < REQUEST_BUDGET_S
    return r


@pytest.mark.parametrize("path, search, expect", [
    ("/pulsation", "?pressure=abc", "pressure='abc'"),
    ("/pulsation", "?speed=1e309&coupled=2", "speed='1e309'"),
    ("/pulsation", "?pressure=%3Cscript%3E", "pressure='<script>'"),
    ("/studies", "?study=nope&quick=x", "study='nope'"),
])
def test_page_callback_shows_the_notice(client, path, search, expect):
    r = page_layout_over_http(client, path, search)
    text = r.get_data(as_text=True)
    assert r.status_code == 200 and "Traceback" not in text and not ABSOLUTE_PATH.search(text)
    assert expect in json.dumps(r.get_json(), ensure_ascii=False)


@pytest.mark.parametrize("path", ["/pulsation", "/studies"])
@pytest.mark.parametrize("value", CORPUS)
def test_page_callback_corpus(client, path, value):
    keys = ("pressure", "speed", "coupled") if path == "/pulsation" else ("study", "quick")
    search = "?" + "&".join(f"{k}={quote(value)}" for k in keys)
    r = page_layout_over_http(client, path, search)
    text = r.get_data(as_text=True)
    assert r.status_code == 200 and "Traceback" not in text and not ABSOLUTE_PATH.search(text)


@pytest.mark.parametrize("path", PATHS)
def test_every_page_path_with_bad_values(client, path):
    c, _ = client
    keys = ("pressure", "speed", "coupled", "study", "quick", "torque", "orders", "duration", "speeds", "set")
    for value in CORPUS:
        t0 = time.perf_counter()
        r = c.get(path + "?" + "&".join(f"{k}={quote(value)}" for k in keys))
        assert time.perf_counter() - t0 < REQUEST_BUDGET_S
        text = r.get_data(as_text=True)
        assert r.status_code == 200, (path, value)
        assert "Traceback" not in text and not ABSOLUTE_PATH.search(text), (path, value)
