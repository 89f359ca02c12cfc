"""Figures of the discrepancy workflow: gap bars, residual maps, ranking, overlays."""

from __future__ import annotations

import html

import numpy as np
import plotly.graph_objects as go
from plotly.subplots import make_subplots

from dampersim.plotting import theme

STAGES = ("before", "calibrated", "after")
STAGE_LABELS = {"before": "model as given", "calibrated": "calibrated", "after": "augmented"}


def gap_figure(diag, title: str | None = "Held-out gap") -> go.Figure:
    """Bars: held-out gap before, after calibration, after augmentation, with the noise floor."""
    vals = [diag.gap_before_nm, diag.gap_calibrated_nm, diag.gap_after_nm]
    fig = go.Figure(go.Bar(x=[STAGE_LABELS[s] for s in STAGES], y=vals,
                           text=[f"{v:.2f}" for v in vals], textposition="outside"))
    fig.add_hline(y=diag.noise_floor_nm, line_dash="dash", annotation_text="noise floor")
    fig.update_xaxes(title_text="model stage (categories, no unit)")
    fig.update_yaxes(title_text="RMS order error, orders 1-8 [N m]")
    return theme.apply(fig, title)


def residual_map_figure(diag, title: str | None = "Where the model disagrees") -> go.Figure:
    """RMS order error per test point over (speed, mean torque), one panel per stage."""
    fig = make_subplots(rows=1, cols=3, subplot_titles=tuple(STAGE_LABELS[s] for s in STAGES), shared_yaxes=True)
    vmax = max(max(np.sqrt(np.mean(np.square(v))) for v in diag.residuals[s].values()) for s in STAGES) or 1.0
    for c, stage in enumerate(STAGES, start=1):
        pts = diag.points
        rms = [float(np.sqrt(np.mean(np.square(diag.residuals[stage][p["id"]])))) for p in pts]
        fig.add_trace(go.Scatter(
            x=[p["speed_rpm"] for p in pts], y=[p["mean_torque_nm"] for p in pts], mode="markers",
            marker=dict(size=14, color=rms, cmin=0, cmax=vmax, colorscale="Viridis", showscale=c == 3,
                        symbol=["diamond" if p["held_out"] else "circle" for p in pts],
                        colorbar=dict(title="N m")),
            text=[f"{p['id']}: {r:.2f} N m" + (" (held out)" if p["held_out"] else "") for p, r in zip(pts, rms)],
            hoverinfo="text", showlegend=False), row=1, col=c)
        fig.update_xaxes(title_text="speed [rpm]", row=1, col=c)
    fig.update_yaxes(title_text="mean torque [N m]", row=1, col=1)
    return theme.apply(fig, title)


def order_residual_figure(diag, title: str | None = "Error by order") -> go.Figure:
    """RMS error per order over all points for each stage."""
    fig = go.Figure()
    for stage in STAGES:
        e = np.array(list(diag.residuals[stage].values()))
        fig.add_trace(go.Bar(name=stage, x=list(range(1, e.shape[1] + 1)), y=np.sqrt(np.mean(e * e, axis=0))))
    fig.update_xaxes(title_text="engine order")
    fig.update_yaxes(title_text="RMS error [N m]")
    return theme.apply(fig, title)


def ranking_figure(diag, title: str | None = "Candidate effects (held-out gap)") -> go.Figure:
    rows = [r for r in diag.ranking if r["gap_held_out_nm"] is not None]
    fig = go.Figure(go.Bar(x=[r["effect"] for r in rows], y=[r["gap_held_out_nm"] for r in rows]))
    fig.add_hline(y=diag.gap_calibrated_nm, line_dash="dot", annotation_text="calibrated, no effect")
    fig.add_hline(y=diag.noise_floor_nm, line_dash="dash", annotation_text="noise floor")
    fig.update_xaxes(title_text="candidate effect (fitted ones only)")
    fig.update_yaxes(title_text="held-out gap [N m]")
    return theme.apply(fig, title)


def overlay_figure(diag, point_id: str, title: str | None = None) -> go.Figure:
    """Measured vs simulated output order amplitudes of one point, each stage."""
    p = next(q for q in diag.points if q["id"] == point_id)
    k = list(range(1, len(p["measured"]) + 1))
    fig = go.Figure(go.Bar(name="measured", x=k, y=p["measured"]))
    for stage in STAGES:
        fig.add_trace(go.Scatter(name=stage, x=k, y=p[stage], mode="markers+lines"))
    fig.update_xaxes(title_text="engine order")
    fig.update_yaxes(title_text="output amplitude [N m]", type="log")
    return theme.apply(fig, title or f"{point_id}: output orders")


def _group_rms(values, keys) -> tuple:
    """RMS of ``values`` per distinct key -> (sorted keys, RMS per key)."""
    keys = np.asarray(keys, dtype=float)
    values = np.asarray(values, dtype=float)
    ks = np.unique(keys)
    return ks, np.array([float(np.sqrt(np.mean(np.square(values[keys == k])))) for k in ks])


