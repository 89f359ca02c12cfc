"""End-to-end: the dashboard in headless Chromium (Playwright), one server per test.

Each test starts ``app.py`` on a free 127.0.0.1 port with its own empty result cache
(DAMPERSIM_CACHE_DIR in a temporary folder) and stops it afterwards. The screenshots of
the README (docs/screenshots/*.png, 1400 x 900) are written by these tests.
"""

from __future__ import annotations

import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

pytestmark = pytest.mark.e2e

ROOT = Path(__file__).resolve().parents[2]
CHROMIUM = "/usr/bin/chromium"
SHOTS = ROOT / "docs" / "screenshots"
VIEWPORT = {"width": 1400, "height": 900}
LAUNCH_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
               "--disable-sync", "--no-first-run"]
#: Starting the server may include compiling the numba kernel once (cached afterwards).
START_TIMEOUT = 240.0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def server(tmp_path):
    """URL of a fresh dashboard server with its own empty cache."""
    if not os.path.exists(CHROMIUM):
        pytest.skip(f"{CHROMIUM} not found")
    port = _free_port()
    env = {**os.environ, "DAMPERSIM_CACHE_DIR": str(tmp_path / "cache"), "PYTHONUNBUFFERED": "1"}
    log = open(tmp_path / "server.log", "w")
    proc = subprocess.Popen([sys.executable, str(ROOT / "app.py"), "--host", "127.0.0.1", "--port", str(port)], cwd=ROOT,
                            env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    url = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + START_TIMEOUT
    try:
        while True:
            if proc.poll() is not None:
                raise RuntimeError("the dashboard server exited:\n" + (tmp_path / "server.log").read_text()[-3000:])
            try:
                with urllib.request.urlopen(url + "/", timeout=2) as r:
                    if r.status == 200:
                        break
            except OSError:
                pass
            if time.monotonic() > deadline:
                raise RuntimeError("the dashboard server did not start:\n" + (tmp_path / "server.log").read_text()[-3000:])
            time.sleep(0.3)
        yield url
    finally:
        # the server and the background jobs it forked form one process group
        for sig, wait in ((signal.SIGTERM, 10), (signal.SIGKILL, 5)):
            try:
                os.killpg(proc.pid, sig)
            except ProcessLookupError:
                break
            try:
                proc.wait(wait)
                break
            except subprocess.TimeoutExpired:
                continue
        log.close()


@pytest.fixture(scope="module")
def browser():
    if not os.path.exists(CHROMIUM):
        pytest.skip(f"{CHROMIUM} not found")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=LAUNCH_ARGS)
        yield b
        b.close()


@pytest.fixture
def page(browser):
    context = browser.new_context(viewport=VIEWPORT)
    pg = context.new_page()
    pg.set_default_timeout(60_000)
    errors = []
    pg.on("pageerror", lambda e: errors.append(str(e)))
    yield pg
    context.close()
    assert not errors, f"JavaScript errors in the page: {errors}"


def graph_data(page, gid):
    """The data of a Plotly graph as the browser holds it (typed arrays made plain)."""
    return page.evaluate(
        """(gid) => {
            const gd = document.querySelector('#' + gid + ' .js-plotly-plot');
            if (!gd || !gd.data) { return null; }
            return gd.data.map(t => ({type: t.type, x: t.x ? Array.from(t.x) : null, y: t.y ? Array.from(t.y) : null}));
        }""",
        gid,
    )


def wait_for_graph(page, gid, trace_type=None, timeout=90_000):
    page.wait_for_function(
        """([gid, type]) => {
            const gd = document.querySelector('#' + gid + ' .js-plotly-plot');
            return gd && gd.data && gd.data.length > 0 && (!type || gd.data.some(t => t.type === type));
        }""",
        arg=[gid, trace_type],
        timeout=timeout,
    )


def graph_title(page, gid):
    return page.evaluate("(gid) => { const gd = document.querySelector('#' + gid + ' .js-plotly-plot');"
                         " return gd && gd.layout && gd.layout.title ? gd.layout.title.text : null; }", gid)


def screenshot(page, name):
    SHOTS.mkdir(parents=True, exist_ok=True)
    path = SHOTS / name
    page.evaluate("window.scrollTo(0, 0)")
    page.mouse.move(5, 890)  # no hover labels in the picture
    time.sleep(0.5)
    page.screenshot(path=str(path))
    assert path.stat().st_size < 300_000, f"{name} is {path.stat().st_size} bytes"
    return path


