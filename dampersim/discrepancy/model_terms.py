"""The likelihood's model-based uncertainty terms, measured as changes of one model's order
coefficients when the same drive runs with the model moved.

Three terms (:mod:`dampersim.discrepancy.likelihood`, module doc): the discretisation check
(two thirds of the spring segments), the input channel (the measured input torque moved up
and down by :func:`~dampersim.discrepancy.likelihood.input_mean_sd`) and what the
calibration cannot follow (the parameter set moved one standard uncertainty up and down
along each direction of :data:`~dampersim.discrepancy.fitting.UNCALIBRATED`). They are
sensitivities of the model, so they depend on where the model sits on its characteristic:
near a knee (the stops sit at fixed angles, the knee's torque moves with the spring rates)
the orders follow the mean torque and the spring split steeply, away from it hardly at all.
:func:`dampersim.discrepancy.diagnose.diagnose` therefore measures them twice: at the
parameter set as given, to calibrate, and again at the calibrated set, which sits nearer
the rig, for everything after the calibration.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dampersim.discrepancy import drive
from dampersim.discrepancy.fitting import coarse_system, uncalibrated_systems
from dampersim.discrepancy.likelihood import input_mean_sd

#: model runs per point of :func:`measure` (coarse model 1, input up and down 2, each
#: uncalibrated direction up and down 6)
RUNS_PER_POINT = 9


@dataclass
class ModelTerms:
    """The three terms at one parameter set, per (point, order) cell.

    y: the set's own complex coefficients [N m] (given, not run here); coarse: with two
    thirds of the segments [N m]; input_up, input_down: with the input moved [N m];
    uncalibrated: (2 x directions, points, orders), each direction moved up then down [N m];
    errors: {"coarse" | "input" | "uncalibrated": {row: message}} of the runs that failed
    (an input failure's row is the point's, whichever way it moved; an uncalibrated one's
    message names the direction). A failed run's cells are NaN."""

    y: np.ndarray
    coarse: np.ndarray
    input_up: np.ndarray
    input_down: np.ndarray
    uncalibrated: np.ndarray
    input_sd: list
    errors: dict = field(default_factory=dict)

    @property
    def model_change(self) -> np.ndarray:
        """|coarse - y| [N m]: the discretisation term's standard deviation."""
        return np.abs(self.coarse - self.y)

    @property
    def input_change(self) -> np.ndarray:
        """Root mean square of the two one-sided changes under the input channel's
        uncertainty [N m]: sqrt((|y_up - y|^2 + |y_down - y|^2) / 2). For a response linear
        in the mean torque it equals half the change from down to up; near a knee, where the
        response bends, half that difference cancels (at an extremum of an order it is zero
        while both moves change the order), the one-sided changes do not."""
        return np.sqrt(0.5 * (np.abs(self.input_up - self.y) ** 2 + np.abs(self.input_down - self.y) ** 2))

    @property
    def uncalibrated_change(self) -> np.ndarray:
        """Root of the summed mean square one-sided change over the directions the
        calibration cannot follow [N m]."""
        return np.sqrt(0.5 * np.sum(np.abs(self.uncalibrated - self.y) ** 2, axis=0))

    def failed_rows(self) -> set:
        """Rows at which any of the runs failed: a recorded error, or a non-finite cell of the
        set's own coefficients or of any check (also after :meth:`at`, which drops the errors)."""
        cells = [self.y, self.coarse, self.input_up, self.input_down, *self.uncalibrated]
        bad = np.any([~np.all(np.isfinite(c), axis=1) for c in cells], axis=0)
        return {int(i) for i in np.flatnonzero(bad)} | {i for errs in self.errors.values() for i in errs}

    def failure_texts(self) -> dict:
        """{row: what failed there} for every row of :meth:`failed_rows`."""
        names = {"coarse": "the discretisation check", "input": "the input check",
                 "uncalibrated": "the check of what the calibration cannot follow"}
        return {i: "; ".join(f"{names.get(k, k)}: {errs[i]}" for k, errs in self.errors.items() if i in errs)
                or "the set's own run" for i in sorted(self.failed_rows())}

    def at(self, rows) -> "ModelTerms":
        """These terms at the points ``rows`` only, without their errors."""
        rows = list(rows)
        return ModelTerms(self.y[rows], self.coarse[rows], self.input_up[rows], self.input_down[rows],
                          self.uncalibrated[:, rows], [self.input_sd[i] for i in rows])

    def filled_from(self, other: "ModelTerms", rows) -> "ModelTerms":
        """These terms with every failed row i (:meth:`failed_rows`) taken from row
        ``rows[i]`` of ``other`` (terms of another set measured on a list of points that
        ``rows`` maps these points into); no errors remain."""
        bad = sorted(self.failed_rows())
        out = ModelTerms(*(np.array(getattr(self, k)) for k in ("y", "coarse", "input_up", "input_down", "uncalibrated")),
                         input_sd=list(self.input_sd))
        for i in bad:
            j = rows[i]
            for k in ("y", "coarse", "input_up", "input_down"):
                getattr(out, k)[i] = getattr(other, k)[j]
            out.uncalibrated[:, i] = other.uncalibrated[:, j]
            out.input_sd[i] = other.input_sd[j]
        return out


def measure(runner, system, points, y) -> ModelTerms:
    """The three terms of ``system`` (a parameter set) driven by each torsional point of
    ``points``, whose own coefficients ``y`` [N m] (points x orders) the caller has run:
    :data:`RUNS_PER_POINT` runs per point, in three maps of ``runner``."""
    n = len(points)
    err_coarse, err_in = {}, {}
    y_coarse = drive.coefficients_of(runner, coarse_system(system), points, err_coarse)
    sd = [input_mean_sd(float(np.mean(p.input_torque))) for p in points]
    moved = [drive.rezeroed(p, s * d) for s in (-1.0, 1.0) for p, d in zip(points, sd)]
    y_moved = drive.coefficients_of(runner, system, moved, err_in)  # one map: up, then down
    sets = [(direction, s) for direction, pair in uncalibrated_systems(system) for s in pair]
    errs = [{} for _ in sets]
    y_unc = drive.coefficients_of_sets(runner, [s for _, s in sets], points, errs)  # one map
    err_unc = {}
    for (direction, _), e in zip(sets, errs):
        err_unc.update({i: f"{direction.replace('_', ' ')}: {msg}" for i, msg in e.items() if i not in err_unc})
    errors = {"coarse": err_coarse, "input": {i % n: msg for i, msg in err_in.items()}, "uncalibrated": err_unc}
    return ModelTerms(np.asarray(y), y_coarse, y_moved[:n], y_moved[n:], y_unc, sd, errors)


__all__ = ["RUNS_PER_POINT", "ModelTerms", "measure"]
