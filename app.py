"""dampersim dashboard: the app shell (navbar, shared stores, background jobs) and its server.

    python app.py [--host 127.0.0.1] [--port 8050] [--allow-host NAME ...] [--threads 8]
                  [--budget STEP_DOF] [--autostart-budget STEP_DOF]
                  [--max-jobs N] [--jobs-per-session N] [--debug]

Pages live in ``pages/`` (layout and callbacks only; physics and figures come from the
library, :mod:`dampersim.views`). Every page keeps its state in the URL query string.
Results are cached under ``$DAMPERSIM_CACHE_DIR`` (default ``cache/``): sweep points in
``results/``, views in ``views/``, background-callback jobs in ``callbacks/`` (folders
made 0700 by :func:`dampersim.locations.private_dir`).

Server: waitress. It is pure Python and serves from threads in one process instead of
forking workers, so the numba kernel loaded at start-up is shared by every request and
nothing forks a process that holds numba's fork-safe threading layer or open SQLite
connections; it runs the same on Linux, macOS and Windows; and it bounds what a client
can hold: idle connections are closed after ``channel_timeout`` seconds, request headers
(and so links) and bodies have size limits, and the number of connections is capped. Long
computations do not run in the request threads: sweeps, maps and studies are background
jobs with their own limits (``--max-jobs``, ``--jobs-per-session``). For several worker
processes behind one address, gunicorn works too (``gunicorn -w 4 -b 127.0.0.1:8050
app:server``, settings through the environment variables below, since it does not read
these flags); the job limits hold across its workers because jobs are counted on disk.
``--debug`` runs Dash's development server with its debugger, and only on a loopback
address.

Every response carries ``Content-Security-Policy: frame-ancestors 'none'``,
``X-Frame-Options: DENY``, ``X-Content-Type-Options: nosniff`` and ``Referrer-Policy:
same-origin`` (no page can be framed by another site); a request whose Host header is not
allowed (loopback names, the bind address and ``--allow-host`` names, or
``$DAMPERSIM_ALLOWED_HOSTS``) gets 400, which stops DNS rebinding. An unexpected error
reaches the browser as one line with an incident id; the log has the traceback.

Settings read from the environment (the flags set them): ``DAMPERSIM_BUDGET`` and
``DAMPERSIM_AUTOSTART_BUDGET`` (step x degrees of freedom), ``DAMPERSIM_MAX_JOBS``,
``DAMPERSIM_JOBS_PER_SESSION``, ``DAMPERSIM_ALLOWED_HOSTS`` (names separated by commas).
"""

from __future__ import annotations

import os
import sys

# Background callbacks fork the server process. A process that has run a numba
# parallel kernel on the default (GNU OpenMP) threading layer cannot fork safely: the
# forked job dies and the page hangs at "running". The fork-safe layer avoids that; it
# must be chosen before numba starts any thread pool.
os.environ["NUMBA_THREADING_LAYER"] = "forksafe"
if "numba" in sys.modules:  # imported earlier (e.g. by a test): still before any parallel call
    import numba

    numba.config.THREADING_LAYER = "forksafe"

from pathlib import Path  # noqa: E402

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

#: Navbar order of the pages (later: pulsation generator, studies, discrepancy).
NAV = (
    ("explorer", "Explorer"),
    ("colourmap", "Colourmap"),
    ("hysteresis", "Hysteresis"),
    ("segments", "Segments"),
    ("maps", "Maps"),
    ("parameters", "Parameters"),
)
# pages that do not take the shared parameter set (default damper and generator)
EXTRA_NAV = (("/pulsation", "Pulsation generator"), ("/studies", "Studies"), ("/discrepancy", "Discrepancy"))



