"""The input channel: its zero offset moves the drive's mean torque (correcting it restores the
record), its mains pick-up hardly moves the model, and the diagnosis carries the offset's
effect into the cell uncertainties."""

import dataclasses

import numpy as np
import pytest

from dampersim.discrepancy import drive, synth
from dampersim.discrepancy.campaign import MeasuredPoint, read_campaign
from dampersim.discrepancy.likelihood import measured_coefficients
from dampersim.parameters import at_thesis_segments

OFFSET = 1.5  # [N m]: within the synthetic DAQ's +-2 N m; likelihood.INPUT_OFFSET_SD


def _record_of_itself(tmp_path, monkeypatch, point_id):
    """A noise-free synthetic record (seed 3, 0.8 s, no gain error) of the diagnosed 18/8 set
    itself (no perturbation, no finer truth) at ``point_id``, and that set at its diagnosis
    step: (point, system)."""
    same = synth.truth_system
    monkeypatch.setattr(synth, "truth_system", lambda *a, **k: same(*a, **{**k, "fine": False}))
    out = tmp_path / "campaign"
    base = at_thesis_segments()
    synth.synthesize(str(out), effects=[], perturb=0.0, noise_db=-60.0, seed=3, points=[point_id], record=0.8,
                     gain_error=0.0, base=base)
    (p,) = read_campaign(str(out)).torsional
    return p, drive.diagnosis_system(base)


def test_an_input_offset_shows_at_350_nm_and_rezeroing_removes_it(tmp_path, monkeypatch):
    """The truth is the diagnosed 18/8 model itself (no perturbation, no noise), recorded at
    1800 rpm and 350 N m, where the mean torque sits near a knee of the characteristic. Drive
    the model with the record's input torque plus a 1.5 N m zero offset: the orders move by
    many times the record's own uncertainty (measured: 0.96 N m on order 2, of 18 N m, and
    0.85 N m on order 6; a record with the usual 1 N m sensor noise has a split-half sigma of
    0.02-0.05 N m there; limit 0.5 N m on the largest change), and by many times the clean
    drive's own error (0.066 N m; limit 0.1). drive.rezeroed with the true offset must give
    back the clean drive's orders (limit 0.01 N m: the two runs then see the same input up to
    rounding)."""
    p, system = _record_of_itself(tmp_path, monkeypatch, "map_1800_350")
    clean = drive.simulate_point(system, p)["coefficients"]
    shifted = dataclasses.replace(p, input_torque=p.input_torque + OFFSET)
    moved = drive.simulate_point(system, shifted)["coefficients"]
    back = drive.rezeroed(shifted, OFFSET)
    restored = drive.simulate_point(system, back)["coefficients"]
    assert np.abs(moved - clean).max() > 0.5, np.abs(moved - clean)
    assert np.abs(restored - clean).max() < 0.01, np.abs(restored - clean)
    # the clean drive's own error at this point, for scale
    assert np.abs(clean - measured_coefficients(p, drive.ORDERS)).max() < 0.1


def test_mains_hum_on_the_input_moves_the_model_little(tmp_path, monkeypatch):
    """pickup.py carries the output channel's pick-up only: 0.13 N m of 50 Hz on the input
    (the synthetic DAQ's draw for seed 3) drives the model at the line frequency, where the
    damper passes little. Measured on the 18/8 set driven by a record of itself at 1500 rpm
    and 350 N m (50 Hz is order 2 there): 0.021 N m on order 2, the most of any order (0.014
    with the engine amplitudes drawn for another set of points), against a record's order
    uncertainty of 0.02-0.05 N m with the usual 1 N m sensor noise; limit 0.03."""
    from dampersim.discrepancy import daq as D

    p, system = _record_of_itself(tmp_path, monkeypatch, "map_1500_350")
    hum = D.DaqCorruption(hum=D.MainsHum(input_nm=0.13, output_nm=0.0, third_harmonic=0.0, seed=1))
    clean = drive.simulate_point(system, p)["coefficients"]
    hummed = drive.simulate_point(system, D.corrupt_point(p, hum, 0))["coefficients"]
    assert np.abs(hummed - clean).max() < 0.03, np.abs(hummed - clean)


