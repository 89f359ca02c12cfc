"""The diagnosis likelihood: complex output orders weighted by uncertainties from the data.

Each torsional point and engine order k gives one complex residual: the measured output
order coefficient minus the model's, both read on the point's measured shaft angle over
the same revolutions (:mod:`dampersim.discrepancy.tracking`). The model is driven by the
measured input torque, so this is the residual of the complex order ratio output/input
times the measured input coefficient: amplitude and phase both count (damping and
stiffness differ in phase where amplitudes alone cannot tell them apart).

Uncertainty of a cell (complex standard deviation s, each of the real and imaginary parts
s / sqrt(2)):

* **repeatability** from the record's two halves: for orders the input carries, half the
  difference of the halves' complex ratios output/input times the whole record's input
  coefficient; for orders the damper generates, half the difference of the halves' output
  coefficients (both halves read on the whole record's angle, so their phases share one
  reference). Half the difference of two half-record estimates has the variance of the whole
  record's estimate. One record gives one such sample per cell, so the variance used is the
  mean of that sample's square and the per-order median of the squares over the campaign's
  points divided by ln 2 (the median of an exponential variable is ln 2 of its mean): a
  single near-zero sample must not make a cell look exact, nor a single large one hide a
  point. The diagnosis can instead take half the difference of the halves' residuals against
  the model driven by the record (:func:`residual_half_sigma`, its ``repeatability="residual"``);
* **model**: the change of the model's coefficient when the same drive runs with two thirds
  of the spring segments (discretisation, and the physical scatter of chaotic orders, which
  moves by tens of per cent with any such change);
* **input channel**: the root mean square of the two changes of the model's coefficient when
  the same drive runs with the measured input torque moved up and down by
  :func:`input_mean_sd` (the input channel's zero and gain are not known better than that,
  and the drive's mean torque moves with them; near a knee of the characteristic the orders
  follow the mean torque steeply, and bend, so half the change from down to up can cancel);
* **uncalibrated parameters**: the root mean square of the model's change when the same
  drive runs with the parameter set moved one standard uncertainty up and down along each
  direction the calibration cannot follow (:data:`~dampersim.discrepancy.fitting.UNCALIBRATED`:
  the split inside a calibration group, the tertiary inertia), summed over the directions.
  A calibration that scales a group together cannot undo an error in the group's split; near
  a knee of the characteristic that error moves the orders by many times a record's noise;
* **mains pick-up** on the output channel where a mains line falls on an order, measured on
  the campaign's records where it falls between the orders (:mod:`dampersim.discrepancy.pickup`);
* a floor of SIGMA_FLOOR_SHARE of the campaign's largest output order.

The three model terms are measured by :mod:`dampersim.discrepancy.model_terms`, at the
parameter set given and again at the calibrated one (the diagnosis, step 2b).

The channels' relative gain and delay are nuisance parameters fitted with every model
(:meth:`Likelihood.fit_nuisance`), each under a Gaussian prior: a skew between the channels
turns the phase of order k by k·Ω·τ and must not read as a transducer's bandwidth, a gain
error must not read as a stiffness. A robust loss (:func:`robust_loss`) bounds the influence
of one point: a point whose standardised misfit stands far above the others' is down-
weighted and flagged as an outlier.
"""

from __future__ import annotations

import contextlib
import math

import numpy as np

from dampersim.discrepancy import tracking

