"""The evidence that the residual of "no missing effect" holds a smooth misfit no library
effect names.

"none" (no library effect missing) is read as a mixture: with prior probability
1 - MISFIT_PRIOR the calibrated model as it is, with MISFIT_PRIOR the calibrated model plus
an unnamed smooth misfit, a linear combination of a few basis functions whose coefficients
have a Gaussian prior of spread sd, the spread itself uniform over a small grid that starts
at 0. For one kind of data the misfit's log evidence gain is

    D = log mean_sd N(r; 0, S + sd^2 B B') / N(r; 0, S)

(r the residual at the prior centre, S its covariance with the calibration and the channels
marginalised, linearised; B the basis), and "none" gains log(1 - q + q exp(D_torsional +
D_ramps)) (:func:`combined`). A candidate effect then has to explain the data better than
such a generic misfit does, not only better than the calibrated model: an effect that takes
up part of a misfit it does not express (a rig part, a friction law of another shape) no
longer wins by default. The effects themselves are not given the misfit: "an effect and an
unnamed misfit" would be a pair, and the ramps, which a wrong effect predicts badly, would
lose their power to refute it (tried: see docs/discrepancy.md, Benchmark).

* Torsional points: the complex order coefficients times (1 + sum_j (a_j + i b_j) P_j(u)),
  P_j Legendre polynomials of degree 0..TORSION_DEGREE in u, the excitation frequency
  k Omega's log mapped onto [-1, 1] over the training cells: a relative amplitude and
  phase error smooth in frequency, as a transfer path the model lacks (a rig part, a
  transducer) leaves. Spreads TORSION_SDS (relative).
* Ramps: the windup plus sum_j (c_j + d_j s) P_j(v), v the input torque over its largest
  magnitude in that ramp, s the torque's direction (+1 loading, -1 unloading): a smooth
  error of the loading and unloading curves, as a friction or stiffness law of another
  shape leaves. Spreads RAMP_SDS_DEG; the ramps' uncertainty scale is fitted again with
  the misfit present.
"""

from __future__ import annotations

import math

import numpy as np

from dampersim.discrepancy.ramps import SCALES, RampLikelihood

#: prior probability, within "no missing effect", that an unnamed smooth misfit is present
MISFIT_PRIOR = 0.2
#: highest Legendre degree in log frequency of the torsional misfit (amplitude and phase each)
TORSION_DEGREE = 3
#: prior spreads of the torsional misfit's coefficients (relative to the coefficient), grid
TORSION_SDS = (0.0, 0.01, 0.03, 0.1)
#: highest Legendre degree in normalised input torque of the ramps' misfit (each branch term)
RAMP_DEGREE = 3
#: prior spreads of the ramps' misfit coefficients [deg], grid
RAMP_SDS_DEG = (0.0, 0.03, 0.1, 0.3, 1.0)
#: a change of the sampled torque below this share of the ramp's largest one is a hold
HOLD_SHARE = 0.1
#: the arrays of a diagnosis's ``misfit_inputs``, per part: :func:`torsion_gain`'s arguments
#: (as naming.Namer.unnamed_inputs gives them) and :func:`ramp_inputs`'s keys
INPUT_KEYS = {"torsion": ("r_fit", "jac", "prec", "offset", "eta", "basis"),
              "ramps": ("residual", "sensitivity", "covariance", "sample_variance", "basis", "share")}


def legendre(u, degree: int) -> np.ndarray:
    """Legendre polynomials P_0..P_degree at u in [-1, 1] (len(u) x (degree + 1))."""
    return np.polynomial.legendre.legvander(np.asarray(u, dtype=float), degree)


def combined(torsional: float, ramps: float) -> float:
    """The log evidence "none" gains from the unnamed misfit: log(1 - q + q exp(D_t + D_r))
    with q = MISFIT_PRIOR. When the misfit explains nothing it costs between 0 and
    log(1 - q) = -0.22: -0.16 with the torsional D at its floor -log 4 (the grid's sd = 0
    term) and the ramps' at 0, -0.21 with both at their floors."""
    d = float(torsional) + float(ramps)
    q = MISFIT_PRIOR
    top = max(0.0, d)
    return float(top + math.log((1.0 - q) * math.exp(-top) + q * math.exp(d - top)))


def spread_gain(r_s, btb, sds) -> float:
    """log mean over ``sds`` of N(r; 0, S + sd^2 B B') / N(r; 0, S), from the whitened terms
    r_s = B' S^-1 r and btb = B' S^-1 B (matrix determinant lemma; sd = 0 gives 0)."""
    terms = []
    k = btb.shape[0]
    for sd in sds:
        if sd <= 0:
            terms.append(0.0)
            continue
        m = np.eye(k) / sd ** 2 + btb
        sign, logdet = np.linalg.slogdet(np.eye(k) + sd ** 2 * btb)
        if sign <= 0:
            terms.append(-math.inf)
            continue
        terms.append(0.5 * float(r_s @ np.linalg.solve(m, r_s)) - 0.5 * logdet)
    return _log_mean_exp(terms)