def test_rezeroing_divides_out_the_gain_and_leaves_the_output_alone():
    t = np.linspace(0.0, 1.0, 11)
    p = MeasuredPoint(id="p", kind="torsional", speed_rpm=1000.0, mean_torque_nm=100.0, sample_rate_hz=10.0, time=t,
                      input_torque=1.02 * (100.0 + t) + 3.0, output_torque=50.0 + t, input_speed_rpm=None,
                      output_speed_rpm=None)
    q = drive.rezeroed(p, 3.0, 1.02)
    assert np.allclose(q.input_torque, 100.0 + t) and q.output_torque is p.output_torque
    assert drive.rezeroed(p) is p


def _input_sensitive_model(fail_when_moved=None):
    """The fake rig's stand-in model with orders that grow by 1 % per N m of the record's mean
    input torque above the manifest's (a damper near its knee); failing when the input of
    point ``fail_when_moved`` is moved."""
    from tests.discrepancy import fake_rig as F

    base = F.fake_model()

    def simulate_point(system, p, halves=False):
        shift = float(np.mean(p.input_torque)) - p.mean_torque_nm
        if p.id == fail_when_moved and abs(shift) > 1.0:
            raise RuntimeError("diverged at the moved input")
        out = base(system, p)
        k = 1.0 + 0.01 * shift
        return {"orders": k * out["orders"], "coefficients": k * out["coefficients"], "halves": k * out["halves"]}

    simulate_point.fake = True
    return simulate_point


def _campaign():
    from tests.discrepancy import fake_rig as F

    return F.campaign([F.point(*q) for q in F.POINTS])


def _spy_on_cell_sigma(monkeypatch, dg):
    """Record the terms diagnose passes to cell_sigma and pass everything on: the returned
    dict's "repeat", "offset", "pickup" and "uncalibrated" are the last call's (the terms the
    verdict reads: at the calibrated factors when the calibration moved them), its "calls"
    every call's in turn (the first: at the parameter set as given)."""
    seen = {"calls": []}
    real = dg.cell_sigma

    def spy(repeat, model_change, meas, pickup=None, offset_change=None, uncalibrated=None):
        call = {"offset": offset_change, "pickup": pickup, "uncalibrated": uncalibrated, "repeat": repeat,
                "model": model_change}
        seen.update(call)
        seen["calls"].append(call)
        return real(repeat, model_change, meas, pickup, offset_change, uncalibrated)

    monkeypatch.setattr(dg, "cell_sigma", spy)
    return seen


def _spy_on_measured_sets(monkeypatch):
    """The parameter sets model_terms.measure is called with, in turn."""
    from dampersim.discrepancy import model_terms

    sets, real = [], model_terms.measure

    def spy(runner, system, points, y):
        sets.append(system)
        return real(runner, system, points, y)

    monkeypatch.setattr(model_terms, "measure", spy)
    return sets