def residual_profile_figure(diag, title: str | None = "Where the error lies: by speed, mean torque and order") -> go.Figure:
    """RMS order error of each stage grouped by speed, by mean torque and by engine order
    (all test points, training and held out)."""
    fig = make_subplots(rows=1, cols=3, shared_yaxes=True, horizontal_spacing=0.05,
                        subplot_titles=("by speed", "by mean torque", "by engine order"))
    pts = diag.points
    n_orders = len(diag.residuals[STAGES[0]][pts[0]["id"]])
    speeds = np.repeat([p["speed_rpm"] for p in pts], n_orders)
    torques = np.repeat([p["mean_torque_nm"] for p in pts], n_orders)
    orders = np.tile(np.arange(1, n_orders + 1), len(pts))
    for i, stage in enumerate(STAGES):
        res = np.array([diag.residuals[stage][p["id"]] for p in pts], dtype=float)  # points x orders [N m]
        colour = theme.COLOURWAY[i % len(theme.COLOURWAY)]
        for col, (keys, unit) in enumerate(((speeds, "rpm"), (torques, "N m"), (orders, "")), start=1):
            x, y = _group_rms(res.ravel(), keys)
            fig.add_trace(go.Scatter(
                x=x, y=y, mode="lines+markers", name=STAGE_LABELS[stage], legendgroup=stage, showlegend=col == 1,
                line=dict(color=colour, dash=theme.DASHES[i % len(theme.DASHES)]),
                hovertemplate=f"{STAGE_LABELS[stage]}<br>%{{x:g}}{(' ' + unit) if unit else ''}: %{{y:.3g}} N m<extra></extra>"),
                row=1, col=col)
    fig.add_hline(y=diag.noise_floor_nm, line_dash="dash", line_color="#6B7280", annotation_text="noise floor")
    fig.update_xaxes(title_text=theme.axis_title("speed", "rpm"), row=1, col=1)
    fig.update_xaxes(title_text=theme.axis_title("mean torque", "N m"), row=1, col=2)
    fig.update_xaxes(title_text=theme.axis_title("engine order", "-"), dtick=1, row=1, col=3)
    fig.update_yaxes(title_text=theme.axis_title("RMS order error", "N m"), rangemode="tozero", row=1, col=1)
    return theme.apply(fig, title)