def wait_text(page, selector, pattern, timeout=60_000):
    """Wait until the element's text matches the regular expression ``pattern``."""
    page.wait_for_function("([sel, pat]) => { const e = document.querySelector(sel); return !!e && new RegExp(pat).test(e.innerText); }",
                           arg=[selector, pattern], timeout=timeout)


def param_input(page, name):
    cid = json.dumps({"name": name, "type": "explorer-param"}, separators=(",", ":"))
    return page.locator(f"[id='{cid}']")


# ----------------------------------------------------------------------------- tests
def test_explorer_from_a_shared_link_reproduces_controls_and_mr(server, page):
    from dampersim import views

    query = {"speed": "2100", "torque": "260", "orders": "2:250,4:80@90", "solver.outer_segments": "12"}
    page.goto(server + "/explorer?" + "&".join(f"{k}={v}" for k, v in query.items()))
    wait_for_graph(page, "explorer-mr", "bar")

    # the controls show the link's values
    assert page.locator("#explorer-speed input[type=number]").input_value() == "2100"
    assert page.locator("#explorer-torque input[type=number]").input_value() == "260"
    assert page.locator("input[name='order-1']").input_value() == "2"
    assert page.locator("input[name='amplitude-1']").input_value() == "250"
    assert page.locator("input[name='order-2']").input_value() == "4"
    assert page.locator("input[name='amplitude-2']").input_value() == "80"
    assert page.locator("input[name='phase-2']").input_value() == "90"
    assert param_input(page, "solver.outer_segments").input_value() == "12"
    assert page.locator("#explorer-link-notices .notice").count() == 0

    # the plotted MR is the MR of that state, computed here independently
    state, notices = views.parse_query("explorer", query)
    assert notices == []
    expected = {r["order"]: r["mr"] for r in views.explorer_view(views.resolve_system(state["params"]), state, use_cache=False)["orders"]
                if r["mr"] is not None}
    mr = graph_data(page, "explorer-mr")[0]
    plotted = dict(zip((float(x) for x in mr["x"]), mr["y"]))
    assert set(plotted) == set(expected) == {2.0, 4.0}
    for k in expected:
        assert plotted[k] == pytest.approx(expected[k], rel=1e-6)
    assert f"{expected[2.0]:.4g}" in page.locator("#explorer-mr-table").inner_text()

    # the copy-link field holds the complete state, parameter override included
    link = page.locator("#explorer-link-text").input_value()
    assert link.startswith(server + "/explorer?speed=2100&torque=260&orders=2:250,4:80@90&duration=2.6")
    assert link.endswith("solver.outer_segments=12")
    page.locator("#explorer-copy").click()
    page.wait_for_function("() => document.querySelector('#explorer-copied').innerText.includes('copied')")
    screenshot(page, "explorer.png")


def test_moving_a_slider_updates_figures_and_the_url(server, page):
    page.goto(server + "/explorer?duration=1.2")
    wait_for_graph(page, "explorer-traces")
    page.wait_for_function("() => location.search.includes('speed=1500')")
    assert "1500 rpm" in graph_title(page, "explorer-traces")
    before = graph_data(page, "explorer-mr")[0]["y"]
    thumb = page.locator("#explorer-speed [role=slider]")
    thumb.focus()
    thumb.press("ArrowRight")
    thumb.press("ArrowRight")
    page.wait_for_function("() => location.search.includes('speed=1520')", timeout=30_000)
    page.wait_for_function("() => { const gd = document.querySelector('#explorer-traces .js-plotly-plot');"
                           " return gd && gd.layout.title.text.includes('1520 rpm'); }", timeout=60_000)
    after = graph_data(page, "explorer-mr")[0]["y"]
    assert after != before
    assert page.locator("#explorer-speed input[type=number]").input_value() == "1520"
    assert "speed=1520" in page.locator("#explorer-link-text").input_value()


