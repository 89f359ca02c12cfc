"""Discrepancy page: a finished diagnosis shows its model comparison, one card per table
(the posterior with the likelihood summary and the outliers, the effects of the most
probable model with their 90 % intervals, the detectability with this campaign, the
recommended next test points); a diagnosis without one (made by an earlier version, or
insufficient data) says so in every card. Through the show callback and Dash's HTTP
endpoint with hand-written diagnosis documents in the view cache; nothing simulates."""

from __future__ import annotations

import json

import pytest

import app  # noqa: F401  (registers the pages)
from dampersim import views
from pages import _diagnosis_tables as T
from pages import discrepancy as D
from tests.dashboard.test_callbacks import find
from tests.dashboard.test_discrepancy_page import as_json
from tests.dashboard.test_http import DashClient
from tests.discrepancy.test_diagnosis_tables import FULL, INSUFFICIENT, OLD

CARDS = ["discrepancy-posterior", "discrepancy-effects", "discrepancy-detectability", "discrepancy-next-points"]


def shown(doc, key) -> dict:
    """The show callback's output for a cached view holding ``doc``: {output id: value}."""
    views.store.save_view(key, {"kind": "discrepancy", "campaign": {"name": "fake", "torsional": 12},
                                "diagnosis": json.loads(json.dumps(doc)), "summary": {"simulations": 1}})
    out = D.show({"key": key, "nonce": "n"})
    ids = [o.component_id for o in D.SHOW_OUTPUTS]
    assert len(out) == len(ids) + 2 and out[-1] == [], as_json(out[-1])  # then the status and notices
    return dict(zip(ids, out))


def test_the_cards_are_in_the_layout_and_written_by_show():
    page = D.layout()
    for cid in CARDS:
        assert find(page, cid) is not None, cid
        assert "No diagnosis shown yet" in as_json(find(page, cid))
    assert [o.component_id for o in D.SHOW_OUTPUTS][-len(CARDS):] == CARDS == list(T.CARD_IDS.values())


def test_a_finished_diagnosis_shows_posterior_intervals_detectability_and_next_points(cache_dir):
    out = shown(FULL, "tables-full")
    post = as_json(out["discrepancy-posterior"])
    # sorted by probability, the most probable highlighted, with prior and log evidence
    table = find(out["discrepancy-posterior"][1], "discrepancy-posterior-table")
    body = table.children[1].children
    assert [r.children[0].children for r in body] == ["clutch_slip", "turbine_drag", "clutch_slip + turbine_drag",
                                                      "none (calibrated model alone)"]
    assert [r.className for r in body] == ["hl", None, None, None]
    assert [c.children for c in body[0].children] == ["clutch_slip", "20 %", "81 %", "-100.25"]
    assert "Reduced χ² 1.13 on the held-out points, 0.97 on the training points (96 cells)" in post
    assert "Fitted output gain 1.002, delay 0.153 ms." in post
    assert "Outliers (down-weighted by the robust loss): map_900_50, tc_1200." in post
    effects = as_json(out["discrepancy-effects"])
    assert "discrepancy-effects-table" in effects and "512 N m" in effects and "480 – 546 N m" in effects
    assert "0.5 – 1.1 N m s/rad" in effects
    detect = as_json(out["discrepancy-detectability"])
    for text in ("detectable below 430 N m", "detectable above 0.0007 kg m^2", "detectable below 180 Hz",
                 "not detectable with this campaign", "capacity", "kg m^2"):
        assert text in detect, text
    nxt = as_json(out["discrepancy-next-points"])
    for text in ("orders 2:150", "protocol pos-350-450", "2500", "separate clutch_slip from clutch_slip+turbine_drag"):
        assert text in nxt, text
    # the rest of the page as before
    assert out["discrepancy-gap"]["data"] and "discrepancy-ranking-table" in as_json(out["discrepancy-ranking"])
    assert "posterior" in json.loads(out["discrepancy-json"])


@pytest.mark.parametrize("doc, why", [
    (OLD, "Not computed: this diagnosis was made by an earlier version"),
    (INSUFFICIENT, "Not computed: the campaign could not be diagnosed."),
], ids=["older-document", "insufficient-data"])
def test_a_diagnosis_without_a_model_comparison_says_so_in_every_card(cache_dir, doc, why):
    out = shown(doc, f"tables-{doc['verdict']}")
    for cid in CARDS:
        text = as_json(out[cid])
        assert why in text and "data-table" not in text, cid


def test_the_tables_over_http(cache_dir):
    views.store.save_view("tables-http", {"kind": "discrepancy", "campaign": {"name": "fake"},
                                          "diagnosis": FULL, "summary": {}})
    dc = DashClient(app.app)
    r = dc.call("discrepancy-posterior.children", {"discrepancy-hit.data": {"key": "tables-http", "from": "cache"},
                                                   "discrepancy-done.data": None}, changed=["discrepancy-hit.data"])
    resp = r.get_json()["response"]
    text = json.dumps({cid: resp[cid] for cid in CARDS}, ensure_ascii=False)
    assert "detectable below 430 N m" in text and "81 %" in text and "orders 2:150" in text
    assert "480 – 546 N m" in text
