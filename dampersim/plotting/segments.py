"""Figures of segment motion: compression of every segment over time and the animated
drawing of the damper from the simulated segment states ([thesis] §7.3, Fig. 7.24-7.25).
"""

from __future__ import annotations

import numpy as np
import plotly.graph_objects as go

from dampersim.errors import InputError
from dampersim.plotting import theme
from dampersim.plotting.theme import axis_title, number_text, thin


def segment_compression_figure(
    result,
    spring: str = "outer",
    angle_unit: str = "deg",
    max_frames: int = 2000,
    title: str | None = None,
    dtype=None,
) -> go.Figure:
    """Compression of each segment of one spring over time ([thesis] §7.3.1, Fig. 7.24-7.25).

    Heatmap: time [s] across, segment index (1 = end at the body before the set) up,
    colour = compression (relaxed arc minus current arc) in ``angle_unit``.

    Args:
        result: a SimulationResult run with ``record_segments=True``.
        spring: "outer", "pair_outer" or "pair_inner".
        max_frames: thin the segment frames to at most this many columns.
        dtype: numpy dtype of the colour values (e.g. float32 halves what a browser receives).
    """
    theme.check_angle_unit(angle_unit)
    if getattr(result, "nodes", None) is None or result.nodes.shape[0] == 0:
        raise InputError("the result holds no segment states: simulate with record_segments=True")
    names = [s.name for s in result.springs]
    if spring not in names:
        raise InputError(f"spring {spring!r}: accepted is one of {names}")
    comp = result.segment_compression(spring)
    sl = thin(comp.shape[0], max_frames)
    t = result.segment_t[sl]
    z = theme.angle(comp[sl], angle_unit).T  # (segments, frames)
    if dtype is not None:
        z = np.asarray(z, dtype=dtype)
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


