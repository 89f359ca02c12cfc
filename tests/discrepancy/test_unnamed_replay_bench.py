"""bench/bench_unnamed_replay.py and the kept inputs of bench_discrepancy --misfit-inputs:
written and read back exactly, recomputed to the run's gains, and a mismatch reported (no
diagnosis is run: the inputs are built by hand)."""

import dataclasses
import json
import math

import numpy as np
import pytest

from dampersim.discrepancy import selection
from dampersim.discrepancy import unnamed as U
from dampersim.discrepancy.ramps import SCALES, RampLikelihood
from tests.discrepancy import fake_rig as F
from tests.discrepancy.benches import load_bench


@pytest.fixture(scope="module")
def replay():
    return load_bench("bench_unnamed_replay")


def _inputs():
    """Torsional inputs with a smooth misfit in the residual, and one 3 s ramp whose
    unloading branch lies 0.2 deg off (a loop the model lacks) with a little noise."""
    rng = np.random.default_rng(7)
    n, p, k = 48, 4, 8
    jac, basis = rng.normal(size=(n, p)), rng.normal(size=(n, k))
    torsion = {"r_fit": rng.normal(size=n) + basis @ rng.normal(size=k) * 0.5, "jac": jac,
               "prec": rng.uniform(0.5, 2.0, p), "offset": 0.1 * rng.normal(size=p), "eta": 0.4, "basis": basis}
    pt = F.ramp("r0")
    model = {pt.id: pt.windup}
    loop = np.where(np.gradient(pt.input_torque) > 0, 0.0, math.radians(0.2))
    meas = dataclasses.replace(pt, windup=pt.windup + loop + rng.normal(0.0, math.radians(0.02), pt.windup.size))
    lik = RampLikelihood([meas], model, model)
    lik.fraction = 0.5
    ramps = U.ramp_inputs(lik, model, np.zeros((lik.residuals, 1)), np.eye(1))
    return {"torsion": torsion, "ramps": ramps}


def _row(inputs, case_id="ool/rig_inertia/1"):
    """A JSON line as bench_discrepancy writes it, with the gains the inputs give."""
    d_t = U.torsion_gain(**inputs["torsion"])
    d_r = U.ramp_gain_of(inputs["ramps"], SCALES)
    gain = U.combined(d_t, d_r)
    log_z = {"none": -100.0 + gain, "transducer_bandwidth": -97.0, "clutch_slip": None}
    priors = {"none": 0.5, "transducer_bandwidth": 0.25, "clutch_slip": 0.25}
    return {"id": case_id, "likelihood": {"unnamed_misfit": {"torsional": d_t, "ramps": d_r, "log_evidence": gain},
                                          "log_evidence": log_z, "model_prior": priors}}


def test_kept_inputs_come_back_exactly(tmp_path, replay):
    inputs = _inputs()
    assert inputs["ramps"] is not None and inputs["ramps"]["share"] == 0.5
    path = replay.B.inputs_file(str(tmp_path), "ool/rig_inertia/1")
    assert path.endswith("ool__rig_inertia__1.npz")
    replay.B.save_misfit_inputs(path, inputs)
    back = replay.read_inputs(path)
    for part in ("torsion", "ramps"):
        assert set(back[part]) == set(inputs[part])
        for key, v in inputs[part].items():
            assert np.array_equal(np.asarray(back[part][key]), np.asarray(v)), (part, key)
    assert isinstance(back["torsion"]["eta"], float)
    # a campaign without ramps keeps the torsional part only, and reads back as None
    replay.B.save_misfit_inputs(path, {"torsion": inputs["torsion"], "ramps": None})
    assert replay.read_inputs(path)["ramps"] is None


