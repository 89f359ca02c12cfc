"""dampersim.views: page-state parsing and the data behind every dashboard view (no Dash)."""

from __future__ import annotations

import base64
import math
import time
from urllib.parse import parse_qsl

import pytest

import dampersim
from dampersim import views
from dampersim.errors import DampersimError, InputError, ParameterError

SHORT = "1.2"  # simulated seconds in these tests (analysis window 0.6 s)


def texts(notices):
    return " | ".join(n["text"] for n in notices)


def query_of(search):
    return dict(parse_qsl(search.lstrip("?"), keep_blank_values=True))


# ----------------------------------------------------------------------------- page state
def test_good_explorer_link_parses_without_notices():
    state, notices = views.parse_query("explorer", {"speed": "2100", "torque": "260", "orders": "2:300,4:100@90",
                                                    "duration": "1.5", "inertias.primary": "0.22"})
    assert notices == []
    assert state["speed"] == 2100.0 and state["torque"] == 260.0 and state["duration"] == 1.5
    assert state["orders"] == "2:300,4:100@90"
    assert state["params"] == {"set": None, "overrides": {"inertias.primary": 0.22}}


def test_defaults_when_the_query_is_empty():
    state, notices = views.parse_query("explorer", {})
    assert notices == []
    assert state["speed"] == 1500.0 and state["torque"] == 200.0 and state["orders"] == "2:300"
    assert state["duration"] == dampersim.default_parameters().solver.duration


@pytest.mark.parametrize(
    "key, raw, expect_in_message, fallback",
    [
        ("speed", "abc", "not a number", 1500.0),
        ("speed", "99999", "out of range", 1500.0),
        ("speed", "nan", "not a finite number", 1500.0),
        ("speed", "", "is empty", 1500.0),
        ("torque", "-5000", "out of range", 200.0),
        ("orders", "2:x", "malformed", "2:300"),
        ("orders", "2:5000", "above 1000 N m", "2:300"),
        ("orders", "1:1,2:1,3:1,4:1,5:1,6:1,7:1", "at most 6", "2:300"),
        ("orders", "2:100@720", "outside -360 to 360 deg", "2:300"),
        ("duration", "0.1", "out of range", 2.6),
    ],
)
def test_bad_values_give_a_specific_notice_and_fall_back(key, raw, expect_in_message, fallback):
    state, notices = views.parse_query("explorer", {key: raw})
    assert len(notices) == 1
    text = notices[0]["text"]
    assert f"{key}={raw!r}" in text and expect_in_message in text
    assert "accepted is" in text and "Using" in text
    assert state[key] == fallback


def test_unknown_keys_are_ignored():
    state, notices = views.parse_query("explorer", {"foo": "1", "x.y.z": "2", "utm_source": "mail"})
    assert notices == []
    assert state == views.default_state("explorer")


def test_repeated_key_uses_the_first_value_with_a_notice():
    state, notices = views.parse_query("explorer", {"speed": ["1800", "1900"]})
    assert state["speed"] == 1800.0
    assert "given 2 times" in texts(notices)


def test_parameter_overrides_are_validated_one_by_one():
    state, notices = views.parse_query("explorer", {
        "inertias.primary": "-1",                  # library: must be > 0
        "solver.outer_segments": "300",            # dashboard range 4-200
        "friction.outer.alpha": "0.2",             # fine
        "outer.spring.stiffness": "lots",          # not a number
        "hardstops.enabled": "maybe",              # not a bool
    })
    assert state["params"]["overrides"] == {"friction.outer.alpha": 0.2}
    msg = texts(notices)
    for name in ("inertias.primary", "solver.outer_segments", "outer.spring.stiffness", "hardstops.enabled"):
        assert f"Parameter {name}" in msg
    assert "Using 0.2 " in msg or "Using 0.2." in msg  # the primary inertia falls back to the set's value


def test_override_that_breaks_the_time_step_bound_names_the_cause():
    # 9e-5 s is inside the page's range of time steps (1e-7 to 1e-4 s) but above this set's bound
    _, notices = views.parse_query("explorer", {"solver.time_step": "9e-5"})
    assert "solver.time_step" in texts(notices) and "stability bound" in texts(notices)
    _, notices = views.parse_query("explorer", {"solver.time_step": "0.001"})  # outside the page's range
    assert "from 1e-07 to 0.0001" in texts(notices)


