"""Plotly figure builders used by the dashboard pages, CLI reports and notebooks.

Importing the package registers the "dampersim" Plotly template
(:mod:`dampersim.plotting.theme`). Builders take existing data (SI units, result objects
read by attribute) and never run simulations. One module per topic:
:mod:`~dampersim.plotting.colourmaps` (speed sweeps), :mod:`~dampersim.plotting.maps`
(magnification maps), :mod:`~dampersim.plotting.hysteresis` (loops),
:mod:`~dampersim.plotting.segments` (segment motion and the damper drawing),
:mod:`~dampersim.plotting.traces` (one record over time), :mod:`~dampersim.plotting.spectra`
(spectra and order amplitudes), :mod:`~dampersim.plotting.modal` (linear model),
:mod:`~dampersim.plotting.export` (HTML files), plus :mod:`~dampersim.plotting.discrepancy`
and :mod:`~dampersim.plotting.studies`.
"""

from dampersim.plotting.theme import TEMPLATE_NAME, register_template
from dampersim.plotting.colourmaps import banded_colourmap_figure, colourmap_figure, order_cut_figure
from dampersim.plotting.export import write_html
from dampersim.plotting.hysteresis import hysteresis_figure, loop_energy_figure, stiffness_figure
from dampersim.plotting.maps import curve_prediction_figure, magnification_map_figure
from dampersim.plotting.modal import campbell_figure, mode_shape_figure
from dampersim.plotting.segments import damper_animation_figure, segment_compression_figure
from dampersim.plotting.spectra import mr_figure, result_spectrum_figure, spectrum_figure, windowed_spectrum_figure
from dampersim.plotting.traces import (
    energy_balance_figure,
    energy_figure,
    recent_traces_figure,
    time_trace_figure,
    windup_figure,
)

__all__ = [
    "TEMPLATE_NAME",
    "register_template",
    "banded_colourmap_figure",
    "campbell_figure",
    "colourmap_figure",
    "curve_prediction_figure",
    "damper_animation_figure",
    "energy_balance_figure",
    "energy_figure",
    "hysteresis_figure",
    "loop_energy_figure",
    "magnification_map_figure",
    "mode_shape_figure",
    "mr_figure",
    "order_cut_figure",
    "recent_traces_figure",
    "result_spectrum_figure",
    "segment_compression_figure",
    "spectrum_figure",
    "stiffness_figure",
    "time_trace_figure",
    "windowed_spectrum_figure",
    "windup_figure",
    "write_html",
]
