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


def _diagnose(monkeypatch, stop_short: bool, campaign=None, screen_calibrated: bool = False):
    """Diagnose ``campaign`` (default: the stand-in campaign, turbine drag hidden) with two
    candidates; with ``stop_short`` the calibration's only Gauss-Newton solves point uphill,
    so its factors stay at the coarse scan's and the candidates' fits find better ones.
    Returns the diagnosis and what the spies saw: "none" before recalibrate (``before``),
    its return value (``moved``), the models as it left them, the Namer, the runs it made
    (``runs``) and its bound (``bound``: the training points per fitted single effect and
    the held-out points once), and the typical-magnitude run each detectability call got
    (``typical``). With ``screen_calibrated`` every candidate is screened and fitted from
    the calibrated start only (on this campaign the estimated start's screen evidence leads
    by 0.1 nats, and the typical-magnitude run is reused only from the calibrated start)."""
    from dampersim.discrepancy import diagnose as dg

    seen = {"typical": {}}
    real_recal, real_solve, real_detect = naming.Namer.recalibrate, dg._lstsq_bounded, naming.Namer.detectability

    def spy_recal(self, models, held_pts, bias=None):
        seen["before"] = {"cost": models["none"]["cost"], "x": np.array(models["none"]["x"])}
        count = self.runner.count
        seen["moved"] = real_recal(self, models, held_pts, bias)
        seen["runs"] = self.runner.count - count
        singles = [m for m in models if m != "none" and models[m].get("base") is None]
        seen["bound"] = len(singles) * len(self.points) + len(held_pts)
        seen["models"], seen["namer"] = models, self
        return seen["moved"]

    def spy_detect(self, name, y_cal, nuisance, y_typ, *args, **kwargs):
        seen["typical"][name] = y_typ
        return real_detect(self, name, y_cal, nuisance, y_typ, *args, **kwargs)

    def screen_from_calibrated(self, name):
        every = self.starts
        self.starts = {"calibrated": every["calibrated"]}
        try:
            return real_screen(self, name)
        finally:
            self.starts = every

    monkeypatch.setattr(naming.Namer, "recalibrate", spy_recal)
    monkeypatch.setattr(naming.Namer, "detectability", spy_detect)
    if screen_calibrated:
        real_screen = naming.Namer.screen
        monkeypatch.setattr(naming.Namer, "screen", screen_from_calibrated)
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


# the drag rig's calibration reaches its minimum, so "none" does not move there (a check
# that nothing changes when nothing should); on the stiffer rig the fits find better factors
@pytest.mark.parametrize("stop_short", [True, False])
@pytest.mark.parametrize("rig", ["drag", "stiffer"])
def test_no_candidate_gains_by_its_calibration_alone(monkeypatch, stop_short, rig):
    d, seen = _diagnose(monkeypatch, stop_short, _stiffer_campaign() if rig == "stiffer" else _campaign())
    models, namer = seen["models"], seen["namer"]
    none = models["none"]
    singles = [m for m in models if m != "none" and models[m].get("base") is None]
    assert singles
    for label in singles:
        # "none" costs no more than the calibration-only model at this candidate's factors;
        # the same deterministic runs and likelihood give equal values, 1e-9 of the cost
        # allows for nothing more than rounding
        assert none["cost"] <= _cost_at(namer, models[label]["x"]) + 1e-9 * none["cost"], label
    assert none["cost"] <= seen["before"]["cost"]
    assert 0 <= seen["runs"] <= seen["bound"]  # the runs costs.diagnosis_runs counts for this step
    assert d.likelihood["calibration_taken_from"] == none.get("refactored")
    # the calibration reported and the calibrated amplitudes are those of "none" as moved
    if d.verdict != "missing_effect":
        assert d.calibration == pytest.approx({k: math.exp(v) for k, v in zip(d.calibration, none["x"])})
    by_id = {p["id"]: p for p in d.points}
    train_ids = [p["id"] for p in d.points if not p["held_out"]]
    held_ids = [p["id"] for p in d.points if p["held_out"]]
    assert train_ids and held_ids
    for rows, y in ((train_ids, none["y"]), (held_ids, none["yh"])):
        for j, pid in enumerate(rows):
            np.testing.assert_allclose(by_id[pid]["calibrated"], np.abs(y[j]), rtol=1e-12)  # copies, not a recomputation
    meas = np.array([by_id[pid]["measured"] for pid in held_ids])
    gap = math.sqrt(float(np.mean((np.abs(none["yh"]) - meas) ** 2)))
    assert d.gap_calibrated_nm == pytest.approx(gap, rel=1e-9)  # the same RMS, summed in another order


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
    assert 0 < seen["runs"] <= seen["bound"]


@pytest.mark.parametrize("rig,stop_short", [("stiffer", True), ("drag", False)])
def test_detectability_reuses_the_screen_run_only_while_none_keeps_its_factors(monkeypatch, rig, stop_short):
    d, seen = _diagnose(monkeypatch, stop_short, _stiffer_campaign() if rig == "stiffer" else _campaign(),
                        screen_calibrated=True)
    assert seen["moved"] == (rig == "stiffer")
    assert set(seen["typical"]) == {"turbine_drag", "clutch_slip"}
    # detectability compares an effect with the calibrated model as it ends up: the screen's
    # run at the typical magnitude (from the calibrated start's factors) serves only while
    # those are still the calibrated model's; once "none" moved, the run is made again
    assert all((v is None) == seen["moved"] for v in seen["typical"].values())