#: prior standard deviation of the relative output/input channel gain (log): the torque
#: transducers' calibration tolerance and the DAQ's gain errors (about 1 % each) with room
#: for a transducer off its calibration by a few per cent
GAIN_PRIOR_SD = 0.03
#: prior standard deviation of the output channel's delay against the input [s]: a DAQ's
#: channel skew (up to 0.2 ms in the synthetic DAQ) and transducer phase lag, with room for
#: a filter group delay of a few samples at 10 kHz
DELAY_PRIOR_SD = 5e-4
#: standard uncertainty of the input torque channel's zero offset [N m] and relative gain
#: [-]. The model is driven by the measured input torque, so both move the drive's mean
#: torque. A 3 kN m transducer's zero moves by about 1.5 N m per 10 K; transducer and
#: amplifier calibration leave about 1 %. The synthetic DAQ (daq.random_corruption) draws
#: narrower: uniform within +-2 N m and +-1 % (RMS 1.15 N m and 0.58 %; what that does to
#: the controls' chi^2 is in docs/discrepancy.md, "What control/none/4's held-out chi^2 of
#: 0.11 is made of"). Away from the knees a gain error is what the calibration factors
#: and the output gain nuisance absorb together; near a knee of the damper's characteristic
#: (the stops sit at fixed angles) the orders follow the mean torque steeply (the 18/8 set
#: driven by a record of itself at 1800 rpm and 350 N m, tests/discrepancy/test_input_channel.py:
#: 0.96 N m of 18 on order 2 for a 1.5 N m offset, against a record's order uncertainty of
#: 0.02-0.05 N m). Carried as an uncertainty rather than fitted: a fitted offset and gain,
#: with that leverage, bent towards a missing effect's signature in the calibration
#: (docs/discrepancy.md, The likelihood)
INPUT_OFFSET_SD = 1.5
INPUT_GAIN_SD = 0.01


def input_mean_sd(mean_torque_nm: float) -> float:
    """Standard uncertainty [N m] of a record's mean input torque ``mean_torque_nm`` [N m]
    from the input channel's zero and gain (INPUT_OFFSET_SD, INPUT_GAIN_SD)."""
    return math.hypot(INPUT_OFFSET_SD, INPUT_GAIN_SD * mean_torque_nm)


#: smallest cell uncertainty, as a share of the campaign's largest output order amplitude
SIGMA_FLOOR_SHARE = 1e-3
#: Huber threshold of the robust loss: a point's RMS standardised residual above
#: ROBUST_C times max(1, the median point's) is down-weighted (and flagged)
ROBUST_C = 3.0
#: Gauss-Newton iterations of the nuisance fit (two parameters, nearly linear)
NUISANCE_ITERATIONS = 4


def measured_coefficients(point, orders) -> np.ndarray:
    """Complex output order coefficients [N m] of a measured torsional point over the whole
    record (amplitude·exp(i·phase) on the tracked angle; real amplitudes without a speed
    channel)."""
    if getattr(point, tracking.SPEED_CHANNEL, None) is None:
        return tracking.point_orders(point, point.output_torque, orders).astype(complex)
    return tracking.tracked(point, point.output_torque, orders).complex


def split_half_sigma(point, orders) -> np.ndarray:
    """Complex standard deviation [N m] of each output order coefficient from the record's
    two halves, measured alone: for the orders the input carries, half the difference of the
    halves' ratios output/input times the whole record's input coefficient, else half the
    difference of the halves' output coefficients (:func:`tracking.half_coefficients`).
    The diagnosis's default record term (its ``repeatability="split_half"``)."""
    read = tracking.record_angle_reader(point, orders)
    (i1, i2), (o1, o2) = (tracking.half_coefficients(point, point.input_torque, orders, read),
                          tracking.half_coefficients(point, point.output_torque, orders, read))
    n = len(point.time) // 2
    a_in = (tracking.point_orders(point, point.input_torque, orders, slice(0, 2 * n)).astype(complex) if read is None
            else read(point.input_torque, slice(0, 2 * n)))
    driven = np.abs(a_in) >= 0.01 * max(float(np.abs(a_in).max()), 1e-12)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = 0.5 * np.abs(o1 / i1 - o2 / i2) * np.abs(a_in)
    return np.where(driven & np.isfinite(ratio), ratio, 0.5 * np.abs(o1 - o2))