def test_the_replay_recomputes_the_run_and_reports_a_mismatch(tmp_path, replay, capsys):
    inputs = _inputs()
    row = _row(inputs)
    # the run's own settings give back the run's posterior; the misfit is real here, so reading it
    # untempered gains more than at the run's learning rate of 0.4
    gain = row["likelihood"]["unnamed_misfit"]["log_evidence"]
    want = {"none": -100.0 + gain, "transducer_bandwidth": -97.0, "clutch_slip": -math.inf}
    priors = row["likelihood"]["model_prior"]
    assert replay.posterior_with(row, gain) == pytest.approx(selection.posterior(want, priors))
    assert U.gains(inputs, eta=1.0)[0] > U.gains(inputs)[0] > 0.0
    lines, ok = replay.replay(row, inputs, etas=[1.0], grids=[(0.0, 0.1)])
    assert ok and "(agrees)" in lines[2] and len(lines) == 4 + 3
    # after >= taken >= 0: a projection takes part of what is left, never more; a basis column that
    # repeats a Jacobian column (as the degree-0 one repeats the output gain's) changes nothing
    after, taken = replay.basis_take(inputs["torsion"])
    assert after >= taken > 0.0
    t = dict(inputs["torsion"], basis=np.column_stack([inputs["torsion"]["jac"][:, :1], inputs["torsion"]["basis"]]))
    assert replay.basis_take(t) == pytest.approx((after, taken), rel=1e-9)
    # through main: agreement exits 0; a run whose recorded gain differs by 1e-6 nats exits 1
    replay.B.save_misfit_inputs(replay.B.inputs_file(str(tmp_path), row["id"]), inputs)
    results = tmp_path / "r.jsonl"
    results.write_text(json.dumps(row) + "\n")
    assert replay.main(["--inputs", str(tmp_path), "--results", str(results)]) == 0
    row["likelihood"]["unnamed_misfit"]["torsional"] += 1e-6
    results.write_text(json.dumps(row) + "\n")
    assert replay.main(["--inputs", str(tmp_path), "--results", str(results)]) == 1
    assert "DISAGREES" in capsys.readouterr().out
    # no kept inputs for any case: said, exit 1 (never an empty success); no such directory: refused
    empty = tmp_path / "empty"
    empty.mkdir()
    assert replay.main(["--inputs", str(empty), "--results", str(results)]) == 1
    assert "has kept inputs" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        replay.main(["--inputs", str(tmp_path / "missing"), "--results", str(results)])
    assert exc.value.code == 2


def test_bad_variants_and_bad_files_are_refused_with_what_is_accepted(replay, tmp_path, capsys):
    inputs = _inputs()
    row = _row(inputs)
    replay.B.save_misfit_inputs(replay.B.inputs_file(str(tmp_path), row["id"]), inputs)
    results = tmp_path / "r.jsonl"
    results.write_text(json.dumps(row) + "\n")
    base = ["--inputs", str(tmp_path), "--results", str(results)]
    for args, said in ((["--eta", "0"], "a learning rate lies in (0, 1]"), (["--eta", "x"], "a learning rate"),
                       (["--eta", "1.5"], "a learning rate lies in (0, 1]"),
                       (["--torsion-sds", "0,-0.1"], "a comma-separated list of spreads >= 0"),
                       (["--torsion-sds", "a"], "a comma-separated list of spreads >= 0")):
        with pytest.raises(SystemExit) as exc:
            replay.main(base + args)
        assert exc.value.code == 2 and said in capsys.readouterr().err, args
    # a kept file that is not what save_misfit_inputs writes: named, the case reported, exit 1
    path = replay.B.inputs_file(str(tmp_path), row["id"])
    for bad in ({"torsion.r_fit": np.zeros(3)}, {"torsion.r_fit": np.zeros(3), "extra": np.zeros(1)}):
        np.savez(path, **bad)
        with pytest.raises(ValueError, match="ool__rig_inertia__1.npz"):
            replay.read_inputs(path)
        assert replay.main(base) == 1
        assert "cannot be replayed" in capsys.readouterr().out
    for junk in (b"not a zip", b""):  # b"": a save killed right after the file was opened
        with open(path, "wb") as fh:
            fh.write(junk)
        with pytest.raises(ValueError, match="not the kept inputs of a diagnosis"):
            replay.read_inputs(path)
        assert replay.main(base) == 1
        assert "cannot be replayed" in capsys.readouterr().out
    # a results line without the misfit's figures (another tool's line of the same case)
    replay.B.save_misfit_inputs(path, inputs)
    results.write_text(json.dumps({"id": row["id"], "likelihood": {}}) + "\n")
    assert replay.main(base) == 1 and "cannot be replayed" in capsys.readouterr().out