#: Host names every server answers to (this machine).
LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1")
#: Environment variable with more allowed Host names, separated by commas.
ALLOWED_HOSTS_ENV = "DAMPERSIM_ALLOWED_HOSTS"
#: Headers set on every response (no script-src: Dash needs its inline scripts).
SECURITY_HEADERS = {
    "Content-Security-Policy": "frame-ancestors 'none'",
    "X-Frame-Options": "DENY",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "same-origin",
}
#: Largest request body Flask accepts [bytes]; uploads arrive base64-encoded in a
#: callback request (parameter files up to 256 kB get a specific message from their page).
MAX_REQUEST_BYTES = 16 * 2**20
#: Largest body waitress buffers (spools) per connection before Flask sees the request
#: [bytes]: MAX_REQUEST_BYTES plus 1 MiB, the room for a request just over the limit to
#: reach Flask, whose message names the limit; anything larger waitress cuts off itself.
MAX_BUFFERED_BYTES = MAX_REQUEST_BYTES + 2**20
#: Largest request line plus headers [bytes] (this caps the length of a link).
MAX_HEADER_BYTES = 64 * 2**10
#: Idle connections are closed after this many seconds.
CHANNEL_TIMEOUT_S = 120
#: Most simultaneous connections.
CONNECTION_LIMIT = 200
#: Request threads by default.
DEFAULT_THREADS = 8
#: Temporary files and folders of this server older than this are removed at start-up [s].
STALE_TEMP_AGE_S = 3600.0
#: Environment variables the flags set (read by dampersim.costs and the job manager).
ENV_OF_FLAG = {
    "budget": "DAMPERSIM_BUDGET",
    "autostart_budget": "DAMPERSIM_AUTOSTART_BUDGET",
    "max_jobs": "DAMPERSIM_MAX_JOBS",
    "jobs_per_session": "DAMPERSIM_JOBS_PER_SESSION",
}

TOO_LARGE_TEXT = (
    "Request too large: the server accepts at most {limit} MiB per request (an upload travels "
    "base64-encoded, so files up to about {file_limit} MiB). For larger recordings or campaigns use the "
    "command line: python -m dampersim import RECORDING --out CAMPAIGN, then "
    "python -m dampersim diagnose CAMPAIGN.\n"
)


# --------------------------------------------------------------------------- protections
def host_name(header) -> str:
    """The host of a Host header, lower case, without port or brackets ("" if none)."""
    text = str(header or "").strip().lower()
    if text.startswith("["):
        return text[1:].split("]", 1)[0]
    if text.count(":") == 1:
        text = text.split(":", 1)[0]
    return text.rstrip(".")


def is_loopback(host: str) -> bool:
    """Whether ``host`` (a name or address) means this machine only."""
    import ipaddress

    name = host_name(host) if not str(host).count(":") > 1 else str(host).strip("[]").lower()
    if name in ("localhost", "localhost.localdomain", "ip6-localhost"):
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False


def allow_hosts(server, names) -> None:
    """Add ``names`` (host names or addresses) to the Host allowlist of ``server``. An
    unspecified address (0.0.0.0, ::: "every interface" as a bind address) names no host
    and is skipped."""
    import ipaddress

    allowed = server.config.setdefault("DAMPERSIM_ALLOWED_HOSTS", set(LOOPBACK_HOSTS))
    for name in names or ():
        name = host_name(name) if str(name).count(":") <= 1 else str(name).strip("[]").lower()
        try:
            unspecified = ipaddress.ip_address(name).is_unspecified
        except ValueError:
            unspecified = False
        if name and not unspecified:
            allowed.add(name)


def install_protections(server) -> None:
    """Host allowlist, security headers, body limit and short error pages on a Flask server."""
    from flask import Response, request
    from werkzeug.exceptions import InternalServerError, RequestEntityTooLarge

    from dampersim import incidents

    allow_hosts(server, os.environ.get(ALLOWED_HOSTS_ENV, "").split(","))
    server.config["MAX_CONTENT_LENGTH"] = MAX_REQUEST_BYTES

    @server.before_request
    def _check_host():
        allowed = server.config["DAMPERSIM_ALLOWED_HOSTS"]
        header = request.environ.get("HTTP_HOST", "")
        if host_name(header) not in allowed:
            shown = header[:80] if header else "(none)"
            return Response(f"Host {shown!r} is not served here: accepted are {', '.join(sorted(allowed))} "
                            "(add a name with app.py --allow-host NAME).\n", status=400, mimetype="text/plain")
        return None

    @server.after_request
    def _security_headers(response):
        for name, value in SECURITY_HEADERS.items():
            response.headers[name] = value
        return response

    @server.errorhandler(InternalServerError)
    def _internal_error(error):
        original = getattr(error, "original_exception", None) or error
        incident = incidents.report(original, f"{request.method} {request.path}")
        return Response(f"unexpected error (incident {incident}; the server log has the details)\n", status=500,
                        mimetype="text/plain")

    @server.errorhandler(RequestEntityTooLarge)
    def _too_large(_error):
        limit = MAX_REQUEST_BYTES / 2**20
        return Response(TOO_LARGE_TEXT.format(limit=f"{limit:g}", file_limit=f"{limit * 3 / 4:g}"), status=413,
                        mimetype="text/plain")


