""""No missing effect" is compared at the best calibration any candidate's fit found
(naming.Namer.recalibrate): every candidate fit re-calibrates at each magnitude it tries,
so without this an effect that explains nothing could win by its better calibration
factors alone (docs/discrepancy.md, "Why the free play wins on control/none/1"). Stand-in
model (tests/discrepancy/fake_rig.py), no simulation."""

import math

import numpy as np
import pytest

from dampersim.discrepancy import drive, naming
from dampersim.discrepancy.fitting import calibrated_system
from tests.discrepancy import fake_rig as F
from tests.discrepancy.test_input_channel import _campaign

#: a rig whose outer springs are 25 % stiffer than estimated (log 0.223), between the coarse
#: scan's steps 0.15 and 0.3 (fitting.CAL_SCAN), with no missing effect
STIFFER = (math.log(1.25), 0.0, 0.0, 0.0, 0.0, 0.0)


def _stiffer_campaign():
    truth = calibrated_system(F.BASE, np.array(STIFFER))
    return F.campaign([F.point(pid, rpm, tq, F.amplitudes(truth, rpm, tq)) for pid, rpm, tq in F.POINTS])


def _diagnose(monkeypatch, stop_short: bool, campaign=None):
    """Diagnose the stand-in campaign (turbine drag hidden) with two candidates; with
    ``stop_short`` the calibration's only Gauss-Newton solves point uphill, so its factors
    stay at the coarse scan's and the candidates' fits find better ones. Returns the
    diagnosis, the models as recalibrate left them, "none"'s cost before it, its return
    value and the Namer."""
    from dampersim.discrepancy import diagnose as dg

    seen = {}
    real_recal, real_solve = naming.Namer.recalibrate, dg._lstsq_bounded

    def spy_recal(self, models, held_pts, bias=None):
        seen["before"] = {"cost": models["none"]["cost"], "x": np.array(models["none"]["x"])}
        seen["moved"] = real_recal(self, models, held_pts, bias)
        seen["models"], seen["namer"] = models, self
        return seen["moved"]

    monkeypatch.setattr(naming.Namer, "recalibrate", spy_recal)
    if stop_short:
        monkeypatch.setattr(dg, "_lstsq_bounded", lambda J, r, x0: -real_solve(J, r, x0))
    monkeypatch.setattr(drive, "simulate_point", F.fake_model())
    d = dg.diagnose(campaign or _campaign(), workers=1, candidates=["turbine_drag", "clutch_slip"], recommend=False,
                    calibration_iterations=1, shortlist=2)
    return d, seen


def _cost_at(namer, x) -> float:
    """Training objective of the calibration-only model at factors x (the stand-in's runs)."""
    y = drive.coefficients_of(namer.runner, calibrated_system(F.BASE, x), namer.points)
    return namer.cost(y, x)


@pytest.mark.parametrize("stop_short", [True, False])
@pytest.mark.parametrize("rig", ["drag", "stiffer"])
def test_no_candidate_gains_by_its_calibration_alone(monkeypatch, stop_short, rig):
    d, seen = _diagnose(monkeypatch, stop_short, _stiffer_campaign() if rig == "stiffer" else _campaign())
    models, namer = seen["models"], seen["namer"]
    none = models["none"]
    singles = [m for m in models if m != "none" and models[m].get("base") is None]
    assert singles
    for label in singles:
        # "none" costs no more than the calibration-only model at this candidate's factors
        # (to 1e-9 of the cost: the same runs, summed in another order)
        assert none["cost"] <= _cost_at(namer, models[label]["x"]) + 1e-9 * none["cost"], label
    assert none["cost"] <= seen["before"]["cost"]
    # the calibration reported and the calibrated amplitudes are those of "none" as moved
    if d.verdict != "missing_effect":
        assert d.calibration == pytest.approx({k: math.exp(v) for k, v in zip(d.calibration, none["x"])})
    held = {p["id"]: p for p in d.points if p["held_out"]}
    assert held
    ids = [p["id"] for p in d.points if p["held_out"]]
    for j, pid in enumerate(ids):
        np.testing.assert_allclose(held[pid]["calibrated"], np.abs(none["yh"][j]), rtol=1e-12)


def test_a_calibration_that_stopped_short_takes_the_factors_a_fit_found(monkeypatch):
    d, seen = _diagnose(monkeypatch, stop_short=True, campaign=_stiffer_campaign())
    none = seen["models"]["none"]
    # the calibration never moved past the coarse scan; the fits' re-calibration did, and
    # "none" now sits at a fitted candidate's factors with a lower objective
    assert seen["moved"] and none["refactored"] in seen["models"]
    np.testing.assert_array_equal(none["x"], seen["models"][none["refactored"]]["x"])
    assert none["cost"] < seen["before"]["cost"]
    assert not np.array_equal(none["x"], seen["before"]["x"])
    # nothing is missing from this rig: the calibration-only model stays the most probable
    assert d.verdict == "no_missing_effect" and d.likelihood["model"] == "none", d.message
    assert d.calibration["outer_stiffness"] == pytest.approx(math.exp(none["x"][0]))
    assert d.simulations <= _run_bound()


def _run_bound() -> int:
    from dampersim import costs

    return costs.diagnosis_runs(len(F.POINTS), 2)