def _log_mean_exp(terms) -> float:
    """log of the mean of exp(terms) (the spreads' grid, weighted evenly)."""
    from scipy.special import logsumexp  # scipy loads only when a diagnosis runs

    return float(logsumexp(terms) - math.log(len(terms)))


def torsion_basis(lik, y, rows, nuisance) -> np.ndarray:
    """Standardised columns (as :meth:`Likelihood.vec`) of the torsional misfit's basis at
    model coefficients y (rows x orders): y P_j(u) and i y P_j(u) for j = 0..TORSION_DEGREE.
    y P_0 repeats the output channel's gain, whose prior (3 %) the misfit widens: an output
    gain that far off is part of what "none" may not express."""
    f = np.log(np.outer(lik.speed[rows], lik.orders))
    span = float(np.ptp(f))
    u = 2.0 * (f - f.min()) / span - 1.0 if span > 0 else np.zeros_like(f)
    p = legendre(u.ravel(), TORSION_DEGREE).reshape(*u.shape, TORSION_DEGREE + 1)
    y = np.asarray(y, dtype=complex)
    cols = []
    with lik.using(nuisance):
        for j in range(TORSION_DEGREE + 1):
            cols.append(lik.vec(y * p[..., j], rows))
            cols.append(lik.vec(1j * y * p[..., j], rows))
    return np.column_stack(cols)


def torsion_gain(r_fit, jac, prec, offset, eta: float, basis, sds=TORSION_SDS) -> float:
    """The torsional log evidence gain D of the unnamed misfit for a model fitted with
    standardised residual ``r_fit``, Jacobian ``jac`` of all its fitted parameters, their prior
    precisions ``prec``, their offsets from the prior centres ``offset`` and the likelihood's
    learning rate eta (the standardised noise variance is 1 / eta). Linear Gaussian: the
    residual at the prior centre is r_fit + J offset, with covariance S = I / eta + J P^-1 J'.
    sds: the coefficients' prior spreads (relative), weighted evenly."""
    jac = np.asarray(jac, dtype=float)
    r0 = np.asarray(r_fit, dtype=float) + jac @ np.asarray(offset, dtype=float)
    a = eta * (jac.T @ jac) + np.diag(np.asarray(prec, dtype=float))

    def s_inv(v):  # Woodbury: S^-1 = eta I - eta^2 J A^-1 J'
        return eta * v - eta ** 2 * (jac @ np.linalg.solve(a, jac.T @ v))

    sb = s_inv(basis)
    return spread_gain(sb.T @ r0, basis.T @ sb, sds)


def signature_share(d, jac, prec, eta: float, basis, ramps=(0.0, 0.0)) -> float:
    """What "none" gains from the unnamed misfit when its residual is an effect's signature,
    as chi^2: twice :func:`combined` at the signature over that at no signature (the
    calibration at its prior centre, the noise left out, as the detectability's chi^2 leaves
    it out). Torsional: :func:`torsion_gain` at the standardised signature d. ramps: the
    ramps' D at the effect's ramp signature and at none (:func:`ramp_signature_gain`; the D at
    none twice for an effect the ramps are not read for, 0 and 0 without ramps: combined is not
    additive, so the ramps' D at none moves even a torsional share). Near the signature's own
    chi^2 improvement (after the calibration) for a strong signature the basis follows, near 0
    for one it cannot follow."""
    zero = np.zeros(np.asarray(jac).shape[1])
    at_d = combined(torsion_gain(d, jac, prec, zero, eta, basis), ramps[0])
    return 2.0 * (at_d - combined(torsion_gain(np.zeros_like(d), jac, prec, zero, eta, basis), ramps[1]))


def ramp_direction(v) -> np.ndarray:
    """The torque's direction at each compared sample of one ramp (+1 loading, -1 unloading)
    from the change since the sample before: a change below HOLD_SHARE of the ramp's largest
    change between samples (a hold, or noise on it) keeps the direction the torque came with,
    as a hold stays on the branch it reached; the samples before the first move take that
    move's direction (+1 for a ramp that never moves)."""
    v = np.asarray(v, dtype=float)
    dv = np.diff(v, prepend=v[:1])
    big = np.zeros(len(v), dtype=bool)
    if np.any(dv):
        big = np.abs(dv) >= HOLD_SHARE * float(np.max(np.abs(dv)))
    out = np.empty(len(v))
    last = float(np.sign(dv[np.argmax(big)])) if np.any(big) else 1.0
    for k in range(len(v)):
        if big[k]:
            last = float(np.sign(dv[k]))
        out[k] = last
    return out