def residual_half_sigma(point, model_halves, orders) -> np.ndarray:
    """Complex standard deviation [N m] of each cell's residual from the record's two halves:
    half the difference of the halves' residuals, measured output minus the model driven by
    the record (``model_halves``: the model's :func:`tracking.half_coefficients`, shape (2,
    orders)). The model reproduces what the recorded input drives; what it cannot reproduce
    from the record (sensor noise, the input channel's noise carried through the model,
    cycle-to-cycle scatter) differs between the halves, a systematic gap does not. The
    diagnosis's ``repeatability="residual"``; measured against a known truth by
    bench/bench_repeatability.py."""
    m1, m2 = tracking.half_coefficients(point, point.output_torque, orders)
    y1, y2 = np.asarray(model_halves)
    return 0.5 * np.abs((m1 - y1) - (m2 - y2))


def sigma_variances(repeat, model_change, meas, pickup=None, offset_change=None, uncalibrated=None) -> dict:
    """The terms of :func:`cell_sigma`, each a variance [N m^2] per (point, order) cell, from
    arguments that are standard deviations [N m]: ``repeat`` (the mean of the cell's
    repeatability variance, :func:`split_half_sigma` or :func:`residual_half_sigma`, and its
    per-order median over points), ``model`` (the discretisation change), ``mains``
    (``pickup``), ``input`` (the model's change under the input channel's uncertainty,
    ``offset_change``), ``uncalibrated`` (the model's change along the directions the
    calibration cannot follow) and ``floor`` (SIGMA_FLOOR_SHARE of the largest measured
    order); absent terms are zeros."""
    repeat = np.asarray(repeat, dtype=float)
    # the square of a complex Gaussian's magnitude is exponential: its median is ln 2 of its mean
    pooled = np.median(repeat ** 2, axis=0, keepdims=True) / math.log(2.0)
    floor = SIGMA_FLOOR_SHARE * max(float(np.nanmax(np.abs(meas))), 1e-9)
    model_change = np.nan_to_num(np.asarray(model_change, dtype=float), nan=0.0)

    def term(x):
        return np.zeros(repeat.shape) if x is None else np.asarray(x, dtype=float) ** 2

    return {"repeat": 0.5 * (repeat ** 2 + pooled), "model": model_change ** 2, "mains": term(pickup),
            "input": term(offset_change), "uncalibrated": term(uncalibrated),
            "floor": np.full(repeat.shape, floor ** 2)}


def cell_sigma(repeat, model_change, meas, pickup=None, offset_change=None, uncalibrated=None) -> np.ndarray:
    """Complex standard deviation [N m] of every (point, order) cell: the root of the sum of
    :func:`sigma_variances` (module docstring)."""
    v = sigma_variances(repeat, model_change, meas, pickup, offset_change, uncalibrated)
    return np.sqrt(v["repeat"] + v["model"] + (v["mains"] + v["input"]) + v["uncalibrated"] + v["floor"])


def robust_weights(point_chi2, n_per_point: int):
    """Huber weights of points from their chi^2 (n_per_point real residuals each):
    (weights, loss per point, flags). A point is down-weighted (and flagged) when its RMS
    standardised residual exceeds ROBUST_C times max(1, the median point's)."""
    z = np.sqrt(np.maximum(np.asarray(point_chi2, dtype=float), 0.0) / n_per_point)
    med = float(np.median(z)) if z.size else 1.0
    c = ROBUST_C * max(1.0, med)
    big = z > c
    w = np.where(big, c / np.where(big, z, 1.0), 1.0)
    loss = np.where(big, n_per_point * (2.0 * c * z - c * c), z * z * n_per_point)
    return w, loss, big