def test_unknown_parameter_set_id_falls_back_to_default(cache_dir):
    state, notices = views.parse_query("parameters", {"set": "0123456789abcdef"})
    assert state["params"]["set"] is None
    assert "not stored on this server" in texts(notices)
    state, notices = views.parse_query("parameters", {"set": "../../etc"})
    assert "not a valid set id" in texts(notices)


@pytest.mark.parametrize("page", list(views.PAGES))
def test_query_round_trip_for_every_page(page):
    state = views.default_state(page)
    again, notices = views.parse_query(page, query_of(views.to_query(page, state)))
    assert notices == [] and again == state


def test_round_trip_keeps_non_default_values_exactly():
    q = {"speed": "2105.5", "torque": "-37.25", "orders": "2:250.5,4:80@-45.5,1.5:10", "duration": "1.75",
         "inertias.primary": "0.2234567891", "outer.hardstop_positive": "0.7", "motor.mode": "held"}
    state, notices = views.parse_query("explorer", q)
    assert notices == []
    search = views.to_query("explorer", state)
    again, _ = views.parse_query("explorer", query_of(search))
    assert again == state
    assert again["params"]["overrides"]["outer.hardstop_positive"] == 0.7
    assert "motor.mode=held" in search


def test_window_must_fit_after_the_start_up():
    state, notices = views.parse_query("colourmap", {"duration": "1.2", "window": "1.25"})
    assert state["window"] == 0.6
    assert "does not fit" in texts(notices)


def test_map_frequency_range_must_not_be_empty():
    state, notices = views.parse_query("maps", {"fmin": "150", "fmax": "100"})
    assert (state["fmin"], state["fmax"]) == (30.0, 200.0)
    assert "fmin < fmax" in texts(notices)


def test_sweep_ranges_are_validated():
    state, notices = views.parse_query("colourmap", {"speeds": "900:2800:1"})
    assert state["speeds"] == "900:2800:50" and "at most 400" in texts(notices)
    state, notices = views.parse_query("colourmap", {"speeds": "100:900:100"})
    assert "outside 300-6000 rpm" in texts(notices)
    state, notices = views.parse_query("hysteresis", {"speeds": "1000,1200,1400,1600,1800,2000,2200"})
    assert "at most 6" in texts(notices)
    state, notices = views.parse_query("colourmap", {"cuts": "2,9"})
    assert "order 9" in texts(notices) and state["cuts"] == "2,4"


def test_orders_keep_their_phase_in_degrees():
    assert views.parse_orders_deg("2:300,4:100@90") == [[2.0, 300.0, 0.0], [4.0, 100.0, 90.0]]
    assert views.format_orders([[2.0, 300.0, 0.0], [4.0, 100.0, 90.0]]) == "2:300,4:100@90"
    k, a, ph = views.orders_si(views.parse_orders_deg("4:100@90"))[0]
    assert ph == pytest.approx(math.pi / 2)


def test_page_href_carries_the_parameter_state():
    params = {"set": None, "overrides": {"inertias.primary": 0.22}}
    assert views.page_href("maps", params) == "/maps?inertias.primary=0.22"
    assert views.page_href("maps", None) == "/maps"


# ----------------------------------------------------------------------------- views
def _explorer_state(**q):
    state, notices = views.parse_query("explorer", {"duration": SHORT, **q})
    assert notices == []
    return state


