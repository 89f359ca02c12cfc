"""What makes up the cell uncertainty of a diagnosis, and what the floor term does to it.

For each named case of the hard benchmark matrix (``bench/bench_discrepancy.py --list``
shows the ids; the campaign is synthesised exactly as that benchmark does, 12 torsional
points of 1 s), the diagnosis's own compare step runs (ten model runs per point) and is
stopped there; printed per case:

* each term's share of the cell variance summed over all cells, and the median over cells
  of its share of the cell's variance (repeatability, discretisation, input channel, uncalibrated
  parameters, mains pick-up, floor;
  :func:`dampersim.discrepancy.likelihood.sigma_variances`);
* per point the RMS of each term [N m].

``--floor F [F ...]`` then runs the whole diagnosis (no next-test design) once per
floor share F (``likelihood.SIGMA_FLOOR_SHARE``) and prints its verdict, posterior and
reduced chi^2 (held out and training), and where the verdict's held-out misfit sits against
the uncertainty terms (:func:`held_out_cells`: per order, and with each term left out, and
:func:`correlated_chi2`: the systematic terms carried as directions, not cell variances): a
whole diagnosis each (697 s for control/none/0 on 2 cores shared with other work, the hard
benchmark's run of it). ``--floor 1e-3`` is the default floor.

    python bench/bench_sigma_terms.py control/none/0
    python bench/bench_sigma_terms.py control/none/0 control/calibration/0 --floor 1e-3 1e-4
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import tempfile
from unittest import mock

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_discrepancy as B  # noqa: E402 - the benchmark's matrix and campaign layout

from dampersim.discrepancy import diagnose as dg  # noqa: E402
from dampersim.discrepancy import drive  # noqa: E402
from dampersim.discrepancy import likelihood  # noqa: E402
from dampersim.discrepancy.campaign import read_campaign  # noqa: E402
from dampersim.discrepancy.fitting import UNCALIBRATED  # noqa: E402
from dampersim.discrepancy.synth import synthesize  # noqa: E402


class _Stop(Exception):
    """Raised by the spy of :func:`diagnose_until` once the diagnosis has made the call watched."""


def campaign_of(case, folder, workers: int):
    spec = case["spec"]
    synthesize(folder, effects=[(n, dict(v)) for n, v in spec["effects"]], perturb=case["perturb"],
               noise_db=case["noise_db"], seed=case["seed"], updates=dict(spec["updates"]) or None,
               points=B.point_ids(12, 1), record=1.0, workers=workers, daq=case["daq"])
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


def whole_diagnosis(camp, workers: int, share: float):
    """The whole diagnosis of ``camp`` (no next-test design) at floor share ``share``: (its
    JSON, :func:`held_out_cells` of the verdict's model, the most probable of the fitted
    models, with a "correlated" key from :func:`correlated_chi2` or the reason it is
    missing; {"error": ...} when the held-out chi^2 cannot be matched)."""
    real_terms, real_chi, real_sets = (likelihood.sigma_variances, likelihood.Likelihood.robust_reduced_chi2,
                                       drive.coefficients_of_sets)
    terms, calls, compare = {}, [], []

    def spy_terms(*args, **kwargs):
        out = real_terms(*args, **kwargs)
        terms.clear()
        terms.update(out)
        return out

    def spy_chi(self, y, rows, nuisance=None):
        value = real_chi(self, y, rows, nuisance)
        calls.append((value, self, y, rows, nuisance))
        return value

    def spy_sets(*args, **kwargs):  # the compare step's four maps come first (diagnose.diagnose, step 1)
        out = real_sets(*args, **kwargs)
        if len(compare) < 4:
            compare.append(out)
        return out

    with (mock.patch.object(likelihood, "SIGMA_FLOOR_SHARE", share),
          mock.patch.object(likelihood, "sigma_variances", spy_terms),
          mock.patch.object(likelihood.Likelihood, "robust_reduced_chi2", spy_chi),
          mock.patch.object(drive, "coefficients_of_sets", spy_sets)):
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
        cells["correlated"] = "not computed: a point was left out, the compare step's rows do not align"
    elif compare[2].shape[1] != 2 * n or compare[3].shape[0] != 2 * len(UNCALIBRATED):
        cells["correlated"] = "not computed: the compare step's maps are not y0, coarse, input, uncalibrated"
    else:
        out = correlated_chi2(terms, compare, lik, y, rows, nuisance)
        cells["correlated"] = {k: round(v, 3) if isinstance(v, float) else {c: round(a, 3) for c, a in v.items()}
                               for k, v in out.items()}
    return d_, cells


def systematic_changes(compare: list, n: int) -> dict:
    """{column name: complex change (points, orders)} of the compare step's systematic terms
    (diagnose step 1's four maps: y0, the coarse model, the input moved up then down, each
    UNCALIBRATED direction moved + then -): the discretisation check y_coarse - y0, the input
    channel's (y_up - y_down) / 2, and per uncalibrated direction its odd part (y+ - y-) / 2
    and even part (y+ + y-) / 2 - y0. The term's cell variance in the diagnosis
    (likelihood.sigma_variances) is |change|^2 for the first two and |odd|^2 + |even|^2 for
    the third, so the columns carry the same sizes as the variances they replace."""
    y0, y_coarse, y_moved, y_unc = (np.asarray(c) for c in compare)
    y0, y_in = y0[0], y_moved[0]
    out = {"model": y_coarse[0] - y0, "input": 0.5 * (y_in[:n] - y_in[n:])}
    for k, name in enumerate(UNCALIBRATED):
        up, down = y_unc[2 * k], y_unc[2 * k + 1]
        out[f"uncalibrated:{name}"] = 0.5 * (up - down)
        out[f"uncalibrated:{name}:even"] = 0.5 * (up + down) - y0
    return out


def correlated_chi2(terms: dict, compare: list, lik, y, rows, nuisance) -> dict:
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
    carry the variance they replace)."""
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

    wc = cols / diag_cell[:, None]
    amp = np.linalg.solve(cols.T @ wc + np.eye(cols.shape[1]), wc.T @ r)
    size = {}
    for term in ("model", "input", "uncalibrated"):
        summed = sum(float(np.sum(np.abs(v[rows]) ** 2)) for k, v in u.items() if k.split(":")[0] == term)
        size[term] = summed / max(float(np.sum(np.asarray(terms[term])[rows])), 1e-300)
    return {"diagonal": chi(diag_all), "global": chi(diag_cell, cols),
            "per_point": chi(diag_cell, np.column_stack(cols_point)), "per_cell_terms_only": chi(diag_cell),
            "amplitudes": dict(zip(u, map(float, amp))), "size": size}


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
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args(argv)
    bad = [f for f in a.floor if not 0.0 < f < 1.0]
    if bad:
        ap.error(f"--floor {bad[0]}: accepted is a share between 0 and 1, both excluded")
    matrix = named_cases(ap, a.cases)
    for cid in a.cases:
        with tempfile.TemporaryDirectory() as d:
            camp = campaign_of(matrix[cid], os.path.join(d, "campaign"), a.workers)
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
                "share_of_summed_variance": {k: round(float(v.sum() / total.sum()), 3) for k, v in var.items()},
                "median_share_per_cell": {k: round(float(np.median(v / total)), 3) for k, v in var.items()},
                "rms_per_point_nm": {pid: {k: round(float(np.sqrt(v[i].mean())), 4) for k, v in var.items()}
                                     for i, pid in enumerate(ids)}}), flush=True)
            for share in a.floor:
                d_, cells = whole_diagnosis(camp, a.workers, share)
                lk = d_["likelihood"]
                print(json.dumps({"case": cid, "floor_share": share, "verdict": d_["verdict"],
                                  "posterior": {k: round(v, 3) for k, v in d_["posterior"].items() if v >= 0.001},
                                  "reduced_chi2_held_out": lk["reduced_chi2_held_out"],
                                  "reduced_chi2_train": lk["reduced_chi2_train"],
                                  "simulations": d_["simulations"], "held_out_cells": cells}), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
