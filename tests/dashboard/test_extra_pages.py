"""Pulsation generator and Studies pages: callbacks called directly."""

import json

import plotly.graph_objects as go

import app  # noqa: F401  (registers the pages)
from pages import pulsation, studies


def _plain(f):
    return getattr(f, "__wrapped__", f)


def test_pulsation_run_and_bad_pressure():
    f1, f2, f3, text, msg = _plain(pulsation.run)(1, 2.5, 1500, [])
    assert all(isinstance(f, (go.Figure, dict)) for f in (f1, f2, f3))
    assert "dominant order" in text and "peak cylinder pressure" in text
    out = _plain(pulsation.run)(1, 9.0, 1500, [])
    assert "bar" in out[-1]  # a visible message naming the pressure range


def test_pulsation_dominant_order_sweep():
    seen = []
    fig, message = _plain(pulsation.sweep)(lambda p: seen.append(p), 1, 2.5, [])
    assert isinstance(fig, (go.Figure, dict)) and seen[-1] == ("9", "9") and message == ""


def test_study_quick_run_shows_checks():
    seen = []
    figs, checks, doc = _plain(studies.run)(lambda p: seen.append(p), 1, "order-rule", ["1"])
    assert figs and seen
    assert "dominant" in json.dumps(json.loads(doc))
    assert checks is not None
