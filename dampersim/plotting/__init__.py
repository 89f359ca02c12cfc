"""Plotly figure builders used by the dashboard pages, CLI reports and notebooks.

Importing the package registers the "dampersim" Plotly template
(:mod:`dampersim.plotting.theme`). Builders take existing data (SI units) and never run
simulations; see :mod:`dampersim.plotting.figures`.
"""

from dampersim.plotting.theme import TEMPLATE_NAME, register_template
from dampersim.plotting.figures import (
    campbell_figure,
    colourmap_figure,
    energy_figure,
    hysteresis_figure,
    magnification_map_figure,
    mode_shape_figure,
    order_cut_figure,
    result_spectrum_figure,
    segment_compression_figure,
    spectrum_figure,
    stiffness_figure,
    time_trace_figure,
    write_html,
)

__all__ = [
    "TEMPLATE_NAME",
    "register_template",
    "campbell_figure",
    "colourmap_figure",
    "energy_figure",
    "hysteresis_figure",
    "magnification_map_figure",
    "mode_shape_figure",
    "order_cut_figure",
    "result_spectrum_figure",
    "segment_compression_figure",
    "spectrum_figure",
    "stiffness_figure",
    "time_trace_figure",
    "write_html",
]
