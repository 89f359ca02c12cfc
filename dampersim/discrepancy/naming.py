"""Naming a missing effect: screen every candidate, fit the promising ones (magnitude,
shape parameters, pairs), weigh them by Laplace evidence against "no missing effect", and
estimate for each effect the smallest magnitude this campaign could detect.

All fits work on the training points through the :class:`~dampersim.discrepancy.likelihood.
Likelihood` (standardised complex residuals with fitted channel gain and delay, robust
loss); the objective of a model is that loss plus the Gaussian priors of its parameters
(:mod:`dampersim.discrepancy.selection`). A run that fails costs infinity: a candidate that
crashes the model is never chosen.
"""

from __future__ import annotations

import math

import numpy as np

from dampersim.discrepancy import detect, drive, selection, shapes, unnamed
from dampersim.discrepancy.effects import clip_magnitude, clip_to_range as _clip, info, parameters_of, with_effect
from dampersim.discrepancy.fitting import CAL_BOUND, CAL_DERIVATIVE_STEPS, FD_STEP, PRIOR_LOG_SD, REFINE_EVALUATIONS, \
    _lstsq_bounded, calibrated_system, fd_magnitude, first_lower, grid_bracket, prior_step
from dampersim.discrepancy.likelihood import DELAY_PRIOR_SD, GAIN_PRIOR_SD
from dampersim.discrepancy.shapes import SHAPES
from dampersim.errors import ParameterError

#: log step of the finite differences for shape parameters: small, since a tuned absorber's
#: response is sharply non-linear in its tuning order (2 % is 0.04 orders at order 2)
SHAPE_FD_STEP = 0.02
#: a candidate's second start is fitted too when its screen evidence is within this many
#: nats of the preferred start's (e^3 = 20: the linear screen may misjudge closer calls)
SECOND_START_NATS = 3.0
#: smallest screen scale (fitted magnitude / typical magnitude) for a candidate to be fitted
MIN_SCREEN_SCALE = 0.05
#: Gauss-Newton iterations of :meth:`Namer.refit` (each takes fresh sensitivities: seven runs per
#: training point, then up to three step lengths)
REFIT_ITERATIONS = 3


