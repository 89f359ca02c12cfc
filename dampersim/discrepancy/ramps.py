"""Hysteresis ramps in the likelihood: the windup curve of every ramp point, compared as a
chi^2 with uncertainties from the record and the model.

A ramp is replayed with its measured input torque (:func:`dampersim.discrepancy.drive.
simulate_point`); the simulated and measured windup are low-passed at 10 Hz as the loops of
[thesis] §3.4 and compared at RAMP_SAMPLE_HZ samples per second. Uncertainty of a sample:

* the windup channel's noise that passes the low pass: the standard deviation of the raw
  channel minus its low-passed self, times sqrt(pi fc / fs) (a first-order low pass passes
  the noise bandwidth pi/2 fc of the Nyquist band fs/2);
* the model's discretisation: the change of the low-passed windup when the ramp runs with
  two thirds of the spring segments (as for the torsional points);
* a floor of WINDUP_FLOOR_DEG.

The angle channels' zero is a nuisance: one offset per ramp under a Gaussian prior of
OFFSET_PRIOR_DEG. The models are fitted on the torsional points; a ramp then enters each
model's evidence as a prediction (:meth:`RampLikelihood.predictive`): the residual's
covariance carries the fitted parameters' uncertainty through the ramp's sensitivity to them,
which also gives the smooth, correlated part of a ramp's misfit its proper weight. The
samples' uncertainty is scaled per model by the factor (at least 1, see SCALES) that makes
the ramps most likely. The samples, 0.5 s apart, are not independent where a smooth misfit
remains: the log likelihood of every model is multiplied by the effective share of
independent samples, (1 - rho) / (1 + rho) for the lag-one autocorrelation rho of the best
model's whitened residual (:func:`effective_share`), so sixty correlated samples do not
count as sixty pieces of evidence.
"""

from __future__ import annotations

import math

import numpy as np

from dampersim.discrepancy import drive
from dampersim.discrepancy.fitting import coarse_system
from dampersim.signal import lowpass_first_order

#: compared windup samples per second of ramp
RAMP_SAMPLE_HZ = 2.0
#: prior standard deviation of a ramp's windup zero (angle transducer offset) [deg]
OFFSET_PRIOR_DEG = 0.2
#: smallest windup uncertainty of a sample [deg]
WINDUP_FLOOR_DEG = 0.02
#: scales of the samples' uncertainty tried per model (the best is kept, maximum likelihood):
#: what the calibration cannot reach (friction factors perturbed one by one, the rig) leaves a
#: smooth windup misfit far above the channel noise, the same for every model; with a scale
#: fitted per model a ramp favours a model by how much of that misfit it removes, not by the
#: misfit's absolute size in units of the channel noise
SCALES = tuple(np.geomspace(1.0, 1000.0, 31))


def _filtered(x, fs: float) -> np.ndarray:
    return lowpass_first_order(np.asarray(x, dtype=float), fs, min(drive.RAMP_FILTER_HZ, 0.45 * fs))