def test_explorer_view_and_its_cache(cache_dir):
    state = _explorer_state(speed="1800", torque="150", orders="2:300,4:100@90")
    system = views.resolve_system(state["params"])
    view = views.explorer_view(system, state)
    assert view["from_cache"] is False
    assert set(view["figures"]) == {"traces", "spectrum", "mr", "windup", "energy"}
    main = [r for r in view["orders"] if r["order"] == 2.0][0]
    assert main["excited"] and 0 < main["mr"] < 1
    assert [r for r in view["orders"] if r["order"] == 3.0][0]["mr"] is None  # not excited: no ratio
    # every axis has a unit
    for name, fig in view["figures"].items():
        for ax, spec in fig["layout"].items():
            if ax.startswith(("xaxis", "yaxis")) and spec.get("title", {}).get("text"):
                assert "[" in spec["title"]["text"], (name, ax, spec["title"]["text"])
    # the same state again: from the cache, fast, identical
    t0 = time.perf_counter()
    again = views.explorer_view(system, state)
    assert time.perf_counter() - t0 < 0.3
    assert again["from_cache"] is True and again["key"] == view["key"]
    assert again["orders"] == view["orders"]
    # another parameter value is another view
    state2 = _explorer_state(speed="1800", torque="150", orders="2:300,4:100@90", **{"inertias.primary": "0.25"})
    assert views.view_key("explorer", views.resolve_system(state2["params"]), state2, module=views.explorer.__name__) != view["key"]


def test_explorer_view_reports_a_failed_simulation_clearly(cache_dir):
    state = _explorer_state()
    system = dampersim.parameters.with_updates(dampersim.default_parameters(), {"solver.outer_segments": 4})
    system = dampersim.parameters.with_updates(system, {"solver.time_step": 1e-3}, check=False)
    with pytest.raises(DampersimError) as exc:
        views.explorer_view(system, state)
    assert "solver.time_step" in str(exc.value)


def test_segments_view_has_heatmap_and_animation(cache_dir):
    state, notices = views.parse_query("segments", {"duration": SHORT, "span": "0.02", "spring": "pair_outer"})
    assert notices == []
    view = views.segments_view(views.resolve_system(state["params"]), state)
    assert view["summary"]["spring"] == "pair_outer"
    assert len(view["segments"]) == dampersim.default_parameters().solver.inner_segments
    anim = view["figures"]["animation"]
    assert len(anim["frames"]) >= 10
    assert anim["layout"]["updatemenus"][0]["buttons"][0]["label"].endswith("Play")
    assert view["figures"]["heatmap"]["data"][0]["type"] == "heatmap"
    assert views.segments_view(views.resolve_system(state["params"]), state)["from_cache"]


def test_hysteresis_view_with_progress(cache_dir):
    state, notices = views.parse_query("hysteresis", {"speeds": "1500", "rate": "500", "hold": "0.2", "protocol": "full-100"})
    assert notices == []
    system = views.resolve_system(state["params"])
    assert views.hysteresis_view(system, state, cache_only=True) is None
    calls = []
    view = views.hysteresis_view(system, state, progress=lambda *a: calls.append(a))
    assert calls[0] == (0, 1, 0) and calls[-1] == (1, 1, 0)
    assert len(view["loops"]) == 1 and view["loops"][0]["energy_j"] > 0
    assert set(view["figures"]) == {"loops", "stiffness", "energy"}
    assert views.hysteresis_view(system, state, cache_only=True)["from_cache"]
    # display options reuse the simulated loop: no simulation, at once
    shown, _ = views.parse_query("hysteresis", {"speeds": "1500", "rate": "500", "hold": "0.2", "protocol": "full-100",
                                               "windup": "outer", "lowpass": "true"})
    t0 = time.perf_counter()
    other = views.hysteresis_view(system, shown, cache_only=True)
    assert other is not None and other["key"] != view["key"] and time.perf_counter() - t0 < 2.0
    # an added speed only simulates the new loop
    more, _ = views.parse_query("hysteresis", {"speeds": "1500,1800", "rate": "500", "hold": "0.2", "protocol": "full-100"})
    assert views.hysteresis_view(system, more, cache_only=True) is None
    calls = []
    views.hysteresis_view(system, more, progress=lambda *a: calls.append(a))
    assert calls[0] == (1, 2, 1) and calls[-1] == (2, 2, 1)


def _colourmap_state(**q):
    state, notices = views.parse_query("colourmap", {"speeds": "1400,1600", "duration": SHORT, "window": "0.5", **q})
    assert notices == []
    return state


