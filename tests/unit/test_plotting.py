"""Every figure builder returns a go.Figure whose axis titles name their units."""

import re

import numpy as np
import pandas as pd
import plotly.graph_objects as go
import plotly.io as pio
import pytest

import dampersim
from dampersim import plotting as P
from dampersim.analysis import colourmap as cm
from dampersim.analysis import hysteresis as hy
from dampersim.analysis import maps, modal
from dampersim.errors import InputError
from dampersim.excitation.torque_curve import DEFAULT_WOT_CURVE
from dampersim.parameters import with_updates
from dampersim.plotting import theme
from dampersim.units import rpm_to_rad_s

UNIT = re.compile(r"\[[^\]]+\]")


@pytest.fixture(scope="module")
def result():
    # a short order-sum run with segment states: 0.8 s simulated (~0.2 s CPU)
    s = with_updates(dampersim.default_parameters(), {"solver.output_sample_rate": 2000})
    ex = dampersim.OrderSum(speed=rpm_to_rad_s(1500), mean_torque=150.0, orders=((2, 200.0, 0.0),), mean_ramp=0.1, amplitude_ramp=0.1)
    return dampersim.simulate(s, ex, duration=0.8)


def _loops():
    t = np.concatenate([np.linspace(0, 450, 500), np.linspace(450, -180, 700), np.linspace(-180, 0, 200)])
    w = np.deg2rad(np.where(t < 320, t / 6.6, 320 / 6.6 + (t - 320) / 34)) + np.deg2rad(1.0) * np.sign(np.gradient(t))
    a = hy.HysteresisLoop.from_arrays(t, w, sample_rate_hz=100.0, speed_rad_s=rpm_to_rad_s(1000), windup_outer_rad=0.8 * w, windup_inner_rad=0.2 * w)
    b = hy.HysteresisLoop.from_arrays(t, 0.9 * w, sample_rate_hz=100.0, speed_rad_s=rpm_to_rad_s(2000))
    return [a, b]


def _sweep():
    speeds = rpm_to_rad_s(np.linspace(1200, 2800, 9))
    a_in = np.tile([300.0, 100.0, 40.0], (9, 1))
    a_out = a_in * np.linspace(0.05, 1.5, 9)[:, None]
    return cm.sweep_table(speeds, DEFAULT_WOT_CURVE.torque_at(speeds), a_in, a_out, orders=(2, 4, 6))


def _check_axes(fig):
    """Every used axis (and colour bar) title carries a [unit]."""
    assert isinstance(fig, go.Figure)
    layout = fig.to_plotly_json()["layout"]
    used = set()
    for tr in fig.data:
        used.add("xaxis" + (tr.xaxis or "x")[1:] if getattr(tr, "xaxis", None) is not None else "xaxis")
        used.add("yaxis" + (tr.yaxis or "y")[1:] if getattr(tr, "yaxis", None) is not None else "yaxis")
    titled = 0
    for name in used:
        ax = layout.get(name, {})
        text = (ax.get("title") or {}).get("text")
        if text is None:
            # only a shared subplot axis may go untitled (its twin carries the title)
            assert ax.get("matches") or ax.get("showticklabels") is False, f"{name} has no title"
            continue
        assert UNIT.search(text), f"{name} title {text!r} lacks a [unit]"
        titled += 1
    assert titled >= 2
    for tr in fig.data:
        cb = getattr(tr, "colorbar", None)
        if cb is not None and cb.title is not None and cb.title.text:
            assert UNIT.search(cb.title.text)
    for key, val in layout.items():
        if key.startswith("coloraxis"):
            assert UNIT.search(val["colorbar"]["title"]["text"])
    assert fig.layout.template.layout.colorway is not None


def test_template_is_registered_and_colour_blind_safe():
    assert theme.TEMPLATE_NAME in pio.templates
    tmpl = pio.templates[theme.TEMPLATE_NAME]
    assert tuple(tmpl.layout.colorway) == theme.COLOURWAY
    assert theme.COLOURWAY[0] == "#0072B2"  # Okabe-Ito blue leads
    assert P.register_template() == "dampersim"