# --------------------------------------------------------------------------- jobs
_JOBS = {"module": None}


def _env_int(name):
    text = os.environ.get(name, "").strip()
    try:
        return int(text) if text else None
    except ValueError:
        return None


def job_manager():
    """The background-callback manager: the job queue of ``pages._background`` (global and
    per-session limits, identical requests shared, idle jobs reaped, shutdown). Its pickled
    job data lives only in ``private_dir("callbacks")`` (0700, owner checked). Jobs are
    shared on the work key stored with their ticket (``_jobs.ticket_work``), never on
    one the browser posts; a call refused because the queue is full gets the page's error."""
    from dampersim.locations import private_dir
    from pages import _background, _jobs

    _JOBS["module"] = _background
    return _background.make_manager(private_dir("callbacks"), max_jobs=_env_int(ENV_OF_FLAG["max_jobs"]),
                                    per_session=_env_int(ENV_OF_FLAG["jobs_per_session"]),
                                    work_of=_jobs.ticket_work, refused_result=_jobs.refused_result)


def shutdown_jobs() -> None:
    """Stop every background job of this server: the job manager's shutdown, then any child
    process still running is terminated (and killed after 3 s)."""
    module = _JOBS.get("module")
    if module is not None:
        try:
            module.shutdown_jobs()
        except Exception as exc:  # keep stopping: the children below are still ours to end
            from dampersim import incidents

            incidents.report(exc, "job shutdown")
    try:
        import psutil

        children = psutil.Process().children(recursive=True)
        for child in children:
            try:
                child.terminate()
            except psutil.Error:
                pass
        _, alive = psutil.wait_procs(children, timeout=3)
        for child in alive:
            try:
                child.kill()
            except psutil.Error:
                pass
    except Exception:
        pass


def remove_stale_temporaries(root, max_age_s: float = STALE_TEMP_AGE_S, now: float | None = None) -> list:
    """Remove what this server leaves behind when it is killed mid-write, older than
    ``max_age_s``: ``tmp*`` folders (tempfile's default names) and ``.dampersim-*`` /
    ``.result-*`` temporary files, in the cache folder and the folders one level below it.
    Symbolic links are never followed. Returns the names removed."""
    import shutil
    import time

    root = Path(root)
    now = time.time() if now is None else now
    removed = []
    folders = [root]
    try:
        folders += [p for p in root.iterdir() if p.is_dir() and not p.is_symlink()]
    except OSError:
        return removed
    for folder in folders:
        try:
            entries = list(folder.iterdir())
        except OSError:
            continue
        for entry in entries:
            name = entry.name
            try:
                st = entry.lstat()
            except OSError:
                continue
            if now - st.st_mtime < max_age_s or entry.is_symlink():
                continue
            try:
                if entry.is_dir() and name.startswith("tmp"):
                    shutil.rmtree(entry)
                elif entry.is_file() and (name.startswith(".dampersim-") or name.startswith(".result-")):
                    entry.unlink()
                else:
                    continue
            except OSError:
                continue
            removed.append(name)
    return removed


