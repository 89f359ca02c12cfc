"""FFT colourmaps, order cuts, magnification maps and the WOT torque curve."""

import math

import numpy as np
import pandas as pd
import pytest

from dampersim.analysis import colourmap as cm
from dampersim.analysis import maps
from dampersim.errors import InputError
from dampersim.excitation.torque_curve import DEFAULT_WOT_CURVE, TorqueCurve, torque_at
from dampersim.units import rpm_to_rad_s

RPM = rpm_to_rad_s(1.0)


# --- colourmap ----------------------------------------------------------------------------
def _peaks(freq, speed, orders_amps):
    a = np.zeros_like(freq)
    for k, amp in orders_amps:
        a += amp * np.exp(-0.5 * ((freq - k * speed / (2 * np.pi)) / 1.0) ** 2)
    return a


def test_colourmap_same_grid_is_stacked_without_interpolation():
    f = np.linspace(0.0, 400.0, 801)
    speeds = np.array([2000, 1000, 1500]) * RPM  # unsorted on purpose
    spectra = [(w, f, _peaks(f, w, [(2, 300.0), (4, 100.0)])) for w in speeds]
    m = cm.colourmap(spectra, label="input")
    assert np.array_equal(m.frequency_hz, f)
    assert np.allclose(m.speed_rad_s, np.sort(speeds), rtol=0, atol=0)
    for row, w in enumerate(np.sort(speeds)):
        # identical bins: the rows must be the very spectra, bit for bit
        assert np.array_equal(m.amplitude_nm[row], _peaks(f, w, [(2, 300.0), (4, 100.0)]))
    # the 2nd order ridge sits at 2 * rpm / 60 Hz
    row = 0
    assert f[np.argmax(m.amplitude_nm[row])] == pytest.approx(2 * 1000 / 60, abs=0.5)  # half the 0.5 Hz bin
    assert m.label == "input"
    assert np.allclose(m.speed_rpm, [1000, 1500, 2000])


def test_colourmap_interpolates_differing_grids_onto_common_grid():
    # a field linear in frequency is reproduced exactly by linear interpolation
    def line(f):
        return 2.0 + 0.01 * f

    f_a = np.arange(0.0, 500.0 + 1e-9, 0.8)
    f_b = np.arange(0.0, 400.0 + 1e-9, 0.5)
    spectra = [(100.0, f_a, line(f_a)), (200.0, f_b, line(f_b))]
    m = cm.colourmap(spectra)
    # default grid: finest spacing (0.5 Hz) up to the lowest top frequency (400 Hz)
    assert m.frequency_hz[1] - m.frequency_hz[0] == pytest.approx(0.5)
    assert m.frequency_hz[-1] == pytest.approx(400.0)
    # exact up to float rounding of the interpolation weights
    assert np.allclose(m.amplitude_nm, line(m.frequency_hz)[None, :], rtol=0, atol=1e-12)
    # a grid beyond a spectrum's range is NaN there, never extrapolated
    m2 = cm.colourmap(spectra, f_max_hz=450.0, df_hz=1.0)
    assert np.all(np.isnan(m2.amplitude_nm[1, m2.frequency_hz > 400.0]))
    assert np.all(np.isfinite(m2.amplitude_nm[0]))


def test_colourmap_averages_duplicate_speeds_and_accepts_dataframes():
    f = np.linspace(0, 100, 11)
    spectra = [(100.0, f, np.full(11, 1.0)), (100.0, f, np.full(11, 3.0)), (150.0, f, np.full(11, 5.0))]
    m = cm.colourmap(spectra)
    assert m.amplitude_nm.shape == (2, 11)
    assert np.allclose(m.amplitude_nm[0], 2.0)
    long = pd.DataFrame({"speed_rad_s": np.repeat([100.0, 150.0], 11), "frequency_hz": np.tile(f, 2), "amplitude_nm": np.repeat([2.0, 5.0], 11)})
    m2 = cm.colourmap(long)
    assert np.allclose(m2.amplitude_nm, m.amplitude_nm)


def test_colourmaps_share_one_grid_and_bad_input_is_explained():
    f1, f2 = np.linspace(0, 300, 601), np.linspace(0, 250, 251)
    maps_ = cm.colourmaps([(100.0, f1, np.ones_like(f1))], [(100.0, f2, np.ones_like(f2))])
    assert np.array_equal(maps_["input"].frequency_hz, maps_["output"].frequency_hz)
    assert maps_["output"].label == "output"
    with pytest.raises(InputError, match="spectra"):
        cm.colourmap([])
    with pytest.raises(InputError, match="positive finite speed"):
        cm.colourmap([(-1.0, f1, f1)])
    with pytest.raises(InputError, match="strictly increasing"):
        cm.colourmap([(1.0, f1[::-1], f1)])