def held_out_overlay_figure(diag, title: str | None = "Held-out points: measured and simulated output orders",
                            columns: int = 2) -> go.Figure:
    """Measured output order amplitudes of every held-out point against the model as given
    and the final model (calibrated plus the named effect, or calibrated alone when none
    was named); one panel per point."""
    held = [p for p in diag.points if p["held_out"]]
    if not held:
        fig = go.Figure()
        fig.add_annotation(text="no held-out points", showarrow=False, xref="paper", yref="paper", x=0.5, y=0.5)
        fig.update_xaxes(title_text=theme.axis_title("engine order", "-"))
        fig.update_yaxes(title_text=theme.axis_title("output amplitude", "N m"))
        return theme.apply(fig, title)
    cols = max(1, min(columns, len(held)))
    rows = -(-len(held) // cols)
    fig = make_subplots(rows=rows, cols=cols, vertical_spacing=min(0.12, 0.3 / rows), horizontal_spacing=0.08,
                        subplot_titles=[f"{p['id']}: {p['speed_rpm']:g} rpm, {p['mean_torque_nm']:g} N m" for p in held])
    final = f"augmented (+{diag.effect})" if diag.effect else "calibrated (no effect added)"
    series = (("before", "model as given", "dash"), ("after", final, "solid"))
    for j, p in enumerate(held):
        r, c = j // cols + 1, j % cols + 1
        k = list(range(1, len(p["measured"]) + 1))
        first = j == 0
        fig.add_trace(go.Bar(x=k, y=p["measured"], name="measured", legendgroup="measured", showlegend=first,
                             marker_color="#BBBBBB"), row=r, col=c)
        for i, (stage, label, dash) in enumerate(series):
            fig.add_trace(go.Scatter(x=k, y=p[stage], mode="lines+markers", name=label, legendgroup=stage, showlegend=first,
                                     line=dict(color=theme.COLOURWAY[(0, 2)[i]], dash=dash)), row=r, col=c)
        fig.update_xaxes(title_text=theme.axis_title("engine order", "-"), dtick=1, row=r, col=c)
        fig.update_yaxes(title_text=theme.axis_title("output amplitude", "N m"), type="log", row=r, col=c)
    return theme.apply(fig, title, height=max(360, 300 * rows))


def _finite(v) -> bool:
    return v is not None and bool(np.isfinite(v))


def sections_html(sections) -> str:
    """Tables with a title and notes as HTML: each section {"title", "columns" ([(key,
    title)]), "rows" (dicts of text), "highlight" (key of a row's bool, or None), "notes"
    (paragraphs before the table), "hint" (a paragraph on reading it), "after" (paragraphs
    after it)}, every key optional; a section without rows has no table. Everything is
    escaped."""
    esc = html.escape
    parts = []
    for sec in sections or ():
        parts.append(f"<h2>{esc(str(sec.get('title') or ''))}</h2>")
        parts += [f"<p>{esc(str(n))}</p>" for n in sec.get("notes") or ()]
        columns, rows, hl = sec.get("columns") or [], sec.get("rows") or [], sec.get("highlight")
        if rows and columns:
            head = "".join(f"<th>{esc(str(t))}</th>" for _, t in columns)
            body = "".join(
                ("<tr style='font-weight:bold'>" if hl and r.get(hl) else "<tr>")
                + "".join(f"<td>{esc(str(r.get(k, '')))}</td>" for k, _ in columns) + "</tr>" for r in rows)
            parts.append(f"<table border='1' cellpadding='4' style='border-collapse:collapse'><thead><tr>{head}</tr>"
                         f"</thead><tbody>{body}</tbody></table>")
        parts += [f"<p>{esc(str(n))}</p>" for n in sec.get("after") or ()]
        if sec.get("hint"):
            parts.append(f"<p><small>{esc(str(sec['hint']))}</small></p>")
    return "\n".join(parts)


def report_html(diag, campaign_name: str = "", sections=None) -> str:
    """A self-contained HTML report (plotly.js from the CDN) of a Diagnosis (or of a
    document read by :func:`dampersim.discrepancy.report.diagnosis_from_document`).

    It states the verdict and its message, the gaps, the candidates left unranked because
    their model runs failed, and the campaign's problems, then the tables of ``sections``
    (see :func:`sections_html`; the model comparison of
    :func:`dampersim.discrepancy.report_tables.report_html`). A campaign that could not be
    diagnosed (verdict ``insufficient_data``: no test points, no numbers) gives the verdict
    and what the campaign lacks, without figures; the gap and ranking figures need the
    gaps, the per-point figures the per-point data."""
    esc = html.escape
    message = getattr(diag, "message", "") or ""
    missing = list(getattr(diag, "missing", None) or [])
    locate = getattr(diag, "locate", None) or {}
    points = list(getattr(diag, "points", None) or [])
    residuals = getattr(diag, "residuals", None) or {}
    parts = [f"<h1>Discrepancy report {esc(campaign_name)}</h1>",
             f"<p><b>Verdict:</b> {esc(str(diag.verdict))}"
             + (f" &mdash; <b>{esc(diag.effect)}</b> {esc(str(diag.effect_parameters))}" if diag.effect else "")
             + "</p>"]
    if message:
        parts.append(f"<p>{esc(message)}</p>")
    if missing:
        parts.append(f"<p><b>Missing:</b> {esc(', '.join(missing))}</p>")
    gaps = _finite(diag.noise_floor_nm)
    if gaps:
        parts.append(f"<p>Noise floor {diag.noise_floor_nm:.3f} N m; held-out gap: as given {diag.gap_before_nm:.3f}, "
                     f"calibrated {diag.gap_calibrated_nm:.3f}, augmented {diag.gap_after_nm:.3f} N m "
                     f"({len(diag.held_out_points)} held-out points).</p>")
    if locate.get("collapses_on"):
        parts.append(f"<p>Residual collapses on: {esc(str(locate['collapses_on']))}</p>")
    excluded = [r for r in diag.ranking or [] if r.get("excluded")]
    if excluded:
        parts.append("<h2>Candidates not ranked</h2><ul>" + "".join(
            f"<li>{esc(str(r['effect']))}: {esc(str(r['excluded']))}</li>" for r in excluded) + "</ul>")
    if diag.problems:
        parts.append("<h2>Campaign problems</h2><ul>" + "".join(
            f"<li>{esc(str(q.get('file')))} [{esc(str(q.get('field')))}]: {esc(str(q.get('message')))}</li>"
            for q in diag.problems) + "</ul>")
    if sections:
        parts.append(sections_html(sections))
    figs = [gap_figure(diag), ranking_figure(diag)] if gaps else []
    if points and all(s in residuals for s in STAGES):
        worst = max(points, key=lambda p: float(np.sum(np.square(residuals["calibrated"][p["id"]]))))
        figs[1:1] = [residual_map_figure(diag), order_residual_figure(diag)]
        figs.append(overlay_figure(diag, worst["id"]))
    for i, f in enumerate(figs):
        parts.append(f.to_html(full_html=False, include_plotlyjs="cdn" if i == 0 else False))
    return ("<!doctype html><html><head><meta charset='utf-8'><title>dampersim discrepancy</title></head><body>"
            + "\n".join(parts) + "</body></html>")


__all__ = ["gap_figure", "residual_map_figure", "order_residual_figure", "ranking_figure", "overlay_figure",
           "residual_profile_figure", "held_out_overlay_figure", "sections_html", "report_html"]
