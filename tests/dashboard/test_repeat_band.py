"""The repeatability spread on the pages, called as plain functions (no browser): the
Colourmap's order cuts with ``repeat=K`` (K runs of every speed, the min-max as a band, the
cost K sweeps, cached like any sweep) and the Explorer's spread check label."""

from __future__ import annotations

import base64
import json
import sys

import numpy as np
import pandas as pd
import pytest

from dampersim.analysis import repeatability as R

SHORT = 1.2
BASE = {"set": None, "overrides": {}}


@pytest.fixture(scope="module")
def app_module():
    import app

    return app


@pytest.fixture
def pages(app_module):
    from types import SimpleNamespace

    return SimpleNamespace(**{n: sys.modules[f"pages.{n}"] for n in ("explorer", "colourmap")})


def as_json(component) -> str:
    return json.dumps(component, default=lambda c: c.to_plotly_json() if hasattr(c, "to_plotly_json") else str(c))


def colourmap_values(speeds="1400,1600", repeat=None):
    return [speeds, 200, [2, 4, None, None, None, None], [300, 100, None, None, None, None], [0, 0, None, None, None, None],
            SHORT, 0.5, 400, [], ["2", "4"], repeat]


def values(arr) -> np.ndarray:
    """A figure dict's array: a list, or plotly's typed-array form {"dtype", "bdata"}."""
    if isinstance(arr, dict):
        return np.frombuffer(base64.b64decode(arr["bdata"]), dtype=arr["dtype"]).astype(float)
    return np.asarray(arr, dtype=float)


def band_traces(fig):
    return [t for t in fig["data"] if t.get("fill") == "toself"]


# ------------------------------------------------------------------------ library parts
def test_repeated_points_follow_the_repeatability_rule():
    from dampersim.sweeps.grid import make_grid, parse_range
    from dampersim.views.sweeps import repeated_points

    base = make_grid(parse_range("1400,1600"), [200.0], ((2.0, 300.0, 0.0), (4.0, 100.0, 1.0)))
    pts = repeated_points(base, 3)
    assert len(pts) == 6 and pts[:2] == list(base) and repeated_points(base, None) == list(base)
    for p, point in enumerate(pts):
        i, j = divmod(p, 2)  # run i of speed j, run after run
        assert point.excitation() == R.scaled_excitation(base[j].excitation(), 1.0 + i * R.STEP)
    with pytest.raises(Exception, match="2 to 32"):
        repeated_points(base, 33)


def test_sweep_spread_of_a_synthetic_table():
    # 2 speeds x 3 runs x 2 orders; order 4 at the second speed is above Nyquist (NaN)
    rows = []
    for p in range(6):
        run, j = divmod(p, 2)
        for k, out in ((2.0, [10.0, 20.0][j] * (1 + 0.01 * run)), (4.0, [1.0, np.nan][j] + 0.1 * run)):
            rows.append({"point": p, "speed_rad_s": [150.0, 170.0][j], "order": k, "output_amplitude_nm": out,
                         "magnification": out / 100.0})
    band = R.sweep_spread(pd.DataFrame(rows), 2)
    assert list(band["point"]) == [0, 0, 1, 1] and list(band["order"]) == [2.0, 4.0, 2.0, 4.0]
    first = band.iloc[0]
    assert (first["output_min_nm"], first["output_max_nm"]) == (10.0, pytest.approx(10.2))
    assert first["spread_pct"] == pytest.approx(100 * 0.2 / 10.1)  # max - min over the median of the 3 runs
    assert band.iloc[1]["spread_pct"] == pytest.approx(100 * 0.2 / 1.1)
    assert np.isnan(band.iloc[3]["spread_pct"]) and band.iloc[2]["spread_pct"] == pytest.approx(2.0 / 1.01)
    with pytest.raises(Exception, match="whole runs"):
        R.sweep_spread(pd.DataFrame(rows), 4)


def test_order_cut_figure_draws_a_band_only_when_given():
    from dampersim.plotting import order_cut_figure

    cuts = pd.DataFrame({"speed_rad_s": [150.0, 170.0], "order": [2.0, 2.0], "input_amplitude_nm": [300.0, 300.0],
                         "output_amplitude_nm": [10.0, 12.0], "magnification": [0.033, 0.04]})
    band = pd.DataFrame({"speed_rad_s": [150.0, 170.0], "order": [2.0, 2.0], "output_min_nm": [9.0, 11.0],
                         "output_max_nm": [11.0, 13.0], "mr_min": [0.03, 0.037], "mr_max": [0.037, 0.043]})
    plain = order_cut_figure(cuts).to_dict()
    banded = order_cut_figure(cuts, band=band, runs=4).to_dict()
    assert band_traces(plain) == []
    out, mr = band_traces(banded)
    assert list(out["y"]) == [11.0, 13.0, 11.0, 9.0] and list(mr["y"]) == [0.037, 0.043, 0.037, 0.03]
    assert "min-max of 4 runs" in json.dumps(banded["layout"]["annotations"])


