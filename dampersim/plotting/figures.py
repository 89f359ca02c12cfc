"""Plotly figure builders for every dampersim view.

Each builder takes data that already exists (analysis results, a SimulationResult, arrays
in SI units) and returns a ``plotly.graph_objects.Figure`` styled with the "dampersim"
template; none runs a simulation. Display units are chosen by argument (``angle_unit``
"deg"/"rad", ``speed_unit`` "rpm"/"rad/s") and converted explicitly with
:mod:`dampersim.units` (via :mod:`dampersim.plotting.theme`); every axis title names its
unit.

Views, with the thesis figures they follow:

- :func:`colourmap_figure`: FFT colourmap(s) with order lines ([thesis] §6.3.1, Fig. 6.12-6.13)
- :func:`order_cut_figure`: order cuts with input context and MR ([thesis] §6.3.1, Fig. 6.14-6.15)
- :func:`magnification_map_figure`: MR map, MR > 1 contour, torque-curve overlay
  ([thesis] §6.3.1 Fig. 6.20-6.21, §7.1.3, §7.2)
- :func:`hysteresis_figure`, :func:`stiffness_figure`: loops and dynamic stiffness
  ([thesis] §6.3.2, §7.3.1 Fig. 7.22, 7.26)
- :func:`segment_compression_figure`: segment compression over time ([thesis] §7.3, Fig. 7.24-7.25)
- :func:`time_trace_figure`, :func:`spectrum_figure`: time traces and spectra with order
  markers ([thesis] §3.4)
- :func:`campbell_figure`, :func:`mode_shape_figure`: linear modes against engine orders
- :func:`energy_figure`: energy balance of a run
"""

from __future__ import annotations


import numpy as np
import pandas as pd
import plotly.graph_objects as go
from plotly.subplots import make_subplots

from dampersim.signal import DEFAULT_ORDERS, amplitude_spectrum
from dampersim.errors import InputError
from dampersim.plotting import theme
from dampersim.plotting.theme import COLOURWAY, DASHES, axis_title

#: Traces longer than this are thinned by a stride for display (keeps HTML files small).
DEFAULT_MAX_POINTS = 5000


def _colour(i: int) -> str:
    return COLOURWAY[i % len(COLOURWAY)]


def _thin(n: int, max_points: int | None) -> slice:
    if max_points is None or n <= max_points:
        return slice(None)
    return slice(None, None, int(np.ceil(n / max_points)))


def _speed_title(speed_unit: str) -> str:
    theme.check_speed_unit(speed_unit)
    return axis_title("Speed", speed_unit)


def _fmt_order(k: float) -> str:
    return f"{k:g}"


# --- colourmaps ----------------------------------------------------------------------------
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
                    name=f"order {_fmt_order(k)}",
                    legendgroup=f"order{k}",
                    showlegend=False,
                    hovertemplate=f"order {_fmt_order(k)}: %{{y:.1f}} Hz<extra></extra>",
                ),
                row=1,
                col=i + 1,
            )
            last = np.flatnonzero(keep)[-1]
            fig.add_annotation(x=x[last], y=fk[last], text=_fmt_order(k), showarrow=False, font=dict(color="white", size=11), xanchor="right", yanchor="bottom" if fk[last] < 0.97 * f_top else "top", row=1, col=i + 1)
        fig.update_xaxes(title_text=_speed_title(speed_unit), row=1, col=i + 1)
    fig.update_yaxes(title_text=axis_title("Frequency", "Hz"), row=1, col=1)
    return theme.apply(fig, title)


