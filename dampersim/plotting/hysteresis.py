"""Figures of hysteresis loops: torque over windup, dynamic stiffness along the loop and the
energy dissipated per loop ([thesis] §6.3.2, §7.3.1 Fig. 7.22, 7.26).
"""

from __future__ import annotations

import math

import numpy as np
import plotly.graph_objects as go

from dampersim.analysis.hysteresis import HysteresisLoop, branch_directions, dynamic_stiffness
from dampersim.errors import InputError
from dampersim.plotting import theme
from dampersim.plotting.theme import DASHES, axis_title, colour, number_text, thin

#: Traces longer than this are thinned by a stride for display (keeps HTML files small).
DEFAULT_MAX_POINTS = 5000


_WINDUP_NAMES = {"total": "total", "outer": "outer set", "inner": "inner set"}


def _loop_items(loops):
    """Normalise loops: HysteresisLoop objects or (label, torque [N m], windup [rad]) tuples."""
    if not isinstance(loops, (list, tuple)) or (len(loops) == 3 and isinstance(loops[0], str)):
        loops = [loops]
    out = []
    for i, lp in enumerate(loops):
        if hasattr(lp, "torque_nm"):
            out.append(lp)
        else:
            try:
                label, t, w = lp
            except (TypeError, ValueError):
                raise InputError("loops: accepted is a list of HysteresisLoop or (label, torque [N m], windup [rad]) tuples") from None
            t = np.asarray(t, dtype=float)
            out.append(HysteresisLoop(float("nan"), np.arange(t.size, dtype=float), t, np.asarray(w, dtype=float), label=str(label)))
    if not out:
        raise InputError("no loops to draw")
    return out


def _loop_label(lp, i):
    if lp.label:
        return lp.label
    if np.isfinite(lp.speed_rad_s):
        return f"{lp.speed_rpm:.0f} rpm"
    return f"loop {i + 1}"


def hysteresis_figure(
    loops,
    windup="total",
    angle_unit: str = "deg",
    knees=None,
    max_points: int | None = DEFAULT_MAX_POINTS,
    title: str | None = "Hysteresis loops",
) -> go.Figure:
    """Input torque over windup for one or more loops ([thesis] §6.3.2, §7.3.1 Fig. 7.22).

    Args:
        loops: :class:`dampersim.analysis.hysteresis.HysteresisLoop` objects (e.g. one per
            speed) or (label, torque [N m], windup [rad]) tuples.
        windup: "total" (the rig's measured windup), "outer", "inner" or a tuple of them;
            colour tells the loops apart, dash the windup kind.
        angle_unit: "deg" or "rad".
        knees: optional :class:`~dampersim.analysis.hysteresis.Knee` per loop (or None
            entries) to mark.
        max_points: thin long records for display.
    """
    theme.check_angle_unit(angle_unit)
    items = _loop_items(loops)
    kinds = (windup,) if isinstance(windup, str) else tuple(windup)
    fig = go.Figure()
    for i, lp in enumerate(items):
        lab = _loop_label(lp, i)
        for j, kind in enumerate(kinds):
            w = lp.windup(kind)
            sl = thin(w.size, max_points)
            name = lab if len(kinds) == 1 else f"{lab}, {_WINDUP_NAMES[kind]}"
            fig.add_trace(
                go.Scatter(
                    x=theme.angle(w[sl], angle_unit),
                    y=lp.torque_nm[sl],
                    mode="lines",
                    name=name,
                    legendgroup=lab,
                    line=dict(color=colour(i), dash=DASHES[j % len(DASHES)]),
                    hovertemplate=f"%{{x:.2f}} {angle_unit}, %{{y:.1f}} N m<extra>{name}</extra>",
                )
            )
        kn = None if knees is None else knees[i]
        if kn is not None and getattr(kn, "found", False):
            fig.add_trace(go.Scatter(x=[float(theme.angle(kn.windup_rad, angle_unit))], y=[kn.torque_nm], mode="markers", marker=dict(symbol="x", size=11, color=colour(i), line=dict(width=2)), name=f"{lab} knee", legendgroup=lab))
    fig.update_xaxes(title_text=axis_title("Windup", theme.angle_label(angle_unit)))
    fig.update_yaxes(title_text=axis_title("Input torque", "N m"))
    return theme.apply(fig, title)


