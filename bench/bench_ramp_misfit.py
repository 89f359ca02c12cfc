"""What a hysteresis ramp's misfit is made of, and what the calibration factors could do
with the ramp alone.

For each named case of the hard benchmark matrix (``bench/bench_discrepancy.py --list``;
the campaign is synthesised exactly as that benchmark does, 12 torsional points of 1 s and
one ramp), the ramp is replayed with the diagnosis's own drive (the recorded input torque,
:func:`dampersim.discrepancy.drive.simulate_point`) and compared as the diagnosis compares
it (:class:`dampersim.discrepancy.ramps.RampLikelihood`: 10 Hz low pass, 2 samples/s, each
ramp's mean removed as its angle offset). Printed: the RMS misfit in degrees and in units of
the median sample uncertainty, for

* the truth driven by the recorded input torque (what the input channel's corruption alone
  leaves), and by the truth's own clean input torque (the replay's own error);
* the estimate (the library's default set, the diagnosis's starting point), the estimate
  with each ``--magnitudes`` of ``--effect``, and the truth without its hidden effects;
* then the same models after a Gauss-Newton fit of the six calibration factors
  (:data:`dampersim.discrepancy.fitting.CALIBRATION`, log scale, within CAL_BOUND) to the
  ramp alone: how far the ramp could separate the models if the factors were free to
  follow it (the diagnosis fits them on the torsional points and lets the ramp move them
  only within that fit's uncertainty).

With ``--factors-from FILE`` (a ``bench_discrepancy.py --out`` file holding the case's line)
the ramp is also replayed at the calibration factors that line reports (those of the
adopted model for a ``missing_effect`` verdict, else the calibration without an effect),
with each magnitude, then with the factors of the
stiffnesses and inertias, and of the frictions, set to the truth's (each group's factor the
geometric mean of its members' truth / estimate): which factors move the magnitude the ramp
prefers. With ``--prediction-sd`` the ramp's predictive log likelihood
(:meth:`~dampersim.discrepancy.ramps.RampLikelihood.predictive`, sensitivities at the
reported factors with the first magnitude) is printed per magnitude for each standard
deviation of the six log factors (independent): how loose the factors must be for the ramp
to prefer a magnitude by its own shape rather than by what the factors leave.

With ``--torsional`` the diagnosis's own compare and calibration steps run first (stopped
where they hand over to the naming step), and each model's calibration objective on the
training points is printed at the estimate's factors, the calibrated factors and the
factors fitted to the ramp, with the ramp misfit at the calibrated factors: whether one set
of the six factors can fit the ramp and the torsional points together.

    python bench/bench_ramp_misfit.py effect/output_backlash/strong/s0
    python bench/bench_ramp_misfit.py effect/output_backlash/strong/s0 control/calibration/2 --torsional
    python bench/bench_ramp_misfit.py control/calibration/2 --magnitudes 0.01 0.024
    python bench/bench_ramp_misfit.py effect/output_backlash/typical/s0 --magnitudes 0.03 0.0427 \
        --factors-from G.jsonl --prediction-sd 0.01 0.03 0.1 --no-ramp-fit
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_sigma_terms as S  # noqa: E402 - the hard matrix's cases and campaigns, as that bench builds them

from dampersim.discrepancy import drive, synth  # noqa: E402
from dampersim.discrepancy.effects import NAMES, info, with_effect  # noqa: E402
from dampersim.discrepancy.fitting import CAL_BOUND, CALIBRATION, PRIOR_LOG_SD, calibrated_system  # noqa: E402
from dampersim.discrepancy.ramps import RampLikelihood, run_ramps  # noqa: E402
from dampersim.excitation import ramp_protocol  # noqa: E402
from dampersim.parameters import default_parameters  # noqa: E402
from dampersim.parameters.io import named_values  # noqa: E402
from dampersim.simulation import simulate  # noqa: E402

#: log-factor step of the ramp's sensitivities (the diagnosis's longer step, 5 %), and iterations
STEP = 0.05
ITERATIONS = 4


def truth_of(case):
    """(truth system, the same truth without its hidden effects) of a hard-matrix case, both
    drawn as synthesize draws them (same seed, perturbation and updates)."""
    spec = case["spec"]
    effects = [(n, dict(v)) for n, v in spec["effects"]]
    updates = dict(spec["updates"]) or None
    truth, _ = synth.truth_system(default_parameters(), effects, case["perturb"],
                                  np.random.default_rng(case["seed"]), updates)
    without, _ = synth.truth_system(default_parameters(), [], case["perturb"],
                                    np.random.default_rng(case["seed"]), updates)
    return truth, without


def clean_input(truth, point) -> np.ndarray:
    """The truth's own input torque of the ramp [N m] on the record's time base (before the DAQ)."""
    res = simulate(truth, ramp_protocol(synth.RAMP_PROTOCOL, point.speed), record_segments=False)
    return np.interp(point.time, res.t - res.t[0], res.input_torque)


def truth_factors(truth, estimate) -> np.ndarray:
    """The truth's log calibration factors against the estimate: each group's geometric mean
    of its members' ratios (dotted names of :data:`CALIBRATION`)."""
    t, e = named_values(truth), named_values(estimate)
    return np.array([np.mean([math.log(t[n] / e[n]) for n in members]) for members in CALIBRATION.values()])


