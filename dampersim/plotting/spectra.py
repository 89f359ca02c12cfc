"""Figures of amplitude spectra and order amplitudes: spectra with engine-order markers and
the magnification ratio per order ([thesis] §3.4).
"""

from __future__ import annotations

import math

import numpy as np
import plotly.graph_objects as go

from dampersim.errors import InputError
from dampersim.plotting import theme
from dampersim.plotting.theme import axis_title, colour, number_text, order_text
from dampersim.signal import DEFAULT_ORDERS, amplitude_spectrum


def spectrum_figure(
    frequency_hz,
    amplitudes: dict,
    speed_rad_s: float | None = None,
    orders=DEFAULT_ORDERS,
    f_max_hz: float | None = None,
    log_y: bool = False,
    title: str | None = "Amplitude spectrum",
) -> go.Figure:
    """Amplitude spectra [N m] over frequency [Hz] with engine-order markers ([thesis] §3.4).

    Args:
        frequency_hz: bin frequencies [Hz].
        amplitudes: {label: amplitude array [N m]} (e.g. "input", "output").
        speed_rad_s: shaft speed [rad/s]; if given, dotted lines mark orders ``orders`` at
            k * speed / (2 pi).
        f_max_hz: top of the frequency axis [Hz].
        log_y: logarithmic amplitude axis.
    """
    f = np.asarray(frequency_hz, dtype=float)
    if not isinstance(amplitudes, dict) or not amplitudes:
        raise InputError("amplitudes: accepted is a dict {label: amplitude array [N m]}")
    keep = f <= f_max_hz if f_max_hz is not None else np.ones(f.size, bool)
    fig = go.Figure()
    for i, (lab, a) in enumerate(amplitudes.items()):
        a = np.asarray(a, dtype=float)
        if a.shape != f.shape:
            raise InputError(f"amplitudes[{lab!r}] has {a.size} values for {f.size} frequencies")
        fig.add_trace(go.Scatter(x=f[keep], y=a[keep], name=str(lab), line=dict(color=colour(0 if i == 0 else i + 2), width=1.5)))
    if speed_rad_s is not None:
        top = float(f[keep][-1])
        for k in orders or ():
            fk = k * float(speed_rad_s) / (2 * np.pi)
            if fk <= top:
                fig.add_vline(x=fk, line=dict(color="#888888", width=1, dash="dot"), annotation_text=order_text(k), annotation_position="top")
    fig.update_xaxes(title_text=axis_title("Frequency", "Hz"))
    fig.update_yaxes(title_text=axis_title("Amplitude", "N m"), type="log" if log_y else "linear")
    return theme.apply(fig, title)


def result_spectrum_figure(result, seconds: float = 1.25, orders=DEFAULT_ORDERS, f_max_hz: float | None = 500.0, log_y: bool = False, title: str | None = None) -> go.Figure:
    """:func:`spectrum_figure` of a result's input and output torque over its analysis window
    (last ``seconds`` [s], Hann amplitude spectrum as [thesis] §3.4)."""
    w = result.window(seconds)
    f, a_in = amplitude_spectrum(result.input_torque[w], result.sample_rate)
    _, a_out = amplitude_spectrum(result.output_torque[w], result.sample_rate)
    rpm = float(theme.speed(result.speed, "rpm"))
    return spectrum_figure(f, {"input": a_in, "output": a_out}, result.speed, orders, f_max_hz, log_y, title if title is not None else f"Amplitude spectrum at {rpm:.0f} rpm")


def windowed_spectrum_figure(res, seconds: float) -> go.Figure:
    """Input and output amplitude spectra over the analysis window on a log axis, engine
    orders marked (as :func:`dampersim.plotting.result_spectrum_figure`, with the order
    markers set in one layout update: adding them one by one costs ~30 ms each)."""
    w = res.window(seconds)
    f, a_in = amplitude_spectrum(res.input_torque[w], res.sample_rate)
    _, a_out = amplitude_spectrum(res.output_torque[w], res.sample_rate)
    top = min(500.0, 0.45 * res.sample_rate)
    fig = spectrum_figure(f, {"input": a_in, "output": a_out}, speed_rad_s=None, f_max_hz=top, log_y=True, title="Amplitude spectra")
    f1 = res.speed / (2 * math.pi)
    ks = [k for k in DEFAULT_ORDERS if k * f1 <= top]
    fig.update_layout(
        shapes=[dict(type="line", xref="x", yref="paper", x0=k * f1, x1=k * f1, y0=0, y1=1,
                     line=dict(color="#888888", width=1, dash="dot"), layer="below") for k in ks],
        annotations=[dict(x=k * f1, y=1.0, xref="x", yref="paper", text=number_text(k), showarrow=False, yanchor="bottom",
                          font=dict(size=11, color="#555555")) for k in ks],
        margin=dict(t=70),
        legend=dict(orientation="v", y=0.99, x=0.99, xanchor="right", yanchor="top", bgcolor="rgba(255,255,255,0.85)"),
    )
    fig.update_yaxes(exponentformat="power", dtick=1)
    fig.update_xaxes(title_text=f"Frequency [Hz] (last {number_text(round(seconds, 3))} s, Hann)")
    return fig


