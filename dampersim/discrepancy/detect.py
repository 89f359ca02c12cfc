"""The detection threshold of a missing effect for a campaign: the smallest magnitude whose
evidence against "no missing effect" would reach the detection posterior, read from the
likelihood's curvature after the calibration, the channels' nuisance and an unnamed smooth
misfit have taken what they can of the effect's signature.

The effect is read at the parameter set's own shape (the library's, unless the set says
otherwise), not at the shape a screen or fit found.
"""

from __future__ import annotations

import numpy as np

from dampersim.discrepancy import selection, unnamed
from dampersim.discrepancy.effects import info, parameters_of, with_effect


def threshold(namer, name, y_cal, nuisance, y_typ, priors, ramp_gain=None, eta: float = 1.0,
              jac=None) -> float | None:
    """The magnitude at the detection threshold of effect ``name`` for this campaign:
    where the chi^2 improvement it would bring, after the calibration and the channels'
    gain and delay have absorbed what they can (its signature projected off those
    directions under their priors), minus what an unnamed smooth misfit beside "none"
    would take of it (:func:`dampersim.discrepancy.unnamed.signature_share`, on the
    torsional points and the ramps) and its magnitude prior's cost, reaches what a
    posterior of DETECTION_POSTERIOR against "none" needs
    (:func:`~dampersim.discrepancy.selection.detection_chi2`). ramp_gain(name, m): (the
    chi^2 the ramps would add at magnitude m, the unnamed misfit's ramp D at that
    signature, at none; see :func:`~dampersim.discrepancy.unnamed.signature_share`) (None:
    torsional points only); eta: the
    likelihood's learning rate, which scales the torsional chi^2 (a threshold read against
    the misfit the calibrated model really leaves); jac: the calibrated model's factor
    Jacobian (default the calibration's; :meth:`Namer.jac_of` of "none")."""
    e = info(name)
    meta = next(p for p in parameters_of(name) if p["name"] == e.magnitude)
    cal = namer.starts["calibrated"][0]
    nu_cols, nu_prec = namer._nuisance(y_cal, nuisance)
    absorb = np.column_stack([namer.jac if jac is None else jac, nu_cols])
    prec = np.concatenate([namer.prec_cal, nu_prec])
    a = eta * (absorb.T @ absorb) + np.diag(prec)
    basis = unnamed.torsion_basis(namer.lik, y_cal, namer.train, nuisance)
    mags, gains = [], []
    for m in e.magnitudes:
        if m == e.magnitudes[1] and y_typ is not None:
            y = y_typ
        else:
            y, failed = namer.runs(with_effect(cal, name, {e.magnitude: m}), name)
            if failed:
                continue
        with namer.lik.using(nuisance):
            d = namer.w(y - y_cal)
        proj = absorb.T @ d
        mags.append(m)
        ramps, *ramp_misfit = ramp_gain(name, m) if ramp_gain is not None else (0.0, 0.0, 0.0)
        torsional = eta * float(d @ d) - eta ** 2 * float(proj @ np.linalg.solve(a, proj))
        share = unnamed.signature_share(d, absorb, prec, eta, basis, ramp_misfit)
        gains.append(torsional - share + ramps - namer._magnitude_prior(name, m))
    if len(mags) < 2:
        return None
    needed = selection.detection_chi2(priors[name], priors["none"])
    return selection.threshold_magnitude(mags, gains, needed, e.grows, (meta["min"], meta["max"]))


__all__ = ["threshold"]
