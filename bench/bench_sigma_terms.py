"""What makes up the cell uncertainty of a diagnosis, and what the floor term does to it.

For each named case of the hard benchmark matrix (``bench/bench_discrepancy.py --list``
shows the ids; the campaign is synthesised exactly as that benchmark does, 12 torsional
points of 1 s), the diagnosis's own compare step runs (ten model runs per point) and is
stopped there; printed per case:

* each term's share of the cell variance summed over all cells, and the median over cells
  of its share of the cell's variance (repeatability, discretisation, input channel, uncalibrated
  parameters, mains pick-up, floor;
  :func:`dampersim.discrepancy.likelihood.sigma_variances`);
* per point the RMS of each term [N m];
* the truth's coordinate along each direction the calibration cannot follow, in standard
  uncertainties (:func:`truth_coordinates`; the correlated reading below prints what its
  fitted amplitudes would be on average if the residuals were these changes alone).

``--floor F [F ...]`` then runs the whole diagnosis (no next-test design) once per
floor share F (``likelihood.SIGMA_FLOOR_SHARE``) and prints its verdict, posterior and
reduced chi^2 (held out and training), and where the verdict's held-out misfit sits against
the uncertainty terms (:func:`held_out_cells`: per order, and with each term left out, and
:func:`correlated_chi2`: the systematic terms carried as directions, not cell variances): a
whole diagnosis each (697 s for control/none/0 on 2 cores shared with other work, the hard
benchmark's run of it). ``--floor 1e-3`` is the default floor. The correlated reading
prints the fitted amplitudes with their posterior standard deviations and a check of their
size against their prior (:func:`prior_check`). ``--rig`` adds the rig's parts as further
directions (:func:`rig_directions`, each at ``--rig-sd``; two runs per point and direction
after the diagnosis) with the truth's coordinates along them.

    python bench/bench_sigma_terms.py control/none/0
    python bench/bench_sigma_terms.py control/none/0 control/calibration/0 --floor 1e-3 1e-4
    python bench/bench_sigma_terms.py control/rig_stiff_parts/1 --floor 1e-3 --rig
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import sys
import tempfile
from unittest import mock

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_discrepancy as B  # noqa: E402 - the benchmark's matrix and campaign layout

from dampersim.discrepancy import diagnose as dg  # noqa: E402
from dampersim.discrepancy import drive  # noqa: E402
from dampersim.discrepancy import likelihood, model_terms  # noqa: E402
from dampersim.discrepancy.campaign import read_campaign  # noqa: E402
from dampersim.discrepancy.fitting import ESTIMATE_LOG_SD, UNCALIBRATED, direction_step, uncalibrated_systems  # noqa: E402
from dampersim.discrepancy.synth import synthesize  # noqa: E402
from dampersim.parameters import default_parameters  # noqa: E402
from dampersim.parameters.io import named_values  # noqa: E402


#: standard uncertainty (log) of each rig part's estimate when ``--rig`` carries the rig's
#: parts as directions: an assumption of this bench, not a measured figure (the thesis gives
#: the rig's shafts and inertias without an uncertainty). The hard matrix's rig control draws
#: its stiff shafts 10-20 % and the motor's inertia 5-10 % off (truths.control); the fitted
#: amplitudes are printed in units of this value
RIG_LOG_SD = 0.1


def rig_directions(system) -> dict:
    """{direction: {dotted parameter: weight}} of the rig's estimated parts, one parameter
    each: the gearbox's shaft and inertia, the shafts of the stiff parts between the gearbox
    and the output motor (flanges, transducer, coupling) and the output motor's inertia. The
    output motor's own shaft (its coupling to the chain, 1.5 MN m/rad) is not among them, as
    the hard matrix's rig control leaves it as estimated; the figures docs/discrepancy.md
    quotes were measured with these seven."""
    els = system.rig.elements
    out = {f"rig:{els[0].name}_stiffness": {f"rig.elements.{els[0].name}.shaft_stiffness": 1.0},
           f"rig:{els[0].name}_inertia": {f"rig.elements.{els[0].name}.inertia": 1.0}}
    for e in els[1:-1]:
        out[f"rig:{e.name}_stiffness"] = {f"rig.elements.{e.name}.shaft_stiffness": 1.0}
    out[f"rig:{els[-1].name}_inertia"] = {f"rig.elements.{els[-1].name}.inertia": 1.0}
    return out


def truth_coordinates(applied: dict, system, directions: dict, log_sd: float) -> dict:
    """{direction: the truth's coordinate along it, in standard uncertainties}: the truth's log
    changes against ``system`` (``applied``: dotted parameter -> the truth's value, as
    synthesize reports them; parameters it does not name are the system's own) projected on
    each direction's move of :func:`dampersim.discrepancy.fitting.uncalibrated_systems`
    (:func:`dampersim.discrepancy.fitting.direction_step` times the weights w, each +-1). Not what the fitted amplitudes
    should read: those are posterior means, shrunk where the data see a direction weakly
    (:func:`correlated_chi2`'s "truth_expected" applies that shrinkage), and the verdict's
    model is calibrated, so the calibration factors may have taken up part of a direction's
    change of the orders."""
    base = named_values(system)
    out = {}
    for name, w in directions.items():
        step = direction_step(w, log_sd)
        t = {n: math.log(float(applied.get(n, base[n])) / float(base[n])) for n in w if n in base}
        out[name] = sum(w[n] * t[n] for n in t) / (step * sum(w[n] ** 2 for n in t)) if t else math.nan
    return out


class _Stop(Exception):
    """Raised by the spy of :func:`diagnose_until` once the diagnosis has made the call watched."""


def campaign_of(case, folder, workers: int, truth: dict | None = None, points=None):
    """The case's campaign, synthesised into ``folder`` as the hard benchmark does (its 12
    torsional points and one ramp, or the point ids ``points``: a record's noise and
    acquisition stream follow its place in that list); ``truth``, when a dict is given,
    receives the synthesis's account of the truth
    (:func:`dampersim.discrepancy.synth.synthesize`'s return, "perturbed" among it)."""
    spec = case["spec"]
    doc = synthesize(folder, effects=[(n, dict(v)) for n, v in spec["effects"]], perturb=case["perturb"],
                     noise_db=case["noise_db"], seed=case["seed"], updates=dict(spec["updates"]) or None,
                     points=B.point_ids(12, 1) if points is None else points, record=1.0, workers=workers, daq=case["daq"])
    if truth is not None:
        truth.update(doc)
    return read_campaign(folder)


def named_cases(ap, ids) -> dict:
    """{id: case} of the hard matrix for the case ids asked for; an unknown id is the parser's error."""
    matrix = {c["id"]: c for c in B.hard_cases()}
    unknown = [c for c in ids if c not in matrix]
    if unknown:
        ap.error(f"unknown case(s) {', '.join(unknown)}: see python bench/bench_discrepancy.py --list")
    return matrix


def diagnose_until(camp, workers: int, name: str, capture) -> None:
    """Run the diagnosis of ``camp`` (no next-test design) until it calls ``name`` of
    :mod:`dampersim.discrepancy.diagnose`: ``capture`` gets that call's arguments, then the
    diagnosis stops (it returns normally when it ends before that call, e.g. not diagnosed)."""
    def spy(*args, **kwargs):
        capture(*args, **kwargs)
        raise _Stop

    with mock.patch.object(dg, name, spy), contextlib.suppress(_Stop):
        dg.diagnose(camp, workers=workers, recommend=False)


def terms_of(camp, workers: int) -> dict:
    """The variances diagnose's compare step passes to cell_sigma, by term."""
    seen = {}
    diagnose_until(camp, workers, "cell_sigma", lambda *a, **k: seen.update(likelihood.sigma_variances(*a, **k)))
    return seen


def whole_diagnosis(camp, workers: int, share: float, directions: dict | None = None, log_sd: float = RIG_LOG_SD,
                    truth: dict | None = None):
    """The whole diagnosis of ``camp`` (no next-test design) at floor share ``share``: (its
    JSON, :func:`held_out_cells` of the verdict's model, the most probable of the fitted
    models, with a "correlated" key from :func:`correlated_chi2` or the reason it is
    missing; {"error": ...} when the held-out chi^2 cannot be matched). ``directions``
    ({name: {dotted parameter: weight}}, e.g. :func:`rig_directions`) are carried as further
    columns at standard uncertainty ``log_sd`` (:func:`direction_changes`, two runs per point
    and direction after the diagnosis); ``truth``: :func:`truth_coordinates` for
    :func:`correlated_chi2`."""
    real_terms, real_chi = likelihood.sigma_variances, likelihood.Likelihood.robust_reduced_chi2
    real_uncertainty, real_measure = dg.uncertainty, model_terms.measure
    terms, calls, compare, measured = {}, [], [], []

    def spy_terms(*args, **kwargs):
        out = real_terms(*args, **kwargs)
        terms.clear()
        terms.update(out)
        return out

    def spy_chi(self, y, rows, nuisance=None):
        value = real_chi(self, y, rows, nuisance)
        calls.append((value, self, y, rows, nuisance))
        return value

    def spy_uncertainty(repeat, meas_c, mains, t, rows=slice(None)):
        # the model terms of the cell uncertainty: the last call's are the verdict's (at the
        # calibrated factors when the calibration moved them; diagnose, step 2b)
        compare[:] = compare_maps(t.at(np.arange(len(t.y))[rows]))
        return real_uncertainty(repeat, meas_c, mains, t, rows)

    def spy_measure(runner, system, points, y):
        measured.append((system, list(points), np.array(y)))
        return real_measure(runner, system, points, y)

    with (mock.patch.object(likelihood, "SIGMA_FLOOR_SHARE", share),
          mock.patch.object(likelihood, "sigma_variances", spy_terms),
          mock.patch.object(likelihood.Likelihood, "robust_reduced_chi2", spy_chi),
          mock.patch.object(dg, "uncertainty", spy_uncertainty),
          mock.patch.object(model_terms, "measure", spy_measure)):
        d_ = dg.diagnose(camp, workers=workers, recommend=False).to_json()
    top = d_["likelihood"]["reduced_chi2_held_out"]
    # the verdict's call: the last whose value is the one the document reports (every call is
    # on the held-out rows; the verdict's comes after the fitted models' own)
    verdict_calls = [c for c in calls if top is not None and c[0] == top]
    if not verdict_calls or not terms:
        return d_, {"error": "the diagnosis reported no held-out chi^2 this bench could match"}
    _, lik, y, rows, nuisance = verdict_calls[-1]
    cells = held_out_cells(terms, lik, y, rows, nuisance)
    n = len(lik.meas)
    if len(compare) < 4 or compare[0].shape[1] != n:
        cells["correlated"] = "not computed: the verdict's model terms do not align with its likelihood's rows"
    elif compare[2].shape[1] != 2 * n or compare[3].shape[0] != 2 * len(UNCALIBRATED):
        cells["correlated"] = "not computed: the model terms' maps are not y0, coarse, input, uncalibrated"
    elif directions and (not measured or len(measured[-1][1]) != n):
        cells["correlated"] = "not computed: a point was left out, the extra directions' rows would not align"
    else:
        extra = None
        if directions:
            # at the set and points the verdict's terms were last measured at, against that set's own
            # coefficients (NaN where its run failed: no change is read there)
            system, points, y_set = measured[-1]
            extra, failed = direction_changes(points, y_set, directions, log_sd, workers, system)
            cells["extra_failed_runs"] = failed
        cells["correlated"] = _rounded(correlated_chi2(terms, compare, lik, y, rows, nuisance, extra, truth))
    return d_, cells


def _rounded(x, digits: int = 3):
    if isinstance(x, dict):
        return {k: _rounded(v, digits) for k, v in x.items()}
    return round(x, digits) if isinstance(x, float) else x


def _odd_even(name: str, up, down, y0) -> dict:
    """The odd part (up - down) / 2 and the even part (up + down) / 2 - y0 of a direction moved
    up and down, as columns ``name`` and ``name:even``."""
    return {name: 0.5 * (up - down), f"{name}:even": 0.5 * (up + down) - y0}


def compare_maps(t) -> list:
    """The four maps :func:`systematic_changes` reads, from a
    :class:`~dampersim.discrepancy.model_terms.ModelTerms`: y, the coarse model, the input moved
    up then down, each UNCALIBRATED direction moved + then -."""
    return [t.y[None], t.coarse[None], np.concatenate([t.input_up, t.input_down])[None], np.asarray(t.uncalibrated)]


def direction_changes(points, y0, directions: dict, log_sd: float, workers: int, system=None):
    """({column: complex change (points, orders)}, failed runs): each direction's odd and even
    parts (:func:`_odd_even`) from the model moved ``log_sd`` up and down along it
    (:func:`dampersim.discrepancy.fitting.uncalibrated_systems`) at ``system`` (the set the
    verdict's model terms were measured at, :func:`whole_diagnosis`; the default set when
    None), driven by each torsional point of ``points`` as the diagnosis drives it; ``y0`` is
    that set's map. A failed run's cells are NaN (read as no change by :func:`correlated_chi2`) and
    counted."""
    moved = uncalibrated_systems(system or default_parameters(), directions, log_sd)
    with drive.Runner(workers) as runner:
        maps = drive.coefficients_of_sets(runner, [s for _, pair in moved for s in pair], points)
    out = {}
    for k, (name, _) in enumerate(moved):
        out.update(_odd_even(name, maps[2 * k], maps[2 * k + 1], y0))
    return out, int(np.sum(np.isnan(maps).any(axis=2)))


def systematic_changes(compare: list, n: int) -> dict:
    """{column name: complex change (points, orders)} of the verdict's model terms
    (:func:`compare_maps`: y0, the coarse model, the input moved up then down, each
    UNCALIBRATED direction moved + then -): the discretisation check y_coarse - y0, and for
    the input channel and per uncalibrated direction the odd part (y+ - y-) / 2 and even part
    (y+ + y-) / 2 - y0 of the move. The term's cell variance in the diagnosis
    (likelihood.sigma_variances, model_terms) is |change|^2 for the first and
    |odd|^2 + |even|^2 summed over the directions for the others, so the columns carry the
    same sizes as the variances they replace."""
    y0, y_coarse, y_moved, y_unc = (np.asarray(c) for c in compare)
    y0, y_in = y0[0], y_moved[0]
    out = {"model": y_coarse[0] - y0, **_odd_even("input", y_in[:n], y_in[n:], y0)}
    for k, name in enumerate(UNCALIBRATED):
        out.update(_odd_even(f"uncalibrated:{name}", y_unc[2 * k], y_unc[2 * k + 1], y0))
    return out


def posterior_amplitudes(cols, diag, r):
    """(posterior mean, posterior covariance) of the amplitudes a of columns ``cols`` (real,
    cells x columns) under a unit prior, for residuals r = cols a + e, e of variance ``diag``
    per cell: ((U^T D^-1 U + I)^-1 U^T D^-1 r, (U^T D^-1 U + I)^-1)."""
    wc = cols / diag[:, None]
    cov = np.linalg.inv(cols.T @ wc + np.eye(cols.shape[1]))
    return cov @ (wc.T @ r), cov


def prior_check(amp, cov, cutoff: float = 0.05) -> dict:
    """Are the posterior means ``amp`` as large as their unit prior makes them? If each
    amplitude is drawn from its prior, the posterior mean has covariance I - C (C the posterior
    covariance): "rms" of the means against "expected_rms" (the root mean of 1 - C_ii), and
    "per_dof", amp^T (I - C)^+ amp over the "dof" eigen-directions of I - C above ``cutoff``
    (those the data determine; below it, a mean carries almost nothing of its prior): about 1,
    within sqrt(2 / dof), when the columns' sizes are honest; far below 1 when the terms are
    wider than what the residuals realise of them."""
    lam, vec = np.linalg.eigh(np.eye(len(amp)) - cov)
    keep = lam > cutoff
    q = float(np.sum((vec[:, keep].T @ amp) ** 2 / lam[keep]))
    dof = int(keep.sum())
    return {"rms": float(np.sqrt(np.mean(amp ** 2))), "expected_rms": float(np.sqrt(np.mean(1.0 - np.diag(cov)))),
            "dof": dof, "per_dof": q / dof if dof else math.nan}


def truth_expected(names: list, cov, truth: dict) -> dict:
    """{column: (I - C) t}: the mean of the posterior amplitudes (columns ``names``, posterior
    covariance ``cov``) if the residual were the columns times amplitudes t plus noise, t the
    truth's coordinate for a direction's odd column ("uncalibrated:NAME" or a rig direction's
    own name, :func:`truth_coordinates`) and 0 for every other column (the discretisation
    check, the input channel and the even parts, whose truth is not known: an assumption).
    E[posterior mean | t] = C U^T D^-1 U t = (I - C) t."""
    t = np.array([truth.get(c.removeprefix("uncalibrated:"), 0.0) if not c.endswith(":even") else 0.0
                  for c in names])
    return dict(zip(names, map(float, (np.eye(len(names)) - cov) @ np.nan_to_num(t))))


def correlated_chi2(terms: dict, compare: list, lik, y, rows, nuisance, extra: dict | None = None,
                    truth: dict | None = None) -> dict:
    """The verdict's held-out reduced chi^2 with the systematic terms (discretisation check,
    input channel, uncalibrated directions) carried as changes of the model's coefficients
    (:func:`systematic_changes`) instead of as independent cell variances: covariance
    D + sum u u^T over the columns u, D the per-cell terms (repeatability and mains pick-up,
    measured; the floor, assumed), half on each of the real and imaginary parts. A unit prior
    on each column's amplitude makes this the marginal of fitting the amplitudes (and equal
    to the profile: min over a of |r - U a|^2_D + |a|^2). "global": one amplitude per column
    for the whole campaign (an assumption: the input channel's move mixes an offset and a
    gain, the discretisation check also carries the scatter of chaotic orders, an even part
    is second order in its odd part's parameter error but gets an amplitude of its own);
    "per_point": one per column and point; "per_cell_terms_only": D alone; "diagonal": the
    diagnosis's own form (every term on the diagonal), which reproduces
    :func:`held_out_cells`'s figure. Also returned: "amplitudes", the global form's fitted
    amplitude of each column (the posterior mean (U^T D^-1 U + I)^-1 U^T D^-1 r; for a term
    drawn from its prior the expected square of a posterior mean is 1 less its posterior
    variance), and "size", each term's summed |u|^2 over the held-out cells against its
    summed variance in ``terms`` (1 where the columns, before the channels' gain and delay,
    carry the variance they replace); "amplitude_sd", the posterior standard deviation of
    each, and "amplitude_check", :func:`prior_check`. ``extra`` ({column: complex change
    (points, orders)}, e.g. :func:`direction_changes`) adds "global_with_extra" and the same
    three readings "..._with_extra" with those columns beside the others. ``truth``
    ({direction: coordinate}, :func:`truth_coordinates`) adds "truth_expected" (and
    "truth_expected_with_extra"), :func:`truth_expected`."""
    n = len(lik.meas)
    u = systematic_changes(compare, n)

    def real(z):  # complex (points, orders) at the held-out rows, after the channels' gain and delay
        t = lik.transform(np.nan_to_num(z[rows]), rows, nuisance)
        return np.concatenate([t.real.ravel(), t.imag.ravel()])

    d = held_out_residual(lik, y, rows, nuisance)
    r = np.concatenate([d.real.ravel(), d.imag.ravel()])
    diag_all = np.tile(0.5 * sum(np.asarray(v)[rows] for v in terms.values()).ravel(), 2)
    diag_cell = np.tile(0.5 * sum(np.asarray(terms[k])[rows] for k in ("repeat", "mains", "floor")).ravel(), 2)
    cols = np.column_stack([real(v) for v in u.values()])
    cols_point = []
    for v in u.values():
        for j in range(len(rows)):
            w = np.zeros_like(v)
            w[rows[j]] = v[rows[j]]
            cols_point.append(real(w))

    def chi(diag, c=None):
        cov = np.diag(diag) if c is None else np.diag(diag) + c @ c.T
        return float(r @ np.linalg.solve(cov, r) / len(r))

    def global_reading(c, names):  # one amplitude per column for the whole campaign
        amp, cov = posterior_amplitudes(c, diag_cell, r)
        got = {"global": chi(diag_cell, c), "amplitudes": dict(zip(names, map(float, amp))),
               "amplitude_sd": dict(zip(names, map(float, np.sqrt(np.diag(cov))))),
               "amplitude_check": prior_check(amp, cov)}
        if truth is not None:
            got["truth_expected"] = truth_expected(names, cov, truth)
        return got

    size = {}
    for term in ("model", "input", "uncalibrated"):
        summed = sum(float(np.sum(np.abs(v[rows]) ** 2)) for k, v in u.items() if k.split(":")[0] == term)
        size[term] = summed / max(float(np.sum(np.asarray(terms[term])[rows])), 1e-300)
    out = {"diagonal": chi(diag_all), **global_reading(cols, list(u)),
           "per_point": chi(diag_cell, np.column_stack(cols_point)), "per_cell_terms_only": chi(diag_cell),
           "size": size}
    if extra:
        both = np.column_stack([cols] + [real(v) for v in extra.values()])
        out.update({f"{k}_with_extra": v for k, v in global_reading(both, [*u, *extra]).items()})
    return out


def held_out_residual(lik, y, rows, nuisance) -> np.ndarray:
    """Measured minus model coefficients [N m] at ``rows`` after the channels' gain and delay."""
    return lik.meas[rows] - lik.transform(y, rows, nuisance)


def held_out_cells(terms: dict, lik, y, rows, nuisance) -> dict:
    """Where the held-out misfit of the verdict's model sits against its uncertainty terms:
    the plain reduced chi^2 (|residual|^2 / sigma^2 per cell, averaged; the diagnosis reports
    the robust one, equal when no held-out point is down-weighted) over all held-out cells and
    per order, the RMS residual and sigma per order [N m], each term's RMS per order over the
    held-out cells [N m], the median share of each term in the held-out cells' variance, and
    the reduced chi^2 the same residuals would have with each term left out of sigma (the
    residuals as fitted, not refitted)."""
    d2 = np.abs(held_out_residual(lik, y, rows, nuisance)) ** 2
    var = {k: np.asarray(v)[rows] for k, v in terms.items()}
    total = sum(var.values())
    orders = [int(k) for k in lik.orders]
    return {"reduced_chi2": round(float(np.mean(d2 / total)), 3),
            "per_order": {k: round(float(np.mean(d2[:, j] / total[:, j])), 3) for j, k in enumerate(orders)},
            "rms_residual_nm": {k: round(float(np.sqrt(d2[:, j].mean())), 4) for j, k in enumerate(orders)},
            "rms_sigma_nm": {k: round(float(np.sqrt(total[:, j].mean())), 4) for j, k in enumerate(orders)},
            "rms_term_nm": {t: {k: round(float(np.sqrt(v[:, j].mean())), 4) for j, k in enumerate(orders)}
                            for t, v in var.items()},
            "median_share": {k: round(float(np.median(v / total)), 3) for k, v in var.items()},
            "without": {k: round(float(np.mean(d2 / np.maximum(total - v, 1e-300))), 3) for k, v in var.items()}}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("cases", nargs="*", default=["control/none/0"], help="hard-matrix case ids (default control/none/0)")
    ap.add_argument("--floor", nargs="*", type=float, default=[], help="floor shares to run the whole diagnosis with")
    ap.add_argument("--rig", action="store_true",
                    help="with --floor: also carry the rig's parts (rig_directions) as columns of the correlated reading")
    ap.add_argument("--rig-sd", type=float, default=RIG_LOG_SD,
                    help=f"standard uncertainty (log) of each rig part for --rig (default {RIG_LOG_SD})")
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args(argv)
    bad = [f for f in a.floor if not 0.0 < f < 1.0]
    if bad:
        ap.error(f"--floor {bad[0]}: accepted is a share between 0 and 1, both excluded")
    if not 0.0 < a.rig_sd <= 1.0:
        ap.error(f"--rig-sd {a.rig_sd}: accepted is a log standard uncertainty above 0 and at most 1")
    matrix = named_cases(ap, a.cases)
    base = default_parameters()
    rig = rig_directions(base) if a.rig else None
    for cid in a.cases:
        with tempfile.TemporaryDirectory() as d:
            truth = {}
            camp = campaign_of(matrix[cid], os.path.join(d, "campaign"), a.workers, truth)
            coords = truth_coordinates(truth["perturbed"], base, UNCALIBRATED, ESTIMATE_LOG_SD)
            if rig:
                coords.update(truth_coordinates(truth["perturbed"], base, rig, a.rig_sd))
            var = terms_of(camp, a.workers)
            if not var:
                print(json.dumps({"case": cid, "error": "the diagnosis stopped before its cell uncertainty"}))
                continue
            total = sum(var.values())
            ids = [p.id for p in camp.torsional]
            if len(ids) != len(total):  # points whose runs failed were left out: rows by index
                ids = [f"kept point {i}" for i in range(len(total))]
            print(json.dumps({
                "case": cid, "floor_share": likelihood.SIGMA_FLOOR_SHARE,
                "truth_coordinates": {k: round(v, 3) for k, v in coords.items()},
                "share_of_summed_variance": {k: round(float(v.sum() / total.sum()), 3) for k, v in var.items()},
                "median_share_per_cell": {k: round(float(np.median(v / total)), 3) for k, v in var.items()},
                "rms_per_point_nm": {pid: {k: round(float(np.sqrt(v[i].mean())), 4) for k, v in var.items()}
                                     for i, pid in enumerate(ids)}}), flush=True)
            for share in a.floor:
                d_, cells = whole_diagnosis(camp, a.workers, share, rig, a.rig_sd, coords)
                lk = d_["likelihood"]
                print(json.dumps({"case": cid, "floor_share": share, "verdict": d_["verdict"],
                                  "posterior": {k: round(v, 3) for k, v in d_["posterior"].items() if v >= 0.001},
                                  "reduced_chi2_held_out": lk["reduced_chi2_held_out"],
                                  "reduced_chi2_train": lk["reduced_chi2_train"], "learning_rate": lk["learning_rate"],
                                  "calibration_taken_from": lk["calibration_taken_from"],
                                  "simulations": d_["simulations"], "wall_time_s": round(d_["wall_time_s"]),
                                  "held_out_cells": cells}), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
