"""The server's own protections: security headers, Host allowlist, --debug only on
loopback, short error pages with an incident id, the body-limit message, start-up clean-up
and the flags that become environment settings.

Budgets: each test asserts its wall time. The Dash app is built once per module (about
1.5 s on 2 shared cores); every other case is a test-client request or a small Flask app,
so 5 s per test leaves room for a loaded machine while still catching a hang.
"""

from __future__ import annotations

import logging
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest
from flask import Flask

REPO = Path(__file__).resolve().parents[2]
#: wall-time budget of one request-level case [s] (see the module docstring)
CASE_BUDGET_S = 5.0
ABSOLUTE_PATH = re.compile(r"(?<![\w.:/])/(?:home|root|tmp|work|usr|var|opt|srv)/")


@pytest.fixture(scope="module")
def dash_app():
    import app

    return app


@pytest.fixture
def timed():
    t0 = time.perf_counter()
    yield
    assert time.perf_counter() - t0 < CASE_BUDGET_S


def small_app():
    """A bare Flask app with the dashboard's protections and two routes of its own."""
    import app

    server = Flask("probe")

    @server.route("/ok")
    def ok():
        return "fine"

    @server.route("/boom")
    def boom():
        raise RuntimeError(f"secret detail in {REPO}/dampersim/secret.py")

    app.install_protections(server)
    return server


@pytest.mark.parametrize("path", ["/", "/_dash-layout", "/pulsation?pressure=abc", "/no-such-page"])
def test_security_headers_on_every_response(dash_app, timed, path):
    r = dash_app.server.test_client().get(path)
    assert r.headers["Content-Security-Policy"] == "frame-ancestors 'none'"
    assert r.headers["X-Frame-Options"] == "DENY"
    assert r.headers["X-Content-Type-Options"] == "nosniff"
    assert r.headers["Referrer-Policy"] == "same-origin"
    assert "script-src" not in r.headers["Content-Security-Policy"]  # Dash needs its inline scripts


def test_security_headers_on_refusals_too(timed):
    r = small_app().test_client().get("/ok", headers={"Host": "evil.example"})
    assert r.status_code == 400 and r.headers["X-Frame-Options"] == "DENY"


@pytest.mark.parametrize("host, status", [
    ("evil.example", 400), ("evil.example:8050", 400), ("127.0.0.1.evil.example", 400), ("", 400),
    ("localhost", 200), ("localhost:8050", 200), ("127.0.0.1:8050", 200), ("[::1]:8050", 200), ("LOCALHOST", 200),
])
def test_host_allowlist_of_the_dashboard(dash_app, timed, host, status):
    r = dash_app.server.test_client().get("/", headers={"Host": host})
    assert r.status_code == status
    if status == 400:
        text = r.get_data(as_text=True)
        assert "not served here" in text and "--allow-host" in text and len(text) < 300


def test_allow_host_extends_the_list(timed):
    import app

    server = small_app()
    client = server.test_client()
    assert client.get("/ok", headers={"Host": "dampersim.example.org"}).status_code == 400
    app.allow_hosts(server, ["dampersim.example.org", "[fd00::1]"])
    assert client.get("/ok", headers={"Host": "dampersim.example.org:443"}).status_code == 200
    assert client.get("/ok", headers={"Host": "[fd00::1]:8050"}).status_code == 200
    assert client.get("/ok", headers={"Host": "evil.example"}).status_code == 400


def test_unspecified_bind_address_is_no_host_name(timed):
    """`--host 0.0.0.0` (or ::) binds every interface; it is not a name a browser sends,
    and a Host header "0.0.0.0" reaches the server only through a crafted request."""
    import app

    server = small_app()
    app.allow_hosts(server, ["0.0.0.0", "::", "[::]", "192.0.2.7"])
    allowed = server.config["DAMPERSIM_ALLOWED_HOSTS"]
    assert "0.0.0.0" not in allowed and "::" not in allowed and "192.0.2.7" in allowed
    client = server.test_client()
    assert client.get("/ok", headers={"Host": "0.0.0.0:8050"}).status_code == 400
    assert client.get("/ok", headers={"Host": "[::]:8050"}).status_code == 400
    assert client.get("/ok", headers={"Host": "192.0.2.7:8050"}).status_code == 200


def test_waitress_buffers_little_more_than_the_request_limit(dash_app):
    """waitress spools a body up to MAX_BUFFERED_BYTES per connection before Flask refuses
    it: the request limit plus 1 MiB (room for Flask's message), not a multiple of it."""
    assert dash_app.MAX_REQUEST_BYTES < dash_app.MAX_BUFFERED_BYTES <= dash_app.MAX_REQUEST_BYTES + 2**20


def test_allowed_hosts_from_the_environment(monkeypatch, timed):
    monkeypatch.setenv("DAMPERSIM_ALLOWED_HOSTS", "team.example, other.example")
    client = small_app().test_client()
    assert client.get("/ok", headers={"Host": "team.example"}).status_code == 200
    assert client.get("/ok", headers={"Host": "evil.example"}).status_code == 400


