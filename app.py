"""dampersim dashboard: the app shell (navbar, shared stores, background callback manager).

    python app.py [--host 127.0.0.1] [--port 8050] [--debug]

Pages live in ``pages/`` (layout and callbacks only; physics and figures come from the
library, :mod:`dampersim.views`). Every page keeps its state in the URL query string.
Results are cached under ``$DAMPERSIM_CACHE_DIR`` (default ``cache/``): sweep points in
``results/``, views in ``views/``, background-callback jobs in ``callbacks/``.
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


def create_app():
    """Build the Dash app (pages, stores, DiskcacheManager on the cache directory)."""
    import diskcache
    from dash import Dash, DiskcacheManager, Input, Output, clientside_callback, dcc, html, page_container

    import dampersim
    from dampersim.plotting import register_template
    from dampersim.views.state import PAGE_PATHS, page_href
    from dampersim.locations import cache_dir

    register_template(make_default=True)
    cache_root = cache_dir()
    os.makedirs(cache_root / "callbacks", exist_ok=True)
    manager = DiskcacheManager(diskcache.Cache(str(cache_root / "callbacks")))
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
    # uploads arrive base64-encoded in a callback request: refuse absurd sizes at the door
    # (parameter files up to 256 kB get a specific message from the Parameters page)
    app.server.config["MAX_CONTENT_LENGTH"] = 16 * 2**20
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
# "__mp_main__": they need the library, not a second Dash app.
if __name__ != "__mp_main__":
    app = create_app()
    server = app.server


def main(argv=None) -> int:
    import argparse

    parser = argparse.ArgumentParser(description="dampersim dashboard")
    parser.add_argument("--host", default="127.0.0.1", help="interface to serve on (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=8050, help="port (default 8050)")
    parser.add_argument("--debug", action="store_true", help="Dash debug mode (reloader off)")
    args = parser.parse_args(argv)
    from dampersim.simulation import ensure_compiled

    ensure_compiled()  # load (or compile once) the kernel before the first request
    app.run(host=args.host, port=args.port, debug=args.debug, use_reloader=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
