"""Figures of a speed sweep: FFT colourmaps with engine-order lines and order cuts.

- :func:`colourmap_figure`: FFT colourmap(s) with order lines ([thesis] §6.3.1, Fig. 6.12-6.13)
- :func:`banded_colourmap_figure`: the same with float32 colours and a fixed dB range below
  each map's peak (the dashboard's view)
- :func:`order_cut_figure`: order cuts with input context and MR ([thesis] §6.3.1, Fig. 6.14-6.15),
  optionally with the repeatability spread of each cut as a shaded band
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import plotly.graph_objects as go
from plotly.subplots import make_subplots

from dampersim.errors import InputError
from dampersim.plotting import theme
from dampersim.plotting.theme import axis_title, colour, order_text, speed_title
from dampersim.signal import DEFAULT_ORDERS


def colourmap_figure(
    maps,
    orders=DEFAULT_ORDERS,
    speed_unit: str = "rpm",
    f_max_hz: float | None = None,
    db: bool = False,
    zmax: float | None = None,
    title: str | None = "FFT colourmap",
) -> go.Figure:
    """FFT colourmap(s) amplitude(speed, frequency) with engine-order lines.

    Args:
        maps: a :class:`dampersim.analysis.colourmap.Colourmap`, a dict such as
            ``{"input": cm_in, "output": cm_out}`` (from ``colourmaps``) or a list; several
            maps are drawn side by side, each with its own colour scale.
        orders: engine orders to draw as lines f = k * speed / (2 pi) (empty: none).
        speed_unit: "rpm" or "rad/s" for the x axis.
        f_max_hz: top of the frequency axis [Hz] (default: the maps' grid).
        db: colour by 20 log10(amplitude / 1 N m) [dB re 1 N m] instead of [N m].
        zmax: clip the colour scale at this value (N m or dB) to bring out weak resonance
            bands, as the thesis does in Fig. 7.19-7.20.
    """
    if isinstance(maps, dict):
        items = list(maps.items())
    elif isinstance(maps, (list, tuple)):
        items = [(getattr(m, "label", "") or f"map {i + 1}", m) for i, m in enumerate(maps)]
    else:
        items = [(getattr(maps, "label", "") or "amplitude", maps)]
    if not items:
        raise InputError("colourmap_figure: no colourmap given")
    n = len(items)
    fig = make_subplots(rows=1, cols=n, shared_yaxes=True, subplot_titles=[str(k).capitalize() for k, _ in items], horizontal_spacing=0.16 if n > 1 else 0.02)
    # leave room on the right of each panel for its colour bar
    for i in range(n):
        ax = "xaxis" if i == 0 else f"xaxis{i + 1}"
        lo, hi = fig.layout[ax].domain
        fig.layout[ax].domain = (lo, hi - 0.07)
    ztitle = "Amplitude [dB re 1 N m]" if db else "Amplitude [N m]"
    for i, (name, cm) in enumerate(items):
        c = cm.limit(f_max_hz) if f_max_hz is not None else cm
        x = theme.speed(c.speed_rad_s, speed_unit)
        z = c.amplitude_nm.T
        if db:
            with np.errstate(divide="ignore", invalid="ignore"):
                z = 20.0 * np.log10(np.maximum(z, 1e-12))
        axis = "coloraxis" if i == 0 else f"coloraxis{i + 1}"
        fig.add_trace(
            go.Heatmap(
                x=x,
                y=c.frequency_hz,
                z=z,
                coloraxis=axis,
                name=str(name),
                hovertemplate=f"%{{x:.0f}} {speed_unit}<br>%{{y:.1f}} Hz<br>%{{z:.3g}} {'dB' if db else 'N m'}<extra>{name}</extra>",
            ),
            row=1,
            col=i + 1,
        )
        xref = "xaxis" if i == 0 else f"xaxis{i + 1}"
        bar_x = float(fig.layout[xref].domain[1]) + 0.01
        fig.update_layout(
            {axis: dict(colorscale=theme.SEQUENTIAL, cmax=zmax, colorbar=dict(title=dict(text=ztitle, side="right"), x=bar_x, xanchor="left", len=0.9, thickness=14))}
        )
        f_top = float(c.frequency_hz[-1])
        for j, k in enumerate(orders or ()):
            fk = k * c.speed_rad_s / (2 * np.pi)
            keep = fk <= f_top
            if not np.any(keep):
                continue
            fig.add_trace(
                go.Scatter(
                    x=x[keep],
                    y=fk[keep],
                    mode="lines",
                    line=dict(color="white", width=1, dash="dot"),
                    name=f"order {order_text(k)}",
                    legendgroup=f"order{k}",
                    showlegend=False,
                    hovertemplate=f"order {order_text(k)}: %{{y:.1f}} Hz<extra></extra>",
                ),
                row=1,
                col=i + 1,
            )
            last = np.flatnonzero(keep)[-1]
            fig.add_annotation(x=x[last], y=fk[last], text=order_text(k), showarrow=False, font=dict(color="white", size=11), xanchor="right", yanchor="bottom" if fk[last] < 0.97 * f_top else "top", row=1, col=i + 1)
        fig.update_xaxes(title_text=speed_title(speed_unit), row=1, col=i + 1)
    fig.update_yaxes(title_text=axis_title("Frequency", "Hz"), row=1, col=1)
    return theme.apply(fig, title)


def banded_colourmap_figure(maps, orders=DEFAULT_ORDERS, f_max_hz: float | None = None, db: bool = False,
                            dynamic_range_db: float = 60.0, height: int = 460, title: str | None = "FFT colourmap") -> go.Figure:
    """:func:`colourmap_figure` with its colours stored as float32 (half the bytes to send)
    and, in dB, each map's colour scale spanning ``dynamic_range_db`` below its peak, so
    numerical noise far below stays dark."""
    fig = colourmap_figure(maps, orders=orders, f_max_hz=f_max_hz, db=db, title=title)
    for tr in fig.data:
        if tr.type == "heatmap":
            z = np.asarray(tr.z, dtype=np.float32)
            tr.z = z
            if db and np.isfinite(z).any():
                top = float(np.nanmax(z))
                fig.layout[tr.coloraxis].update(cmin=top - dynamic_range_db, cmax=top)
    fig.update_layout(height=height)
    return fig


def order_cut_figure(
    cuts: pd.DataFrame,
    orders=None,
    speed_unit: str = "rpm",
    reference: pd.DataFrame | None = None,
    reference_label: str = "measured",
    title: str | None = "Order cuts",
    band: pd.DataFrame | None = None,
    runs: int | None = None,
) -> go.Figure:
    """Order amplitudes over speed with the input for context ([thesis] §6.3.1, Fig. 6.14).

    Top: output amplitude per order (left axis) and input amplitude (dashed, right axis,
    usually an order of magnitude larger). Bottom: magnification ratio with MR = 1 marked.

    Args:
        cuts: :func:`dampersim.analysis.colourmap.order_cuts` table (speed_rad_s, order,
            input_amplitude_nm, output_amplitude_nm, magnification).
        orders: orders to draw (default all in ``cuts``).
        speed_unit: "rpm" or "rad/s".
        reference: optional second cut table (e.g. measured) drawn dotted for comparison.
        band: optional spread of the cuts over repeatability runs
            (:func:`dampersim.analysis.repeatability.sweep_spread`: speed_rad_s, order,
            output_min_nm, output_max_nm, mr_min, mr_max), drawn as a shaded band around
            the output and the MR of each order; runs: the number of runs, for its label.
    """
    need = ("speed_rad_s", "order", "input_amplitude_nm", "output_amplitude_nm", "magnification")
    for name, tab in (("cuts", cuts), ("reference", reference)):
        if tab is None:
            continue
        if not isinstance(tab, pd.DataFrame) or any(c not in tab.columns for c in need):
            raise InputError(f"{name}: accepted is an order-cut DataFrame with columns {list(need)}")
    ks = sorted(set(cuts["order"])) if orders is None else [float(k) for k in orders]
    fig = make_subplots(rows=2, cols=1, shared_xaxes=True, vertical_spacing=0.08, row_heights=[0.6, 0.4], specs=[[{"secondary_y": True}], [{}]])
    for i, k in enumerate(ks):
        col = colour(i)
        sub = cuts[np.isclose(cuts["order"], k)].sort_values("speed_rad_s")
        if sub.empty:
            raise InputError(f"order {k:g} is not in the cut table: accepted are {sorted(set(cuts['order']))}")
        x = theme.speed(sub["speed_rad_s"], speed_unit)
        lab = f"order {order_text(k)}"
        if band is not None:
            _band(fig, band, k, col, lab, speed_unit)
        fig.add_trace(go.Scatter(x=x, y=sub["output_amplitude_nm"], name=f"{lab} output", legendgroup=lab, line=dict(color=col)), row=1, col=1, secondary_y=False)
        fig.add_trace(go.Scatter(x=x, y=sub["input_amplitude_nm"], name=f"{lab} input", legendgroup=lab, line=dict(color=col, dash="dash", width=1.5), opacity=0.7), row=1, col=1, secondary_y=True)
        fig.add_trace(go.Scatter(x=x, y=sub["magnification"], name=f"{lab} MR", legendgroup=lab, line=dict(color=col), showlegend=False), row=2, col=1)
        if reference is not None:
            ref = reference[np.isclose(reference["order"], k)].sort_values("speed_rad_s")
            if not ref.empty:
                xr = theme.speed(ref["speed_rad_s"], speed_unit)
                fig.add_trace(go.Scatter(x=xr, y=ref["output_amplitude_nm"], name=f"{lab} output ({reference_label})", legendgroup=lab, line=dict(color=col, dash="dot")), row=1, col=1, secondary_y=False)
                fig.add_trace(go.Scatter(x=xr, y=ref["magnification"], name=f"{lab} MR ({reference_label})", legendgroup=lab, line=dict(color=col, dash="dot"), showlegend=False), row=2, col=1)
    fig.add_hline(y=1.0, line=dict(color="#444444", width=1, dash="dash"), row=2, col=1)
    if band is not None:
        fig.add_annotation(text=(f"bands: min-max of {runs} runs" if runs else "bands: min-max over the repeatability runs")
                           + ", input amplitudes x (1 + i·1e-9)", showarrow=False, xref="paper", yref="paper", x=1.0, y=1.0,
                           xanchor="right", yanchor="bottom", font=dict(size=11))
    fig.update_yaxes(title_text=axis_title("Output amplitude", "N m"), row=1, col=1, secondary_y=False, rangemode="tozero")
    fig.update_yaxes(title_text=axis_title("Input amplitude", "N m"), row=1, col=1, secondary_y=True, showgrid=False, rangemode="tozero")
    fig.update_yaxes(title_text=axis_title("Magnification ratio", "-"), row=2, col=1)
    fig.update_xaxes(title_text=speed_title(speed_unit), row=2, col=1)
    return theme.apply(fig, title, height=650)


BAND_COLUMNS = ("speed_rad_s", "order", "output_min_nm", "output_max_nm", "mr_min", "mr_max")


def _band(fig, band, k, col, lab, speed_unit):
    """Shaded min-max band of order ``k``'s output (top panel) and MR (bottom panel)."""
    if not isinstance(band, pd.DataFrame) or any(c not in band.columns for c in BAND_COLUMNS):
        raise InputError(f"band: accepted is a spread table with columns {list(BAND_COLUMNS)}")
    sub = band[np.isclose(band["order"], k)].sort_values("speed_rad_s")
    r, g, b = (int(col[i:i + 2], 16) for i in (1, 3, 5))
    fill = f"rgba({r},{g},{b},0.25)"
    for lo, hi, row, name in (("output_min_nm", "output_max_nm", 1, "output"), ("mr_min", "mr_max", 2, "MR")):
        ok = np.isfinite(sub[lo].to_numpy(float)) & np.isfinite(sub[hi].to_numpy(float))
        if not ok.any():
            continue
        x = np.asarray(theme.speed(sub["speed_rad_s"].to_numpy(float)[ok], speed_unit), dtype=float)
        y_lo, y_hi = sub[lo].to_numpy(float)[ok], sub[hi].to_numpy(float)[ok]
        fig.add_trace(go.Scatter(x=np.concatenate([x, x[::-1]]).tolist(), y=np.concatenate([y_hi, y_lo[::-1]]).tolist(), fill="toself",
                                 fillcolor=fill, line=dict(width=0.5, color=fill), mode="lines", name=f"{lab} {name} spread",
                                 legendgroup=lab, showlegend=row == 1, hoverinfo="skip"),
                      row=row, col=1, **({"secondary_y": False} if row == 1 else {}))


__all__ = ["BAND_COLUMNS", "colourmap_figure", "banded_colourmap_figure", "order_cut_figure"]
