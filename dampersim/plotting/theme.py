"""The "dampersim" Plotly template and the display-unit helpers of the figure builders.

One look for every view: white background, light grid, readable fonts, and the Okabe-Ito
palette for lines (distinguishable with the common colour-vision deficiencies). Heatmaps use
the perceptually uniform, colour-blind-safe "Viridis"; maps of magnification ratio use a
diverging blue-red scale centred on MR = 1 so attenuation and amplification read apart.

Figure builders take SI data and convert only for display, explicitly through
:mod:`dampersim.units`; every axis title carries its unit.
"""

from __future__ import annotations


import numpy as np
import plotly.graph_objects as go
import plotly.io as pio

from dampersim.errors import InputError
from dampersim.units import number_text, rad_s_to_rpm, rad_to_deg

TEMPLATE_NAME = "dampersim"

#: Okabe & Ito (2008) colour-blind-safe qualitative palette (black moved last).
COLOURWAY = (
    "#0072B2",  # blue
    "#E69F00",  # orange
    "#009E73",  # bluish green
    "#D55E00",  # vermillion
    "#CC79A7",  # reddish purple
    "#56B4E9",  # sky blue
    "#F0E442",  # yellow
    "#000000",  # black
)
#: Sequential scale for amplitude heatmaps.
SEQUENTIAL = "Viridis"
#: Diverging scale for magnification ratio (blue: attenuation, red: amplification).
DIVERGING = "RdBu_r"
#: Dash patterns to tell series apart without colour.
DASHES = ("solid", "dash", "dot", "dashdot", "longdash", "longdashdot")

ANGLE_UNITS = ("deg", "rad")
SPEED_UNITS = ("rpm", "rad/s")


def _build_template() -> go.layout.Template:
    axis = dict(
        showgrid=True,
        gridcolor="#E5E5E5",
        zeroline=False,
        linecolor="#444444",
        ticks="outside",
        tickcolor="#444444",
        showline=True,
        mirror=True,
        title=dict(standoff=8),
    )
    layout = go.Layout(
        font=dict(family="Inter, Helvetica, Arial, sans-serif", size=13, color="#222222"),
        title=dict(font=dict(size=16), x=0.0, xanchor="left"),
        paper_bgcolor="white",
        plot_bgcolor="white",
        colorway=list(COLOURWAY),
        colorscale=dict(sequential=SEQUENTIAL, diverging=DIVERGING),
        xaxis=axis,
        yaxis=axis,
        legend=dict(bgcolor="rgba(255,255,255,0.8)", bordercolor="#CCCCCC", borderwidth=1),
        hovermode="closest",
        margin=dict(l=70, r=30, t=60, b=60),
    )
    data = go.layout.template.Data(
        scatter=[go.Scatter(line=dict(width=2))],
        heatmap=[go.Heatmap(colorscale=SEQUENTIAL)],
        contour=[go.Contour(colorscale=SEQUENTIAL)],
    )
    return go.layout.Template(layout=layout, data=data)


def register_template(make_default: bool = False) -> str:
    """Register the "dampersim" template with plotly.io (idempotent); returns its name.

    ``make_default`` also makes it plotly's default template for this process.
    """
    if TEMPLATE_NAME not in pio.templates:
        pio.templates[TEMPLATE_NAME] = _build_template()
    if make_default:
        pio.templates.default = TEMPLATE_NAME
    return TEMPLATE_NAME


register_template()


# --- display units -------------------------------------------------------------------------
def check_angle_unit(unit: str) -> str:
    if unit not in ANGLE_UNITS:
        raise InputError(f"angle_unit {unit!r}: accepted is one of {ANGLE_UNITS}")
    return unit


def check_speed_unit(unit: str) -> str:
    if unit not in SPEED_UNITS:
        raise InputError(f"speed_unit {unit!r}: accepted is one of {SPEED_UNITS}")
    return unit


def angle(values_rad, unit: str = "deg"):
    """Angles [rad] in display ``unit`` ("deg" or "rad")."""
    v = np.asarray(values_rad, dtype=float)
    return rad_to_deg(v) if check_angle_unit(unit) == "deg" else v


def stiffness(values_nm_per_rad, unit: str = "deg"):
    """Torsional stiffness [N m/rad] in N m per display angle ``unit``."""
    v = np.asarray(values_nm_per_rad, dtype=float)
    return v / rad_to_deg(1.0) if check_angle_unit(unit) == "deg" else v


def speed(values_rad_s, unit: str = "rpm"):
    """Speeds [rad/s] in display ``unit`` ("rpm" or "rad/s")."""
    v = np.asarray(values_rad_s, dtype=float)
    return rad_s_to_rpm(v) if check_speed_unit(unit) == "rpm" else v


def angle_label(unit: str) -> str:
    """Unit text of a display angle unit for axis titles ("deg" or "rad")."""
    return check_angle_unit(unit)


def axis_title(quantity: str, unit: str) -> str:
    """Axis title with its unit, e.g. ``axis_title("Speed", "rpm")`` -> "Speed [rpm]"."""
    return f"{quantity} [{unit}]"


# --- shared by the builders ------------------------------------------------------------------
def colour(i: int) -> str:
    """The ``i``-th colour of the palette (cycling)."""
    return COLOURWAY[i % len(COLOURWAY)]


def thin(n: int, max_points: int | None) -> slice:
    """Stride that keeps at most ``max_points`` of ``n`` samples for display (None: all)."""
    if max_points is None or n <= max_points:
        return slice(None)
    return slice(None, None, int(np.ceil(n / max_points)))


def speed_title(speed_unit: str) -> str:
    """Axis title of a speed axis in ``speed_unit``."""
    check_speed_unit(speed_unit)
    return axis_title("Speed", speed_unit)


def order_text(k: float) -> str:
    """Short label of an engine order ("2", "1.5")."""
    return f"{k:g}"


def apply(fig: go.Figure, title: str | None = None, height: int | None = None) -> go.Figure:
    """Apply the dampersim template (and optional title/height) to ``fig``."""
    fig.update_layout(template=TEMPLATE_NAME)
    if title is not None:
        fig.update_layout(title=dict(text=title))
    if height is not None:
        fig.update_layout(height=height)
    return fig


__all__ = [
    "TEMPLATE_NAME",
    "COLOURWAY",
    "SEQUENTIAL",
    "DIVERGING",
    "DASHES",
    "register_template",
    "angle",
    "stiffness",
    "speed",
    "angle_label",
    "axis_title",
    "apply",
    "colour",
    "thin",
    "speed_title",
    "order_text",
    "number_text",
]