def test_colourmap_view_cache_only_then_computed_then_cached(cache_dir):
    state = _colourmap_state()
    system = views.resolve_system(state["params"])
    assert views.colourmap_view(system, state, cache_only=True) is None
    assert views.colourmap_status(system, state) == {"total": 2, "cached": 0}
    seen = []
    view = views.colourmap_view(system, state, progress=lambda d, t, c: seen.append((d, t, c)), executor="serial")
    assert seen[0] == (0, 2, 0) and seen[-1] == (2, 2, 0)
    assert view["summary"]["points"] == 2 and view["summary"]["computed"] == 2
    fig = view["figures"]["colourmap"]
    assert sum(1 for tr in fig["data"] if tr["type"] == "heatmap") == 2
    assert [r["order"] for r in view["cuts"]] == [2.0, 4.0]
    assert views.colourmap_status(system, state) == {"total": 2, "cached": 2}
    hit = views.colourmap_view(system, state, cache_only=True)
    assert hit["from_cache"] and hit["key"] == view["key"]
    # a display-only change is assembled from the cached points, without simulating
    other = views.colourmap_view(system, _colourmap_state(db="false", fmax="300"), cache_only=True)
    assert other is not None and other["from_cache"] is False and other["summary"]["computed"] == 0


def test_cancelled_sweep_keeps_finished_points_and_previous_views(cache_dir):
    from dampersim.sweeps.executor import SweepCancelled

    first = _colourmap_state()
    system = views.resolve_system(first["params"])
    good = views.colourmap_view(system, first, executor="serial")
    state = _colourmap_state(speeds="1400,1500,1600,1700")
    done = []
    with pytest.raises(SweepCancelled) as exc:
        views.colourmap_view(system, state, progress=lambda d, t, c: done.append(d), cancel=lambda: len(done) >= 2,
                             executor="serial")
    assert "kept in the cache" in str(exc.value)
    status = views.colourmap_status(system, state)
    assert status == {"total": 4, "cached": 3}  # 1400 and 1600 from before, plus the one finished before the cancel
    assert views.load_view(good["key"]) is not None  # the previous result is intact


def test_maps_view(cache_dir):
    state, notices = views.parse_query("maps", {"speeds": "1200:1600:200", "torques": "100,300", "duration": SHORT,
                                                "window": "0.5", "fmin": "30", "fmax": "120"})
    assert notices == []
    system = views.resolve_system(state["params"])
    assert views.maps_status(system, state) == {"total": 6, "cached": 0}
    view = views.maps_view(system, state, executor="serial")
    assert view["summary"]["points"] == 6 and view["summary"]["max_mr"] > 0
    assert set(view["figures"]) == {"map", "curve"}
    assert views.maps_view(system, state, cache_only=True)["from_cache"]


def test_maps_view_needs_two_torques(cache_dir):
    state, _ = views.parse_query("maps", {"speeds": "1200,1400", "torques": "200", "duration": SHORT, "window": "0.5"})
    with pytest.raises(InputError, match="at least two torques"):
        views.maps_view(views.resolve_system(state["params"]), state, executor="serial")


# ----------------------------------------------------------------------------- parameters
def _upload(text: str | bytes) -> str:
    data = text.encode() if isinstance(text, str) else text
    return "data:application/toml;base64," + base64.b64encode(data).decode()


def test_parameters_view_rows_and_changes():
    system = dampersim.parameters.with_updates(dampersim.default_parameters(), {"inertias.primary": 0.25})
    rows = {r["name"]: r for r in views.parameters_view(system)}
    assert rows["inertias.primary"]["changed"] and rows["inertias.primary"]["unit"] == "kg m^2"
    assert not rows["inertias.secondary"]["changed"]
    assert "accepted" in rows["solver.outer_segments"] and "[4, 200]" in rows["solver.outer_segments"]["accepted"]


def test_uploaded_parameter_file_round_trip(cache_dir):
    system = dampersim.parameters.with_updates(dampersim.default_parameters(), {"outer.spring.stiffness": 140.0})
    loaded = views.parse_uploaded_parameters(_upload(views.parameters_toml(system)), "mine.toml")
    params = views.params_for_system(loaded)
    assert params == {"set": None, "overrides": {"outer.spring.stiffness": 140.0}}


