"""Figures of magnification maps: MR over excitation frequency and mean torque, and the
MR predicted along an engine torque curve ([thesis] §6.3.1 Fig. 6.20-6.21, §7.1.3, §7.2).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import plotly.graph_objects as go

from dampersim.errors import InputError
from dampersim.plotting import theme
from dampersim.plotting.theme import DASHES, axis_title, number_text, order_text


def magnification_map_figure(
    mmap,
    overlays=None,
    show_points: bool = False,
    zmax: float | None = None,
    title: str | None = "Magnification map",
    height: int | None = None,
) -> go.Figure:
    """Magnification ratio over (excitation frequency, mean torque) ([thesis] §6.3.1).

    Diverging colours centred on MR = 1, the MR = 1 contour drawn in black (regions inside
    amplify the vibration), optional torque-curve overlays.

    Args:
        mmap: :class:`dampersim.analysis.maps.MagnificationMap`.
        overlays: a DataFrame from :func:`dampersim.analysis.maps.torque_curve_overlay`
            (columns frequency_hz, mean_torque_nm, order) or a list of them.
        show_points: mark the averaged test points behind the map.
        zmax: upper end of the colour scale [-] (default: the data's, at least 2).
        height: figure height [px] (default: the template's).
    """
    z = mmap.magnification
    finite = z[np.isfinite(z)]
    top = float(zmax) if zmax is not None else max(2.0, float(finite.max()) if finite.size else 2.0)
    fig = go.Figure()
    fig.add_trace(
        go.Heatmap(
            x=mmap.frequency_hz,
            y=mmap.mean_torque_nm,
            z=z,
            zmin=0.0,
            zmax=top,
            zmid=1.0,
            colorscale=theme.DIVERGING,
            colorbar=dict(title=dict(text="MR [-]")),
            name="MR",
            hovertemplate="%{x:.1f} Hz<br>%{y:.0f} N m<br>MR %{z:.3f}<extra></extra>",
        )
    )
    if finite.size and finite.min() < 1.0 < finite.max():
        fig.add_trace(
            go.Contour(
                x=mmap.frequency_hz,
                y=mmap.mean_torque_nm,
                z=z,
                contours=dict(start=1.0, end=1.0, size=1.0, coloring="none", showlabels=True),
                line=dict(color="black", width=2),
                showscale=False,
                name="MR = 1",
                showlegend=True,
                hoverinfo="skip",
            )
        )
    if show_points:
        p = mmap.points
        fig.add_trace(go.Scatter(x=p["frequency_hz"], y=p["mean_torque_nm"], mode="markers", marker=dict(size=3, color="#444444"), name="test points", hovertemplate="%{x:.1f} Hz, %{y:.0f} N m<extra>test point</extra>"))
    if overlays is not None:
        if isinstance(overlays, pd.DataFrame):
            overlays = [overlays]
        for i, ov in enumerate(overlays):
            if not isinstance(ov, pd.DataFrame) or not {"frequency_hz", "mean_torque_nm"} <= set(ov.columns):
                raise InputError("overlays: accepted is a DataFrame (or list) with frequency_hz and mean_torque_nm, e.g. from torque_curve_overlay()")
            k = ov["order"].iloc[0] if "order" in ov.columns and len(ov) else None
            name = "torque curve" + (f", order {order_text(k)}" if k is not None else "")
            fig.add_trace(go.Scatter(x=ov["frequency_hz"], y=ov["mean_torque_nm"], mode="lines", line=dict(color="black", width=2.5, dash=DASHES[(i + 1) % len(DASHES)]), name=name))
    fig.update_xaxes(title_text=axis_title("Excitation frequency", "Hz"), range=[float(mmap.frequency_hz[0]), float(mmap.frequency_hz[-1])])
    fig.update_yaxes(title_text=axis_title("Mean torque", "N m"), range=[float(mmap.mean_torque_nm[0]), float(mmap.mean_torque_nm[-1])])
    fig.update_layout(legend=dict(orientation="h", y=-0.18))
    return theme.apply(fig, title, height=height)


def curve_prediction_figure(prediction: pd.DataFrame, order: float, curve_name: str, title: str | None = None) -> go.Figure:
    """Predicted MR [-] over engine speed [rpm] along a torque curve, MR = 1 marked.

    ``prediction``: :func:`dampersim.analysis.maps.predict_along_curve` table (speed_rpm,
    magnification, frequency_hz, mean_torque_nm) of engine order ``order`` on the curve
    named ``curve_name``.
    """
    pred = prediction
    k = order
    fig = go.Figure()
    fig.add_trace(go.Scatter(x=pred["speed_rpm"], y=pred["magnification"], mode="lines", name=f"order {number_text(k)}",
                             line=dict(color=theme.COLOURWAY[0]),
                             customdata=np.column_stack([pred["frequency_hz"], pred["mean_torque_nm"]]),
                             hovertemplate="%{x:.0f} rpm<br>MR %{y:.3f}<br>%{customdata[0]:.1f} Hz, %{customdata[1]:.0f} N m<extra></extra>"))
    fig.add_trace(go.Scatter(x=[float(pred["speed_rpm"].min()), float(pred["speed_rpm"].max())], y=[1, 1], mode="lines",
                             line=dict(color="#D55E00", dash="dash", width=1.5), name="MR = 1", hoverinfo="skip"))
    fig.update_xaxes(title_text=theme.axis_title("Engine speed on the torque curve", "rpm"))
    fig.update_yaxes(title_text=theme.axis_title("Predicted magnification ratio", "-"), rangemode="tozero")
    fig.update_layout(legend=dict(orientation="h", y=1.1, x=1, xanchor="right"))
    return theme.apply(fig, title if title is not None else f"MR along the torque curve ({curve_name}), order {number_text(k)}")


__all__ = ["magnification_map_figure", "curve_prediction_figure"]
