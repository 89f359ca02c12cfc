"""Figures of the linear model: Campbell diagram (engine orders against natural
frequencies) and mode shapes."""

from __future__ import annotations

import numpy as np
import plotly.graph_objects as go

from dampersim.errors import InputError
from dampersim.plotting import theme
from dampersim.plotting.theme import axis_title, colour, order_text, speed_title


def campbell_figure(data, speed_unit: str = "rpm", max_frequency_hz: float | None = None, title: str | None = "Campbell diagram") -> go.Figure:
    """Engine-order lines over speed against the natural frequencies, crossings marked.

    Args:
        data: :class:`dampersim.analysis.modal.CampbellData`.
        speed_unit: "rpm" or "rad/s".
        max_frequency_hz: top of the frequency axis [Hz] (default: the highest order line).
    """
    lines = data.order_lines
    top = float(max_frequency_hz) if max_frequency_hz is not None else float(lines["frequency_hz"].max())
    x_lo, x_hi = (float(v) for v in theme.speed(np.asarray(data.speed_range_rad_s), speed_unit))
    fig = go.Figure()
    for i, k in enumerate(data.orders):
        sub = lines[np.isclose(lines["order"], k)]
        fig.add_trace(go.Scatter(x=theme.speed(sub["speed_rad_s"], speed_unit), y=sub["frequency_hz"], mode="lines", line=dict(color="#777777", width=1), name="engine orders" if i == 0 else f"order {order_text(k)}", legendgroup="orders", showlegend=i == 0, hovertemplate=f"order {order_text(k)}: %{{y:.1f}} Hz<extra></extra>"))
        end = sub.iloc[-1]
        if end["frequency_hz"] <= top:
            fig.add_annotation(x=float(theme.speed(end["speed_rad_s"], speed_unit)), y=float(end["frequency_hz"]), text=order_text(k), showarrow=False, xanchor="left", font=dict(size=11, color="#555555"))
    for j, (m, f) in enumerate(zip(data.modes, data.natural_frequencies_hz)):
        if f > top:
            continue
        fig.add_trace(go.Scatter(x=[x_lo, x_hi], y=[f, f], mode="lines", line=dict(color=colour(j), dash="dash", width=1.5), name=f"mode {m}: {f:.1f} Hz"))
    cr = data.crossings[data.crossings["natural_frequency_hz"] <= top]
    if not cr.empty:
        fig.add_trace(
            go.Scatter(
                x=theme.speed(cr["speed_rad_s"], speed_unit),
                y=cr["natural_frequency_hz"],
                mode="markers",
                marker=dict(size=8, color="black", symbol="circle-open", line=dict(width=2)),
                name="crossings",
                customdata=np.column_stack([cr["order"], cr["mode"]]),
                hovertemplate=f"order %{{customdata[0]:g}} x mode %{{customdata[1]}}<br>%{{x:.0f}} {speed_unit}, %{{y:.1f}} Hz<extra></extra>",
            )
        )
    fig.update_xaxes(title_text=speed_title(speed_unit), range=[x_lo, x_hi])
    fig.update_yaxes(title_text=axis_title("Frequency", "Hz"), range=[0, top * 1.02])
    return theme.apply(fig, title)


def mode_shape_figure(modal, modes=None, max_frequency_hz: float | None = 300.0, title: str | None = "Mode shapes") -> go.Figure:
    """Mode shapes (scaled to max |value| = 1) over the DOFs of a
    :class:`dampersim.analysis.modal.ModalResult`; ``modes`` are 1-based numbers (default:
    elastic modes up to ``max_frequency_hz`` [Hz])."""
    if modes is None:
        modes = [i + 1 for i, f in enumerate(modal.frequencies_hz) if not modal.rigid[i] and (max_frequency_hz is None or f <= max_frequency_hz)]
    fig = go.Figure()
    for j, m in enumerate(modes):
        if not (1 <= int(m) <= modal.frequencies_hz.size):
            raise InputError(f"mode {m!r}: accepted is 1 to {modal.frequencies_hz.size}")
        fig.add_trace(go.Scatter(x=list(modal.dof_names), y=modal.shapes[:, int(m) - 1], mode="lines+markers", marker=dict(size=5), name=f"mode {m}: {modal.frequencies_hz[int(m) - 1]:.1f} Hz", line=dict(color=colour(j))))
    fig.update_xaxes(title_text=axis_title("Degree of freedom", "-"), tickangle=-60)
    fig.update_yaxes(title_text=axis_title("Relative amplitude", "-"))
    return theme.apply(fig, title)


__all__ = ["campbell_figure", "mode_shape_figure"]
