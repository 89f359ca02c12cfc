"""Uploads checked in the browser before they are sent: a file above the page's limit is
never posted (the server would answer a request above its limit with a bare 413); the page
says how large it is, what the page accepts and which command takes larger files.

:func:`size_checked_upload` registers a clientside callback on a ``dcc.Upload``'s contents:
a file within the limit goes on to the page's server callback through a ``dcc.Store``
(``<upload id>-data``: {"contents", "filename"}); a larger one only shows the notice
(``<upload id>-size-notice``). The server checks the size again when it decodes the file.

The server's check of a file (decoding, unpacking, reading its metadata) runs off the
request thread: :func:`background_check` gives the keyword arguments of a background
callback that goes through the dashboard's job queue (queued like every other job) and
shows :func:`checking` (a line saying what is being checked, with the queue position or
the step) while it runs. The file's contents reach the job only as the callback's
argument (the job queue keeps the arguments of a queued job in its private folder).
"""

from __future__ import annotations

import json

from dash import Input, Output, State, clientside_callback, dcc, html

#: Styles of the "checking" line: shown while the check runs, hidden otherwise.
SHOWN = {}
HIDDEN = {"display": "none"}
#: Milliseconds between two polls of a running check (a check takes 0.1-1 s).
CHECK_POLL_MS = 300

_JS = """
function(contents, filename) {
    var cfg = %s;
    var nu = window.dash_clientside.no_update;
    if (!contents) { return [nu, nu, nu]; }
    var i = contents.indexOf(',');
    var b64 = i < 0 ? '' : contents.slice(i + 1);
    var pad = b64.endsWith('==') ? 2 : (b64.endsWith('=') ? 1 : 0);
    var n = Math.max(0, Math.floor(b64.length * 3 / 4) - pad);
    if (n > cfg.limit) {
        var size = cfg.mb ? (n / 1048576).toFixed(1) + ' MB' : Math.ceil(n / 1024) + ' kB';
        var text = 'The file ' + (filename || '(no name)') + ' is ' + size + '; this page accepts up to ' +
            cfg.limit_text + '. ' + cfg.hint + ' The file was not sent to the server.';
        return [nu, text, {}];
    }
    return [{contents: contents, filename: filename || null}, '', {display: 'none'}];
}
"""


def limit_text(limit_bytes: int) -> str:
    """"10 MB" or "256 kB"."""
    return f"{limit_bytes / 2**20:g} MB" if limit_bytes >= 2**20 else f"{limit_bytes / 1024:g} kB"


def size_check_js(limit_bytes: int, hint: str) -> str:
    """The clientside function: (contents, filename) -> (store data, notice text, notice style)."""
    cfg = {"limit": int(limit_bytes), "limit_text": limit_text(limit_bytes), "mb": limit_bytes >= 2**20, "hint": hint}
    return _JS % json.dumps(cfg)


def size_checked_upload(upload_id: str, limit_bytes: int, hint: str) -> list:
    """Register the size check of the ``dcc.Upload`` ``upload_id`` (call once, at import of
    the page) and return the components it writes to: the store that carries a file within
    ``limit_bytes`` to the server and the (hidden) notice for a larger one, which names the
    file, its size, the limit and ``hint`` (the command for larger files)."""
    clientside_callback(
        size_check_js(limit_bytes, hint),
        Output(f"{upload_id}-data", "data"),
        Output(f"{upload_id}-size-text", "children"),
        Output(f"{upload_id}-size-notice", "style"),
        Input(upload_id, "contents"),
        State(upload_id, "filename"),
        prevent_initial_call=True,
    )
    return components(upload_id)


def components(upload_id: str) -> list:
    """The store and the hidden notice of :func:`size_checked_upload` (for a page layout)."""
    return [
        dcc.Store(id=f"{upload_id}-data", data=None),
        html.Div([html.Span("⛔", className="notice-icon"), html.Span("", id=f"{upload_id}-size-text", className="notice-text")],
                 id=f"{upload_id}-size-notice", className="notice notice-error", role="alert", style={"display": "none"}),
    ]


def store_contents(data) -> tuple:
    """(contents, filename) of the store's data (None, None when there is none)."""
    if not isinstance(data, dict):
        return None, None
    contents, filename = data.get("contents"), data.get("filename")
    return (contents if isinstance(contents, str) else None), (filename if isinstance(filename, str) else None)


def checking(cid: str, label: str):
    """The line shown while the background check ``cid`` runs (hidden otherwise): ``label``
    (what is being checked), a bar and the job's status (its place in the queue, then the
    step). Element ids: ``<cid>-checking``, ``-checking-bar``, ``-checking-text``."""
    return html.Div([
        html.Span("⏳", className="notice-icon"),
        html.Div([
            html.Span(label, className="notice-text"),
            html.Progress(id=f"{cid}-checking-bar", className="progress"),
            html.Div("", id=f"{cid}-checking-text", className="progress-text"),
        ], style={"flex": "1 1 auto"}),
    ], id=f"{cid}-checking", className="notice notice-info", role="status", style=HIDDEN)


def background_check(cid: str, running=()) -> dict:
    """Keyword arguments of the background callback that checks for ``cid`` (see
    :func:`checking`): through the job queue, with the queue position or step as progress
    (bar value, bar max, text) and the checking line shown while it runs; ``running``:
    more ``(Output, while running, after)`` triples, e.g. the upload disabled."""
    return {
        "background": True,
        "progress": [Output(f"{cid}-checking-bar", "value"), Output(f"{cid}-checking-bar", "max"),
                     Output(f"{cid}-checking-text", "children")],
        "running": [(Output(f"{cid}-checking", "style"), SHOWN, HIDDEN), *running],
        "interval": CHECK_POLL_MS,
    }


def check_started(set_progress, text: str) -> None:
    """Tell the page that the check runs now (bar without a value: it moves without an
    end) and what it does."""
    set_progress((None, None, text))