class Likelihood:
    """Weighted complex residuals of a set of torsional points.

    meas: complex measured coefficients (points x orders) [N m]; sigma: complex standard
    deviations (same shape) [N m]; speed: each point's mean speed [rad/s]; orders: engine
    orders. Model coefficients pass through the nuisance transform
    g·exp(-i·k·Ω·τ) (relative gain g = exp(log_gain), output delay τ [s]) before they are
    compared."""

    def __init__(self, meas, sigma, speed, orders):
        self.meas = np.asarray(meas, dtype=complex)
        self.sigma = np.asarray(sigma, dtype=float)
        self.speed = np.asarray(speed, dtype=float)
        self.orders = np.asarray(orders, dtype=float)
        self.nuisance = np.zeros(2)  # (log gain, delay [s])
        self.weights = np.ones(len(self.meas))  # robust point weights, refreshed by fit_nuisance

    # --- transforms -----------------------------------------------------------------------
    def _phase(self, rows):
        return np.outer(self.speed[rows], self.orders)  # k·Ω [rad/s]

    def transform(self, y, rows, nuisance=None) -> np.ndarray:
        """Model coefficients y (len(rows) x orders) after the channels' gain and delay."""
        lg, tau = self.nuisance if nuisance is None else nuisance
        return np.asarray(y, dtype=complex) * math.exp(lg) * np.exp(-1j * self._phase(rows) * tau)

    def _scale(self, rows):
        return (self.sigma[rows] / math.sqrt(2.0)) / np.sqrt(self.weights[rows])[:, None]

    def vec(self, y, rows) -> np.ndarray:
        """Standardised model vector (real and imaginary parts stacked) at the current
        nuisance and robust weights; vec(meas) - vec(model) is the weighted residual."""
        z = self.transform(y, rows) / self._scale(rows)
        return np.concatenate([z.real.ravel(), z.imag.ravel()])

    def mvec(self, rows) -> np.ndarray:
        z = self.meas[rows] / self._scale(rows)
        return np.concatenate([z.real.ravel(), z.imag.ravel()])

    def point_chi2(self, y, rows, nuisance=None) -> np.ndarray:
        """Unweighted chi^2 of each point (2 x orders real residuals each)."""
        d = (self.meas[rows] - self.transform(y, rows, nuisance)) / (self.sigma[rows] / math.sqrt(2.0))
        return np.sum(d.real ** 2 + d.imag ** 2, axis=1)

    def nuisance_prior(self, nuisance=None) -> float:
        lg, tau = self.nuisance if nuisance is None else nuisance
        return (lg / GAIN_PRIOR_SD) ** 2 + (tau / DELAY_PRIOR_SD) ** 2

    def nuisance_jacobian(self, y, rows) -> np.ndarray:
        """d vec / d (log gain, delay), standardised like :meth:`vec` (len x 2)."""
        z = self.transform(y, rows) / self._scale(rows)
        dz_tau = -1j * self._phase(rows) * z
        return np.column_stack([np.concatenate([z.real.ravel(), z.imag.ravel()]),
                                np.concatenate([dz_tau.real.ravel(), dz_tau.imag.ravel()])])

    # --- fitting ----------------------------------------------------------------------------
    def fit_nuisance(self, y, rows, refresh_weights: bool = True) -> np.ndarray:
        """Fit (log gain, delay) to model coefficients y at rows (Gauss-Newton under their
        priors) and refresh the robust point weights; returns the nuisance."""
        y = np.asarray(y, dtype=complex)
        if not np.all(np.isfinite(y)):
            return self.nuisance
        if refresh_weights:
            self.weights[rows] = 1.0
        nu = self.nuisance.copy()
        prec = np.array([1.0 / GAIN_PRIOR_SD ** 2, 1.0 / DELAY_PRIOR_SD ** 2])
        for _ in range(NUISANCE_ITERATIONS):
            self.nuisance = nu
            jac = self.nuisance_jacobian(y, rows)
            r = self.mvec(rows) - self.vec(y, rows)
            a = jac.T @ jac + np.diag(prec)
            nu = nu + np.linalg.solve(a, jac.T @ r - prec * nu)
        self.nuisance = nu
        if refresh_weights:
            w, _, _ = robust_weights(self.point_chi2(y, rows), 2 * len(self.orders))
            self.weights[rows] = w
        return nu

    def profile(self, y, rows) -> tuple:
        """(robust loss with the nuisance fitted to y, that nuisance), leaving the stored
        nuisance and weights as they were (for comparing trial models)."""
        saved = self.nuisance.copy(), self.weights.copy()
        try:
            nu = self.fit_nuisance(y, rows).copy()
            return self.loss(y, rows), nu
        finally:
            self.nuisance, self.weights = saved

    @contextlib.contextmanager
    def using(self, nuisance):
        """Temporarily compare at ``nuisance`` (for linearising around another model)."""
        saved = self.nuisance
        self.nuisance = np.asarray(nuisance, dtype=float)
        try:
            yield self
        finally:
            self.nuisance = saved

    def reweighting(self, y, rows, nuisance) -> np.ndarray:
        """Row factors that carry standardised vectors at ``rows`` (:meth:`vec`, :meth:`mvec`: at
        the stored robust weights) to the robust weights of model coefficients y at ``nuisance``.
        With the down-weighting threshold held, the robust loss's gradient in a point's residuals
        is that of a least-squares term weighted by its Huber weight (:func:`robust_weights`),
        so a Gauss-Newton step of the robust loss linearised at y takes these weights
        (iteratively re-weighted least squares); the stored ones are those of another model. The
        threshold follows the median point's misfit once that exceeds 1, a dependence left out
        here as re-weighted least squares with a fixed scale leaves it out. A row whose stored
        weight is 0 gets 0."""
        w, _, _ = robust_weights(self.point_chi2(y, rows, nuisance), 2 * len(self.orders))
        stored = self.weights[rows]
        ratio = np.divide(w, stored, out=np.zeros_like(w), where=stored > 0)
        per_row = np.repeat(np.sqrt(ratio), len(self.orders))
        return np.concatenate([per_row, per_row])

    def loss(self, y, rows) -> float:
        """Robust chi^2 of model coefficients y at rows (current nuisance), plus the nuisance
        prior; infinite when y is not finite (a failed run is never a good fit)."""
        y = np.asarray(y, dtype=complex)
        if not np.all(np.isfinite(y)):
            return math.inf
        _, loss, _ = robust_weights(self.point_chi2(y, rows), 2 * len(self.orders))
        return float(np.sum(loss)) + self.nuisance_prior()

    def outliers(self, y, rows, nuisance=None) -> np.ndarray:
        """Flags of the points the robust loss down-weights under model coefficients y."""
        _, _, big = robust_weights(self.point_chi2(y, rows, nuisance), 2 * len(self.orders))
        return big

    def robust_reduced_chi2(self, y, rows, nuisance=None) -> float:
        """The robust loss (no nuisance prior) per real residual of y at rows: one bad point
        cannot decide a verdict on its own."""
        y = np.asarray(y, dtype=complex)
        if not len(rows) or not np.all(np.isfinite(y)):
            return math.nan
        _, loss, _ = robust_weights(self.point_chi2(y, rows, nuisance), 2 * len(self.orders))
        return float(np.sum(loss) / (2 * len(rows) * len(self.orders)))

    def reduced_chi2(self, y, rows, nuisance=None) -> float:
        """Plain chi^2 per real residual of y at rows (given or current nuisance, no robust
        weights)."""
        y = np.asarray(y, dtype=complex)
        if not len(rows) or not np.all(np.isfinite(y)):
            return math.nan
        return float(np.sum(self.point_chi2(y, rows, nuisance)) / (2 * len(rows) * len(self.orders)))


__all__ = ["GAIN_PRIOR_SD", "DELAY_PRIOR_SD", "ROBUST_C", "measured_coefficients", "split_half_sigma",
           "residual_half_sigma", "sigma_variances", "cell_sigma", "robust_weights", "Likelihood"]