def reported_factors(path, case_id) -> np.ndarray:
    """The log calibration factors the line of ``case_id`` in a bench_discrepancy result file reports."""
    with open(path, encoding="utf-8") as fh:
        rows = [json.loads(line) for line in fh if line.strip()]
    row = next((r for r in rows if r.get("id") == case_id), None)
    if row is None or not row.get("calibration"):
        raise SystemExit(f"{path}: no line with calibration factors for {case_id}")
    return np.log([float(row["calibration"][k]) for k in CALIBRATION])


#: calibration groups set to the truth's in the --factors-from replays (indices into CALIBRATION)
GROUPS = {"stiffnesses and inertias": [k for k, g in enumerate(CALIBRATION) if not g.endswith("_friction")],
          "frictions": [k for k, g in enumerate(CALIBRATION) if g.endswith("_friction")]}


def at_factors(runner, lik, est, effect, mags, x, x_truth, sds, show) -> None:
    """The --factors-from replays (see the module doc)."""
    mag = info(effect).magnitude
    variants = {"reported factors": x}
    for label, part in GROUPS.items():
        xv = x.copy()
        xv[part] = x_truth[part]
        variants[f"reported, {label} the truth's"] = xv
    runs = {}
    for label, xv in variants.items():
        for m in mags:
            runs[label, m] = run_ramps(runner, with_effect(calibrated_system(est, xv), effect, {mag: m}), lik.points)
            show(f"{label} + {m:g}", misfit(lik, runs[label, m]))
    if not sds:
        return
    at = runs["reported factors", mags[0]]
    cols = []
    for k in range(len(x)):
        h = STEP if x[k] + STEP <= CAL_BOUND else -STEP  # the other way at the upper bound
        xk = x.copy()
        xk[k] += h
        cols.append(lik.column(run_ramps(runner, with_effect(calibrated_system(est, xk), effect, {mag: mags[0]}),
                                         lik.points), at, h))
    for sd in sds:
        parts = []
        for m in mags:
            ll = lik.predictive(runs["reported factors", m], np.column_stack(cols), np.eye(len(x)) * sd ** 2)[0]
            parts.append(f"{m:g}: {ll:8.2f}")
        print(f"  predictive log likelihood, factors' sd {sd:g}: " + ", ".join(parts), flush=True)


def unit(lik) -> float:
    """The median sample uncertainty [rad] of the ramps: the unit misfits are printed in."""
    return float(np.median(np.concatenate(list(lik.sigma.values()))))


def misfit(lik, windups):
    """The ramp residual in units of the median sample uncertainty, each ramp's mean removed
    (None when a replay failed: a failed run is reported, never compared)."""
    out, k = [], 0
    r = lik.residual(windups)
    if r is None:
        return None
    for n in lik.lengths():
        seg = r[k:k + n]
        out.append(seg - seg.mean())
        k += n
    return np.concatenate(out) / unit(lik)


