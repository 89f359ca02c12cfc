"""Figures of one record over time: torque traces, windup per set against the hardstops and
the energy balance.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import plotly.graph_objects as go
from plotly.subplots import make_subplots

from dampersim.errors import InputError
from dampersim.plotting import theme
from dampersim.plotting.theme import axis_title, colour, number_text, thin
from dampersim.units import rad_to_deg


def time_trace_figure(result, seconds: float | None = None, max_points: int | None = 20000, title: str | None = "Torque time traces") -> go.Figure:
    """Input and output torque [N m] over time [s] of a result.

    ``result`` needs ``t``, ``input_torque``, ``output_torque`` (a SimulationResult, or any
    object / dict with those); ``seconds``: show only the last so many seconds [s].
    """
    get = (lambda k: result[k]) if isinstance(result, dict) else (lambda k: getattr(result, k))
    try:
        t = np.asarray(get("t"), dtype=float)
        tin = np.asarray(get("input_torque"), dtype=float)
        tout = np.asarray(get("output_torque"), dtype=float)
    except (KeyError, AttributeError):
        raise InputError("time_trace_figure: accepted is a result with t [s], input_torque and output_torque [N m]") from None
    if seconds is not None:
        keep = t >= t[-1] - float(seconds)
        t, tin, tout = t[keep], tin[keep], tout[keep]
    sl = thin(t.size, max_points)
    fig = go.Figure()
    fig.add_trace(go.Scatter(x=t[sl], y=tin[sl], name="input torque", line=dict(color=colour(0))))
    fig.add_trace(go.Scatter(x=t[sl], y=tout[sl], name="output torque", line=dict(color=colour(3))))
    fig.update_xaxes(title_text=axis_title("Time", "s"))
    fig.update_yaxes(title_text=axis_title("Torque", "N m"))
    return theme.apply(fig, title)


def recent_traces_figure(result, duration: float, max_points: int | None = 4000, title: str | None = "Torque time traces") -> go.Figure:
    """:func:`time_trace_figure` of a ``duration`` [s] record, opened on its last few
    revolutions (at least 0.05 s; a double-click shows the whole record), legend on top."""
    fig = time_trace_figure(result, max_points=max_points, title=title)
    rev = 2 * math.pi / result.speed
    show = min(duration, max(4 * rev, 0.05))
    fig.update_xaxes(range=[duration - show, float(result.t[-1])],
                     title_text=f"Time [s] (last {number_text(round(show, 3))} s; double-click: all)")
    fig.update_layout(legend=dict(orientation="h", y=1.01, x=0, xanchor="left", yanchor="bottom", borderwidth=0,
                                  bgcolor="rgba(0,0,0,0)"), margin=dict(t=80))
    return fig


def windup_figure(result, system, max_points=4000, title="Windup per set with hardstop limits"):
    """Windup of each set over time [deg] with its hardstop limits (dashed)."""
    sl = thin(result.t.size, max_points)
    t = result.t[sl]
    fig = make_subplots(rows=2, cols=1, shared_xaxes=True, vertical_spacing=0.12,
                        subplot_titles=("Outer set (J_pri → J_sec)", "Inner set (J_sec → J_ter)"))
    on = system.hardstops.enabled
    for row, (name, w, ss, col) in enumerate((("outer", result.windup_outer, system.outer, theme.COLOURWAY[0]),
                                              ("inner", result.windup_inner, system.inner, theme.COLOURWAY[2])), 1):
        fig.add_trace(go.Scatter(x=t, y=rad_to_deg(w[sl]), name=f"{name} set windup", line=dict(color=col)), row=row, col=1)
        for lim, lab in ((ss.hardstop_positive, "positive hardstop"), (ss.hardstop_negative, "negative hardstop")):
            fig.add_trace(go.Scatter(
                x=[float(t[0]), float(t[-1])], y=[float(rad_to_deg(lim))] * 2, mode="lines",
                line=dict(color="#D55E00" if on else "#AAAAAA", dash="dash", width=1.5),
                name=("hardstops" if on else "hardstops (disabled)"), legendgroup="hs", showlegend=(row == 1 and lab.startswith("pos")),
                hovertemplate=f"{name} {lab}: %{{y:.1f}} deg<extra></extra>"), row=row, col=1)
        fig.update_yaxes(title_text=theme.axis_title("Windup", "deg"), row=row, col=1)
    fig.update_xaxes(title_text=theme.axis_title("Time", "s"), row=2, col=1)
    fig.update_layout(legend=dict(orientation="h", y=-0.16, x=0.5, xanchor="center", yanchor="top"), margin=dict(b=90))
    return theme.apply(fig, title)


def energy_figure(result, title: str | None = "Energy balance") -> go.Figure:
    """Cumulative energies [J] of a run over time [s]: work in, stored, dissipated, residual.

    Uses ``result.energy`` (input_work, motor_work, kinetic, elastic, friction, damping,
    stacking) and ``result.t``; stored energies are shown as changes from the start. The
    residual (work in minus stored change minus dissipation) should stay near zero.
    """
    e = getattr(result, "energy", None)
    need = ("input_work", "motor_work", "kinetic", "elastic", "friction", "damping", "stacking")
    if not isinstance(e, dict) or any(k not in e for k in need):
        raise InputError(f"energy_figure: accepted is a result with an energy dict holding {list(need)}")
    t = np.asarray(result.t, dtype=float)
    series = {
        "input work": e["input_work"],
        "motor work": e["motor_work"],
        "kinetic (change)": e["kinetic"] - e["kinetic"][0],
        "elastic (change)": e["elastic"] - e["elastic"][0],
        "friction": e["friction"],
        "damping": e["damping"],
        "stacking": e["stacking"],
    }
    stored = series["kinetic (change)"] + series["elastic (change)"]
    residual = e["input_work"] + e["motor_work"] - stored - e["friction"] - e["damping"] - e["stacking"]
    sl = thin(t.size, 20000)
    fig = make_subplots(rows=2, cols=1, shared_xaxes=True, row_heights=[0.7, 0.3], vertical_spacing=0.08)
    for i, (name, y) in enumerate(series.items()):
        fig.add_trace(go.Scatter(x=t[sl], y=np.asarray(y)[sl], name=name, line=dict(color=colour(i))), row=1, col=1)
    fig.add_trace(go.Scatter(x=t[sl], y=residual[sl], name="residual", line=dict(color="black")), row=2, col=1)
    fig.update_yaxes(title_text=axis_title("Energy", "J"), row=1, col=1)
    fig.update_yaxes(title_text=axis_title("Residual", "J"), row=2, col=1)
    fig.update_xaxes(title_text=axis_title("Time", "s"), row=2, col=1)
    return theme.apply(fig, title, height=600)


def energy_balance_figure(result, max_points=2000, title="Energy balance"):
    """:func:`dampersim.plotting.energy_figure` of a thinned copy of the record."""
    sl = thin(result.t.size, max_points)
    light = SimpleNamespace(t=result.t[sl], energy={k: np.asarray(v)[sl] for k, v in result.energy.items()})
    fig = energy_figure(light, title=title)
    fig.update_layout(height=None, legend=dict(font=dict(size=11)))
    return fig


__all__ = ["time_trace_figure", "recent_traces_figure", "windup_figure", "energy_figure", "energy_balance_figure"]
