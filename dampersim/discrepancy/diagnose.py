"""The discrepancy workflow: compare -> calibrate -> name -> augment -> show.

The data are the complex output orders 1-8 of every torsional point, compared with the
model driven by the same measured input (:mod:`dampersim.discrepancy.likelihood`: weights
from split-record repeatability, the model's discretisation, its change under the input
channel's zero and gain uncertainty and the mains pick-up (:mod:`dampersim.discrepancy.pickup`);
channel gain and delay fitted; robust loss). The calibration (six log scale factors under a prior) and every
candidate model are fitted on the training points; the models ("none", each effect,
pairs) are weighed by Laplace evidence (:mod:`dampersim.discrepancy.selection`); the
verdict asks whether the most probable model brings the misfit on held-out points (every
third torsional point, never fitted) to the noise level, and adopts an effect only when its
posterior is decisive (:func:`decide`). A failed model run is never a
match: its point is left out (listed under ``problems``), its trial rejected, its candidate
not ranked. A campaign that cannot be diagnosed gets the verdict ``insufficient_data``.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from dampersim.discrepancy import (design, drive, fitting, intervals, model_terms, partner, pickup, ramp_models,
                                   selection)
from dampersim.discrepancy import unnamed as misfit
from dampersim.discrepancy import ramps as ramps_lik
from dampersim.discrepancy.effects import NAMES, info, with_effect
from dampersim.discrepancy.fitting import (CAL_BOUND, CAL_SCAN, CAL_STEP_FRACTIONS, CALIBRATION, COARSE_SEGMENTS,
                                           ESTIMATE_LOG_SD, GAIN_TOLERANCE, PRIOR_LOG_SD, REFINE_EVALUATIONS, UNCALIBRATED,
                                           _effect_grid, _lstsq_bounded, _resid, _rms, calibrated_system,
                                           first_lower)
from dampersim.discrepancy.likelihood import (Likelihood, cell_sigma, measured_coefficients,
                                              residual_half_sigma, split_half_sigma)
from dampersim.discrepancy.naming import Namer
from dampersim.discrepancy.outcome import (INSUFFICIENT, MIN_SPEEDS, MIN_TORSIONAL_POINTS, SAME_SPEED_SHARE,
                                           Diagnosis, _not_diagnosed, _verdict_message, decide, locate,
                                           recalibration_trigger, shortfall, speeds_of)
from dampersim.discrepancy.tracking import point_orders
from dampersim.errors import InputError
from dampersim.parameters import default_parameters

#: the record terms of the cell uncertainty diagnose accepts (its ``repeatability`` argument)
REPEATABILITY = ("split_half", "residual")
#: reduced chi^2 on held-out points that counts as the noise level (the issue's criterion);
#: with few held-out residuals the 99 % quantile of chi^2 per degree of freedom is allowed
CHI2_NOISE = 1.5


def held_out_indices(n_points: int) -> list:
    """Indices of the held-out torsional points among ``n_points`` kept ones: every third,
    from the second (the others are the training points)."""
    return [i for i in range(n_points) if i % 3 == 1]


def noise_level(dof: int) -> float:
    """Reduced chi^2 at the noise level for ``dof`` real residuals: CHI2_NOISE, or the 99 %
    quantile of chi^2/dof where that is larger (few residuals scatter more)."""
    from scipy.stats import chi2

    return max(CHI2_NOISE, float(chi2.ppf(0.99, max(1, dof)) / max(1, dof)))


def uncertainty(repeat, meas_c, mains, terms, rows=slice(None)) -> tuple:
    """(complex standard deviation of every cell [N m], the displayed noise floor [N m]) from
    the record terms ``repeat`` and ``mains`` and the model terms ``terms``
    (:class:`~dampersim.discrepancy.model_terms.ModelTerms`) at its ``rows``. The floor is the
    root sum of squares of each term's RMS over the campaign with the channels' gain tolerance:
    for display; the verdict uses the likelihood."""
    model, inp, unc = (np.asarray(a)[rows] for a in (terms.model_change, terms.input_change, terms.uncalibrated_change))
    floor = math.sqrt(_rms(repeat) ** 2 + (GAIN_TOLERANCE * _rms(np.abs(meas_c))) ** 2 + _rms(model) ** 2
                      + _rms(inp) ** 2 + _rms(unc) ** 2 + _rms(mains) ** 2)
    return cell_sigma(repeat, model, meas_c, mains, inp, unc), floor


def diagnose(campaign, system=None, workers: int | None = None, progress=None, candidates=None,
             calibration_iterations: int = 6, shortlist: int = 3, recommend: bool = True,
             repeatability: str = "split_half") -> Diagnosis:
    """Run the whole workflow on a :class:`~dampersim.discrepancy.campaign.Campaign`.

    system: the parameter set to diagnose (default set if None); progress(fraction, text)
    is called between steps; candidates: effect names to consider (default all);
    recommend: rank next test points (simulates candidate points); repeatability: the cell
    uncertainty's record term, ``"split_half"`` (the measured output's own halves,
    :func:`~dampersim.discrepancy.likelihood.split_half_sigma`) or ``"residual"`` (the
    halves' residuals against the model as given,
    :func:`~dampersim.discrepancy.likelihood.residual_half_sigma`; docs/discrepancy.md says
    why it is not the default). A campaign that cannot be diagnosed gives the verdict
    INSUFFICIENT (see :func:`shortfall`).
    """
    if repeatability not in REPEATABILITY:
        raise InputError(f"repeatability {repeatability!r}: accepted is one of {', '.join(REPEATABILITY)}")

    t0 = time.perf_counter()
    system = system or default_parameters()
    cands = list(candidates or NAMES)
    report = progress or (lambda f, s: None)
    problems = [{"file": q.file, "field": q.field, "point": q.point, "message": q.message} for q in campaign.problems]
    every = campaign.torsional
    missing, message = shortfall(every, len(campaign.ramps))
    if missing:
        return _not_diagnosed(system, missing, message, problems, 0, t0)
    meas_c = np.array([measured_coefficients(p, drive.ORDERS) for p in every])
    with drive.Runner(workers) as runner:
        # 1) compare
        report(0.02, "compare: driving the model with every measured input torque")
        err0, halves0 = {}, ({} if repeatability == "residual" else None)
        y0 = drive.coefficients_of(runner, system, every, err0, halves0)
        if halves0 is None:
            repeat = np.array([split_half_sigma(p, drive.ORDERS) for p in every])
        else:  # the residual's halves (a failed run's point is left out below)
            repeat = np.array([residual_half_sigma(p, halves0[i], drive.ORDERS) if i in halves0
                               else np.full(len(drive.ORDERS), np.nan) for i, p in enumerate(every)])
        # the model-based terms at the set as given (model_terms): the discretisation check (two
        # thirds of the segments; for first-order convergence in 1/N that change is half the
        # model's own discretisation error: a scale, not a correction), the input channel's
        # zero and gain (likelihood.input_mean_sd) and what the calibration cannot follow
        # (fitting.UNCALIBRATED); measured again at the calibrated set below
        terms0 = model_terms.measure(runner, system, every, y0)
        err_coarse, err_in, err_unc = (terms0.errors[k] for k in ("coarse", "input", "uncalibrated"))
        sd_in = terms0.input_sd
        left_out = {i: f"the model run with the parameter set as given failed ({err0[i]})" if i in err0 else
                    f"the discretisation check (two thirds of the spring segments) failed ({err_coarse[i]})"
                    if i in err_coarse else f"the input check (input moved by {sd_in[i]:.3g} N m) failed ({err_in[i]})"
                    if i in err_in else f"the check of what the calibration cannot follow (the estimated parameters "
                    f"moved by {100 * ESTIMATE_LOG_SD:.0f} %) failed ({err_unc[i]})"
                    for i in sorted({*err0, *err_coarse, *err_in, *err_unc})}
        problems += [drive.run_problem(every[i], f"{why}; the point is left out of the calibration, the effect fits and "
                                       "the verdict") for i, why in left_out.items()]
        keep = [i for i in range(len(every)) if i not in left_out]
        pts = [every[i] for i in keep]
        missing, message = shortfall(pts, len(campaign.ramps), [every[i].id for i in left_out])
        if missing:
            return _not_diagnosed(system, missing, message, problems, runner.count, t0)
        y0, meas_c, repeat = y0[keep], meas_c[keep], repeat[keep]
        meas = np.abs(meas_c)
        held = held_out_indices(len(pts))
        train = [i for i in range(len(pts)) if i not in held]
        ptr = [pts[i] for i in train]
        mains = pickup.pickup_sigma(pts, drive.ORDERS)
        sigma, floor = uncertainty(repeat, meas_c, mains, terms0, keep)
        lik = Likelihood(meas_c, sigma, [p.speed for p in pts], drive.ORDERS)

        def cost(y, x):
            return lik.profile(y, train)[0] + float(np.sum(np.asarray(x) ** 2)) / PRIOR_LOG_SD ** 2

        def coeffs(s, points, errors=None):
            return drive.coefficients_of(runner, s, points, errors)

        def sensitivities(dy, h, x, y):
            """d coefficients / d log factor at x from steps h (into dy, one map for all factors),
            standardised per column. A failed derivative run gives no direction (0), never a fit."""
            shifted = [calibrated_system(system, x + h * e) for e in np.eye(len(x))]
            dy[:] = np.nan_to_num((drive.coefficients_of_sets(runner, shifted, ptr) - y) / h, nan=0.0)
            return columns(dy)

        def joined(y_train, y_held):
            """Coefficients of every kept point from those of the training and held-out points."""
            y = np.zeros_like(y0)
            y[train], y[held] = y_train, y_held
            return y

        def on_held_out(x):
            """The calibrated system at log factors x, the held-out points' run failures {index in held:
            message} and their coefficients."""
            s, errors = calibrated_system(system, x), {}
            return s, errors, coeffs(s, [pts[i] for i in held], errors)

        def trial_at(xn):
            """The calibrated model at log factors xn on the training points: (objective, xn, coefficients)."""
            yn = coeffs(calibrated_system(system, xn), ptr)
            return cost(yn, xn), xn, yn

        def columns(dy):
            return np.column_stack([lik.vec(dy[k], train) for k in range(len(dy))])

        # 2) calibrate (Gauss-Newton on log scale factors, training points only), from the
        # best point of a coarse scan of each factor alone: near a resonance the order
        # response is so non-linear in a stiffness that Gauss-Newton from the estimate can
        # stall in a local minimum. A trial whose run fails costs infinity.
        x = np.zeros(len(CALIBRATION))
        y_tr = y0[train]
        best = (cost(y_tr, x), x, y_tr)
        for k in range(len(x) if calibration_iterations > 0 else 0):
            report(0.05 + 0.03 * k / len(x), "calibrate: coarse scan of each factor")
            for step in CAL_SCAN:
                xk = x.copy()
                xk[k] = step
                yk = coeffs(calibrated_system(system, xk), ptr)
                ck = cost(yk, xk)
                if ck < best[0]:
                    best = (ck, xk, yk)
        _, x, y_tr = best
        # d coefficients / d log factor, per derivative step (the longer step's is handed on to the naming)
        steps = fitting.CAL_DERIVATIVE_STEPS
        dys = {h: np.zeros((len(x),) + y_tr.shape, dtype=complex) for h in steps}
        first = 0  # the derivative step an iteration starts with: the one that last moved the factors
        fresh = False  # the last iteration took the longer step's sensitivities (at its start); none yet
        for it in range(calibration_iterations):
            report(0.08 + 0.25 * it / calibration_iterations, f"calibrate: iteration {it + 1} of {calibration_iterations}")
            lik.fit_nuisance(y_tr, train)  # linearise at the current nuisance and robust weights
            c_now, moved = cost(y_tr, x), False
            # the sensitivities from the step that last moved the factors (the longer one at first);
            # when no step length lowers the cost along its direction, from the other one
            fresh = False
            for j in [first] + [i for i in range(len(steps)) if i != first]:
                jac = sensitivities(dys[steps[j]], steps[j], x, y_tr)
                fresh = fresh or j == 0
                dx = _lstsq_bounded(jac, lik.mvec(train) - lik.vec(y_tr, train), x)
                found = first_lower(lambda f: trial_at(x + f * dx), c_now)
                if found is not None:
                    _, x, y_tr = found
                    moved, first = True, j
                    break
            if not moved:
                break
        lik.fit_nuisance(y_tr, train)  # the calibrated model's nuisance and robust weights
        # the naming's sensitivities are the longer step's: the last iteration's (taken at its start), or
        # taken again at the calibrated factors when the last iteration moved them with the shorter
        # step alone (so at most two sets per iteration in all, as costs.diagnosis_runs counts)
        jac = columns(dys[steps[0]]) if fresh else sensitivities(dys[steps[0]], steps[0], x, y_tr)
        report(0.35, "calibrate: checking the calibrated model on held-out points")
        cal, err_cal, y_cal_h = on_held_out(x)
        # 2b) when the calibration moved the factors, the model-based terms again at the calibrated
        # set: they follow where the model sits on its characteristic (model_terms), and the
        # calibrated set sits nearer the rig than the set as given. A row whose checks fail there
        # keeps the first measurement. Then one Gauss-Newton step of the factors under the new
        # uncertainties, from the sensitivities the naming gets, kept when a real run lowers the
        # objective
        terms_cal, kept_first = terms0.at(keep), {}
        if np.any(x):
            report(0.36, "calibrate: the uncertainty checks at the calibrated model")
            measured = model_terms.measure(runner, cal, pts, joined(y_tr, y_cal_h))
            kept_first = measured.failure_texts()  # reported below, for the points that stay
            terms_cal = measured.filled_from(terms0, keep)
            lik.sigma, floor = uncertainty(repeat, meas_c, mains, terms_cal)
            lik.fit_nuisance(y_tr, train)
            jac = columns(dys[steps[0]])
            c_now = cost(y_tr, x)
            dx = _lstsq_bounded(jac, lik.mvec(train) - lik.vec(y_tr, train), x)
            found = first_lower(lambda f: trial_at(x + f * dx), c_now)
            if found is not None:
                _, x, y_tr = found
                cal, err_cal, y_cal_h = on_held_out(x)
                # the naming keeps the Jacobian standardised before this one step; standardising it
                # again at the refitted weights moved the strict CI absorber's 90 % interval to
                # exclude the truth by 0.02 % (docs/discrepancy.md, Known limits)
                lik.fit_nuisance(y_tr, train)
        y_cal = joined(y_tr, y_cal_h)
        dropped = {held[j] for j in err_cal}
        y_cal_h = y_cal_h[[j for j in range(len(held)) if j not in err_cal]]  # the held-out points that ran
        problems += [drive.run_problem(pts[held[j]], f"the model run with the calibrated parameter set failed ({msg}); "
                                       "the point is left out of the verdict") for j, msg in err_cal.items()]
        held = [i for i in held if i not in dropped]
        problems += [drive.run_problem(pts[i], f"a check at the calibrated parameter set failed ({why}); the point "
                                       "keeps the uncertainty checks of the parameter set as given")
                     for i, why in kept_first.items() if i not in dropped]
        if not held:
            return _not_diagnosed(system, ["held_out_points"], "not diagnosed: the calibrated model fails at every held-out"
                                  " point (see problems). Accepted: at least one held-out torsional point (every third) "
                                  "that the calibrated model can run.", problems, runner.count, t0)
        level = noise_level(2 * len(held) * len(drive.ORDERS))
        # 3) name: screen, fit the shortlist (magnitude, shape parameters), pairs, evidence
        failures = {n: {} for n in cands}
        starts = {"calibrated": (cal, x, y_tr), "estimated": (system, np.zeros_like(x), y0[train])}
        namer = Namer(runner, lik, train, ptr, jac, starts, failures)
        screen = {}
        for j, name in enumerate(cands):
            report(0.40 + 0.15 * j / len(cands), f"name: signature screen of {name}")
            screen[name] = namer.screen(name)
        order = sorted(cands, key=lambda n: -screen[n]["rel_log_evidence"])
        # the best by screen evidence are fitted (a scale held at its minimum can still fit
        # better than "none": a slightly slipping clutch); the others keep the screen's evidence
        shortlisted = [n for n in order if math.isfinite(screen[n]["rel_log_evidence"])][:shortlist] or order[:1]
        held_pts = [pts[i] for i in held]
        # the discretisation check at the calibrated set, standardised
        bias_w = lik.vec(np.nan_to_num(terms_cal.coarse[train] - terms_cal.y[train]), train)
        models = {"none": {"cost": cost(y_tr, x), "x": x, "y": y_tr, "system": cal, "yh": y_cal_h, "effects": [],
                           "columns": [], "nuisance": lik.profile(y_tr, train)[1], "start": "calibrated"}}
        models["none"]["log_z"], models["none"]["cov"] = namer.evidence(models["none"], [], bias_w)
        unfitted = {}  # shortlisted candidates every fit of which failed: no evidence

        def finish(label, fit, names):
            """Evidence, held-out run and intervals of a fitted model ``label``."""
            fit["nuisance"] = lik.profile(fit["y"], train)[1]
            fit["log_z"], fit["cov"] = namer.evidence(fit, names, bias_w)
            yh, failed = namer.runs(fit["system"], label, held_pts)
            fit["yh"] = None if failed else yh
            models[label] = fit

        def held_chi2(fit):
            """A fitted model's robust reduced chi^2 on the held-out points; None when its held-out run failed."""
            return None if fit["yh"] is None else lik.robust_reduced_chi2(fit["yh"], held, fit["nuisance"])

        for j, name in enumerate(shortlisted):
            report(0.56 + 0.2 * j / len(shortlisted), f"name: fitting {name}")
            fits = namer.fit_candidate(name, screen[name])
            if not fits:
                unfitted[name] = (f"not ranked: the model runs with {name} failed at every magnitude tried "
                                  f"({drive.failed_text(failures.get(name, {}))})")
                continue
            fit = namer.fit_shapes(name, fits[0])
            fit["effects"] = [name]
            fit["columns"] = [fit["column"], *fit.get("shape_columns", [])]
            finish(name, fit, [name])
        lead = max((n for n in shortlisted if n in models), key=lambda n: models[n]["log_z"], default=None)
        recalibrated = None  # {effect, adopted, trigger} when the leading effect was fitted again with the calibration
        trigger = None if lead is None else recalibration_trigger(
            lik.robust_reduced_chi2(models[lead]["y"], train, models[lead]["nuisance"]),
            noise_level(2 * len(train) * len(drive.ORDERS)), held_chi2(models[lead]), level)
        if trigger is not None:
            # the leading effect leaves the training or the held-out misfit above the noise: the calibration
            # without it may have taken it up, out of the reach of the fits' linearisation (docs/discrepancy.md,
            # Naming, 3b)
            report(0.76, f"name: re-calibrating with {lead}")
            first_fit, first_failures = models[lead], dict(failures.get(lead, {}))
            refit = namer.fit_shapes(lead, namer.refit(lead, first_fit))
            recalibrated = {"effect": lead, "adopted": False, "trigger": trigger}
            if refit is not None and refit["cost"] < first_fit["cost"]:
                refit["effects"], refit["columns"] = [lead], [refit["column"], *refit.get("shape_columns", [])]
                finish(lead, refit, [lead])
                recalibrated["adopted"] = refit["yh"] is not None
            if not recalibrated["adopted"]:  # kept only where it fits better and runs at every held-out point
                models[lead], failures[lead] = first_fit, first_failures
        if namer.recalibrate(models, held_pts, bias_w):  # "none" at the best factors a candidate's fit found
            cal, x, y_tr = namer.starts["calibrated"]
            y_cal[train], y_cal[held] = y_tr, models["none"]["yh"]

        def temper():
            """The learning rate from the best-fitting model so far: when even that model leaves
            a training misfit above the noise, every model's evidence and covariance are read
            against that misfit (see selection.learning_rate)."""
            rate = _learning_rate(namer, models, train)
            for fit in models.values():
                fit["log_z"], fit["cov"] = namer.evidence(fit, fit["effects"], bias_w, rate)
            return rate

        eta = temper()  # before the pair is chosen: the singles are ranked by tempered evidence
        singles = [n for n in shortlisted if n in models]
        pairs, partners = [], None  # partners: the partner screen's gains [nats], when it ran
        best_single = max(singles, key=lambda n: models[n]["log_z"], default=None)
        if best_single is not None and len(singles) >= 2:
            f1 = models[best_single]
            if (chi_1 := held_chi2(f1)) is None or chi_1 > level:
                report(0.78, "name: screening the partners of a pair")
                # the partner explains what the first fit leaves: every other candidate screened on
                # top of it (the second-best single fit when every such run failed)
                gained = partner.gains(namer, best_single, f1, cands, eta)
                partners = {n: (g.nats if math.isfinite(g.nats) else None) for n, g in gained.items()}
                second = partner.choose(gained, max((n for n in singles if n != best_single),
                                                    key=lambda n: models[n]["log_z"]))
                report(0.79, f"name: trying the pair {best_single} + {second}")
                # the first effect stays as fitted: its magnitude's and shapes' prior terms count
                prior_1 = namer._magnitude_prior(best_single, f1["m"]) + namer.shape_prior(
                    best_single, {**f1.get("shape_start", {}), **f1.get("shapes", {})})
                label = partner.pair_label(best_single, second)
                # the second effect held at a shape read on top of the first (its prior term counts)
                shape_2, mass_2 = partner.shape(namer, second, f1, gained, models, label, prior_1)
                fit = namer.fit(second, (f1["system"], f1["x"], f1["y"]), extra_prior=prior_1, label=label,
                                jac=namer.jac_of(f1), shape=shape_2)
                if fit is not None:
                    fit["log_mass"] = f1.get("log_mass", 0.0) + mass_2
                    fit["jac"] = f1.get("jac")  # read at the first effect's factors
                    fit["effects"] = [best_single, second]
                    fit["columns"] = [f1["column"], fit["column"]]
                    fit["m_first"] = f1["m"]
                    finish(label, fit, [best_single, second])
                    pairs.append(label)
                    eta = temper()  # the pair may fit better than any single effect
        # ramps: every fitted model replays them and they join its evidence as a prediction
        # carrying the fit's uncertainty (the fits themselves use the torsional points)
        ramp_lik, ramp_runs, ramp_ll, chi_r = None, {}, {}, {}
        if campaign.ramps:
            report(0.8, "ramps: windup of every fitted model and its sensitivities")
            ramp_lik, ramp_runs, ramp_ll, chi_r = ramp_models.evidence(runner, system, x, models, campaign.ramps)
        # a fitted model that predicts the held-out points worse than "none" is penalised by
        # the difference (held_out_penalty); one that predicts them better gains nothing,
        # since an effect can imitate the model's own systematic error there as on the
        # training points (docs/discrepancy.md, Naming)
        penalty = selection.held_out_penalty(lik, models, held, eta)
        # posterior over all models: fitted models by their Laplace evidence, the others by
        # the linear screen's evidence relative to "none" (exact for a linear signature;
        # their ramps are taken as those of "none")
        screen_z = {n: namer.screen_evidence(screen[n], eta) for n in cands if n not in models}
        # "none" may hold a smooth misfit no library effect names (docs/discrepancy.md, Naming):
        # a candidate has to explain the data better than such a misfit does
        misfit_inputs = {"torsion": namer.unnamed_inputs(models["none"], eta),
                         "ramps": ramp_lik.unnamed_inputs if ramp_lik is not None else None}
        unnamed = dict(zip(("torsional", "ramps"), misfit.gains(misfit_inputs)))
        unnamed["log_evidence"] = misfit.combined(unnamed["torsional"], unnamed["ramps"])
        log_z = selection.model_log_evidence(models, cands, pairs, screen_z, ramp_ll, penalty, unfitted,
                                             unnamed["log_evidence"])
        priors = selection.model_priors(cands, pairs)
        post = selection.posterior(log_z, priors)
        judged = [m for m in models if models[m]["yh"] is not None]
        top = max(judged, key=lambda m: post.get(m, 0.0))
        if top != "none" and ramp_lik is not None:
            report(0.82, f"ramps: sizing {top}")
            if ramp_models.size_by_ramps(runner, models[top], pts, train, held, lik, ramp_lik, campaign.ramps):
                ramp_runs[top] = ramps_lik.run_ramps(runner, models[top]["system"], campaign.ramps)
        # the verdict's misfit is robust: one bad held-out point cannot decide it alone
        chi = {m: held_chi2(models[m]) for m in judged}
        chi_plain = {m: lik.reduced_chi2(models[m]["yh"], held, models[m]["nuisance"]) for m in judged}
        verdict = decide(top, post.get(top, 0.0), chi[top], chi["none"], level)
        # detectability of every candidate (two more magnitudes each, from the calibrated start)
        detect = {}

        # the unnamed misfit's ramp D when the ramps hold no signature (0 without ramps)
        ramp_none = 0.0 if ramp_lik is None else misfit.ramp_signature_gain(
            ramp_lik.unnamed_inputs, np.zeros(ramp_lik.residuals), ramp_lik.noise_scale)

        def ramp_gain(name, m):
            """The ramps' share of an effect's detectability: (chi^2 of its windup signature at
            magnitude m against the calibrated model's prediction, the unnamed misfit's ramp D at
            that signature, at none); no chi^2 and D at none twice for an effect the ramps are
            not read for, or whose ramp run failed."""
            if ramp_lik is None or name not in design.RAMP_PROTOCOLS:
                return 0.0, ramp_none, ramp_none
            w = ramps_lik.run_ramps(runner, with_effect(cal, name, {info(name).magnitude: m}), campaign.ramps)
            cov = models["none"]["cov"]
            pad = [np.zeros(ramp_lik.residuals)] * (cov.shape[0] - len(ramp_lik.cols_x))
            sig = ramp_lik.signature(w, ramp_runs["none"])
            chi2 = ramp_lik.signature_chi2(sig, np.column_stack([*ramp_lik.cols_x, *pad]), cov)
            at = ramp_none if sig is None else misfit.ramp_signature_gain(ramp_lik.unnamed_inputs, sig,
                                                                          ramp_lik.noise_scale)
            return chi2, at, ramp_none

        for j, name in enumerate(cands):
            report(0.82 + 0.06 * j / len(cands), f"detectability: {name}")
            at_cal = screen[name]["start"] == "calibrated" and "refactored" not in models["none"]
            typ = screen[name]["y_library"] if at_cal else None
            detect[name] = namer.detectability(name, y_tr, models["none"]["nuisance"], typ, priors, ramp_gain, eta,
                                               namer.jac_of(models["none"]))
        # 4) augment
        final = models[top]
        y_aug = y_cal.copy()
        y_aug[train], y_aug[held] = final["y"], final["yh"]
        # intervals: the Laplace covariance's, widened where leaving out a training point moves a parameter further
        groups = intervals.point_groups(len(train), len(drive.ORDERS))
        jack, jack_noise = intervals.jackknife(*namer.linearised(final), groups, eta)
        effects_out = intervals.effects_of(top, final, jack)
        effect = effects_out[0]["name"] if verdict == "missing_effect" else None
        eff_params = {}
        if effect:
            cur = getattr(final["system"].effects, effect)
            eff_params = {f.name: getattr(cur, f.name) for f in dataclasses.fields(cur) if f.name != "enabled"}
        system_out = final["system"] if verdict == "missing_effect" else cal
        y_all = np.zeros_like(y0)
        y_all[train], y_all[held] = final["y"], final["yh"]
        rows_all = sorted(train + held)
        flags = lik.outliers(y_all[rows_all], rows_all, final["nuisance"])
        # next tests
        recs = []
        if recommend:
            report(0.9, "design: ranking next test points")
            recs = _recommend(runner, models, post, detect, cands, pts, lik, campaign)
        # ramps shown: windup error before, calibrated, after
        ramps, traces = {}, {}
        if campaign.ramps:
            report(0.95, "show: hysteresis ramps")
            before = ramps_lik.run_ramps(runner, system, campaign.ramps)
            ramps, traces, failed = ramps_lik.errors_and_traces(
                {"before": before, "calibrated": ramp_runs["none"],
                 "after": ramp_runs[top] if verdict == "missing_effect" else ramp_runs["none"]}, campaign.ramps)
            problems += failed
        sims = runner.count
    ranking = _ranking(cands, models, screen, post, chi, failures, held, meas, log_z, unfitted)
    gap_cal = _rms(_resid(np.abs(y_cal), meas)[held])
    res = {"before": _resid(np.abs(y0), meas), "calibrated": _resid(np.abs(y_cal), meas),
           "after": _resid(np.abs(y_aug), meas)}
    shown = [i for i in range(len(pts)) if i not in dropped]
    ids = [p.id for p in pts]
    diag = Diagnosis(
        verdict=verdict, effect=effect, effect_parameters=eff_params, ranking=ranking, noise_floor_nm=floor,
        gap_before_nm=_rms(res["before"][held]), gap_calibrated_nm=gap_cal,
        gap_after_nm=_rms(res["after"][held]) if verdict == "missing_effect" else gap_cal,
        held_out_points=[ids[i] for i in held],
        calibration={k: math.exp(v) for k, v in zip(CALIBRATION, final["x"] if verdict == "missing_effect" else x)},
        points=[{"id": pts[i].id, "speed_rpm": pts[i].speed_rpm, "mean_torque_nm": pts[i].mean_torque_nm,
                 "held_out": i in held, "measured": meas[i].tolist(), "before": np.abs(y0[i]).tolist(),
                 "calibrated": np.abs(y_cal[i]).tolist(),
                 "after": np.abs(y_aug[i] if verdict == "missing_effect" else y_cal[i]).tolist()} for i in shown],
        residuals={k: {ids[i]: v[i].tolist() for i in shown} for k, v in res.items()},
        ramps=ramps, ramp_traces=traces, problems=problems, simulations=sims, system=system_out,
        misfit_inputs=misfit_inputs,
        # every library effect has a key: those not considered have prior and posterior 0
        posterior={**dict.fromkeys(NAMES, 0.0), **post}, effects=effects_out,
        detectability={**dict.fromkeys(NAMES), **detect}, recommended_points=recs,
        outliers=[ids[i] for i, f in zip(rows_all, flags) if f],
        likelihood={"reduced_chi2_held_out": chi[top], "reduced_chi2_held_out_calibrated": chi["none"],
                    "reduced_chi2_held_out_plain": chi_plain[top],
                    "reduced_chi2_train": lik.reduced_chi2(final["y"], train, final["nuisance"]),
                    "noise_level": level, "cells": int(len(pts) * len(drive.ORDERS)), "model": top,
                    "point_reduced_chi2": {ids[i]: float(c) / (2 * len(drive.ORDERS)) for i, c in
                                           zip(rows_all, lik.point_chi2(y_all[rows_all], rows_all, final["nuisance"]))},
                    "nuisance": {"output_gain": math.exp(final["nuisance"][0]),
                                 "delay_ms": 1e3 * float(final["nuisance"][1])},
                    "log_evidence": log_z, "model_prior": priors, "learning_rate": eta,
                    "held_out_penalty": penalty, "calibration_taken_from": models["none"].get("refactored"),
                    "recalibrated": recalibrated, "pair_partners": partners,
                    "interval_spread": intervals.spread(final, jack),
                    "interval_spread_noise": intervals.spread(final, jack_noise),
                    "ramp_effective_share": ramp_lik.fraction if ramp_lik is not None else None,
                    "chi2_ramps": chi_r.get(top) if ramp_lik is not None else None,
                    "ramp_log_likelihood": ramp_ll,
                    "unnamed_misfit": unnamed,
                    "ramp_noise_scale": ramp_lik.scales.get(top) if ramp_lik is not None else None,
                    "ramp_samples": ramp_lik.residuals if ramp_lik is not None else 0},
    )
    diag.message = _verdict_message(diag, [every[i].id for i in left_out] + [pts[i].id for i in sorted(dropped)], level)
    diag.locate = locate(diag, system)
    diag.wall_time_s = time.perf_counter() - t0
    report(1.0, "done")
    return diag