# ------------------------------------------------------------------------ Colourmap page
def test_colourmap_repeat_is_validated_and_its_cost_is_k_sweeps(pages, cache_dir):
    cm = pages.colourmap
    plain = cm.request(False, True, colourmap_values(), BASE, False)
    assert "Not computed yet: 2 test points" in as_json(plain["status"]) and "repeat" not in plain["search"]
    out = cm.request(False, True, colourmap_values(repeat=3), BASE, False)
    assert "Not computed yet: 6 test points" in as_json(out["status"]) and "repeat=3" in out["search"]
    for bad in (1, 33, 2.5, "x"):
        out = cm.request(False, True, colourmap_values(repeat=bad), BASE, False)
        text = as_json(out["notices"])
        assert f"repeat={bad!r}" in text and "2 to 32" in text and "Using off" in text
        assert "Not computed yet: 2 test points" in as_json(out["status"]) and "repeat" not in out["search"]
    from dampersim.parameters import default_parameters
    from dampersim.views.state import parse_query, state_cost

    state, _ = parse_query("colourmap", {"speeds": "900:2800:50"})
    one = state_cost("colourmap", default_parameters(), state)
    assert state_cost("colourmap", default_parameters(), {**state, "repeat": 8}).work == pytest.approx(8 * one.work)


def test_colourmap_job_draws_the_band_and_run_0_is_the_plain_sweep(pages, cache_dir):
    cm = pages.colourmap
    out = cm.request(True, False, colourmap_values(repeat=2), BASE, False)
    assert out["job"]["state"]["repeat"] == 2
    progress = []
    done = cm.job(out["job"], lambda d, t, text: progress.append((d, t)))
    assert "key" in done and progress[-1] == (4, 4)  # 2 speeds x 2 runs
    shown = cm.show({**done, "nonce": "x"})
    cuts_fig, table, summary = shown[1], as_json(shown[2]), as_json(shown[3])
    bands = band_traces(cuts_fig)
    # orders 2 and 4, each an output band (top) and an MR band (bottom)
    assert [t["name"] for t in bands] == ["order 2 output spread", "order 2 MR spread", "order 4 output spread",
                                          "order 4 MR spread"]
    assert "Largest spread of 2 runs [%]" in table and "2 speeds x 2 runs" in summary
    # the band holds the shown (run 0) line: min <= run 0 <= max at every speed
    line = next(t for t in cuts_fig["data"] if t.get("name") == "order 2 output")
    top = np.asarray(bands[0]["y"], dtype=float)
    hi, lo = top[:2], top[2:][::-1]
    assert np.all(lo <= values(line["y"])) and np.all(values(line["y"]) <= hi)
    # the same sweep without repeat is run 0: every point is in the cache already, so the
    # request answers from the cache at once (no job)
    again = cm.request(False, True, colourmap_values(), BASE, False)
    assert "job" not in again
    from dampersim.views.store import load_view

    view = load_view(again["hit"]["key"])
    assert view["summary"]["computed"] == 0 and view["summary"]["from_cache"] == 2
    plain_line = next(t for t in view["figures"]["cuts"]["data"] if t.get("name") == "order 2 output")
    assert list(values(plain_line["y"])) == list(values(line["y"])) and band_traces(view["figures"]["cuts"]) == []


# ------------------------------------------------------------------------ Explorer page
def explorer_args(duration=1.0):
    # the thesis's 18/8 segments: the spread column is what is tested, and the spread check
    # runs the point several times
    ids = [{"type": "explorer-param", "name": "solver.outer_segments"}, {"type": "explorer-param", "name": "solver.inner_segments"}]
    return (1500.0, 200.0, [2, None, None, None, None, None], [300, None, None, None, None, None],
            [0, None, None, None, None, None], duration, [18, 8], [], "pi", ids, BASE)


def test_explorer_spread_check_labels_the_spread_column(pages, cache_dir, monkeypatch):
    import dampersim.views.explorer as ve

    calls = []

    def fake_check(system, ex, rep, seconds, duration=None):
        calls.append(rep.runs)
        n = len(rep.orders)
        return R.SpreadCheck(time_step=system.solver.time_step / 2, output_nm=rep.output_nm,
                             spread_pct=(0.5,) * n, origin=tuple(R.PHYSICAL if k == 2.0 else R.NUMERICAL for k in rep.orders))

    monkeypatch.setattr(ve, "spread_check", fake_check)
    out = pages.explorer.explorer_outputs(*explorer_args(), repeat=2, spread_check=["on"])
    assert out["error"] is None and calls == [2] and "spread_check=true" in out["search"]
    table = as_json(out["table"])
    assert "Spread of 2 runs [%]" in table and "(physical)" in table
    assert "(physical)" in json.dumps(out["figures"]["mr"]["data"][0]["customdata"])
    # without the box: no second set of runs, no label
    plain = pages.explorer.explorer_outputs(*explorer_args(), repeat=2, spread_check=[])
    assert calls == [2] and "(physical)" not in as_json(plain["table"]) and "spread_check" not in plain["search"]
    # the box without runs: a notice, nothing extra runs
    alone = pages.explorer.explorer_outputs(*explorer_args(), spread_check=["on"])
    assert calls == [2] and "needs repeat" in json.dumps(alone["notices"])


def test_explorer_spread_check_runs_at_half_the_step(pages, cache_dir):
    from dampersim.views.explorer import explorer_view
    from dampersim.views.params import resolve_system
    from dampersim.views.state import parse_query

    # frictionless, no hardstops: linear, so its spread is the 1e-9 input change at both steps
    state, notices = parse_query("explorer", {"duration": "1", "repeat": "2", "spread_check": "true",
                                              "friction.enabled": "false", "hardstops.enabled": "false"})
    assert notices == []
    view = explorer_view(resolve_system(state["params"]), state)
    row = next(r for r in view["orders"] if r["order"] == 2.0)
    # 1e-7 % at both steps (5 % for the FFT's rounding, as in test_repeatability): far below
    # the 0.01 % floor, so no label
    assert row["spread_pct"] == pytest.approx(1e-7, rel=0.05) and row["spread_half_pct"] == pytest.approx(1e-7, rel=0.05)
    assert row["spread_origin"] is None and view["summary"]["spread_check"] is True