def test_colourmap_sweep_runs_with_progress_to_completion(server, page):
    page.goto(server + "/colourmap?speeds=1000:2800:50&duration=1.5&window=0.8")
    page.wait_for_selector("#colourmap-progress-wrap", state="visible", timeout=60_000)
    seen = set()
    deadline = time.monotonic() + 180
    while time.monotonic() < deadline:
        text = page.locator("#colourmap-progress-text").inner_text()
        m = re.match(r"(\d+) / 37 test points", text)
        if m:
            seen.add(int(m.group(1)))
        if "Done" in page.locator("#colourmap-status").inner_text():
            break
        time.sleep(0.2)
    assert "Done" in page.locator("#colourmap-status").inner_text()
    assert len(seen) >= 2 and max(seen) > min(seen), f"progress seen: {sorted(seen)}"
    wait_for_graph(page, "colourmap-graph", "heatmap")
    assert page.locator("#colourmap-progress-wrap").is_hidden()
    assert page.locator("#colourmap-run").is_enabled() and page.locator("#colourmap-cancel").is_disabled()
    assert "37 points" in page.locator("#colourmap-summary").inner_text()
    screenshot(page, "colourmap.png")
    # the same view again is a cache hit: shown at once, no job
    page.reload()
    page.wait_for_function("() => document.querySelector('#colourmap-status') &&"
                           " document.querySelector('#colourmap-status').innerText.includes('Shown from the cache')", timeout=30_000)
    wait_for_graph(page, "colourmap-graph", "heatmap")


def test_bad_query_values_show_a_notice_and_fall_back(server, page):
    page.goto(server + "/explorer?speed=abc&torque=99999&orders=2:x&duration=1.2&foo=bar")
    notices = page.locator("#explorer-link-notices .notice-warning")
    notices.first.wait_for()
    text = page.locator("#explorer-link-notices").inner_text()
    assert notices.count() == 3
    assert "speed='abc'" in text and "Using 1500 rpm" in text
    assert "torque='99999'" in text and "Using 200 N m" in text
    assert "orders='2:x'" in text and "foo" not in text
    assert page.locator("#explorer-speed input[type=number]").input_value() == "1500"
    page.wait_for_function("() => location.search.startsWith('?speed=1500&torque=200&orders=2:300')")
    wait_for_graph(page, "explorer-mr", "bar")  # the safe values still give a result
    page.goto(server + "/colourmap?speeds=fast&window=-1")
    page.locator("#colourmap-link-notices .notice-warning").first.wait_for()
    assert "speeds='fast'" in page.locator("#colourmap-link-notices").inner_text()


@pytest.mark.slow
def test_cancelled_sweep_and_two_tabs(server, browser):
    context = browser.new_context(viewport=VIEWPORT)
    try:
        a, b = context.new_page(), context.new_page()
        for pg in (a, b):
            pg.set_default_timeout(60_000)
        # tab A: a long sweep, cancelled halfway
        long_url = server + "/colourmap?speeds=900:2800:25&duration=2.6"
        a.goto(long_url)
        wait_text(a, "#colourmap-progress-text", r"[1-9]\d* / 77 test points", timeout=120_000)
        # tab B meanwhile runs another sweep: it says that it shares the server
        b.goto(server + "/colourmap?speeds=1200:1500:100&duration=1.2&window=0.5")
        wait_text(b, "#colourmap-progress-text", "other sweep")
        a.locator("#colourmap-cancel").click()
        wait_text(a, "#colourmap-status", "Cancelled")
        a.wait_for_function("() => !document.querySelector('#colourmap-run').disabled")
        assert a.locator("#colourmap-progress-wrap").is_hidden()
        # tab B finishes normally; the server keeps serving
        wait_text(b, "#colourmap-status", "Done", timeout=120_000)
        wait_for_graph(b, "colourmap-graph", "heatmap")
        # the finished points of the cancelled sweep stayed in the cache
        a.goto(long_url)
        wait_text(a, "#colourmap-status", r"Starting the sweep: 77 test points, [1-9]\d* already in the cache")
        # ... and the resumed sweep can be cancelled in turn: once its job runs (the Cancel
        # button shows) or, if it computed the rest first, once it is done; either end frees
        # the run button (tab B above saw a sweep through to its figure)
        running = ("() => { const b = document.querySelector('#colourmap-cancel');"
                   " return !!b && !b.disabled && b.offsetParent !== null; }")
        a.wait_for_function(f"() => ({running})() || /Done/.test(document.querySelector('#colourmap-status').innerText)",
                            timeout=120_000)
        a.evaluate(f"() => {{ if (({running})()) document.querySelector('#colourmap-cancel').click(); }}")
        wait_text(a, "#colourmap-status", "Cancelled|Done", timeout=120_000)
        a.wait_for_function("() => !document.querySelector('#colourmap-run').disabled")
    finally:
        context.close()