def _samples(point) -> np.ndarray:
    step = max(1, int(round(point.sample_rate_hz / RAMP_SAMPLE_HZ)))
    return np.arange(step // 2, len(point.windup), step)


def windup_noise(point) -> float:
    """Noise [rad] of the point's windup channel after the 10 Hz low pass."""
    fs = point.sample_rate_hz
    raw = np.asarray(point.windup, dtype=float)
    fc = min(drive.RAMP_FILTER_HZ, 0.45 * fs)
    return float(np.std(raw - _filtered(raw, fs)) * math.sqrt(math.pi * fc / fs))


def effective_share(whitened, lengths) -> float:
    """The share of independent samples in a residual whose samples follow each other in
    time (one run per ramp, ``lengths`` samples each): (1 - rho) / (1 + rho) for its pooled
    lag-one autocorrelation rho (an AR(1) process's effective sample size over its length),
    1 for rho <= 0, never below one sample per ramp."""
    e = np.asarray(whitened, dtype=float)
    n = len(e)
    if n < 3:
        return 1.0
    num, den, k = 0.0, 0.0, 0
    for m in lengths:
        seg = e[k:k + m] - np.mean(e[k:k + m])
        k += m
        num += float(np.sum(seg[1:] * seg[:-1]))
        den += float(np.sum(seg * seg))
    rho = num / den if den > 0 else 0.0
    if rho <= 0:
        return 1.0
    return float(max((1.0 - rho) / (1.0 + rho), len(lengths) / n))


def ramp_reference(ll: dict) -> str:
    """The model whose ramp prediction is best (highest log likelihood; "none" when every
    model failed): the ramps' noise is read off its residual. Its uncertainty scale is the
    one detectability thresholds are read against, since the scale "none" fits
    to a campaign with a free play grows with that free play's own misfit, and would
    make the effect present in the data look undetectable (benchmark case
    effect/output_backlash/strong/s0 on commit 19acb87: named with posterior 0.999 but
    detectability null)."""
    finite = {m: v for m, v in ll.items() if math.isfinite(v)}
    return max(finite, key=lambda m: finite[m]) if finite else "none"


def run_ramps(runner, system, points) -> dict:
    """{point id: simulated windup [rad] on the record's time base, or the run's error text}."""
    return windups(points, runner.map([(drive.diagnosis_system(system), p) for p in points]))


def windups(points, outs) -> dict:
    """{point id: windup [rad], or the run's error text} of the runs ``outs`` of ``points``."""
    return {p.id: (o["windup"] if "windup" in o else o.get("error", "no result")) for p, o in zip(points, outs)}


class RampLikelihood:
    """chi^2 of model windups against the measured ramps (offset per ramp fitted)."""

    def __init__(self, points, base: dict, coarse: dict):
        self.points = [p for p in points if not isinstance(base.get(p.id), str)]
        self.scale = 1.0  # the uncertainty scale of the last prediction
        self.whitened = None  # the last prediction's whitened residual
        self.fraction = 1.0  # the effective share of independent samples (see effective_share)
        self.scales = {}  # {model: its prediction's uncertainty scale} (settle)
        self.reference = "none"  # the model whose ramp prediction is best (settle, ramp_reference)
        self.unnamed_inputs = None  # what the unnamed misfit's gain beside "none" is computed from (ramp_models)
        self.meas, self.sigma, self.idx = {}, {}, {}
        floor = math.radians(WINDUP_FLOOR_DEG)
        for p in self.points:
            i = _samples(p)
            fs = p.sample_rate_hz
            self.idx[p.id] = i
            self.meas[p.id] = _filtered(p.windup, fs)[i]
            model = np.zeros(len(i))
            if not isinstance(coarse.get(p.id), str) and coarse.get(p.id) is not None:
                model = np.abs(_filtered(coarse[p.id], fs) - _filtered(base[p.id], fs))[i]
            self.sigma[p.id] = np.sqrt(windup_noise(p) ** 2 + model ** 2 + floor ** 2)

    @property
    def residuals(self) -> int:
        """Number of compared samples."""
        return int(sum(len(i) for i in self.idx.values()))

    def _model(self, windups: dict):
        """Low-passed samples of simulated windups, stacked over the ramps (None if a run
        failed: a failed run is no match)."""
        out = []
        for p in self.points:
            w = windups.get(p.id)
            if w is None or isinstance(w, str):
                return None
            out.append(_filtered(w, p.sample_rate_hz)[self.idx[p.id]])
        return np.concatenate(out) if out else np.zeros(0)

    def residual(self, windups: dict):
        """Measured minus simulated samples [rad], stacked (None if a run failed)."""
        y = self._model(windups)
        return None if y is None else np.concatenate([self.meas[p.id] for p in self.points]) - y

    def column(self, windups: dict, base: dict, step: float):
        """d samples / d parameter from a run with the parameter moved by ``step`` (zeros if
        that run failed: no direction, never a fit)."""
        a, b = self._model(windups), self._model(base)
        return np.zeros(self.residuals) if a is None or b is None else (a - b) / step

    def lengths(self) -> list:
        """Number of compared samples of each ramp, in stacking order."""
        return [len(self.idx[p.id]) for p in self.points]

    def torque_samples(self) -> list:
        """The low-passed input torque [N m] at the compared samples of each ramp, in stacking
        order (the same low pass and samples as the windups)."""
        return [_filtered(np.asarray(p.input_torque, dtype=float), p.sample_rate_hz)[self.idx[p.id]]
                for p in self.points]

    def offset_columns(self) -> np.ndarray:
        """d samples / d offset of each ramp's angle zero (samples x ramps)."""
        cols, k = np.zeros((self.residuals, len(self.points))), 0
        for j, p in enumerate(self.points):
            n = len(self.idx[p.id])
            cols[k:k + n, j] = 1.0
            k += n
        return cols

    def chi2(self, windups: dict) -> tuple:
        """(total chi^2, {point id: chi^2}) of simulated windups {id: rad} with each ramp's
        offset fitted; a failed run makes the total infinite."""
        total, per = 0.0, {}
        so = math.radians(OFFSET_PRIOR_DEG)
        for p in self.points:
            w = windups.get(p.id)
            if w is None or isinstance(w, str):
                per[p.id] = math.inf
                total = math.inf
                continue
            r = self.meas[p.id] - _filtered(w, p.sample_rate_hz)[self.idx[p.id]]
            wgt = 1.0 / self.sigma[p.id] ** 2
            off = float(np.sum(r * wgt) / (np.sum(wgt) + 1.0 / so ** 2))
            c = float(np.sum((r - off) ** 2 * wgt) + (off / so) ** 2)
            per[p.id] = c
            total += c
        return total, per

    def parts(self, jac, cov):
        """(J, C, sample variances): the sensitivities with the ramps' angle offsets appended,
        the parameter covariance with the offsets' prior, and sigma^2 of every sample."""
        so2 = math.radians(OFFSET_PRIOR_DEG) ** 2
        off = self.offset_columns()
        j = np.column_stack([np.asarray(jac, dtype=float).reshape(self.residuals, -1), off])
        n = j.shape[1] - off.shape[1]
        c = np.zeros((j.shape[1], j.shape[1]))
        c[:n, :n] = cov
        c[n:, n:] = np.eye(off.shape[1]) * so2
        return j, c, np.concatenate([self.sigma[p.id] ** 2 for p in self.points])

    def _covariance(self, jac, cov, scale: float):
        """diag((scale sigma)^2) + J C J' (see :meth:`parts`)."""
        j, c, sig2 = self.parts(jac, cov)
        return np.diag(sig2 * scale ** 2) + j @ c @ j.T

    def signature(self, windups: dict, base: dict):
        """An effect's ramp signature: its compared samples minus the base model's [rad],
        stacked (None when a run failed or there are no samples)."""
        a, b = self._model(windups), self._model(base)
        return None if not self.residuals or a is None or b is None else a - b

    def signature_gain(self, windups: dict, base: dict, jac, cov, scale: float | None = None) -> float:
        """The chi^2 an effect's ramp signature (windups minus the base model's) would add
        against a model with parameter covariance ``cov`` through sensitivities ``jac`` and
        uncertainty scale ``scale`` (default: ``noise_scale``, set by :meth:`settle`): what
        the calibration and the offsets cannot absorb (0 when a run failed or there are no
        samples)."""
        return self.signature_chi2(self.signature(windups, base), jac, cov, scale)

    def signature_chi2(self, d, jac, cov, scale: float | None = None) -> float:
        """:meth:`signature_gain` of a signature ``d`` already taken (:meth:`signature`; None:
        0)."""
        if d is None:
            return 0.0
        scale = self.noise_scale if scale is None else scale
        return self.fraction * float(d @ np.linalg.solve(self._covariance(jac, cov, scale), d))

    def settle(self, ll: dict, scales: dict, whitened: dict) -> dict:
        """Fix the ramps' noise from every model's prediction ({model: log likelihood},
        {model: fitted uncertainty scale}, {model: whitened residual}, as :meth:`predictive`
        left them): the model whose prediction is best (:func:`ramp_reference`) gives the
        samples' effective share ``fraction`` (its residual is the least systematic) and the
        ``noise_scale`` detectability is read against. Returns the log likelihoods scaled by
        that share."""
        best = ramp_reference(ll)
        if whitened.get(best) is not None and math.isfinite(ll[best]):
            self.fraction = effective_share(whitened[best], self.lengths())
            ll = {m: v * self.fraction for m, v in ll.items()}
        self.scales, self.reference = dict(scales), best
        return ll

    @property
    def noise_scale(self) -> float:
        """The uncertainty scale of the best ramp prediction (1 before :meth:`settle`; that of
        "none" when every prediction failed, see :func:`ramp_reference`)."""
        return float(self.scales.get(self.reference, 1.0))

    @staticmethod
    def fit_scale(r, sig2, extra, scales=SCALES):
        """The samples' uncertainty scale, fitted (maximum likelihood over ``scales``, at least
        1): the best (log likelihood up to a constant, chi^2, covariance S, S^-1 r, scale) for
        r ~ N(0, diag(sig2 scale^2) + extra); None when no scale gives a proper covariance."""
        best = None
        const = float(np.sum(np.log(sig2))) if np.all(sig2 > 0) else 0.0  # common to all models
        for scale in scales:
            s = np.diag(sig2 * scale ** 2) + extra
            sign, logdet = np.linalg.slogdet(s)
            if sign <= 0:
                continue
            sol = np.linalg.solve(s, r)
            chi2 = float(r @ sol)
            ll = -0.5 * chi2 - 0.5 * (logdet - const)
            if best is None or ll > best[0]:
                best = (ll, chi2, s, sol, scale)
        return best

    def predictive(self, windups: dict, jac, cov):
        """The ramps' log likelihood given a model fitted on the torsional points, with that
        fit's parameter uncertainty carried over (linearised): the samples' residual r is
        Gaussian with covariance diag(sigma^2) + J cov J' (J: d samples / d parameters, the
        ramps' angle offsets appended with their prior), so a ramp does not condemn a model
        for what its fit leaves uncertain. Returns (log likelihood up to a constant common to
        all models, times the effective share ``fraction``; chi^2; parameter update
        cov J' S^-1 r; updated covariance) or (-inf, inf, None, None) when a run failed. The
        whitened residual L^-1 r (S = L L') is kept as ``whitened``."""
        self.whitened = None
        if not self.residuals:  # no ramp whose calibrated run worked: the ramps say nothing
            return 0.0, 0.0, None, None
        r = self.residual(windups)
        if r is None:
            return -math.inf, math.inf, None, None
        j, c, sig2 = self.parts(jac, cov)
        n = j.shape[1] - len(self.points)
        ll, chi2, s, sol, self.scale = self.fit_scale(r, sig2, j @ c @ j.T)
        self.whitened = np.linalg.solve(np.linalg.cholesky(s), r)
        ll *= self.fraction
        gain = c @ j.T
        update = gain @ sol
        new_cov = c - gain @ np.linalg.solve(s, gain.T)
        return ll, chi2, update[:n], new_cov[:n, :n]


def ramp_likelihood(runner, calibrated, points):
    """(RampLikelihood, the calibrated model's windups) from the calibrated model's runs and
    its coarse-discretisation check."""
    base = run_ramps(runner, calibrated, points)
    coarse = run_ramps(runner, coarse_system(calibrated), points)
    return RampLikelihood(points, base, coarse), base


def errors_and_traces(stages: dict, points) -> tuple:
    """The ramp display of a diagnosis from windups already run, {stage: {id: windup or
    error text}}: ({stage: {id: windup error deg}}, {id: {stage: windup}}, problems)."""
    errors, traces, problems = {}, {}, []
    for stage, runs in stages.items():
        errors[stage] = {}
        for p in points:
            w = runs.get(p.id)
            if w is None or isinstance(w, str):
                problems.append(drive.run_problem(p, f"the ramp's model run ({stage} parameter set) failed "
                                                  f"({w or 'no result'}); no windup error for it"))
                continue
            errors[stage][p.id] = drive.windup_error_deg(w, p)
            traces.setdefault(p.id, {})[stage] = w
    return errors, traces, problems


__all__ = ["RAMP_SAMPLE_HZ", "OFFSET_PRIOR_DEG", "WINDUP_FLOOR_DEG", "effective_share", "ramp_reference", "windup_noise",
           "run_ramps", "windups",
           "RampLikelihood",
           "ramp_likelihood", "errors_and_traces"]