def rms(r) -> float:
    """Root mean square of a residual (NaN for a failed replay)."""
    return float("nan") if r is None else float(np.sqrt(np.mean(r ** 2)))


def torsional_of(campaign, workers: int) -> dict:
    """The diagnosis's own torsional likelihood, training rows and points and its calibrated
    factors: the diagnosis (no next-test design) runs its compare and calibration steps and is
    stopped where it hands them to the naming step."""
    seen = {}

    def capture(runner, lik, train, points, jac, starts, failures):
        seen.update(lik=lik, train=train, points=points, x=np.asarray(starts["calibrated"][1], dtype=float))

    S.diagnose_until(campaign, workers, "Namer", capture)
    if not seen:
        raise SystemExit("the diagnosis stopped before its calibration (see its verdict): no torsional comparison")
    return seen


def torsional_cost(runner, tors, system, x) -> float:
    """The calibration's objective (robust loss on the training points with the channels'
    gain and delay fitted, plus the factors' prior) of ``system`` at log factors ``x``, as the
    diagnosis computes it; NaN when a run failed."""
    errs = {}
    y = drive.coefficients_of(runner, calibrated_system(system, x), tors["points"], errs)
    if errs:
        return float("nan")
    return tors["lik"].profile(y, tors["train"])[0] + float(np.sum(np.asarray(x) ** 2)) / PRIOR_LOG_SD ** 2