class Namer:
    """The naming step's state: runner, likelihood, training rows and points, the
    calibration's Jacobian (standardised, at the factors where the calibration's
    Gauss-Newton stopped; it stays there when :meth:`recalibrate` moves "none", which then
    reads :meth:`jac_of` the fit whose factors it took) and the starts."""

    def __init__(self, runner, lik, train, points, jac, starts, failures):
        self.runner, self.lik, self.train, self.points = runner, lik, train, points
        self.jac, self.starts, self.failures, self.base = jac, starts, failures, starts["estimated"][0]
        self.prec_cal = np.full(jac.shape[1], 1.0 / PRIOR_LOG_SD ** 2)

    # --- runs and costs -------------------------------------------------------------------
    def runs(self, system, name, points=None):
        """Complex coefficients of ``system`` at the training points (or ``points``) and
        whether a run failed (recorded against candidate ``name``)."""
        pts = self.points if points is None else points
        errs = {}
        y = drive.coefficients_of(self.runner, system, pts, errs)
        self._record(name, errs, pts)
        return y, bool(errs)

    def _record(self, name, errs, pts):
        """Record the failed runs {row: message} of ``pts`` against model ``name`` (the first
        message per point is kept)."""
        for j, msg in errs.items():
            self.failures.setdefault(name, {}).setdefault(pts[j].id, msg)

    def cost(self, y, x, extra: float = 0.0) -> float:
        """Objective of a model: robust loss (nuisance fitted) + calibration prior + ``extra``
        (the effect parameters' prior terms)."""
        loss, _ = self.lik.profile(y, self.train)
        return loss + float(np.sum(np.asarray(x) ** 2)) / PRIOR_LOG_SD ** 2 + extra

    def w(self, dy) -> np.ndarray:
        """Standardised vector of a change of model coefficients (linear in dy)."""
        return self.lik.vec(dy, self.train)

    # --- screen -----------------------------------------------------------------------------
    def screen(self, name):
        """Linearised joint fit of the effect at its typical magnitude with a re-calibration,
        from each start (scale at least MIN_SCREEN_SCALE: an effect cannot act backwards) and
        at each screened shape (shapes.variants; for most effects only the parameter set's).
        Keeps the start and shape of highest evidence plus log prior weight: {start, shape ({}:
        the set's own), scale, rel_log_evidence (the shapes' prior-weighted sum at the better
        start against the better of the starts' "none" evidences), cost, y_library (that
        start's run at the set's own shape, None if it failed), parts (per start: standardised
        residual, [(signature or None, log weight)] per shape, factors), start_z (per start,
        the shape-summed log evidence; -inf: every run failed)}."""
        e = info(name)
        own = self.library_effect(name)
        variants = self.screen_variants(name)
        best, parts, start_z, kept = None, [], {}, {}
        for start, (s0, x0, y_s) in self.starts.items():
            nu = self.lik.profile(y_s, self.train)[1]  # this start's own nuisance
            with self.lik.using(nu):
                r = self.lik.mvec(self.train) - self.lik.vec(y_s, self.train)
            ds, scored, y_lib = [], [], None
            for vals, lw in variants:
                ye, failed = self.runs(with_effect(s0, name, {**vals, e.magnitude: e.magnitudes[1]}), name)
                with self.lik.using(nu):
                    d = None if failed else self.w(ye - y_s)
                ds.append((d, lw))
                if failed:
                    cand = {"start": start, "shape": vals, "scale": 0.0, "z": -math.inf, "cost": math.inf}
                else:
                    z, sc, _, c = selection.linear_screen_evidence(r, self.jac, d, x0, PRIOR_LOG_SD,
                                                                   min_scale=MIN_SCREEN_SCALE)
                    cand = {"start": start, "shape": vals, "scale": sc, "z": z + lw, "cost": c}
                    if all(v == getattr(own, q) for q, v in vals.items()):
                        y_lib = ye
                scored.append((vals, cand["z"]))
                if best is None or cand["z"] > best["z"]:
                    best = cand
            kept[start] = y_lib
            parts.append((r, ds, x0))
            start_z[start] = shapes.logsumexp(z for _, z in scored)
        if not math.isfinite(best.pop("z")):  # every run failed: the set's own shape, as before any grid
            best["shape"] = {}
        best["y_library"] = kept[best["start"]]
        best["parts"], best["start_z"] = parts, start_z
        best["rel_log_evidence"] = self.screen_evidence(best, 1.0)
        return best

    def _screen_z(self, r, ds, x0, eta: float) -> float:
        """The linear screen's log evidence of one start, summed over its screened shapes with
        their prior weights ([(signature or None, log weight)]), with the likelihood tempered by
        eta (residual, Jacobian and signature scaled by sqrt(eta): exact for the linear model)."""
        k = math.sqrt(eta)
        return shapes.logsumexp(
            -math.inf if d is None else lw + selection.linear_screen_evidence(
                k * r, k * self.jac, k * d, x0, PRIOR_LOG_SD, min_scale=MIN_SCREEN_SCALE)[0]
            for d, lw in ds)

    def screen_evidence(self, entry, eta: float) -> float:
        """A screened candidate's log evidence relative to "none" at learning rate eta: its
        best start (its shapes summed) against the better of the starts' "none" evidences."""
        k = math.sqrt(eta)
        z_none = max(selection.linear_screen_evidence(k * r, k * self.jac, None, x0, PRIOR_LOG_SD)[0]
                     for r, _, x0 in entry["parts"])
        return max(self._screen_z(r, ds, x0, eta) for r, ds, x0 in entry["parts"]) - z_none

    # --- fits --------------------------------------------------------------------------------
    def _magnitude_prior(self, name, m) -> float:
        e = info(name)
        return ((math.log(m) - math.log(e.magnitudes[1])) / selection.MAGNITUDE_PRIOR_SD) ** 2

    def fit_candidate(self, name, screened):
        """Fit effect ``name`` from the start its screen preferred; the other start is fitted
        too when the preferred fit failed or when the screen could not tell the starts apart
        (their linear evidences within SECOND_START_NATS: the linearisation may rank them
        wrongly). Both hold the screen's shape and :meth:`choose`'s discrete choice, whose log
        prior mass (``log_mass``) joins their evidence. The fits that succeeded, best first by
        cost (may be empty)."""
        pref = screened["start"]
        zs = screened.get("start_z", {})
        shape, log_mass = self.choose(name, screened)
        fits = [f for f in [self.fit(name, pref, shape=shape)] if f is not None]
        for other in (s for s in self.starts if s != pref):
            close = math.isfinite(zs.get(other, -math.inf)) and zs[other] >= zs.get(pref, math.inf) - SECOND_START_NATS
            if not fits or close:
                fits += [f for f in [self.fit(name, other, shape=shape)] if f is not None]
        for f in fits:
            f["log_mass"] = log_mass
        return sorted(fits, key=lambda f: f["cost"])

    def choose(self, name, screened, jac=None, label: str | None = None, extra_prior: float = 0.0) -> tuple:
        """(shape, log prior mass) to fit an effect with discrete shapes at (shapes.SCREEN_CHOICES):
        each choice runs once from the screen's start (a key of starts, or (system, x, y) on top of
        another effect's fit, with that fit's ``jac``, failures recorded against ``label`` and
        ``extra_prior``, the other effect's prior terms) and shape at the magnitude that keeps the
        screen's total (shapes.magnitude_at_choice: the same count x stiffness), and the lowest
        objective (:meth:`_trial`) wins. The linear screen scales a signature as a whole, so two
        springs at 360 N m/rad look to it as three at 240; below the clearance each short pair
        lacks its full-length spring whatever the stiffness, which real runs see. Choices the set
        refuses are left out (:meth:`admissible`). The mass: shapes.choice_log_mass, from the
        untempered objectives (bounded by log of the number of choices, it is not read again at
        the learning rate). Every run
        failed: the set's own choice, with the equal share; no discrete shapes: (shape, 0)."""
        shape = dict(screened.get("shape") or {})
        if name not in shapes.SCREEN_CHOICES:
            return shape, 0.0
        own = self.library_effect(name)
        options = [c for c, _ in self.admissible(name, [({**shape, **c}, 0.0) for c in shapes.choices(name)])]
        if len(options) < 2:  # nothing to choose among (the set accepts one choice at most)
            return (options[0] if options else shape), 0.0
        e = info(name)
        start = screened["start"]
        s0, x0, _ = self.starts[start] if isinstance(start, str) else start
        held = {q: getattr(own, q) for q in shapes.SCREEN_CHOICES[name]}
        m = e.magnitudes[1] * max(float(screened.get("scale", 1.0)), MIN_SCREEN_SCALE)
        scored = []
        for choice in options:
            mk = clip_magnitude(name, shapes.magnitude_at_choice(name, m, held, choice))
            c, *_ = self._trial(name, s0, x0, {**choice, e.magnitude: mk}, label or name,
                                self.jac if jac is None else jac,
                                self._magnitude_prior(name, mk) + self.shape_prior(name, shape) + extra_prior)
            scored.append((choice, -0.5 * c))
        if not any(math.isfinite(z) for _, z in scored):  # every choice failed: the set's own, as the screen ran it
            return shape, shapes.choice_log_mass(name, held, scored)
        best = max(scored, key=lambda t: t[1])[0]
        return best, shapes.choice_log_mass(name, best, scored)

    def library_effect(self, name):
        """Effect ``name``'s parameters in the parameter set as given (``base``, the estimated
        start's): the centre of its shapes' priors and of the screen's grid."""
        return getattr(self.base.effects, name)

    def admissible(self, name, options) -> list:
        """The (shape values, weight) of ``options`` the parameter set accepts for effect ``name``
        (a clearance must leave the short spring longer than its block arc, a count must stay
        below the inner set's pairs): the others are left out, not run."""
        e = info(name)
        out = []
        for vals, lw in options:
            try:
                with_effect(self.base, name, {**vals, e.magnitude: e.magnitudes[1]})
            except ParameterError:
                continue
            out.append((vals, lw))
        return out

    def screen_variants(self, name, grid=None) -> list:
        """The (shape values, log weight) effect ``name`` is screened at: shapes.variants around
        the parameter set's shape (over ``grid``, default shapes.SCREEN_FACTORS), those it
        refuses left out, the weights renormalised (the set's own shape, ({}, 0), when it
        refuses them all)."""
        own = self.library_effect(name)
        return shapes.renormalised(self.admissible(name, shapes.variants(name, own, grid))) or [({}, 0.0)]

    def shape_values(self, name, system) -> dict:
        """The fitted and screened shape values of effect ``name`` in ``system``."""
        eff = getattr(system.effects, name)
        keys = [*SHAPES.get(name, ()), *shapes.SCREEN_CHOICES.get(name, {})]
        return {q: getattr(eff, q) for q in keys}

    def shape_prior(self, name, values: dict) -> float:
        """The objective's prior term of effect ``name``'s continuous shapes at ``values``."""
        return shapes.prior_term(name, values, self.library_effect(name))

    def fit(self, name, start, extra_prior: float = 0.0, label: str | None = None, jac=None, shape=None):
        """Fit effect ``name``'s magnitude from ``start`` (a key of starts, or a tuple (system, x, y)
        to fit on top of another effect): a five-value grid, continued beyond an end that holds its
        lowest objective (:func:`~dampersim.discrepancy.fitting.grid_bracket`), a bounded search in
        log magnitude, a linearised re-calibration at every trial, then real runs against the
        re-calibrated, the start's and the estimated factors (on top of another effect the start's
        alone: the search's own run at the best magnitude). Returns a dict (cost, m, x, y, system,
        column: :meth:`magnitude_column`) or None when every run failed. extra_prior: prior terms
        of parameters fitted before (the pair's other effect); label: the model failed runs are
        recorded against (default ``name``); jac: the factors' Jacobian of the linearised
        re-calibration (default the calibration's; a pair on top of a re-calibrated effect passes
        that effect's, :meth:`jac_of`); shape: the effect's shape values held through the fit (default
        the parameter set's), their prior term counted in the objective."""
        from scipy.optimize import minimize_scalar  # scipy loads only when a diagnosis runs

        e = info(name)
        label = label or name
        jc = self.jac if jac is None else jac
        s0, x0, _ = self.starts[start] if isinstance(start, str) else start
        tried = {}
        shape = dict(shape or {})
        extra_prior = extra_prior + self.shape_prior(name, shape)

        def at(m):
            if m not in tried:
                tried[m] = self._trial(name, s0, x0, {**shape, e.magnitude: float(m)}, label, jc,
                                       self._magnitude_prior(name, m) + extra_prior)
            return tried[m]

        lo, hi = grid_bracket(name, lambda m: at(m)[0])
        with np.errstate(invalid="ignore", over="ignore"):
            minimize_scalar(lambda u: at(math.exp(u))[0], bounds=(lo, hi), method="bounded",
                            options={"xatol": 0.01, "maxiter": REFINE_EVALUATIONS})
        m, (c_lin, x_fit, y_m) = min(tried.items(), key=lambda kv: kv[1][0])
        if not math.isfinite(c_lin):
            return None
        base = s0 if not isinstance(start, str) else None
        options = [x_fit, x0, np.zeros_like(x0)] if base is None else [x0]
        options = [xo for i, xo in enumerate(options) if not any(np.array_equal(xo, o) for o in options[:i])]
        best = None
        for xo in options:
            sysx = _with_factors(self.starts, base, xo)
            if base is not None:  # the search's run at m is this one: same set, same factors
                ys, failed = y_m, False
            else:
                ys, failed = self.runs(with_effect(sysx, name, {**shape, e.magnitude: m}), label)
            c = math.inf if failed else self.cost(ys, xo, self._magnitude_prior(name, m) + extra_prior)
            if best is None or c < best["cost"]:
                best = {"cost": c, "m": float(m), "x": xo, "y": ys, "base": base,
                        "start": start if isinstance(start, str) else "pair",
                        "system": with_effect(sysx, name, {**shape, e.magnitude: m}), "shapes": {}}
        if not math.isfinite(best["cost"]):
            return None
        best["column"] = self.magnitude_column(name, best, label)
        return best

    def magnitude_column(self, name, fit, label=None, zeroed=None) -> np.ndarray:
        """Standardised column of effect ``name``'s log magnitude at ``fit`` (:func:`fd_magnitude`);
        zero where its run (recorded against ``label``, default ``name``) fails, named in ``zeroed``."""
        moved, step = fd_magnitude(name, fit["m"])
        yd, failed = self.runs(with_effect(fit["system"], name, {info(name).magnitude: moved}), label or name)
        if failed and zeroed is not None:
            zeroed.append(info(name).magnitude)
        return np.zeros_like(self.lik.mvec(self.train)) if failed else self.w((yd - fit["y"]) / step)

    def _trial(self, name, s0, x0, values, label, jac, extra) -> tuple:
        """(objective, factors, the run's coefficients) of effect ``name`` at ``values`` on top of
        start system s0 with factors x0, the better of two calibrations: x0 as it is (exact: the
        robust loss with the nuisance fitted to this run) and a linearised re-calibration under the
        prior around this run (Jacobian ``jac``, at the run's own nuisance; :meth:`fit` verifies
        its factors by real runs). extra: the effect parameters' prior terms. (inf, x0, None) when
        the run fails."""
        ym, failed = self.runs(with_effect(s0, name, values), label)
        if failed:
            return math.inf, x0, None
        loss0, nu = self.lik.profile(ym, self.train)
        exact = loss0 + float(np.sum(x0 ** 2)) / PRIOR_LOG_SD ** 2 + extra
        with self.lik.using(nu):
            r = self.lik.mvec(self.train) - self.lik.vec(ym, self.train)
        dx = _lstsq_bounded(jac, r, x0)
        rr = r - jac @ dx
        lin = float(rr @ rr) + self.lik.nuisance_prior(nu) + float(np.sum((x0 + dx) ** 2)) / PRIOR_LOG_SD ** 2 + extra
        return (exact, x0, ym) if exact <= lin else (lin, x0 + dx, ym)

    def recalibrate(self, models, held_pts, bias=None) -> bool:
        """Give "no missing effect" the calibration factors every single-effect fit reached.

        Each candidate fit re-calibrates at every magnitude it tries (:meth:`fit`), while
        "none" keeps the factors where the calibration's Gauss-Newton stopped; an effect that
        changes nothing could then win by its better calibration alone (docs/discrepancy.md,
        "Why the free play wins on control/none/1"). So "none" is evaluated at the factors of
        each fitted single effect (an effect's evidence can lead while its objective does not:
        ramps, Occam factors), and moves to the best of them when that lowers its objective and
        the held-out points run too. Updates ``models["none"]``
        (cost, factors, coefficients, system, held-out run, nuisance, evidence, ``refactored``:
        the fitted model whose factors it took) and the "calibrated" start; True when it moved.
        Runs: the training points per distinct trial factors, the held-out points once.

        The moved model's evidence keeps the robust weights and linearisation nuisance of where
        the Gauss-Newton stopped, as every effect's evidence does, and the Jacobian of the fit
        whose factors it takes (:meth:`jac_of`: the calibration's, unless that fit was
        re-calibrated by :meth:`refit`; in control/none/1 the factors move by less than 1 %;
        near a resonance the Jacobian at the new factors could differ). The move is judged on the training points
        alone: the held-out misfit of "none" may rise, and so may the baseline of the
        held-out penalty."""
        none = models["none"]
        tried, best = [np.asarray(none["x"])], None
        for label, fit in models.items():
            xc = np.asarray(fit["x"])
            if fit.get("base") is not None or any(np.array_equal(xc, t) for t in tried):
                continue
            tried.append(xc)
            errs = {}
            system = _with_factors(self.starts, None, xc)
            y = drive.coefficients_of(self.runner, system, self.points, errs)
            c = math.inf if errs else self.cost(y, xc)
            if c < (none["cost"] if best is None else best[0]):
                best = (c, xc, y, label, system, fit.get("jac"))
        if best is None:
            return False
        c, xc, y, label, system, jac = best
        errs = {}
        yh = drive.coefficients_of(self.runner, system, held_pts, errs)
        if errs:  # the calibration-only model must run everywhere the old one did
            return False
        none.update(cost=c, x=xc, y=y, system=system, yh=yh, nuisance=self.lik.profile(y, self.train)[1],
                    refactored=label, jac=jac)
        none["log_z"], none["cov"] = self.evidence(none, [], bias)
        self.starts["calibrated"] = (system, xc, y)
        return True

    def jac_of(self, fit) -> np.ndarray:
        """The calibration factors' standardised Jacobian a fitted model is read with: the one
        :meth:`refit` took near the model's factors (a pair on top of it, or "none" moved to its
        factors, carries it on), else the calibration's."""
        return fit["jac"] if fit.get("jac") is not None else self.jac

    def refit(self, name, fit):
        """Fit effect ``name`` again with the calibration factors, by Gauss-Newton on the six log
        factors and the log magnitude together from the estimated factors (shape parameters held
        at ``fit``'s; :meth:`fit_shapes` may move them after), with sensitivities taken
        afresh at every iteration (CAL_DERIVATIVE_STEPS[0] for a factor, FD_STEP for the
        magnitude) and at most REFIT_ITERATIONS iterations; a parameter whose derivative run
        fails is held where it is for that iteration. Each step weights the points by the robust
        weights of the iteration's own model (:meth:`Likelihood.reweighting`), as the
        calibration's iterations do; the returned Jacobians stay standardised at the stored
        weights, which the evidence reads them with.

        For the effect the calibration without it has taken up: :meth:`fit` re-calibrates
        through the Jacobian taken where that calibration stopped, and when the calibration
        has moved far to imitate the effect (factors of 1.5 to 2 for a 5 % perturbation) that
        linearisation does not bring the factors back. Returns a fit like :meth:`fit`'s, with
        ``jac`` the factors' Jacobian of its last iteration and ``column`` the magnitude's:
        taken at the start of that iteration, so one step behind the returned factors when its
        step was accepted (one more set would cost seven runs per training point), and two when
        :meth:`fit_shapes` then moves them. None when its first run fails."""
        e = info(name)
        h = CAL_DERIVATIVE_STEPS[0]
        n = self.jac.shape[1]
        x, m = np.zeros(n), float(fit["m"])
        shape = self.shape_values(name, fit["system"]) if "system" in fit else {}
        shape_term = self.shape_prior(name, shape)

        def system_at(xs, ms):
            return with_effect(_with_factors(self.starts, None, xs), name, {**shape, e.magnitude: ms})

        def cost(ys, xs, ms):
            return self.cost(ys, xs, self._magnitude_prior(name, ms) + shape_term)

        def trial(xs, ms, step, frac):
            """(objective, factors, magnitude, coefficients) a fraction frac along step."""
            xn = np.clip(xs + frac * step[:n], -CAL_BOUND, CAL_BOUND)
            mn = clip_magnitude(name, ms * math.exp(frac * float(step[n])))
            yn, failed = self.runs(system_at(xn, mn), name)
            return (math.inf if failed else cost(yn, xn, mn)), xn, mn, yn

        y, failed = self.runs(system_at(x, m), name)
        if failed:
            return None
        c = cost(y, x, m)
        prec = np.concatenate([self.prec_cal, [1.0 / selection.MAGNITUDE_PRIOR_SD ** 2]])
        jac = None
        for _ in range(REFIT_ITERATIONS):
            nu, r, rw = self._at_own_weights(y)
            m_fd, fd = fd_magnitude(name, m)
            trials = [system_at(x + h * k, m) for k in np.eye(n)] + [system_at(x, m_fd)]
            errs = [{} for _ in trials]
            ys = drive.coefficients_of_sets(self.runner, trials, self.points, errs)
            for err in errs:
                self._record(name, err, self.points)
            ok = np.array([not err for err in errs])
            with self.lik.using(nu):  # a failed derivative run gives no direction (0), never a fit
                jac = np.column_stack([self.w((yk - y) / dk) if good else np.zeros(len(self.lik.mvec(self.train)))
                                       for yk, good, dk in zip(ys, ok, [h] * n + [fd])])
            centre = np.concatenate([-x, [math.log(e.magnitudes[1] / m)]])
            step = np.zeros(n + 1)  # the parameters without a direction stay: no pull to the prior alone
            if ok.any():
                step[ok] = prior_step(jac[:, ok] * rw[:, None], r * rw, prec[ok], centre[ok])
            found = first_lower(lambda f: trial(x, m, step, f), c) if step.any() else None
            if found is None:  # at its minimum, no direction at all, or no step length lowers the objective
                break
            c, x, m, y = found
        return {"cost": c, "m": m, "x": x, "y": y, "base": None, "start": "refit", "system": system_at(x, m),
                "shapes": {}, "column": jac[:, n], "jac": jac[:, :n], "log_mass": fit.get("log_mass", 0.0)}

    def fit_shapes(self, name, fit):
        """One Gauss-Newton step on the effect's shape parameters (log scale, prior SHAPE_PRIOR_SD
        around the parameter set's values, whichever shape the fit started from; discrete shapes
        stay as chosen) jointly with its magnitude and the calibration, kept when a real run
        lowers the objective. The step weights the points by the fit's own model's robust weights
        (:meth:`_at_own_weights`), as :meth:`refit`'s do; the columns are the evidence's,
        standardised at the stored weights and nuisance (after :meth:`refit`, its last iteration's;
        docs/discrepancy.md, Known limits), a first-order difference the real run's verdict covers.
        Adds the shape columns (:meth:`shape_columns`) to ``fit`` for the evidence; returns it."""
        fitted = SHAPES.get(name, ())
        if not fitted or fit is None or fit.get("base") is not None:  # not on top of another effect
            return fit
        meta = {p["name"]: p for p in parameters_of(name)}
        held = self.shape_values(name, fit["system"])
        own = self.library_effect(name)
        start = {q: float(held[q]) for q in fitted if float(held[q]) > 0}
        cols = self.shape_columns(name, fit, start)
        fit["shape_start"], fit["shape_columns"] = dict(start), cols
        if not cols:
            return fit
        jac = np.column_stack([self.jac_of(fit), fit["column"], *cols])
        n = self.jac.shape[1]
        prec = np.concatenate([self.prec_cal, [1.0 / selection.MAGNITUDE_PRIOR_SD ** 2],
                               np.full(len(cols), 1.0 / selection.SHAPE_PRIOR_SD ** 2)])
        centre = np.concatenate([-fit["x"], [math.log(info(name).magnitudes[1] / fit["m"])],
                                 [shapes.log_ratio(float(getattr(own, q)), v) for q, v in start.items()]])
        _, r, rw = self._at_own_weights(fit["y"])
        step = prior_step(jac * rw[:, None], r * rw, prec, centre)
        new = {q: _clip(v * math.exp(float(step[n + 1 + j])), meta[q]) for j, (q, v) in enumerate(start.items())}
        m = clip_magnitude(name, fit["m"] * math.exp(float(step[n])))
        x = np.clip(fit["x"] + step[:n], -CAL_BOUND, CAL_BOUND)
        e = info(name)
        sysn = with_effect(_with_factors(self.starts, None, x), name, {**held, **new, e.magnitude: m})
        yn, failed = self.runs(sysn, name)
        extra = self._magnitude_prior(name, m) + self.shape_prior(name, new)
        c = math.inf if failed else self.cost(yn, x, extra)
        if c < fit["cost"]:
            fit.update({"cost": c, "m": m, "x": x, "y": yn, "system": sysn, "shapes": new})
        return fit

    def shape_columns(self, name, fit, values, zeroed=None) -> list:
        """Standardised columns of effect ``name``'s shapes ``values`` ({parameter: value}) at ``fit``, log forward
        differences of SHAPE_FD_STEP in range; zero (named in ``zeroed``) where a run fails or a shape is at a bound."""
        meta = {p["name"]: p for p in parameters_of(name)}
        cols = []
        for q, v in values.items():
            up = _clip(v * math.exp(SHAPE_FD_STEP), meta[q])
            yq, failed = self.runs(with_effect(fit["system"], name, {q: up}), name)
            bad = failed or up == v
            cols.append(np.zeros_like(fit["column"]) if bad else self.w((yq - fit["y"]) / math.log(up / v)))
            if bad and zeroed is not None:
                zeroed.append(q)
        return cols

    def _at_own_weights(self, y) -> tuple:
        """(nuisance, residual, row factors) for a Gauss-Newton step of the robust loss
        linearised at model coefficients y: the channels' nuisance fitted to y, the standardised
        training residual at it, and the factors (:meth:`Likelihood.reweighting`) that carry
        standardised vectors from the stored robust weights (the calibrated model's) to y's own.
        A step takes ``prior_step(J * factors[:, None], residual * factors, ...)``."""
        nu = self.lik.profile(y, self.train)[1]
        with self.lik.using(nu):
            r = self.lik.mvec(self.train) - self.lik.vec(y, self.train)
        return nu, r, self.lik.reweighting(y, self.train, nu)

    def _nuisance(self, y, nuisance):
        """The channels' gain and delay columns (standardised) at model coefficients y and
        their prior precisions: fitted with every model, they belong to its evidence and its
        covariance (a delay resembles a transducer's lag, a gain a stiffness)."""
        with self.lik.using(nuisance):
            cols = self.lik.nuisance_jacobian(y, self.train)
        return cols, np.array([1.0 / GAIN_PRIOR_SD ** 2, 1.0 / DELAY_PRIOR_SD ** 2])

    def evidence(self, fit, names, bias=None, eta: float = 1.0) -> tuple:
        """(log evidence, covariance) of a fitted model; ``names``: its effects (the fit
        carries one magnitude column per effect, then its shape columns, in ``columns``;
        "none" has none). The columns are ordered calibration factors, magnitudes, shapes,
        channel gain and delay.

        The covariance is the Laplace posterior covariance plus, with ``bias`` (the
        standardised change of the training coefficients under the discretisation check),
        the square of the parameter shift that change would cause if it were all
        systematic: the model's own discretisation error moves a fitted magnitude without
        adding scatter, and an interval from the scatter alone would not cover it. eta: the
        likelihood's learning rate (:func:`~dampersim.discrepancy.selection.learning_rate`)."""
        jac, prec = self._evidence_columns(fit, names)
        cov = selection.posterior_covariance(jac, prec, eta)
        if bias is not None:
            shift = eta * (cov @ (jac.T @ bias))
            cov = cov + np.outer(shift, shift)
        loss = self.data_loss(fit["y"], fit["nuisance"])
        # plus the log prior mass of the discrete shapes the screen chose (0 for most effects)
        log_z = selection.log_evidence(fit["cost"], jac, prec, eta, loss, self._offset(fit, names))
        return log_z + fit.get("log_mass", 0.0), cov

    def _evidence_columns(self, fit, names) -> tuple:
        """(Jacobian, prior precisions) of a fitted model's parameters in the evidence's order."""
        cols = fit.get("columns", [])
        nu_cols, nu_prec = self._nuisance(fit["y"], fit["nuisance"])
        jac = np.column_stack([self.jac_of(fit), *cols, nu_cols])
        prec = np.concatenate([self.prec_cal, np.full(len(names), 1.0 / selection.MAGNITUDE_PRIOR_SD ** 2),
                               np.full(len(cols) - len(names), 1.0 / selection.SHAPE_PRIOR_SD ** 2), nu_prec])
        return jac, prec

    def unnamed_inputs(self, fit, eta: float = 1.0) -> dict:
        """What the torsional evidence gain of an unnamed smooth misfit beside a fitted model is
        computed from, as :func:`dampersim.discrepancy.unnamed.torsion_gain`'s arguments: the
        standardised training residual, the Jacobian and prior precisions of the model's
        evidence columns, the parameters' offsets from their prior centres, the learning rate
        eta and the misfit's basis (:func:`~dampersim.discrepancy.unnamed.torsion_basis`)."""
        r, jac, prec, offset = self.linearised(fit)
        return {"r_fit": r, "jac": jac, "prec": prec, "offset": offset, "eta": float(eta),
                "basis": unnamed.torsion_basis(self.lik, fit["y"], self.train, fit["nuisance"])}

    def linearised(self, fit) -> tuple:
        """(standardised training residual at the fit's nuisance, Jacobian and prior precisions
        of the evidence's columns, the parameters' offsets from their prior centres) of a fitted
        model: its objective linearised at the fit, as the evidence reads it."""
        jac, prec = self._evidence_columns(fit, fit["effects"])
        with self.lik.using(fit["nuisance"]):
            r = self.lik.mvec(self.train) - self.lik.vec(fit["y"], self.train)
        return r, jac, prec, self._offset(fit, fit["effects"])

    def _offset(self, fit, names) -> np.ndarray:
        """The fitted parameters minus their prior centres, in the evidence's column order:
        calibration factors, magnitudes (log, against the typical value), shapes (log,
        against the parameter set's values), channel log gain and delay."""
        mags = [fit.get("m_first", fit.get("m")), fit.get("m")][-len(names):] if names else []
        moved = fit.get("shapes") or {}
        start = fit.get("shape_start") or {}
        own = self.library_effect(names[-1]) if start else None
        return np.concatenate([np.asarray(fit["x"], dtype=float),
                               [math.log(m / info(n).magnitudes[1]) for n, m in zip(names, mags)],
                               [shapes.log_ratio(moved.get(q, v), float(getattr(own, q))) for q, v in start.items()],
                               np.asarray(fit["nuisance"], dtype=float)])

    def data_loss(self, y, nuisance) -> float:
        """The robust chi^2 of model coefficients y on the training points at ``nuisance``
        (the data part of a fit's objective, without any prior term)."""
        with self.lik.using(nuisance):
            return self.lik.loss(y, self.train) - self.lik.nuisance_prior()

    # --- detectability --------------------------------------------------------------------
    def detectability(self, name, y_cal, nuisance, y_typ, priors, ramp_gain=None, eta: float = 1.0,
                      jac=None) -> float | None:
        """The magnitude at the detection threshold of effect ``name`` for this campaign
        (:func:`dampersim.discrepancy.detect.threshold`, which takes the same arguments)."""
        return detect.threshold(self, name, y_cal, nuisance, y_typ, priors, ramp_gain, eta, jac)


def _with_factors(starts, base, x):
    """The estimated parameter set (the estimated start's) with calibration factors exp(x),
    or ``base`` unchanged when fitting on top of another effect."""
    return base if base is not None else calibrated_system(starts["estimated"][0], x)


__all__ = ["SHAPES", "MIN_SCREEN_SCALE", "SECOND_START_NATS", "REFIT_ITERATIONS", "Namer",
           "clip_magnitude"]