def test_order_lines_follow_k_times_speed():
    w = np.array([1000.0, 2000.0]) * RPM
    lines = cm.order_lines(w, orders=(1, 2, 4))
    for k in (1, 2, 4):
        sub = lines[lines["order"] == k]
        assert np.allclose(sub["frequency_hz"], k * np.array([1000.0, 2000.0]) / 60.0, rtol=1e-12)
    cut = cm.order_lines(w, orders=(1, 2, 4), f_max_hz=60.0)
    assert cut["frequency_hz"].max() <= 60.0 and len(cut) == 3  # 16.7, 33.3 (1st); 33.3 (2nd)


# --- sweep tables and order cuts -----------------------------------------------------------
def _sweep():
    speeds = np.array([1000.0, 1500.0, 2000.0, 1500.0]) * RPM  # 1500 rpm repeated
    a_in = np.array([[300.0, 100.0]] * 4)
    a_out = np.array([[30.0, 5.0], [20.0, 4.0], [10.0, 2.0], [22.0, 6.0]])
    return cm.sweep_table(speeds, [250.0, 300.0, 350.0, 301.0], a_in, a_out, orders=(2, 4))


def test_sweep_table_columns_and_magnification():
    tab = _sweep()
    assert list(tab.columns) == list(cm.SWEEP_COLUMNS)
    assert len(tab) == 8
    row = tab[(tab["order"] == 2) & np.isclose(tab["speed_rpm"], 1000)].iloc[0]
    assert row["frequency_hz"] == pytest.approx(2 * 1000 / 60)
    assert row["magnification"] == pytest.approx(0.1)


def test_order_cuts_average_repeats_and_refuse_mixed_operating_points():
    cuts = cm.order_cuts(_sweep(), orders=[2])
    assert list(cuts["speed_rpm"].round(6)) == [1000.0, 1500.0, 2000.0]
    mid = cuts.iloc[1]
    assert mid["n_points"] == 2
    assert mid["output_amplitude_nm"] == pytest.approx(21.0)  # mean of 20 and 22
    assert mid["magnification"] == pytest.approx((20 / 300 + 22 / 300) / 2)
    # two mean torques 50 N m apart at one speed is a mapping set, not a cut
    tab = _sweep()
    tab.loc[tab["mean_torque_nm"] == 301.0, "mean_torque_nm"] = 350.0
    with pytest.raises(InputError, match="mean_torque_nm"):
        cm.order_cuts(tab)
    only = cm.order_cuts(tab, mean_torque_nm=350.0)
    assert set(np.round(only["speed_rpm"])) == {1500.0, 2000.0}
    with pytest.raises(InputError, match="not in the table"):
        cm.order_cuts(_sweep(), orders=[3])
    with pytest.raises(InputError, match="lacks columns"):
        cm.order_cuts(_sweep().drop(columns=["magnification"]))


# --- magnification maps --------------------------------------------------------------------------
def _field(f, t):
    return 0.2 + 0.004 * f + 0.001 * t


def _table(f, t, mr):
    f, t = np.asarray(f, float), np.asarray(t, float)
    return pd.DataFrame({"frequency_hz": f, "mean_torque_nm": t, "magnification": np.asarray(mr, float), "order": 2.0})


def test_average_duplicates_means_repeated_points():
    tab = _table([50, 50, 50, 80], [200, 200, 200, 300], [1.0, 2.0, 3.0, 4.0])
    avg = maps.average_duplicates(tab)
    assert len(avg) == 2
    row = avg[avg["frequency_hz"] == 50].iloc[0]
    assert row["magnification"] == pytest.approx(2.0)
    assert row["n_points"] == 3
    # NaN ratios (orders without input) are dropped, not averaged in
    tab2 = pd.concat([tab, _table([80], [300], [np.nan])])
    assert maps.average_duplicates(tab2)["n_points"].sum() == 4


def test_map_is_exact_on_a_linear_field_and_averages_duplicates():
    rng = np.random.default_rng(7)
    f = np.concatenate([[30, 200, 30, 200], rng.uniform(30, 200, 150)])
    t = np.concatenate([[50, 50, 500, 500], rng.uniform(50, 500, 150)])
    mr = _field(f, t)
    # duplicates of 20 points, offset +-0.3: they only average back to the field
    dup = np.arange(20)
    tab = pd.concat([_table(f, t, mr), _table(f[dup], t[dup], mr[dup] + 0.3), _table(f[dup], t[dup], mr[dup] - 0.3)])
    mmap = maps.magnification_map(tab, torque_range_nm=(50, 500), torque_step_nm=25)
    assert mmap.frequency_hz[0] == 30 and mmap.frequency_hz[-1] == 200  # the thesis's default range
    assert mmap.magnification.shape == (mmap.mean_torque_nm.size, mmap.frequency_hz.size)
    assert len(mmap.points) == 154
    ff, tt = np.meshgrid(mmap.frequency_hz, mmap.mean_torque_nm)
    # the corners make the hull the whole grid; linear interpolation of a linear field is
    # exact up to float rounding (values ~1, 1e-9 leaves room for Qhull's rescaling)
    assert np.all(np.isfinite(mmap.magnification))
    assert np.allclose(mmap.magnification, _field(ff, tt), rtol=0, atol=1e-9)
    # bilinear read-out between nodes is exact too on a linear field
    assert mmap.at(101.3, 333.3) == pytest.approx(_field(101.3, 333.3), abs=1e-9)