def stiffness_figure(
    loops,
    windup: str = "total",
    x: str = "torque",
    angle_unit: str = "deg",
    window_nm: float | None = None,
    branch: str = "loading",
    max_points: int | None = DEFAULT_MAX_POINTS,
    log_y: bool = False,
    title: str | None = "Dynamic stiffness along the loop",
) -> go.Figure:
    """Dynamic stiffness dT/dtheta along the loop ([thesis] §7.3.1, Fig. 7.26).

    Computes :func:`dampersim.analysis.hysteresis.dynamic_stiffness` of each loop's
    ``windup`` ("total", "outer", "inner") and plots it against input torque [N m]
    (``x="torque"``) or windup (``x="windup"``). ``branch``: "loading" (rising torque
    only, the thesis's view) or "all"; ``window_nm``: torque window of the local fit [N m].
    Stiffness in N m per ``angle_unit``; gaps where the windup stops (a set on its hardstop);
    ``log_y`` (ticks at powers of ten) helps when the stiffness climbs steeply into a hardstop.
    """
    theme.check_angle_unit(angle_unit)
    if x not in ("torque", "windup"):
        raise InputError(f"x {x!r}: accepted is 'torque' or 'windup'")
    if branch not in ("loading", "all"):
        raise InputError(f"branch {branch!r}: accepted is 'loading' or 'all'")
    fig = go.Figure()
    for i, lp in enumerate(_loop_items(loops)):
        w = lp.windup(windup)
        s = branch_directions(lp.torque_nm)
        k = dynamic_stiffness(lp.torque_nm, w, window_nm, directions=s)
        keep = np.isfinite(k) & ((s > 0) if branch == "loading" else (s != 0))
        idx = np.flatnonzero(keep)
        step = max(1, int(np.ceil(idx.size / max_points))) if max_points else 1
        idx = idx[::step]
        xv = lp.torque_nm[idx] if x == "torque" else theme.angle(w[idx], angle_unit)
        yv = theme.stiffness(k[idx], angle_unit)
        if branch == "loading":
            # one line per loading ramp: NaN breaks the line between ramps
            gaps = np.flatnonzero(np.diff(idx) > step) + 1
            xv = np.insert(np.asarray(xv, dtype=float), gaps, np.nan)
            yv = np.insert(np.asarray(yv, dtype=float), gaps, np.nan)
        fig.add_trace(go.Scatter(x=xv, y=yv, mode="lines" if branch == "loading" else "markers", marker=dict(size=3), name=_loop_label(lp, i), line=dict(color=colour(i)), connectgaps=False))
    fig.update_xaxes(title_text=axis_title("Input torque", "N m") if x == "torque" else axis_title(f"Windup ({_WINDUP_NAMES[windup]})", theme.angle_label(angle_unit)))
    fig.update_yaxes(title_text=axis_title("Dynamic stiffness", f"N m/{theme.angle_label(angle_unit)}"), type="log" if log_y else "linear")
    if log_y:
        fig.update_yaxes(dtick=1, exponentformat="power")
    return theme.apply(fig, title)


def loop_energy_figure(speeds_rpm, energies_j, title: str | None = "Energy per loop (loop area)") -> go.Figure:
    """Bars of the energy dissipated per loop [J] (the loop area) at each speed [rpm]."""
    energies = list(energies_j)
    fig = go.Figure(go.Bar(x=[f"{number_text(r)} rpm" for r in speeds_rpm], y=energies, width=0.4 if len(energies) > 1 else 0.3,
                           text=[f"{e:.3g} J" for e in energies], textposition="outside",
                           marker=dict(color=[theme.COLOURWAY[i % len(theme.COLOURWAY)] for i in range(len(energies))]),
                           hovertemplate="%{x}: %{y:.4g} J<extra></extra>"))
    fig.update_xaxes(title_text=theme.axis_title("Speed", "rpm"), type="category")
    fig.update_yaxes(title_text=theme.axis_title("Energy dissipated per loop", "J"), rangemode="tozero")
    top = max([e for e in energies if math.isfinite(e)] or [1.0])
    fig.update_yaxes(range=[0, 1.25 * top if top > 0 else 1.0])
    return theme.apply(fig, title)


__all__ = ["DEFAULT_MAX_POINTS", "hysteresis_figure", "stiffness_figure", "loop_energy_figure"]