def cleanup_at_start(root) -> None:
    """Start-up housekeeping: stale temporaries, the job registry's reap (jobs of a server
    that died are failed or cancelled, so they no longer count against the limits), then
    stale uploads (when the discrepancy package offers ``cleanup_stale_uploads``)."""
    import logging

    log = logging.getLogger("dampersim.app")
    removed = remove_stale_temporaries(root)
    if removed:
        log.warning("removed %d stale temporary file(s)/folder(s) from the cache", len(removed))
    try:
        from dampersim.jobs import JobRegistry

        report = JobRegistry().reap()
        if report.idle or report.dropped or report.failed:
            log.warning("job registry at start: %d job(s) of an earlier server ended",
                        len(report.idle) + len(report.dropped) + len(report.failed))
    except Exception as exc:  # the server still starts; the next poll reaps again
        from dampersim import incidents

        incidents.report(exc, "job registry reap at start")
    try:
        from dampersim.discrepancy import upload
    except ImportError:
        return
    cleanup = getattr(upload, "cleanup_stale_uploads", None)
    if cleanup is not None:
        try:
            cleanup()
        except Exception as exc:
            from dampersim import incidents

            incidents.report(exc, "cleanup of stale uploads")


# --------------------------------------------------------------------------- app
def create_app():
    """Build the Dash app (pages, stores, background job manager, protections)."""
    from dash import Dash, Input, Output, clientside_callback, dcc, html, page_container

    import dampersim
    from dampersim.plotting import register_template
    from dampersim.views.state import PAGE_PATHS, page_href

    register_template(make_default=True)
    manager = job_manager()
    app = Dash(
        __name__,
        use_pages=True,
        pages_folder=str(HERE / "pages"),
        assets_folder=str(HERE / "assets"),
        background_callback_manager=manager,
        title="dampersim",
        update_title=None,
        meta_tags=[{"name": "viewport", "content": "width=device-width, initial-scale=1"}],
    )
    install_protections(app.server)
    _JOBS["module"].install_sessions(app.server)
    nav = html.Nav(
        [
            dcc.Link([html.Img(src=app.get_asset_url("logo.svg"), className="brand-logo", alt=""),
                      html.Span("dampersim", className="brand-name")], href="/explorer", className="brand", id="nav-brand"),
            html.Div([dcc.Link(label, href=PAGE_PATHS[page], id=f"nav-{page}", className="nav-link") for page, label in NAV]
                     + [dcc.Link(label, href=path, className="nav-link") for path, label in EXTRA_NAV],
                     className="nav-links"),
            html.Div(f"two-stage arc-spring damper on the test rig · v{dampersim.__version__}", className="nav-meta"),
        ],
        className="navbar",
    )
    app.layout = html.Div(
        [
            dcc.Store(id="shared-params"),
            nav,
            html.Main(page_container, className="main"),
            html.Footer("SI inside; rpm, N m, Hz and degrees at the edge. Every view is a link: use “Copy link” to share it.",
                        className="footer"),
        ],
        className="app",
    )

    @app.callback(*[Output(f"nav-{page}", "href") for page, _ in NAV], Output("nav-brand", "href"), Input("shared-params", "data"))
    def nav_links(params):
        """Navbar links carry the current parameter set to the other pages."""
        hrefs = [page_href(page, params) for page, _ in NAV]
        return (*hrefs, hrefs[0])

    clientside_callback(
        """
        function(pathname) {
            const pages = %s;
            let here = (pathname || "/").replace(/\\/+$/, "") || "/explorer";
            if (here === "/") { here = "/explorer"; }
            return pages.map(p => "nav-link" + (here === p ? " active" : ""));
        }
        """ % [PAGE_PATHS[p] for p, _ in NAV],
        *[Output(f"nav-{page}", "className") for page, _ in NAV],
        Input("_pages_location", "pathname"),
    )
    return app


# Worker processes of sweeps are started with "spawn" and import the main module as
# "__mp_main__": they need the library, not a second Dash app. ``python app.py`` builds the
# app in main(), after the flags have set the environment.
if __name__ not in ("__main__", "__mp_main__"):
    app = create_app()
    server = app.server


def _positive(kind):
    def parse(text):
        import argparse

        try:
            value = kind(text)
        except ValueError:
            value = None
        if value is None or not value > 0 or value != value or value == float("inf"):
            raise argparse.ArgumentTypeError(f"{text!r}: accepted is a positive {'whole number' if kind is int else 'number'}")
        return value
    return parse


