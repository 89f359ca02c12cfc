"""Figures of the chapter 7 studies and of the pulsation generator, built from the
studies' result documents (plain dicts) and PulsationResult objects; no simulation here."""

from __future__ import annotations

import numpy as np
import plotly.graph_objects as go

from dampersim.plotting.theme import TEMPLATE_NAME


def _fig(title, x, y):
    f = go.Figure()
    f.update_layout(template=TEMPLATE_NAME, title=title, xaxis_title=x, yaxis_title=y)
    return f


def order_rule_figures(res):
    f = _fig("Order rule: MR change against the full signal ([thesis] Fig. 7.3)", "dominant orders replicated", "MR change [%]")
    for case in res["results"]["cases"]:
        for k in case["mr_full"]:
            xs, ys = [], []
            for row in case["replicas"]:
                if k in row["mr_change_pct"]:
                    xs.append(row["n_orders"])
                    ys.append(row["mr_change_pct"][k])
            f.add_scatter(x=xs, y=ys, mode="lines+markers", name=f"{case['speed_rpm']:g} rpm, order {k}")
    rep = res["results"].get("max_abs_perturbation_mr_change_pct")
    if rep:  # the MR change a 1e-9 input change causes: the scale below which changes mean nothing
        f.add_hrect(y0=-rep, y1=rep, fillcolor="grey", opacity=0.2, line_width=0,
                    annotation_text="MR change from a 1e-9 input change (full signal)", annotation_position="top left")
    return [f]


def additional_orders_figures(res):
    f = _fig("Dominant 4th order MR change as an extra order grows ([thesis] Fig. 7.7-7.8)",
             "extra order amplitude / dominant amplitude [%]", "MR change of the 4th order [%]")
    for c in res["results"]["curves"]:
        f.add_scatter(x=[100 * r for r in c["ratios"]], y=c["mr_change_pct"], mode="lines+markers",
                      name=f"{c['side']} ({c['extra_order']:g}th) at {c['mean_torque_nm']:g} N m")
    f.add_hline(y=5, line_dash="dot")
    f.add_hline(y=-5, line_dash="dot")
    return [f]


def sufficient_excitation_figures(res):
    f = _fig("Parameter-change impact vs excitation magnitude ([thesis] Fig. 7.9-7.10)", "excitation amplitude [N m]",
             "mean |output change| for +-20 % [N m]")
    for r in res["results"]["rows"]:
        f.add_scatter(x=r["magnitudes_nm"], y=r["impact_nm"], mode="lines+markers",
                      name=f"{r['parameter']} @ {r['mean_torque_nm']:g} N m")
    return [f]


def mapping_figures(res):
    out = []
    for a, m in res["results"]["maps"].items():
        f = _fig(f"MR map, Table 7.1 points at {a} N m amplitude ([thesis] Fig. 7.14)", "frequency [Hz]", "mean torque [N m]")
        f.add_heatmap(x=m["frequency_hz"], y=m["mean_torque_nm"], z=m["magnification"], colorbar_title="MR")
        out.append(f)
    for k, row in res["results"]["prediction"].items():
        f = _fig(f"Torque-curve MR, order {k}: campaign vs map prediction ([thesis] Fig. 7.16)", "speed [rpm]", "MR [-]")
        f.add_scatter(x=row["speed_rpm"], y=row["campaign_mr"], mode="lines+markers", name="fired-engine campaign")
        for key in row:
            if key.startswith("predicted_mr_"):
                f.add_scatter(x=row["speed_rpm"], y=row[key], mode="lines", name=f"map {key.split('_')[-1]} N m")
        out.append(f)
    return out