# --- order cuts --------------------------------------------------------------------------------
def order_cut_figure(
    cuts: pd.DataFrame,
    orders=None,
    speed_unit: str = "rpm",
    reference: pd.DataFrame | None = None,
    reference_label: str = "measured",
    title: str | None = "Order cuts",
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
        col = _colour(i)
        sub = cuts[np.isclose(cuts["order"], k)].sort_values("speed_rad_s")
        if sub.empty:
            raise InputError(f"order {k:g} is not in the cut table: accepted are {sorted(set(cuts['order']))}")
        x = theme.speed(sub["speed_rad_s"], speed_unit)
        lab = f"order {_fmt_order(k)}"
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
    fig.update_yaxes(title_text=axis_title("Output amplitude", "N m"), row=1, col=1, secondary_y=False, rangemode="tozero")
    fig.update_yaxes(title_text=axis_title("Input amplitude", "N m"), row=1, col=1, secondary_y=True, showgrid=False, rangemode="tozero")
    fig.update_yaxes(title_text=axis_title("Magnification ratio", "-"), row=2, col=1)
    fig.update_xaxes(title_text=_speed_title(speed_unit), row=2, col=1)
    return theme.apply(fig, title, height=650)


# --- magnification maps ----------------------------------------------------------------------------
def magnification_map_figure(
    mmap,
    overlays=None,
    show_points: bool = False,
    zmax: float | None = None,
    title: str | None = "Magnification map",
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
            name = "torque curve" + (f", order {_fmt_order(k)}" if k is not None else "")
            fig.add_trace(go.Scatter(x=ov["frequency_hz"], y=ov["mean_torque_nm"], mode="lines", line=dict(color="black", width=2.5, dash=DASHES[(i + 1) % len(DASHES)]), name=name))
    fig.update_xaxes(title_text=axis_title("Excitation frequency", "Hz"), range=[float(mmap.frequency_hz[0]), float(mmap.frequency_hz[-1])])
    fig.update_yaxes(title_text=axis_title("Mean torque", "N m"), range=[float(mmap.mean_torque_nm[0]), float(mmap.mean_torque_nm[-1])])
    fig.update_layout(legend=dict(orientation="h", y=-0.18))
    return theme.apply(fig, title)


# --- hysteresis -------------------------------------------------------------------------------------
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
            from dampersim.analysis.hysteresis import HysteresisLoop

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
            sl = _thin(w.size, max_points)
            name = lab if len(kinds) == 1 else f"{lab}, {_WINDUP_NAMES[kind]}"
            fig.add_trace(
                go.Scatter(
                    x=theme.angle(w[sl], angle_unit),
                    y=lp.torque_nm[sl],
                    mode="lines",
                    name=name,
                    legendgroup=lab,
                    line=dict(color=_colour(i), dash=DASHES[j % len(DASHES)]),
                    hovertemplate=f"%{{x:.2f}} {angle_unit}, %{{y:.1f}} N m<extra>{name}</extra>",
                )
            )
        kn = None if knees is None else knees[i]
        if kn is not None and getattr(kn, "found", False):
            fig.add_trace(go.Scatter(x=[float(theme.angle(kn.windup_rad, angle_unit))], y=[kn.torque_nm], mode="markers", marker=dict(symbol="x", size=11, color=_colour(i), line=dict(width=2)), name=f"{lab} knee", legendgroup=lab))
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
    ``log_y`` helps when the stiffness climbs steeply into a hardstop.
    """
    from dampersim.analysis.hysteresis import branch_directions, dynamic_stiffness

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
        fig.add_trace(go.Scatter(x=xv, y=yv, mode="lines" if branch == "loading" else "markers", marker=dict(size=3), name=_loop_label(lp, i), line=dict(color=_colour(i)), connectgaps=False))
    fig.update_xaxes(title_text=axis_title("Input torque", "N m") if x == "torque" else axis_title(f"Windup ({_WINDUP_NAMES[windup]})", theme.angle_label(angle_unit)))
    fig.update_yaxes(title_text=axis_title("Dynamic stiffness", f"N m/{theme.angle_label(angle_unit)}"), type="log" if log_y else "linear")
    return theme.apply(fig, title)


# --- segments ---------------------------------------------------------------------------------------
def segment_compression_figure(
    result,
    spring: str = "outer",
    angle_unit: str = "deg",
    max_frames: int = 2000,
    title: str | None = None,
) -> go.Figure:
    """Compression of each segment of one spring over time ([thesis] §7.3.1, Fig. 7.24-7.25).

    Heatmap: time [s] across, segment index (1 = end at the body before the set) up,
    colour = compression (relaxed arc minus current arc) in ``angle_unit``.

    Args:
        result: a SimulationResult run with ``record_segments=True``.
        spring: "outer", "pair_outer" or "pair_inner".
        max_frames: thin the segment frames to at most this many columns.
    """
    theme.check_angle_unit(angle_unit)
    if getattr(result, "nodes", None) is None or result.nodes.shape[0] == 0:
        raise InputError("the result holds no segment states: simulate with record_segments=True")
    names = [s.name for s in result.springs]
    if spring not in names:
        raise InputError(f"spring {spring!r}: accepted is one of {names}")
    comp = result.segment_compression(spring)
    sl = _thin(comp.shape[0], max_frames)
    t = result.segment_t[sl]
    z = theme.angle(comp[sl], angle_unit).T  # (segments, frames)
    unit = theme.angle_label(angle_unit)
    fig = go.Figure(
        go.Heatmap(
            x=t,
            y=np.arange(1, comp.shape[1] + 1),
            z=z,
            colorscale=theme.SEQUENTIAL,
            colorbar=dict(title=dict(text=f"Compression [{unit}]")),
            hovertemplate=f"t %{{x:.3f}} s<br>segment %{{y}}<br>%{{z:.3f}} {unit}<extra></extra>",
        )
    )
    fig.update_xaxes(title_text=axis_title("Time", "s"))
    fig.update_yaxes(title_text=axis_title("Segment index", "-"), dtick=1 if comp.shape[1] <= 20 else None)
    return theme.apply(fig, title if title is not None else f"Segment compression, {spring} spring")


# --- time traces and spectra --------------------------------------------------------------------------
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
    sl = _thin(t.size, max_points)
    fig = go.Figure()
    fig.add_trace(go.Scatter(x=t[sl], y=tin[sl], name="input torque", line=dict(color=_colour(0))))
    fig.add_trace(go.Scatter(x=t[sl], y=tout[sl], name="output torque", line=dict(color=_colour(3))))
    fig.update_xaxes(title_text=axis_title("Time", "s"))
    fig.update_yaxes(title_text=axis_title("Torque", "N m"))
    return theme.apply(fig, title)


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
        fig.add_trace(go.Scatter(x=f[keep], y=a[keep], name=str(lab), line=dict(color=_colour(0 if i == 0 else i + 2), width=1.5)))
    if speed_rad_s is not None:
        top = float(f[keep][-1])
        for k in orders or ():
            fk = k * float(speed_rad_s) / (2 * np.pi)
            if fk <= top:
                fig.add_vline(x=fk, line=dict(color="#888888", width=1, dash="dot"), annotation_text=_fmt_order(k), annotation_position="top")
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


# --- modal ----------------------------------------------------------------------------------------------
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
        fig.add_trace(go.Scatter(x=theme.speed(sub["speed_rad_s"], speed_unit), y=sub["frequency_hz"], mode="lines", line=dict(color="#777777", width=1), name="engine orders" if i == 0 else f"order {_fmt_order(k)}", legendgroup="orders", showlegend=i == 0, hovertemplate=f"order {_fmt_order(k)}: %{{y:.1f}} Hz<extra></extra>"))
        end = sub.iloc[-1]
        if end["frequency_hz"] <= top:
            fig.add_annotation(x=float(theme.speed(end["speed_rad_s"], speed_unit)), y=float(end["frequency_hz"]), text=_fmt_order(k), showarrow=False, xanchor="left", font=dict(size=11, color="#555555"))
    for j, (m, f) in enumerate(zip(data.modes, data.natural_frequencies_hz)):
        if f > top:
            continue
        fig.add_trace(go.Scatter(x=[x_lo, x_hi], y=[f, f], mode="lines", line=dict(color=_colour(j), dash="dash", width=1.5), name=f"mode {m}: {f:.1f} Hz"))
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
    fig.update_xaxes(title_text=_speed_title(speed_unit), range=[x_lo, x_hi])
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
        fig.add_trace(go.Scatter(x=list(modal.dof_names), y=modal.shapes[:, int(m) - 1], mode="lines+markers", marker=dict(size=5), name=f"mode {m}: {modal.frequencies_hz[int(m) - 1]:.1f} Hz", line=dict(color=_colour(j))))
    fig.update_xaxes(title_text=axis_title("Degree of freedom", "-"), tickangle=-60)
    fig.update_yaxes(title_text=axis_title("Relative amplitude", "-"))
    return theme.apply(fig, title)


# --- energy -------------------------------------------------------------------------------------------
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
    sl = _thin(t.size, 20000)
    fig = make_subplots(rows=2, cols=1, shared_xaxes=True, row_heights=[0.7, 0.3], vertical_spacing=0.08)
    for i, (name, y) in enumerate(series.items()):
        fig.add_trace(go.Scatter(x=t[sl], y=np.asarray(y)[sl], name=name, line=dict(color=_colour(i))), row=1, col=1)
    fig.add_trace(go.Scatter(x=t[sl], y=residual[sl], name="residual", line=dict(color="black")), row=2, col=1)
    fig.update_yaxes(title_text=axis_title("Energy", "J"), row=1, col=1)
    fig.update_yaxes(title_text=axis_title("Residual", "J"), row=2, col=1)
    fig.update_xaxes(title_text=axis_title("Time", "s"), row=2, col=1)
    return theme.apply(fig, title, height=600)


# --- output ---------------------------------------------------------------------------------------------
def write_html(fig: go.Figure, path, include_plotlyjs=True) -> str:
    """Write ``fig`` to ``path`` as a self-contained HTML file (atomic: temp file + rename).

    ``include_plotlyjs``: True embeds plotly.js (works offline), "cdn" links it instead.
    Returns the path written.
    """
    from dampersim.fileio import atomic_write

    return atomic_write(path, lambda tmp: fig.write_html(tmp, include_plotlyjs=include_plotlyjs, full_html=True),
                        suffix=".html.tmp")


__all__ = [
    "colourmap_figure",
    "order_cut_figure",
    "magnification_map_figure",
    "hysteresis_figure",
    "stiffness_figure",
    "segment_compression_figure",
    "time_trace_figure",
    "spectrum_figure",
    "result_spectrum_figure",
    "campbell_figure",
    "mode_shape_figure",
    "energy_figure",
    "write_html",
]