def test_uploaded_set_with_another_structure_is_stored(cache_dir):
    import dataclasses

    base = dampersim.default_parameters()
    rig = dataclasses.replace(base.rig, elements=base.rig.elements[:2] + base.rig.elements[3:],
                              output_transducer="flange_group_1")
    other = dataclasses.replace(base, rig=rig, name="short-rig")
    params = views.params_for_system(other)
    assert params["set"] and params["overrides"] == {}
    again = views.resolve_system(params)
    assert [e.name for e in again.rig.elements] == [e.name for e in rig.elements]
    state, notices = views.parse_query("explorer", {"set": params["set"]})
    assert notices == [] and state["params"]["set"] == params["set"]


@pytest.mark.parametrize(
    "contents, message",
    [
        ("data:application/toml;base64,@@@", "not valid base64"),
        (_upload(b"\xff\xfe\x00bad"), "not UTF-8"),
        (_upload(""), "is empty"),
        (_upload("this is [not toml"), "valid TOML"),
        (_upload("[inertias]\nprimary = -1\n"), "inertias"),
        (_upload("[inertias]\nprimery = 0.2\n"), "did you mean"),
        (_upload("x" * (views.MAX_UPLOAD_BYTES + 10)), "up to 256 kB"),
        (None, "without content"),
    ],
)
def test_bad_uploads_are_refused_with_a_specific_message(contents, message):
    with pytest.raises(DampersimError) as exc:
        views.parse_uploaded_parameters(contents, "upload.toml")
    assert message in str(exc.value)
    assert "upload.toml" in str(exc.value)


def test_table_edits_apply_or_refuse():
    params = {"set": None, "overrides": {}}
    rows = [{"name": "inertias.primary", "value": "0.3"}, {"name": "inertias.secondary", "value": "0.06"}]
    new, system = views.apply_table_edits(params, rows)
    assert new["overrides"] == {"inertias.primary": 0.3} and system.inertias.primary == 0.3
    with pytest.raises(ParameterError, match="outer.spring.stiffness"):
        views.apply_table_edits(new, [{"name": "outer.spring.stiffness", "value": "-3"}])
    assert new["overrides"] == {"inertias.primary": 0.3}  # unchanged by the refused edit


def test_sweep_registry_counts_running_sweeps(cache_dir):
    a, b = views.SweepRegistry(), views.SweepRegistry()
    a.start("colourmap", 10)
    b.start("maps", 5)
    assert views.running_sweeps() == 2 and a.others() == 1
    a.stop()
    b.stop()
    assert views.running_sweeps() == 0


def test_view_key_survives_a_json_round_trip_of_the_state():
    import json

    state, _ = views.parse_query("maps", {"fmin": "30", "fmax": "120"})
    system = views.resolve_system(state["params"])
    through_browser = json.loads(json.dumps({k: (int(v) if isinstance(v, float) and v.is_integer() else v) for k, v in state.items()}))
    assert through_browser["fmin"] == 30 and isinstance(through_browser["fmin"], int)
    assert views.view_key("maps", system, through_browser, module=views.sweeps.__name__) == views.view_key("maps", system, state, module=views.sweeps.__name__)


def test_segments_display_options_reuse_the_simulation(cache_dir, monkeypatch):
    state, _ = views.parse_query("segments", {"duration": SHORT, "span": "0.02"})
    system = views.resolve_system(state["params"])
    first = views.segments_view(system, state)
    monkeypatch.setattr(views.segments, "simulate", lambda *a, **k: pytest.fail("simulated again for a display option"))
    other = views.segments_view(system, {**state, "spring": "pair_inner", "gain": 1.0, "window": 0.5})
    assert other["key"] != first["key"] and other["summary"]["spring"] == "pair_inner"


def test_coarse_time_step_from_a_link_runs_with_a_notice():
    # a stable step above the accuracy-tested default is accepted (it runs), and the page
    # says its accuracy is not checked; the default step gives no such notice
    from dampersim.parameters import default_parameters
    from dampersim.views.params import apply_overrides

    base = default_parameters()
    notices = []
    system, accepted = apply_overrides(base, {"solver.time_step": 2 * base.solver.time_step}, notices)
    assert accepted == {"solver.time_step": 2 * base.solver.time_step}
    assert system.solver.time_step == 2 * base.solver.time_step
    assert any("solver.time_step" in n["text"] and "accuracy is checked" in n["text"] for n in notices), notices
    quiet = []
    apply_overrides(base, {"solver.time_step": base.solver.time_step / 2}, quiet)
    assert quiet == []