def ramp_calibration(runner, lik, system, ramps) -> tuple:
    """Gauss-Newton on the six log calibration factors against the ramp residual alone:
    (factors, RMS misfit in sample uncertainties) after ITERATIONS steps (a step that does not
    lower the misfit ends the fit). Each sensitivity step stays within CAL_BOUND (it goes the
    other way at the upper bound); a sensitivity whose replay failed is a zero column, so that
    factor does not move. (None, NaN) when the model's own replay fails."""
    x = np.zeros(len(CALIBRATION))
    r0 = misfit(lik, run_ramps(runner, calibrated_system(system, x), ramps))
    if r0 is None:
        return None, float("nan")
    for _ in range(ITERATIONS):
        steps = np.where(x + STEP <= CAL_BOUND, STEP, -STEP)
        shifted = [calibrated_system(system, x + h * e) for h, e in zip(steps, np.eye(len(x)))]
        outs = runner.map([(drive.diagnosis_system(s), p) for s in shifted for p in ramps])
        cols = []
        for j, h in enumerate(steps):
            w = {p.id: outs[j * len(ramps) + i].get("windup") for i, p in enumerate(ramps)}
            r = misfit(lik, w)
            cols.append(np.zeros_like(r0) if r is None else (r - r0) / h)
        dx = np.linalg.lstsq(np.column_stack(cols), -r0, rcond=None)[0]
        xn = np.clip(x + dx, -CAL_BOUND, CAL_BOUND)
        rn = misfit(lik, run_ramps(runner, calibrated_system(system, xn), ramps))
        if rn is None or rms(rn) >= rms(r0):
            break
        x, r0 = xn, rn
    return x, rms(r0)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("cases", nargs="*", default=["effect/output_backlash/strong/s0"],
                    help="hard-matrix case ids (default effect/output_backlash/strong/s0)")
    ap.add_argument("--effect", default="output_backlash", choices=NAMES, help="effect added to the estimate")
    ap.add_argument("--magnitudes", type=float, nargs="+", default=[0.024, 0.06],
                    help="magnitudes of --effect, in its unit (default 0.024 0.06: free play [rad])")
    ap.add_argument("--torsional", action="store_true",
                    help="also run the diagnosis's compare and calibration steps and print each model's "
                         "torsional objective at the estimate's factors, the calibrated factors and the "
                         "factors fitted to the ramp (whether one set of factors can fit both)")
    ap.add_argument("--factors-from", metavar="FILE",
                    help="a bench_discrepancy.py result file: also replay the ramp at the calibration factors "
                         "its line for the case reports (see the module doc)")
    ap.add_argument("--prediction-sd", type=float, nargs="*", default=[], metavar="SD",
                    help="with --factors-from: standard deviations of the log factors for the ramp's predictive "
                         "log likelihood per magnitude")
    ap.add_argument("--no-ramp-fit", action="store_true",
                    help="leave out the factors fitted to the ramp alone (29 replays per model)")
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args(argv)
    if a.prediction_sd and not a.factors_from:
        ap.error("--prediction-sd needs --factors-from (the factors the prediction is read at)")
    matrix = S.named_cases(ap, a.cases)
    for cid in a.cases:
        case = matrix[cid]
        with tempfile.TemporaryDirectory() as d:
            camp = S.campaign_of(case, os.path.join(d, "campaign"), a.workers)
        ramps = list(camp.ramps)
        tors = torsional_of(camp, a.workers) if a.torsional else None
        truth, without = truth_of(case)
        print(f"{cid}: hidden {case['spec']['effects']}, {len(ramps)} ramp(s)", flush=True)
        est = default_parameters()
        models = {"estimate": est, **{f"estimate + {a.effect} {m:g}": with_effect(est, a.effect,
                                                                                    {info(a.effect).magnitude: m})
                                      for m in a.magnitudes},
                  "truth without its hidden effects": without}
        with drive.Runner(a.workers) as runner:
            base = run_ramps(runner, truth, ramps)
            lik = RampLikelihood(ramps, base, base)  # the channel noise and floor only
            sig = np.degrees(unit(lik))
            print(f"  median sample uncertainty {sig:.4f} deg ({lik.residuals} samples)")

            def show(label, r):
                if r is None:
                    print(f"  {label:48s} the replay failed", flush=True)
                else:
                    print(f"  {label:48s} RMS {rms(r) * sig:7.4f} deg = {rms(r):6.1f} sigma", flush=True)

            show("truth, recorded input", misfit(lik, base))
            clean = [dataclasses.replace(p, input_torque=clean_input(truth, p)) for p in ramps]
            show("truth, its clean input", misfit(lik, {p.id: w for p, w in
                                                        zip(ramps, run_ramps(runner, truth, clean).values())}))
            for label, system in models.items():
                show(label, misfit(lik, run_ramps(runner, system, ramps)))
            if a.factors_from:
                x = reported_factors(a.factors_from, cid)
                print(f"  reported factors {np.round(np.exp(x), 3).tolist()}, "
                      f"truth's {np.round(np.exp(truth_factors(truth, est)), 3).tolist()}", flush=True)
                at_factors(runner, lik, est, a.effect, a.magnitudes, x, truth_factors(truth, est),
                           a.prediction_sd, show)
            fitted = {}
            for label, system in ({} if a.no_ramp_fit else models).items():
                x, e = ramp_calibration(runner, lik, system, ramps)
                fitted[label] = x
                if x is None:
                    print(f"  {label:48s} not fitted to the ramp: its replay failed", flush=True)
                    continue
                print(f"  {label:48s} factors fitted to the ramp {np.round(x, 3).tolist()}: "
                      f"RMS {e * sig:7.4f} deg = {e:6.1f} sigma", flush=True)
            if tors is not None:
                cells = 2 * len(tors["train"]) * len(drive.ORDERS)
                print(f"  torsional objective on {len(tors['train'])} training points ({cells} real residuals), "
                      f"calibrated factors {np.round(tors['x'], 3).tolist()}")
                for label, system in models.items():
                    costs = [float("nan") if x is None else torsional_cost(runner, tors, system, x)
                             for x in (np.zeros(len(CALIBRATION)), tors["x"], fitted.get(label))]
                    at_cal = misfit(lik, run_ramps(runner, calibrated_system(system, tors["x"]), ramps))
                    print(f"  {label:48s} objective at estimate {costs[0]:9.1f}, calibrated {costs[1]:9.1f}, "
                          f"fitted to the ramp {costs[2]:9.1f}; ramp at the calibrated factors "
                          f"{rms(at_cal):6.1f} sigma", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