def _learning_rate(namer, models, train) -> float:
    """The likelihood's learning rate from the best-fitting model on the training points
    (:func:`~dampersim.discrepancy.selection.learning_rate`; parameters: the calibration
    factors, the channels' gain and delay and the model's own columns). Models whose
    held-out run failed are no match and do not count."""
    n = 2 * len(train) * len(drive.ORDERS)
    best = min(((namer.data_loss(f["y"], f["nuisance"]), len(CALIBRATION) + 2 + len(f["columns"]))
                for label, f in models.items() if label == "none" or f["yh"] is not None),
               key=lambda t: t[0] / max(1, n - t[1]))
    return selection.learning_rate(best[0], n, best[1])


def _ranking(cands, models, screen, post, chi, failures, held, meas, log_z, unfitted) -> list:
    """One entry per candidate (and pair tried), most probable first."""
    rows = []
    for name in [*cands, *[m for m in models if "+" in m]]:
        fit = models.get(name)
        entry = {"effect": name, "parameters": {}, "posterior": post.get(name, 0.0), "log_evidence": log_z.get(name),
                 "gap_held_out_nm": None, "reduced_chi2_held_out": chi.get(name), "train_fit_nm": None,
                 "screen_rel_log_evidence": screen.get(name, {}).get("rel_log_evidence"),
                 "fitted_from": (fit or {}).get("start", screen.get(name, {}).get("start")),
                 "excluded": unfitted.get(name)}
        fails = dict(failures.get(name, {}))
        if fit is not None:
            entry["parameters"] = {p: v for e in intervals.effects_of(name, fit) for p, v in e["parameters"].items()}
            if fit["yh"] is not None:
                entry["gap_held_out_nm"] = _rms(_resid(np.abs(fit["yh"]), meas[held]))
            else:
                entry["excluded"] = (f"not ranked: with {name} fitted the model run failed at held-out point(s) "
                                     f"{drive.failed_text(fails)}; a failed run is no match")
        elif name in screen and not math.isfinite(screen[name]["rel_log_evidence"]):
            entry["excluded"] = f"not ranked: the screening runs with {name} failed ({drive.failed_text(fails)})"
        entry["failed_points"] = sorted(fails)
        if entry["excluded"]:
            entry["posterior"] = 0.0
        rows.append(entry)
    rows.sort(key=lambda r: (r["excluded"] is not None, -r["posterior"]))
    return rows