def poor_performance_figures(res):
    out = []
    for name, xlab in (("low_frequency", "frequency [Hz]"), ("low_amplitude", "amplitude [N m]"), ("high_frequency", "frequency [Hz]")):
        rows = res["results"].get(name, [])
        f = _fig(f"{name.replace('_', ' ')} ([thesis] §7.2)", xlab, "MR [-]")
        groups = {}
        for r in rows:
            key = (r["mean_torque_nm"], r["amplitude_nm"]) if name != "low_amplitude" else (r["mean_torque_nm"], round(r["frequency_hz"], 1))
            groups.setdefault(key, []).append(r)
        for key, rr in sorted(groups.items()):
            xk = "amplitude_nm" if name == "low_amplitude" else "frequency_hz"
            rr = sorted(rr, key=lambda r: r[xk])
            label = f"{key[0]:g} N m, {key[1]:g} {'Hz' if name == 'low_amplitude' else 'N m'}"
            f.add_scatter(x=[r[xk] for r in rr], y=[r["magnification"] for r in rr], mode="lines+markers", name=label)
        out.append(f)
    return out


def speed_stiffness_figures(res):
    r = res["results"]
    f = _fig("Outer-set dynamic stiffness over speed ([thesis] Fig. 7.27-7.28)", "speed [rpm]", "stiffness [N m/rad]")
    sa = r["stiffness_at_angle"]
    for ang in ("5", "30"):
        f.add_scatter(x=sa["speeds_rpm"], y=sa[ang], mode="lines+markers", name=f"{ang} deg vibration angle")
    g = _fig("Outer segment motion range ([thesis] Fig. 7.29-7.30)", "segment (0 = secondary end)", "compression range [deg]")
    for key, s in r["segments"].items():
        g.add_scatter(y=s["segment_range_deg"], mode="lines+markers", name=f"{key} ({s['angle_deg']:.1f} deg)")
    return [f, g]


_BUILDERS = {
    "order-rule": order_rule_figures,
    "additional-orders": additional_orders_figures,
    "sufficient-excitation": sufficient_excitation_figures,
    "mapping": mapping_figures,
    "poor-performance": poor_performance_figures,
    "speed-stiffness": speed_stiffness_figures,
}


def study_figures(res) -> list:
    """Plotly figures of one study result document."""
    return _BUILDERS[res["study"]](res)


def pulsation_figures(result, orders=(1, 2, 3, 4, 5, 6, 7, 8)) -> list:
    """Torque trace (last 0.1 s), cylinder-1 pressure over crank angle and order content
    of one pulsation-generator run (a :class:`~dampersim.simulation.PulsationResult`, read by attribute)."""
    w = result.window(0.1)
    f = _fig("Pulsation generator output torque", "time [s]", "torque [N m]")
    f.add_scatter(x=result.t[w], y=result.output_torque[w], mode="lines", name="generator output")
    if result.coupled:
        f.add_scatter(x=result.t[w], y=result.damper_output_torque[w], mode="lines", name="rig output transducer")
    p = _fig("Cylinder 1 pressure", "crank angle [deg]", "pressure [bar]")
    ww = result.window(60.0 / (result.speed * 60 / (2 * np.pi)) * 1.0)
    ang = np.degrees(np.mod(result.crank_angle[ww] + np.pi, 2 * np.pi) - np.pi)
    o = np.argsort(ang)
    p.add_scatter(x=ang[o], y=result.cylinder_pressure[ww][o] / 1e5, mode="lines", name="cylinder 1")
    a = result.order_amplitudes(tuple(float(k) for k in orders))
    b = _fig("Order content of the output torque", "order", "amplitude [N m]")
    b.add_bar(x=list(orders), y=a)
    return [f, p, b]


def dominant_order_figure(rows, title="Dominant order over speed ([thesis] Fig. 4.12)"):
    """rows: [(rpm, dominant order, [A2, A4, A6])] from ``dominant_order_over_speed``."""
    f = _fig(title, "speed [rpm]", "amplitude [N m]")
    rpm = [r[0] for r in rows]
    for i, k in enumerate((2, 4, 6)):
        f.add_scatter(x=rpm, y=[r[2][i] for r in rows], mode="lines+markers", name=f"order {k}")
    return f


__all__ = ["study_figures", "pulsation_figures", "dominant_order_figure"]
