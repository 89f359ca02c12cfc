"""Writing figures to files: self-contained HTML, written atomically."""

from __future__ import annotations

import plotly.graph_objects as go

from dampersim.fileio import atomic_write


def write_html(fig: go.Figure, path, include_plotlyjs=True) -> str:
    """Write ``fig`` to ``path`` as a self-contained HTML file (atomic: temp file + rename).

    ``include_plotlyjs``: True embeds plotly.js (works offline), "cdn" links it instead.
    Returns the path written.
    """
    return atomic_write(path, lambda tmp: fig.write_html(tmp, include_plotlyjs=include_plotlyjs, full_html=True),
                        suffix=".html.tmp")


__all__ = ["write_html"]
