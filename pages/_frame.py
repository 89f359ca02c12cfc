"""The frame of every dashboard page: controls beside results, the link notices and the
"Copy link" bar that shows the page's current address.

URL state: each page parses its query string with :func:`dampersim.views.state.parse_query`
in its ``layout(**query)``, renders its controls from that state and mirrors every later
state back into the URL through a page-local ``dcc.Location(refresh=False)`` (writing
``search`` changes the address bar without re-rendering the page). The "Copy link" button
copies that address.
"""

from __future__ import annotations

from dash import Input, Output, State, clientside_callback, dcc, html

from pages._widgets import render_notices


def page_frame(page: str, title: str, intro: str, controls, content, notices=(), extra=()):
    """Two-column page: a control panel (left) and the results (right).

    Holds the page-local Location that mirrors the state into the URL, the link notices
    (rendered once from the query string) and the copy-link bar.
    """
    return html.Div(
        [
            dcc.Location(id=f"{page}-url", refresh=False),
            html.Div(
                [
                    html.Div([html.H1(title, className="page-title"), html.P(intro, className="page-intro")], className="page-heading"),
                    copy_link(page),
                ],
                className="page-header",
            ),
            html.Div(render_notices(notices, "The link contained values that could not be used:"), id=f"{page}-link-notices",
                     className="notices"),
            html.Div(
                [
                    html.Aside(controls, className="panel controls", **{"aria-label": "controls"}),
                    html.Section(content, className="results"),
                ],
                className="page-grid",
            ),
            *extra,
        ],
        className=f"page page-{page}",
    )


def copy_link(page: str):
    """"Copy link" button plus the current link in a read-only field."""
    return html.Div(
        [
            dcc.Input(id=f"{page}-link-text", type="text", readOnly=True, value="", className="link-text", name="link"),
            html.Div([dcc.Clipboard(id=f"{page}-copy", content="", className="clipboard-icon", title="Copy link to this view"),
                      html.Span("Copy link", className="copy-label")],
                     className="copy-button", title="Copy a link that reproduces this view"),
            html.Span("", id=f"{page}-copied", className="copied"),
        ],
        className="link-bar",
    )


def register_link_callbacks(page: str):
    """Client-side: show the page's current link; copy it on click."""
    clientside_callback(
        """
        function(search, pathname) {
            return window.location.origin + (pathname || window.location.pathname) + (search || "");
        }
        """,
        Output(f"{page}-link-text", "value"),
        Input(f"{page}-url", "search"),
        State(f"{page}-url", "pathname"),
    )
    clientside_callback(
        """
        function(n, link) {
            if (!n) { return [window.dash_clientside.no_update, ""]; }
            return [link || window.location.href, "Link copied"];
        }
        """,
        Output(f"{page}-copy", "content"),
        Output(f"{page}-copied", "children"),
        Input(f"{page}-copy", "n_clicks"),
        State(f"{page}-link-text", "value"),
        prevent_initial_call=True,
    )