def mr_figure(rows, title="Magnification ratio per order", runs: int | None = None):
    """MR [-] per order on a log axis with MR = 1 marked (excited orders dark); orders
    without input (not excited) have no ratio and are left out. Rows with ``mr_range``
    ([min, max] over ``runs`` repeatability runs) get it as an error bar around the bar, and
    their ``spread_pct`` [%] in the hover, with ``spread_origin`` ("physical" or "numerical")
    where a spread check labelled it."""
    rows = [r for r in rows if r["mr"] is not None and r["mr"] > 0]
    fig = go.Figure()
    band = any(r.get("mr_range") for r in rows)
    if rows:
        labels = [f"{number_text(r['order'])}" for r in rows]
        extra = {}
        if band:
            extra["error_y"] = dict(type="data", symmetric=False, color="#333333", thickness=1.5, width=8,
                                    array=[(r["mr_range"][1] - r["mr"]) if r.get("mr_range") else 0.0 for r in rows],
                                    arrayminus=[(r["mr"] - r["mr_range"][0]) if r.get("mr_range") else 0.0 for r in rows])
        fig.add_trace(go.Bar(
            x=labels,
            y=[r["mr"] for r in rows],
            text=[f"{r['mr']:.3g}" for r in rows],
            textposition="outside",
            width=0.45 if len(rows) > 1 else 0.3,
            marker=dict(color=[theme.COLOURWAY[0] if r["excited"] else "#9AB8D3" for r in rows]),
            customdata=[[r["input_nm"], r["output_nm"], r["frequency_hz"],
                         ("—" if r.get("spread_pct") is None else f"{r['spread_pct']:.3g} %")
                         + (f" ({r['spread_origin']})" if r.get("spread_origin") else "")] for r in rows],
            hovertemplate="order %{x}<br>MR %{y:.4g}<br>input %{customdata[0]:.3g} N m<br>"
                          "output %{customdata[1]:.3g} N m<br>%{customdata[2]:.1f} Hz"
                          + ("<br>spread %{customdata[3]}" if band else "") + "<extra></extra>",
            name="MR",
            **extra,
        ))
        lo = min(r["mr_range"][0] if r.get("mr_range") else r["mr"] for r in rows)
        hi = max(r["mr_range"][1] if r.get("mr_range") else r["mr"] for r in rows)
        fig.add_hline(y=1.0, line=dict(color="#D55E00", dash="dash", width=1.5),
                      annotation_text="MR = 1", annotation_position="top left")
        fig.update_yaxes(type="log", dtick=1, exponentformat="power",
                         range=[math.floor(math.log10(min(lo, 0.5))) - 0.1, math.log10(max(hi, 1.0)) + 0.45])
    else:
        fig.add_annotation(text="no excited order", showarrow=False, xref="paper", yref="paper", x=0.5, y=0.5)
    fig.update_xaxes(title_text=theme.axis_title("Engine order", "-"), type="category")
    fig.update_yaxes(title_text=theme.axis_title("Magnification ratio", "-"))
    fig.update_layout(showlegend=False, margin=dict(t=50, b=50))
    if band:
        fig.add_annotation(text=f"bars: min-max of {runs} runs, input amplitudes x (1 + i·1e-9)" if runs
                           else "bars: min-max over the repeatability runs", showarrow=False,
                           xref="paper", yref="paper", x=1.0, y=1.0, xanchor="right", yanchor="bottom", font=dict(size=11))
    return theme.apply(fig, title)


__all__ = ["spectrum_figure", "result_spectrum_figure", "windowed_spectrum_figure", "mr_figure"]