def test_colourmap_figure_side_by_side_with_order_lines():
    f = np.linspace(0, 400, 401)
    spectra = [(w, f, np.exp(-((f - 2 * w / (2 * np.pi)) ** 2))) for w in rpm_to_rad_s(np.linspace(900, 2800, 12))]
    fig = P.colourmap_figure(cm.colourmaps(spectra, spectra), orders=(1, 2, 4), f_max_hz=300)
    _check_axes(fig)
    heat = [t for t in fig.data if isinstance(t, go.Heatmap)]
    assert len(heat) == 2 and heat[0].y[-1] <= 300
    assert sum(1 for t in fig.data if t.name and t.name.startswith("order")) >= 4
    # display unit conversion: rad/s leaves the speeds as they are
    fig2 = P.colourmap_figure(cm.colourmap(spectra), speed_unit="rad/s", db=True)
    assert np.isclose(fig2.data[0].x[0], rpm_to_rad_s(900))
    assert "[rad/s]" in fig2.layout.xaxis.title.text
    with pytest.raises(InputError, match="speed_unit"):
        P.colourmap_figure(cm.colourmap(spectra), speed_unit="Hz")


def test_order_cut_figure_has_input_on_secondary_axis():
    cuts = cm.order_cuts(_sweep())
    fig = P.order_cut_figure(cuts, reference=cuts)
    _check_axes(fig)
    titles = [fig.layout[a].title.text for a in ("yaxis", "yaxis2", "yaxis3")]
    assert titles == ["Output amplitude [N m]", "Input amplitude [N m]", "Magnification ratio [-]"]
    x = [t for t in fig.data if t.name == "order 2 output"][0].x
    assert np.allclose(x, np.linspace(1200, 2800, 9))  # rpm by default


def test_magnification_map_figure_with_overlay_and_contour():
    rows = _sweep()
    tab = pd.concat([rows.assign(mean_torque_nm=tq) for tq in (100.0, 300.0, 500.0)])
    mmap = maps.magnification_map(tab)
    fig = P.magnification_map_figure(mmap, overlays=maps.torque_curve_overlay(DEFAULT_WOT_CURVE, 2), show_points=True)
    _check_axes(fig)
    assert any(isinstance(t, go.Contour) and t.contours.start == 1.0 for t in fig.data)
    assert any(t.name == "torque curve, order 2" for t in fig.data)
    assert fig.layout.xaxis.title.text == "Excitation frequency [Hz]"


def test_hysteresis_and_stiffness_figures_convert_angles():
    loops = _loops()
    knees = [hy.find_knee(lp.torque_nm, lp.windup_rad) for lp in loops]
    fig = P.hysteresis_figure(loops, knees=knees)
    _check_axes(fig)
    assert np.allclose(fig.data[0].x, np.rad2deg(loops[0].windup_rad))
    fig_rad = P.hysteresis_figure(loops[:1], windup=("total", "outer", "inner"), angle_unit="rad")
    assert np.allclose(fig_rad.data[1].x, loops[0].windup_outer_rad)
    assert fig_rad.layout.xaxis.title.text == "Windup [rad]"
    fig_s = P.stiffness_figure(loops)
    _check_axes(fig_s)
    assert fig_s.layout.yaxis.title.text == "Dynamic stiffness [N m/deg]"
    assert P.stiffness_figure(loops, x="windup", angle_unit="rad", branch="all").layout.yaxis.title.text == "Dynamic stiffness [N m/rad]"
    tup = P.hysteresis_figure([("measured", loops[0].torque_nm, loops[0].windup_rad)])
    assert tup.data[0].name == "measured"
    with pytest.raises(InputError, match="angle_unit"):
        P.hysteresis_figure(loops, angle_unit="grad")