def ramp_basis(lik_r) -> np.ndarray:
    """Columns of the ramps' misfit basis over the stacked compared samples [rad per unit
    coefficient]: P_j(v) and s P_j(v) per ramp (:func:`ramp_direction`), block-diagonal over
    the ramps. P_0 repeats the ramp's angle offset, whose prior (0.2 deg) the misfit widens:
    a windup zero that far off is part of what "none" may not express."""
    from scipy.linalg import block_diag  # scipy loads only when a diagnosis runs

    blocks = []
    for torque in lik_r.torque_samples():
        top = float(np.max(np.abs(torque))) if len(torque) else 0.0
        v = torque / top if top > 0 else np.zeros_like(torque)
        leg = legendre(v, RAMP_DEGREE)
        blocks.append(np.column_stack([leg, leg * ramp_direction(torque)[:, None]]))
    return block_diag(*blocks)


def ramp_inputs(lik_r, windups, jac, cov) -> dict | None:
    """What the ramps' misfit gain is computed from (:func:`ramp_gain_of`), as arrays a
    reader can keep and recompute it with: the compared samples' residual (measured minus
    simulated) [rad], the sensitivities with the ramps' angle offsets appended
    ``sensitivity`` [rad per unit parameter], the parameters' covariance ``covariance``, the
    samples' variances ``sample_variance`` [rad^2] (as :meth:`RampLikelihood.parts` gives
    them), the basis :func:`ramp_basis` [rad per unit coefficient] and the samples'
    effective share ``share``. None without samples and for a failed run."""
    if not lik_r.residuals:
        return None
    r = lik_r.residual(windups)
    if r is None:
        return None
    j, c, sig2 = lik_r.parts(jac, cov)
    return {"residual": r, "sensitivity": j, "covariance": c, "sample_variance": sig2,
            "basis": ramp_basis(lik_r), "share": float(lik_r.fraction)}


def ramp_gain_of(inputs, scales, sds_deg=RAMP_SDS_DEG) -> float:
    """The ramps' log evidence gain D of the unnamed misfit from :func:`ramp_inputs`: for
    every spread of ``sds_deg`` [deg] the samples' uncertainty scale is fitted again over
    ``scales``, and the log likelihoods are tempered by the effective share, as the ramps'
    own term is. 0 for no inputs (no samples, a failed run: its ramp term is already -inf)."""
    if inputs is None:
        return 0.0
    j, c = inputs["sensitivity"], inputs["covariance"]
    jcj = j @ c @ j.T
    basis = inputs["basis"]
    bbt = basis @ basis.T
    best = []
    for sd in (math.radians(d) for d in sds_deg):
        fit = RampLikelihood.fit_scale(inputs["residual"], inputs["sample_variance"], jcj + sd ** 2 * bbt, scales)
        best.append(-math.inf if fit is None else inputs["share"] * fit[0])
    if not math.isfinite(best[0]):  # no scale gives a proper covariance without the misfit: no gain is read
        return 0.0
    return _log_mean_exp(np.asarray(best) - best[0])


def gains(inputs, eta=None, torsion_sds=TORSION_SDS, ramp_sds_deg=RAMP_SDS_DEG) -> tuple:
    """(D_torsional, D_ramps) of the unnamed misfit from a diagnosis's ``misfit_inputs``
    ({"torsion": :func:`torsion_gain`'s arguments, "ramps": :func:`ramp_inputs` or None}):
    what the diagnosis reads, and, with another learning rate ``eta`` or other spreads, what
    the same residuals would give (bench/bench_unnamed_replay.py)."""
    t = dict(inputs["torsion"])
    if eta is not None:
        t["eta"] = float(eta)
    return torsion_gain(**t, sds=torsion_sds), ramp_gain_of(inputs["ramps"], SCALES, ramp_sds_deg)


def ramp_signature_gain(inputs, d, scale: float, sds_deg=RAMP_SDS_DEG) -> float:
    """The ramps' D of the unnamed misfit when the compared samples' residual is ``d`` [rad]
    (an effect's ramp signature; zeros for none), from "none"'s :func:`ramp_inputs`, at the
    fixed uncertainty scale ``scale`` that detectability reads the ramps against
    (:attr:`RampLikelihood.noise_scale`: a signature must not buy itself a wider noise):
    :func:`ramp_gain_of` with ``d`` as the residual and ``scale`` the only scale. 0 for no
    inputs."""
    return 0.0 if inputs is None else ramp_gain_of({**inputs, "residual": np.asarray(d, dtype=float)}, (scale,),
                                                   sds_deg)


__all__ = ["MISFIT_PRIOR", "INPUT_KEYS", "combined", "TORSION_DEGREE", "TORSION_SDS", "RAMP_DEGREE", "RAMP_SDS_DEG",
           "HOLD_SHARE", "legendre", "spread_gain", "torsion_basis", "torsion_gain", "signature_share",
           "ramp_direction", "ramp_basis", "ramp_inputs", "ramp_gain_of", "gains", "ramp_signature_gain"]
