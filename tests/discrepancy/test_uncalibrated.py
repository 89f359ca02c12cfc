"""The cell uncertainty carries what the calibration cannot follow, and the repeatability of
the residual: both wired from diagnose into the likelihood (stand-in model, no simulation)."""

import math

import numpy as np
import pytest

from dampersim.discrepancy import drive, tracking
from dampersim.discrepancy.fitting import ESTIMATE_LOG_SD
from dampersim.discrepancy.likelihood import residual_half_sigma
from tests.discrepancy import fake_rig as F
from tests.discrepancy.test_input_channel import _campaign, _spy_on_cell_sigma, _spy_on_measured_sets

EXPONENT = 0.5  # the stand-in's orders follow the tertiary inertia as J_ter^0.5


def _tertiary_sensitive_model(fail_when_moved=None):
    base = F.fake_model()
    j0 = F.BASE.inertias.tertiary

    def simulate_point(system, p, halves=False):
        if p.id == fail_when_moved and system.inertias.tertiary != j0:
            raise RuntimeError("diverged with the tertiary inertia moved")
        out = base(system, p)
        k = (system.inertias.tertiary / j0) ** EXPONENT
        return {key: k * v for key, v in out.items()}

    simulate_point.fake = True
    return simulate_point


def test_the_diagnosis_carries_the_uncalibrated_parameters_into_the_cell_uncertainty(monkeypatch):
    """The tertiary inertia is estimated but not calibrated: diagnose moves it by
    +-ESTIMATE_LOG_SD and passes cell_sigma the RMS of the two changes. With the stand-in's
    J_ter^0.5 that is a fixed share of every coefficient; without the wiring the captured
    term would be None or zero (the stand-in ignores the two group splits)."""
    from dampersim.discrepancy import diagnose as dg

    seen = _spy_on_cell_sigma(monkeypatch, dg)
    sets = _spy_on_measured_sets(monkeypatch)
    monkeypatch.setattr(drive, "simulate_point", _tertiary_sensitive_model())
    camp = _campaign()
    dg.diagnose(camp, workers=1, candidates=["turbine_drag"], recommend=False)
    up, down = math.exp(EXPONENT * ESTIMATE_LOG_SD) - 1.0, math.exp(-EXPONENT * ESTIMATE_LOG_SD) - 1.0
    share = math.sqrt(0.5 * (up ** 2 + down ** 2))
    # first at the parameter set as given, then at the calibrated factors (model_terms);
    # rel 1e-9: the same arithmetic in another order (the stand-in is exact, no simulation)
    assert len(sets) == len(seen["calls"]) == 2
    for s, call in zip(sets, seen["calls"]):
        unmoved = np.abs(np.array([F.fake_model()(drive.diagnosis_system(s), p)["coefficients"]
                                   for p in camp.torsional]))
        assert np.asarray(call["uncalibrated"]) == pytest.approx(share * unmoved, rel=1e-9)


def test_a_point_whose_uncalibrated_check_fails_is_left_out_and_reported(monkeypatch):
    from dampersim.discrepancy import diagnose as dg

    seen = _spy_on_cell_sigma(monkeypatch, dg)
    monkeypatch.setattr(drive, "simulate_point", _tertiary_sensitive_model(fail_when_moved="p4"))
    d = dg.diagnose(_campaign(), workers=1, candidates=["turbine_drag"], recommend=False)
    assert [(q["point"], q["field"]) for q in d.problems] == [("p4", "model")]
    message = d.problems[0]["message"]
    assert "calibration cannot follow" in message and "tertiary inertia" in message and "left out" in message
    assert "p4" not in {p["id"] for p in d.points} and d.verdict != dg.INSUFFICIENT
    assert np.asarray(seen["uncalibrated"]).shape == (len(d.points), len(drive.ORDERS))  # the kept points' rows


def test_the_diagnosis_takes_the_repeatability_asked_for(monkeypatch):
    """repeatability="residual": half the difference of the halves' residuals against the
    model driven by the record (with a stand-in whose output is the record's noise-free
    signal, the record's noise over the two halves); the default: the measured output's own
    halves (split_half_sigma). Anything else is refused before any run."""
    from dampersim.discrepancy import diagnose as dg
    from dampersim.discrepancy.likelihood import split_half_sigma
    from dampersim.errors import InputError

    seen = _spy_on_cell_sigma(monkeypatch, dg)
    monkeypatch.setattr(drive, "simulate_point", F.fake_model())
    camp = _campaign()
    system = drive.diagnosis_system(dg.default_parameters())
    dg.diagnose(camp, workers=1, candidates=["turbine_drag"], recommend=False, repeatability="residual")
    expected = np.array([residual_half_sigma(p, F.fake_model()(system, p)["halves"], drive.ORDERS)
                         for p in camp.torsional])
    # rel 1e-12: the same function of the same numbers (diagnose's path against a direct call)
    assert np.asarray(seen["repeat"]) == pytest.approx(expected, rel=1e-12)
    assert np.all(expected > 0)  # the records carry noise
    dg.diagnose(camp, workers=1, candidates=["turbine_drag"], recommend=False)
    measured = np.array([split_half_sigma(p, drive.ORDERS) for p in camp.torsional])
    assert np.asarray(seen["repeat"]) == pytest.approx(measured, rel=1e-12)
    with pytest.raises(InputError, match="repeatability 'halves'.*split_half, residual"):
        dg.diagnose(camp, workers=1, repeatability="halves")


def test_residual_repeatability_cancels_what_both_halves_share():
    """A gap the same in both halves (a systematic model error) is not repeatability; noise is."""
    p = F.point("q", 1500.0, 200.0)
    clean = tracking.half_coefficients(p, p.output_torque, drive.ORDERS)
    # abs 1e-12 N m: the same numbers subtracted, zero to rounding
    assert residual_half_sigma(p, clean, drive.ORDERS) == pytest.approx(np.zeros(len(drive.ORDERS)), abs=1e-12)
    biased = clean + 0.7  # the model off by 0.7 N m in every order, alike in both halves
    assert residual_half_sigma(p, biased, drive.ORDERS) == pytest.approx(np.zeros(len(drive.ORDERS)), abs=1e-12)
    one_half = clean.copy()
    one_half[1] += 0.4  # differs between the halves: half of it is the repeatability
    # rel 1e-9: a difference of coefficients of tens of N m, exact to rounding
    assert residual_half_sigma(p, one_half, drive.ORDERS) == pytest.approx(np.full(len(drive.ORDERS), 0.2), rel=1e-9)
