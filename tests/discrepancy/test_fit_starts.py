"""Which starts a candidate is fitted from: the screen's preferred one, and the other only
when the preferred fit fails or the screen could not tell the two apart."""

import math

import pytest

from dampersim.discrepancy.naming import SECOND_START_NATS, Namer


class _Recorder(Namer):
    """A Namer whose fits only record the start they were asked for."""

    def __init__(self, failing=()):  # noqa: D107 - no runner, likelihood or campaign needed
        self.starts = {"calibrated": None, "estimated": None}
        self.failing, self.calls = set(failing), []

    def fit(self, name, start, extra_prior=0.0, label=None, jac=None, shape=None):
        self.calls.append(start)
        if start in self.failing:
            return None
        return {"cost": {"calibrated": 10.0, "estimated": 9.0}[start], "start": start}


def _screened(pref, z_pref, z_other):
    other = "estimated" if pref == "calibrated" else "calibrated"
    return {"start": pref, "start_z": {pref: z_pref, other: z_other}}


def test_a_clear_screen_fits_one_start_only():
    n = _Recorder()
    fits = n.fit_candidate("turbine_drag", _screened("calibrated", 40.0, 40.0 - SECOND_START_NATS - 0.1))
    assert n.calls == ["calibrated"] and [f["start"] for f in fits] == ["calibrated"]


def test_a_close_call_fits_both_and_keeps_the_cheaper_first():
    n = _Recorder()
    fits = n.fit_candidate("turbine_drag", _screened("calibrated", 40.0, 40.0 - SECOND_START_NATS + 0.1))
    assert n.calls == ["calibrated", "estimated"]
    assert [f["start"] for f in fits] == ["estimated", "calibrated"]  # by cost, 9 before 10


@pytest.mark.parametrize("z_other", [-math.inf, -1e6])
def test_a_failed_preferred_fit_falls_back_to_the_other_start(z_other):
    # even when the other start's screen run failed (-inf): a fit is tried before giving up
    n = _Recorder(failing={"calibrated"})
    fits = n.fit_candidate("turbine_drag", _screened("calibrated", 5.0, z_other))
    assert n.calls == ["calibrated", "estimated"] and [f["start"] for f in fits] == ["estimated"]


def test_every_fit_failing_gives_no_fit():
    n = _Recorder(failing={"calibrated", "estimated"})
    assert n.fit_candidate("turbine_drag", _screened("estimated", 5.0, 4.0)) == []