def _recommend(runner, models, post, detect, cands, pts, lik, campaign) -> list:
    """Next test points: separate the two most probable models; look for effects this
    campaign cannot detect (threshold beyond the library's strong magnitude, or none)."""
    ranked = sorted((m for m in post if m in models), key=lambda m: -post[m])
    contrasts = []
    if len(ranked) >= 2:
        contrasts.append((ranked[0], ranked[1], "separates the two most probable models"))
    hidden = []
    for name in cands:
        e, thr = info(name), detect.get(name)
        strong = e.magnitudes[2]
        if thr is None or (thr > strong if e.grows else thr < strong):
            hidden.append(name)
    look = {}
    for name in hidden[:2]:
        look[f"{name} (typical)"] = design.effect_model(models["none"]["system"], name)
        contrasts.append(("none", f"{name} (typical)", f"would reveal {name}, which this campaign cannot detect"))
    systems = {**{m: models[m]["system"] for m in models}, **look}
    sigma = np.median(lik.sigma, axis=0)
    amp = float(np.median([point_orders(p, p.input_torque, (2.0,))[0] for p in pts]))
    return design.recommend(runner, systems, contrasts, pts, sigma, amp, bool(campaign.ramps), hidden)


__all__ = ["CALIBRATION", "UNCALIBRATED", "INSUFFICIENT", "REPEATABILITY", "decide", "MIN_TORSIONAL_POINTS",
           "MIN_SPEEDS", "SAME_SPEED_SHARE", "CHI2_NOISE", "Diagnosis", "diagnose", "locate", "calibrated_system",
           "shortfall", "speeds_of", "noise_level", "CAL_BOUND", "CAL_SCAN", "CAL_STEP_FRACTIONS", "COARSE_SEGMENTS",
           "PRIOR_LOG_SD", "REFINE_EVALUATIONS", "_effect_grid", "_lstsq_bounded", "_resid", "with_effect", "uncertainty"]