def parse_args(argv=None):
    import argparse

    parser = argparse.ArgumentParser(description="dampersim dashboard (served by waitress)")
    parser.add_argument("--host", default="127.0.0.1", help="interface to serve on (default 127.0.0.1; 0.0.0.0 for all)")
    parser.add_argument("--port", type=int, default=8050, help="port (default 8050)")
    parser.add_argument("--allow-host", action="append", default=[], metavar="NAME",
                        help="also answer requests whose Host header is NAME (repeatable); loopback names and the "
                             "bind address are always allowed")
    parser.add_argument("--threads", type=_positive(int), default=DEFAULT_THREADS,
                        help=f"request threads (default {DEFAULT_THREADS})")
    parser.add_argument("--budget", type=_positive(float), metavar="STEP_DOF",
                        help="largest request in time steps x degrees of freedom (sets DAMPERSIM_BUDGET)")
    parser.add_argument("--autostart-budget", type=_positive(float), metavar="STEP_DOF",
                        help="largest request a link starts without a click, step x DOF (sets DAMPERSIM_AUTOSTART_BUDGET)")
    parser.add_argument("--max-jobs", type=_positive(int), metavar="N",
                        help="background jobs running at once on this server (sets DAMPERSIM_MAX_JOBS)")
    parser.add_argument("--jobs-per-session", type=_positive(int), metavar="N",
                        help="background jobs running at once per browser session (sets DAMPERSIM_JOBS_PER_SESSION)")
    parser.add_argument("--debug", action="store_true",
                        help="Dash debug mode on the development server (loopback hosts only)")
    return parser.parse_args(argv)


def main(argv=None) -> int:
    import atexit
    import signal

    args = parse_args(argv)
    if args.debug and not is_loopback(args.host):
        print(f"app.py: --debug with --host {args.host}: the debugger shows tracebacks and server paths, so it is "
              f"accepted only on a loopback host ({', '.join(LOOPBACK_HOSTS)})", file=sys.stderr)
        return 2
    for flag, env in ENV_OF_FLAG.items():
        value = getattr(args, flag)
        if value is not None:
            os.environ[env] = f"{value:g}" if isinstance(value, float) else str(value)
    # half of the request threads may compute in the foreground (Explorer, Segments); the
    # other half keeps answering page loads and polls (an explicit setting wins)
    os.environ.setdefault("DAMPERSIM_FOREGROUND_SLOTS", str(max(1, args.threads // 2)))

    global app, server
    app = create_app()
    server = app.server
    allow_hosts(server, [args.host, *args.allow_host])

    from dampersim.locations import cache_dir
    from dampersim.simulation import ensure_compiled

    cleanup_at_start(cache_dir())
    ensure_compiled()  # load (or compile once) the kernel before the first request

    atexit.register(shutdown_jobs)

    def _stop(signum, _frame):
        raise SystemExit(128 + signum)

    signal.signal(signal.SIGTERM, _stop)
    signal.signal(signal.SIGHUP, _stop)  # a closed terminal stops the jobs too, as SIGTERM does
    try:
        if args.debug:
            app.run(host=args.host, port=args.port, debug=True, use_reloader=False)
            return 0
        import logging

        from waitress import create_server

        logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
        srv = create_server(
            server, host=args.host, port=args.port, threads=args.threads, channel_timeout=CHANNEL_TIMEOUT_S,
            connection_limit=CONNECTION_LIMIT, max_request_header_size=MAX_HEADER_BYTES,
            max_request_body_size=MAX_BUFFERED_BYTES, expose_tracebacks=False, ident="dampersim",
        )
        srv.print_listen("dampersim serving on http://{}:{}")
        try:
            srv.run()  # returns on SIGINT/SIGTERM/SIGHUP (waitress stops its threads)
        finally:
            srv.close()
    except KeyboardInterrupt:
        pass
    finally:
        shutdown_jobs()
    return 0


if __name__ == "__main__":
    sys.exit(main())