def test_result_figures(result, tmp_path):
    seg = P.segment_compression_figure(result, spring="pair_inner")
    _check_axes(seg)
    assert seg.data[0].z.shape[0] == result.segment_compression("pair_inner").shape[1]
    with pytest.raises(InputError, match="spring"):
        P.segment_compression_figure(result, spring="middle")
    for fig in (
        P.time_trace_figure(result, seconds=0.5),
        P.result_spectrum_figure(result, seconds=0.5),
        P.energy_figure(result),
        P.spectrum_figure(np.linspace(0, 100, 11), {"input": np.ones(11)}, speed_rad_s=rpm_to_rad_s(600), log_y=True),
    ):
        _check_axes(fig)
    path = P.write_html(P.time_trace_figure(result), tmp_path / "trace.html")
    assert (tmp_path / "trace.html").stat().st_size > 1000 and path.endswith("trace.html")
    with pytest.raises(InputError, match="does not exist"):
        P.write_html(go.Figure(), tmp_path / "missing" / "x.html")


def test_campbell_and_mode_shape_figures():
    res = modal.modal_analysis(dampersim.default_parameters())
    data = modal.campbell(res)
    fig = P.campbell_figure(data, max_frequency_hz=250)
    _check_axes(fig)
    cross = [t for t in fig.data if t.name == "crossings"][0]
    assert np.all(np.asarray(cross.y) <= 250)
    fig_rad = P.campbell_figure(data, speed_unit="rad/s")
    assert fig_rad.layout.xaxis.title.text == "Speed [rad/s]"
    _check_axes(P.mode_shape_figure(res, max_frequency_hz=100))


def test_figures_of_one_test_point(result):
    """The dashboard's figures of one record take the result object and its parameter set."""
    from dampersim.analysis.order_table import order_table

    system = result.parameters
    rows = order_table(result, [2.0], 0.5)
    for fig in (
        P.recent_traces_figure(result, 0.8, title="traces"),
        P.windowed_spectrum_figure(result, 0.5),
        P.mr_figure(rows),
        P.windup_figure(result, system),
        P.energy_balance_figure(result),
    ):
        _check_axes(fig)
    assert "2" in P.mr_figure(rows).data[0].x  # orders as category labels
    anim = P.damper_animation_figure(result, system, span=0.02, gain=3.0)
    assert len(anim.frames) >= 2 and anim.layout.updatemenus[0].buttons[0].label.endswith("Play")
    assert "×3" in anim.layout.title.text
    heat = P.segment_compression_figure(result, spring="outer", dtype=np.float32)
    assert np.asarray(heat.data[0].z).dtype == np.float32


def test_loop_energy_and_curve_prediction_figures():
    _check_axes(P.loop_energy_figure([1000.0, 2000.0], [3.5, 4.25]))
    rows = _sweep()
    tab = pd.concat([rows.assign(mean_torque_nm=tq) for tq in (100.0, 300.0, 500.0)])
    mmap = maps.magnification_map(tab)
    pred = maps.predict_along_curve(mmap, DEFAULT_WOT_CURVE, 2.0)
    fig = P.curve_prediction_figure(pred, 2.0, DEFAULT_WOT_CURVE.name)
    _check_axes(fig)
    assert fig.data[0].name == "order 2" and "order 2" in fig.layout.title.text
    f = np.linspace(0, 400, 401)
    spectra = [(w, f, np.exp(-((f - 2 * w / (2 * np.pi)) ** 2))) for w in rpm_to_rad_s(np.linspace(900, 2800, 6))]
    banded = P.banded_colourmap_figure(cm.colourmaps(spectra, spectra), f_max_hz=300, db=True)
    _check_axes(banded)
    heat = [t for t in banded.data if isinstance(t, go.Heatmap)]
    assert all(np.asarray(t.z).dtype == np.float32 for t in heat)
    assert banded.layout.coloraxis.cmax - banded.layout.coloraxis.cmin == pytest.approx(60.0)


def test_plotting_reads_results_by_attribute_only():
    """Figure builders import analysis and below, never results, views or the packages that
    run work (sweeps, studies, discrepancy, simulation)."""
    import ast
    from pathlib import Path

    banned = ("dampersim.results", "dampersim.views", "dampersim.sweeps", "dampersim.studies", "dampersim.discrepancy",
              "dampersim.simulation")
    for path in sorted((Path(dampersim.__file__).parent / "plotting").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            for name in names:
                assert not name.startswith(banned), f"{path.name} imports {name}"