@pytest.mark.parametrize("host", ["0.0.0.0", "192.168.1.20", "::", "example.org"])
def test_debug_refused_off_loopback(dash_app, capsys, monkeypatch, host):
    def no_app():  # refusing must happen before anything is built or served
        raise AssertionError("create_app called")

    monkeypatch.setattr(dash_app, "create_app", no_app)
    assert dash_app.main(["--debug", "--host", host]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--debug" in err and host in err and "127.0.0.1" in err


@pytest.mark.parametrize("host", ["127.0.0.1", "localhost", "::1"])
def test_loopback_hosts(dash_app, host):
    assert dash_app.is_loopback(host)


def test_error_page_hides_the_traceback(caplog, timed):
    with caplog.at_level(logging.ERROR, logger="dampersim.incidents"):
        r = small_app().test_client().get("/boom", headers={"Host": "localhost"})
    text = r.get_data(as_text=True)
    assert r.status_code == 500
    assert re.fullmatch(r"unexpected error \(incident [0-9a-f]{8}; the server log has the details\)\n", text)
    assert "Traceback" not in text and "secret" not in text and str(REPO) not in text
    incident = re.search(r"incident ([0-9a-f]{8})", text).group(1)
    logged = "\n".join(rec.getMessage() + (logging.Formatter().formatException(rec.exc_info) if rec.exc_info else "")
                       for rec in caplog.records)
    assert incident in logged and "Traceback" in logged and "secret detail" in logged


def test_broken_callback_request_gets_no_traceback(dash_app, timed):
    client = dash_app.server.test_client()
    client.get("/")
    r = client.post("/_dash-update-component", data=b'{"output": 3, "inputs": "x"}', content_type="application/json")
    text = r.get_data(as_text=True)
    assert r.status_code in (400, 500)
    assert "Traceback" not in text and not ABSOLUTE_PATH.search(text)


def test_oversized_request_names_the_limit_and_the_command_line(dash_app, timed):
    client = dash_app.server.test_client()
    body = b"x" * (dash_app.MAX_REQUEST_BYTES + 1)
    r = client.post("/_dash-update-component", data=body, content_type="application/json")
    text = r.get_data(as_text=True)
    assert r.status_code == 413
    assert "16 MiB" in text and "dampersim import" in text and "dampersim diagnose" in text
    assert r.mimetype == "text/plain" and len(text) < 400


def test_flags_become_settings(dash_app, monkeypatch):
    seen = {}

    class Stop(Exception):
        pass

    def record():
        seen.update({k: os.environ.get(k) for k in dash_app.ENV_OF_FLAG.values()})
        raise Stop

    for env in dash_app.ENV_OF_FLAG.values():
        monkeypatch.delenv(env, raising=False)
    monkeypatch.setattr(dash_app, "create_app", record)
    with pytest.raises(Stop):
        dash_app.main(["--budget", "2e9", "--autostart-budget", "5e7", "--max-jobs", "3", "--jobs-per-session", "1"])
    assert seen == {"DAMPERSIM_BUDGET": "2e+09", "DAMPERSIM_AUTOSTART_BUDGET": "5e+07",
                    "DAMPERSIM_MAX_JOBS": "3", "DAMPERSIM_JOBS_PER_SESSION": "1"}
    for env in dash_app.ENV_OF_FLAG.values():
        os.environ.pop(env, None)


def test_threads_set_the_foreground_slots_unless_given(dash_app, monkeypatch):
    class Stop(Exception):
        pass

    def stop():
        raise Stop

    monkeypatch.setattr(dash_app, "create_app", stop)
    monkeypatch.delenv("DAMPERSIM_FOREGROUND_SLOTS", raising=False)
    with pytest.raises(Stop):
        dash_app.main(["--threads", "12"])
    assert os.environ["DAMPERSIM_FOREGROUND_SLOTS"] == "6"  # half the request threads
    monkeypatch.setenv("DAMPERSIM_FOREGROUND_SLOTS", "2")
    with pytest.raises(Stop):
        dash_app.main(["--threads", "12"])
    assert os.environ["DAMPERSIM_FOREGROUND_SLOTS"] == "2"  # an explicit setting wins


@pytest.mark.parametrize("flag, value", [("--budget", "-1"), ("--max-jobs", "0"), ("--threads", "many"),
                                         ("--autostart-budget", "nan")])
def test_bad_flag_values_exit_2(dash_app, capsys, flag, value):
    with pytest.raises(SystemExit) as exc:
        dash_app.parse_args([flag, value])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert repr(value) in err and "accepted is a positive" in err


def test_stale_temporaries_removed_at_start(dash_app, tmp_path):
    root = tmp_path / "cache"
    (root / "views").mkdir(parents=True)
    old, fresh = root / "tmpold", root / "views" / "tmpfresh"
    old.mkdir()
    (old / "part").write_text("x")
    fresh.mkdir()
    stale_file, other = root / "views" / ".result-abc.parquet", root / "views" / "cache.db"
    stale_file.write_text("x")
    other.write_text("x")
    outside = tmp_path / "outside"
    outside.mkdir()
    (root / "tmplink").symlink_to(outside)
    hour_ago = time.time() - 2 * 3600
    for p in (old, stale_file, other):
        os.utime(p, (hour_ago, hour_ago))
    removed = dash_app.remove_stale_temporaries(root)
    assert sorted(removed) == [".result-abc.parquet", "tmpold"]
    assert not old.exists() and not stale_file.exists()
    assert fresh.exists() and other.exists() and outside.exists()  # young, not ours, behind a link


def test_shutdown_ends_child_processes(tmp_path):
    """The fallback shutdown (no job manager module) terminates the server's children."""
    code = (
        "import subprocess, sys, time, psutil\n"
        "import app\n"
        "child = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(60)'])\n"
        "time.sleep(0.2)\n"
        "app.shutdown_jobs()\n"
        "print('alive', psutil.pid_exists(child.pid))\n"
    )
    env = {**os.environ, "DAMPERSIM_CACHE_DIR": str(tmp_path / "cache"), "PYTHONPATH": str(REPO)}
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, env=env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "alive False" in out.stdout  # terminated and reaped by the shutdown
    assert time.perf_counter() - t0 < 30  # app import (~2 s) + terminate; 30 s: 2 shared cores under load