def damper_animation_figure(result, system, span: float = 0.04, gain: float = 5.0, max_frames: int = 60,
                            title="Damper drawing (primary plate fixed)"):
    """Animated drawing of the damper from the simulated segment states.

    Drawn in the frame of the primary plate: the outer set's springs run between the
    primary's stoppers (grey) and the secondary's (blue), the nested pairs of the inner set
    between the secondary's inner stoppers and the tertiary's (green). Every spring is drawn
    through its simulated nodes (slot coordinates, docs/model.md), each segment as one coil,
    so compressed segments show as tight coils. Red ticks mark where the driven body's
    stopper meets its hardstop. ``gain`` enlarges the motion about its mean over the
    animated span (the span is the last ``span`` seconds of the record); 1 draws true angles.
    """
    if result.nodes.shape[0] < 2:
        raise InputError("the result holds no segment states: simulate with record_segments=True")
    ts = result.segment_t
    keep = np.flatnonzero(ts >= ts[-1] - float(span))
    if keep.size < 2:
        keep = np.arange(max(0, ts.size - 2), ts.size)
    keep = keep[thin(keep.size, max_frames)]
    t_frames = ts[keep]
    w_o = np.interp(t_frames, result.t, result.windup_outer)
    w_i = np.interp(t_frames, result.t, result.windup_inner)
    nodes = {sp.name: result.spring_nodes(sp.name)[keep] for sp in result.springs}

    def exaggerate(a):
        m = a.mean(axis=0, keepdims=True)
        return m + gain * (a - m)

    w_o_d, w_i_d = exaggerate(w_o[:, None])[:, 0], exaggerate(w_i[:, None])[:, 0]
    # drawing: angle on screen = 90 deg - slot angle measured in the primary's frame
    r_out, r_in, r_nest = 1.0, 0.62, 0.55
    band = 0.07

    def xy(angle_rad, r):
        a = np.pi / 2 - np.asarray(angle_rad)
        return r * np.cos(a), r * np.sin(a)

    def coil(x_nodes, r, amp, offset, count, pitch):
        """Polyline of one spring type in all slots: one coil per segment."""
        xs, ys = [], []
        n_sub = 6
        s = np.linspace(0, 1, n_sub, endpoint=False)
        for k in range(count):
            seg_a = x_nodes[:-1, None] + np.diff(x_nodes)[:, None] * s[None, :]
            ang = np.append(seg_a.ravel(), x_nodes[-1]) + offset + k * pitch
            wig = np.append(np.tile(np.sin(2 * np.pi * s), x_nodes.size - 1), 0.0)
            x, y = xy(ang, r + amp * wig)
            xs += list(np.round(x, 4)) + [None]
            ys += list(np.round(y, 4)) + [None]
        return xs, ys

    def node_marks(x_nodes, r, offset, count, pitch):
        xs, ys = [], []
        for k in range(count):
            x, y = xy(x_nodes + offset + k * pitch, r)
            xs += list(np.round(x, 4))
            ys += list(np.round(y, 4))
        return xs, ys

    def stoppers(offset, half, count, pitch, r, width):
        xs, ys = [], []
        for k in range(count):
            for side in (-half, half):
                a = offset + k * pitch + side
                x0, y0 = xy(a, r - width)
                x1, y1 = xy(a, r + width)
                xs += [round(float(x0), 4), round(float(x1), 4), None]
                ys += [round(float(y0), 4), round(float(y1), 4), None]
            # the stopper's face ring segment
            aa = offset + k * pitch + np.linspace(-half, half, 6)
            x, y = xy(aa, r + width)
            xs += list(np.round(x, 4)) + [None]
            ys += list(np.round(y, 4)) + [None]
        return xs, ys

    def ticks(angles, r, length):
        xs, ys = [], []
        for a in angles:
            x0, y0 = xy(a, r + length)
            x1, y1 = xy(a, r + 2.2 * length)
            xs += [round(float(x0), 4), round(float(x1), 4), None]
            ys += [round(float(y0), 4), round(float(y1), 4), None]
        return xs, ys

    so, si = system.outer, system.inner
    n_o = nodes["outer"]
    n_po = nodes["pair_outer"]
    n_pi = nodes.get("pair_inner")
    n_o_d, n_po_d = exaggerate(n_o), exaggerate(n_po)
    n_pi_d = exaggerate(n_pi) if n_pi is not None else None
    hs_colour = "#D55E00" if system.hardstops.enabled else "#BBBBBB"

    def frame_traces(j):
        tr = []
        x, y = coil(n_o_d[j], r_out, 0.035, 0.0, so.count, so.pitch)
        tr.append(go.Scatter(x=x, y=y, mode="lines", line=dict(color=theme.COLOURWAY[1], width=2), name="outer springs", hoverinfo="skip"))
        x, y = node_marks(n_o_d[j], r_out, 0.0, so.count, so.pitch)
        tr.append(go.Scatter(x=x, y=y, mode="markers", marker=dict(size=4, color="#7A4F00"), name="outer segment nodes", hoverinfo="skip"))
        off_i = w_o_d[j]
        x, y = coil(n_po_d[j], r_in, 0.03, off_i, si.count, si.pitch)
        tr.append(go.Scatter(x=x, y=y, mode="lines", line=dict(color=theme.COLOURWAY[4], width=2), name="nested pairs, outer", hoverinfo="skip"))
        if n_pi_d is not None:
            x, y = coil(n_pi_d[j], r_nest, 0.018, off_i, si.count, si.pitch)
        else:
            x, y = [], []
        tr.append(go.Scatter(x=x, y=y, mode="lines", line=dict(color=theme.COLOURWAY[5], width=1.5), name="nested pairs, inner", hoverinfo="skip"))
        x, y = stoppers(w_o_d[j], so.secondary_stopper_half_width, so.count, so.pitch, r_out, band)
        tr.append(go.Scatter(x=x, y=y, mode="lines", line=dict(color=theme.COLOURWAY[0], width=4), name="secondary stoppers", hoverinfo="skip"))
        x, y = stoppers(w_o_d[j], si.primary_stopper_half_width, si.count, si.pitch, r_in, band)
        tr.append(go.Scatter(x=x, y=y, mode="lines", line=dict(color=theme.COLOURWAY[0], width=3, dash="dot"), name="secondary inner stoppers", hoverinfo="skip"))
        x, y = stoppers(w_o_d[j] + w_i_d[j], si.secondary_stopper_half_width, si.count, si.pitch, r_in, band * 0.8)
        tr.append(go.Scatter(x=x, y=y, mode="lines", line=dict(color=theme.COLOURWAY[2], width=4), name="tertiary (hub) stoppers", hoverinfo="skip"))
        angs = [off_i + k * si.pitch + lim for k in range(si.count) for lim in (si.hardstop_positive, si.hardstop_negative)]
        x, y = ticks(angs, r_in, band)
        tr.append(go.Scatter(x=x, y=y, mode="lines", line=dict(color=hs_colour, width=3), name="inner hardstops", hoverinfo="skip"))
        return tr

    # static parts: primary stoppers, outer hardstops, plate rings
    static = []
    circ = np.linspace(0, 2 * np.pi, 241)
    for r, col in ((r_out + band + 0.04, "#888888"), (r_in + band + 0.03, "#9AB8D3"), (r_nest - 0.08, "#B5D9C6")):
        static.append(go.Scatter(x=list(np.round(r * np.cos(circ), 4)), y=list(np.round(r * np.sin(circ), 4)), mode="lines",
                                 line=dict(color=col, width=1), hoverinfo="skip", showlegend=False))
    x, y = stoppers(0.0, so.primary_stopper_half_width, so.count, so.pitch, r_out, band)
    static.append(go.Scatter(x=x, y=y, mode="lines", line=dict(color="#555555", width=4), name="primary stoppers", hoverinfo="skip"))
    angs = [k * so.pitch + lim for k in range(so.count) for lim in (so.hardstop_positive, so.hardstop_negative)]
    x, y = ticks(angs, r_out, band)
    static.append(go.Scatter(x=x, y=y, mode="lines", line=dict(color=hs_colour, width=3), name="outer hardstops", hoverinfo="skip"))

    first = frame_traces(0)
    n_static = len(static)
    fig = go.Figure(data=static + first)
    moving = list(range(n_static, n_static + len(first)))
    frames = []
    for j in range(len(keep)):
        frames.append(go.Frame(data=frame_traces(j), traces=moving, name=f"{t_frames[j]:.4f}"))
    fig.frames = frames
    steps = [dict(method="animate", label=f"{t_frames[j]:.3f}",
                  args=[[f"{t_frames[j]:.4f}"], dict(mode="immediate", frame=dict(duration=0, redraw=False), transition=dict(duration=0))])
             for j in range(len(keep))]
    fig.update_layout(
        updatemenus=[dict(type="buttons", showactive=False, x=0.0, y=-0.02, xanchor="left", yanchor="top", direction="left", pad=dict(t=10),
                          buttons=[dict(label="▶ Play", method="animate",
                                        args=[None, dict(frame=dict(duration=60, redraw=False), fromcurrent=True, transition=dict(duration=0), mode="immediate")]),
                                   dict(label="❚❚ Pause", method="animate",
                                        args=[[None], dict(frame=dict(duration=0, redraw=False), mode="immediate", transition=dict(duration=0))])])],
        sliders=[dict(active=0, steps=steps, x=0.3, len=0.7, y=-0.02, yanchor="top",
                      currentvalue=dict(prefix="t = ", suffix=" s", font=dict(size=12)), pad=dict(t=10))],
        xaxis=dict(visible=False, range=[-1.35, 1.35], scaleanchor="y", scaleratio=1, showgrid=False),
        yaxis=dict(visible=False, range=[-1.3, 1.3], showgrid=False),
        legend=dict(orientation="v", x=1.02, y=1, font=dict(size=11)),
        margin=dict(l=10, r=10, t=60, b=80),
    )
    theme.apply(fig, title + (f" · motion ×{number_text(gain)} about the mean" if gain != 1 else ""))
    fig.update_xaxes(visible=False, showline=False)
    fig.update_yaxes(visible=False, showline=False)
    return fig


__all__ = ["segment_compression_figure", "damper_animation_figure"]