def test_map_is_nan_outside_the_hull_and_mask_marks_mr_above_one():
    f = np.array([30, 200, 30, 200, 115])
    t = np.array([100, 100, 300, 300, 200])
    mmap = maps.magnification_map(_table(f, t, f / 100.0), torque_range_nm=(0, 500), torque_step_nm=50)
    outside = (mmap.mean_torque_nm < 100) | (mmap.mean_torque_nm > 300)
    assert np.all(np.isnan(mmap.magnification[outside]))
    inside = mmap.magnification[~outside]
    assert np.all(np.isfinite(inside))
    ff = np.broadcast_to(mmap.frequency_hz, mmap.magnification.shape)
    assert np.array_equal(mmap.above_one, np.isfinite(mmap.magnification) & (ff > 100.0 + 1e-9))
    assert not mmap.above_one[outside].any()


def test_map_orders_filter_and_errors():
    tab = pd.concat([_table([30, 200, 100], [50, 50, 500], [1, 1, 1]), _table([30, 200, 100], [50, 50, 500], [9, 9, 9]).assign(order=4.0)])
    m2 = maps.magnification_map(tab, orders=[2])
    assert np.nanmax(m2.magnification) == pytest.approx(1.0)
    with pytest.raises(InputError, match="not in the table"):
        maps.magnification_map(tab, orders=[6])
    with pytest.raises(InputError, match="one mean torque"):
        maps.magnification_map(_table([30, 100, 200], [100, 100, 100], [1, 1, 1]))
    with pytest.raises(InputError, match="frequency_range_hz"):
        maps.magnification_map(tab, frequency_range_hz=(200, 30))


# --- torque curve ------------------------------------------------------------------------------
def test_default_wot_curve_matches_the_thesis_facts():
    c = DEFAULT_WOT_CURVE
    lo, hi = c.speed_range_rad_s
    assert lo == pytest.approx(1200 * RPM) and hi == pytest.approx(2800 * RPM)  # [thesis] §3.3.2
    w, tq = c.sample(161)
    assert tq.min() == pytest.approx(240.0) and tq.max() == pytest.approx(415.0)
    # crosses the default set's ~300 N m knee between 1360 and 1380 rpm ([thesis] §6.2.1)
    assert torque_at(1360 * RPM) < 300.0 < torque_at(1380 * RPM)
    assert "estimate" in c.name
    assert c.torque_at(1250 * RPM) == pytest.approx(257.5)  # halfway between 240 and 275


def test_torque_curve_rejects_out_of_range_speeds_and_bad_points():
    with pytest.raises(InputError, match="1200-2800 rpm"):
        torque_at(1000 * RPM)
    with pytest.raises(InputError, match="outside"):
        DEFAULT_WOT_CURVE.torque_at(np.array([1500, 3000]) * RPM)
    assert torque_at(3000 * RPM, extrapolate=True) == pytest.approx(385.0)
    with pytest.raises(InputError, match="strictly increasing"):
        TorqueCurve.from_rpm([1000, 900], [100, 200])
    with pytest.raises(InputError, match="two or more"):
        TorqueCurve.from_rpm([1000], [100])
    with pytest.raises(InputError, match="finite"):
        torque_at(float("nan"))


def test_torque_curve_overlay_and_prediction():
    ov = maps.torque_curve_overlay(DEFAULT_WOT_CURVE, order=2, n=17)
    assert np.allclose(ov["frequency_hz"], 2 * ov["speed_rpm"] / 60.0, rtol=1e-12)
    assert ov["frequency_hz"].iloc[0] == pytest.approx(40.0) and ov["frequency_hz"].iloc[-1] == pytest.approx(2 * 2800 / 60)
    assert np.allclose(ov["mean_torque_nm"], DEFAULT_WOT_CURVE.torque_at(ov["speed_rad_s"].to_numpy()))
    # map only above 300 N m: the low-speed end of the curve (240-300 N m) is off the map
    mmap = maps.magnification_map(_table([30, 200, 30, 200], [300, 300, 450, 450], [0.5] * 4), frequency_step_hz=5, torque_step_nm=10)
    pred = maps.predict_along_curve(mmap, DEFAULT_WOT_CURVE, order=2, n=17)
    on_map = pred["mean_torque_nm"] >= 300
    assert 0 < on_map.sum() < len(pred)
    assert np.allclose(pred.loc[on_map, "magnification"], 0.5)
    assert pred.loc[~on_map, "magnification"].isna().all()
    assert math.isnan(mmap.at(10.0, 300.0))