def test_the_diagnosis_carries_the_input_offset_check_into_the_cell_uncertainty(monkeypatch):
    """diagnose passes cell_sigma the root mean square of the two changes of every point's
    coefficients when its input moves up and down by likelihood.input_mean_sd of its mean
    torque: with the stand-in's 1 % per N m (linear, so both changes are alike) that is that
    many per cent of each coefficient, first at the parameter set as given, then at the
    calibrated factors. Without the wiring the captured term would be None or 0; without the
    second measurement the last call would carry the first set's coefficients."""
    from dampersim.discrepancy import diagnose as dg
    from dampersim.discrepancy.likelihood import input_mean_sd

    seen = _spy_on_cell_sigma(monkeypatch, dg)
    sets = _spy_on_measured_sets(monkeypatch)
    monkeypatch.setattr(drive, "simulate_point", _input_sensitive_model())
    camp = _campaign()
    d = dg.diagnose(camp, workers=1, candidates=["turbine_drag"], recommend=False)
    from tests.discrepancy import fake_rig as F

    system = drive.diagnosis_system(dg.default_parameters())
    unmoved = np.array([F.fake_model()(system, p)["coefficients"] for p in camp.torsional])
    sd = np.array([[input_mean_sd(float(np.mean(p.input_torque)))] for p in camp.torsional])
    # rel 1e-9: the same arithmetic in another order (the stand-in is exact, no simulation)
    assert np.asarray(seen["calls"][0]["offset"]) == pytest.approx(0.01 * sd * np.abs(unmoved), rel=1e-9)
    assert len(sets) == len(seen["calls"]) == 2 and sets[0] == dg.default_parameters()
    calibrated = np.array([F.fake_model()(drive.diagnosis_system(sets[1]), p)["coefficients"] for p in camp.torsional])
    assert np.abs(np.abs(calibrated) - np.abs(unmoved)).max() > 1e-3  # the calibration moved the orders
    assert np.asarray(seen["offset"]) == pytest.approx(0.01 * sd * np.abs(calibrated), rel=1e-9)
    # the displayed noise floor carries the term as a root sum of squares: against the same
    # stand-in without the input sensitivity (which gives the same unmoved orders)
    with_term, rms = d.noise_floor_nm, float(np.sqrt(np.mean(np.asarray(seen["offset"]) ** 2)))
    monkeypatch.setattr(drive, "simulate_point", F.fake_model())
    without = dg.diagnose(camp, workers=1, candidates=["turbine_drag"], recommend=False).noise_floor_nm
    assert with_term ** 2 - without ** 2 == pytest.approx(rms ** 2, rel=1e-6)


def test_a_point_whose_input_check_fails_is_left_out_and_reported(monkeypatch):
    from dampersim.discrepancy import diagnose as dg

    seen = _spy_on_cell_sigma(monkeypatch, dg)
    monkeypatch.setattr(drive, "simulate_point", _input_sensitive_model(fail_when_moved="p4"))
    d = dg.diagnose(_campaign(), workers=1, candidates=["turbine_drag"], recommend=False)
    assert [(q["point"], q["field"]) for q in d.problems] == [("p4", "model")]
    assert "input check" in d.problems[0]["message"] and "left out" in d.problems[0]["message"]
    assert "p4" not in {p["id"] for p in d.points} and d.verdict != dg.INSUFFICIENT
    assert np.asarray(seen["offset"]).shape == (len(d.points), len(drive.ORDERS))  # the kept points' rows


def test_the_diagnosis_passes_the_mains_pickup_to_the_cell_uncertainty(monkeypatch):
    """diagnose hands cell_sigma what pickup.pickup_sigma gives for the kept points: with a
    stand-in pick-up of 0.1 N m on every cell the spy must receive exactly that (without the
    wiring it would receive None)."""
    from dampersim.discrepancy import diagnose as dg
    from dampersim.discrepancy import pickup

    from tests.discrepancy import fake_rig as F

    seen = _spy_on_cell_sigma(monkeypatch, dg)
    # the plain stand-in: no model term moves with the calibrated factors, which the pick-up
    # shifts, so the two floors differ by the pick-up alone
    monkeypatch.setattr(drive, "simulate_point", F.fake_model())
    floors = {}
    for level in (0.0, 0.1):
        monkeypatch.setattr(pickup, "pickup_sigma", lambda pts, orders, v=level: np.full((len(pts), len(orders)), v))
        d = dg.diagnose(_campaign(), workers=1, candidates=["turbine_drag"], recommend=False)
        floors[level] = d.noise_floor_nm
    assert np.asarray(seen["pickup"]) == pytest.approx(np.full((len(d.points), len(drive.ORDERS)), 0.1))
    # the displayed noise floor carries it too, as a root sum of squares
    assert floors[0.1] ** 2 - floors[0.0] ** 2 == pytest.approx(0.1 ** 2, rel=1e-6)
