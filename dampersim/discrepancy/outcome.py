"""What a diagnosis returns: the :class:`Diagnosis` record, the check that a campaign can be
diagnosed at all, the verdict's sentence and where the residual lies (locate)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from dampersim.discrepancy.effects import NAMES
from dampersim.discrepancy.fitting import _rms
from dampersim.discrepancy.selection import DETECTION_POSTERIOR

#: fewest valid torsional test points a diagnosis accepts (every third is held out)
MIN_TORSIONAL_POINTS = 3
#: fewest distinct speeds: at one speed a calibration cannot tell inertia from stiffness,
#: nor a speed-dependent effect from a calibration factor
MIN_SPEEDS = 2
#: speeds within this share of each other count as one: an imported campaign carries the
#: measured mean speed, which scatters by tenths of a per cent around the set point
SAME_SPEED_SHARE = 0.02
#: the verdict of a campaign that cannot be diagnosed (``missing`` says what it lacks)
INSUFFICIENT = "insufficient_data"

@dataclass
class Diagnosis:
    """Everything the workflow found (JSON-ready through :meth:`to_json`)."""

    verdict: str
    effect: str | None
    effect_parameters: dict
    ranking: list
    noise_floor_nm: float
    gap_before_nm: float
    gap_calibrated_nm: float
    gap_after_nm: float
    held_out_points: list
    calibration: dict = field(default_factory=dict)
    locate: dict = field(default_factory=dict)
    points: list = field(default_factory=list)  # per point: id, speed, torque, held_out, orders
    residuals: dict = field(default_factory=dict)  # stage -> {point id: [8 errors N m]}
    ramps: dict = field(default_factory=dict)  # stage -> {point id: windup error deg}
    ramp_traces: dict = field(default_factory=dict)
    problems: list = field(default_factory=list)
    simulations: int = 0
    wall_time_s: float = 0.0
    system: object = None  # augmented (or calibrated) parameter set
    message: str = ""  # the verdict in one sentence (for INSUFFICIENT: what is missing, what is accepted)
    missing: list = field(default_factory=list)  # INSUFFICIENT: "torsional_points", "speeds", "held_out_points"
    posterior: dict = field(default_factory=dict)  # {model: probability}: "none", effects, pairs "a+b"
    effects: list = field(default_factory=list)  # most probable model: [{name, parameters, intervals}]
    detectability: dict = field(default_factory=dict)  # {effect: magnitude at the detection threshold or None}
    recommended_points: list = field(default_factory=list)  # [{kind, speed_rpm, mean_torque_nm, orders, protocol, reason}]
    outliers: list = field(default_factory=list)  # point ids the robust loss down-weights
    likelihood: dict = field(default_factory=dict)  # reduced chi^2, nuisance, log evidence, model priors
    #: what likelihood["unnamed_misfit"] is computed from, as arrays (not in the JSON):
    #: {"torsion": unnamed.torsion_gain's arguments, "ramps": unnamed.ramp_inputs or None}
    misfit_inputs: dict = field(default_factory=dict, repr=False, compare=False)

    def to_json(self) -> dict:
        return {
            "verdict": self.verdict,
            "effect": self.effect,
            "effect_parameters": self.effect_parameters,
            "ranking": self.ranking,
            "noise_floor_nm": self.noise_floor_nm,
            "gap_before_nm": self.gap_before_nm,
            "gap_calibrated_nm": self.gap_calibrated_nm,
            "gap_after_nm": self.gap_after_nm,
            "held_out_points": self.held_out_points,
            "calibration": self.calibration,
            "locate": self.locate,
            "ramp_windup_error_deg": self.ramps,
            "problems": self.problems,
            "simulations": self.simulations,
            "wall_time_s": self.wall_time_s,
            "message": self.message,
            "missing": self.missing,
            "posterior": self.posterior,
            "effects": self.effects,
            "detectability": self.detectability,
            "recommended_points": self.recommended_points,
            "outliers": self.outliers,
            "likelihood": self.likelihood,
        }


def speeds_of(points) -> list:
    """Distinct nominal speeds [rpm] of ``points``, ascending (within SAME_SPEED_SHARE of
    the first of a group count as one)."""
    out = []
    for s in sorted(p.speed_rpm for p in points):
        if not out or s > out[-1] * (1.0 + SAME_SPEED_SHARE):
            out.append(s)
    return out


def shortfall(points, ramps: int = 0, left_out=()) -> tuple:
    """What torsional ``points`` lack for a diagnosis: (missing, message), ([], "") when
    nothing. ramps: number of ramp points; left_out: ids of points whose model run failed."""
    n, speeds = len(points), speeds_of(points)
    missing, lacks = [], []
    if n == 0:
        missing.append("torsional_points")
        lacks.append("no valid torsional test point" + (f" ({ramps} ramp(s): ramps are evidence only and do not enter "
                                                          "the verdict)" if ramps else ""))
    elif n < MIN_TORSIONAL_POINTS:
        missing.append("torsional_points")
        lacks.append(f"only {n} valid torsional test point(s) ({', '.join(p.id for p in points)}): too few to calibrate "
                     "and to check on held-out points")
    if n >= 2 and len(speeds) < MIN_SPEEDS:
        missing.append("speeds")
        lacks.append(f"all {n} torsional test points are at one speed ({speeds[0]:.0f} rpm): at one speed the calibration "
                     "cannot tell inertia from stiffness, nor a speed-dependent effect from a calibration factor")
    if not missing:
        return [], ""
    if left_out:
        lacks.append(f"{len(left_out)} torsional point(s) were left out because the model run failed there "
                     f"({', '.join(left_out)}; see problems)")
    return missing, ("not diagnosed: " + "; ".join(lacks) + f". Accepted: at least {MIN_TORSIONAL_POINTS} valid "
                     f"torsional test points (two to fit, every third held out for the verdict) at {MIN_SPEEDS} or more "
                     f"speeds (speeds within {100 * SAME_SPEED_SHARE:g} % count as one).")


def _not_diagnosed(system, missing, message, problems, simulations, t0) -> Diagnosis:
    """The Diagnosis of a campaign that cannot be diagnosed: every field present, no numbers."""
    nan = float("nan")
    # every contract key is present: no model was compared, so "none" keeps its probability 1
    # (nothing was found) and no threshold could be estimated
    return Diagnosis(verdict=INSUFFICIENT, effect=None, effect_parameters={}, ranking=[], noise_floor_nm=nan,
                     gap_before_nm=nan, gap_calibrated_nm=nan, gap_after_nm=nan, held_out_points=[],
                     problems=problems, simulations=simulations, wall_time_s=time.perf_counter() - t0, system=system,
                     message=message, missing=list(missing), posterior={"none": 1.0, **dict.fromkeys(NAMES, 0.0)},
                     detectability=dict.fromkeys(NAMES))


def decide(top: str, posterior: float, chi_top: float, chi_none: float, level: float) -> str:
    """The verdict from the most probable model ``top`` (its posterior and held-out robust
    reduced chi^2 ``chi_top``), the calibrated model's ``chi_none`` and the noise level.

    An effect is adopted ("missing_effect") only when it is decisive (posterior at least
    DETECTION_POSTERIOR, the threshold the detectability estimate is read against) and
    brings the held-out misfit to the noise level. An effect that is more probable than
    "none" but not decisive is not adopted: when the calibrated model already predicts
    the held-out points at the noise level the verdict is "no_missing_effect", otherwise
    "unexplained" (the message gives the candidate and its posterior)."""
    if top == "none":
        return "no_missing_effect" if chi_top <= level else "unexplained"
    if posterior >= DETECTION_POSTERIOR and chi_top <= level:
        return "missing_effect"
    if posterior < DETECTION_POSTERIOR and chi_none <= level:
        return "no_missing_effect"
    return "unexplained"


def recalibration_trigger(chi_train: float, train_level: float, chi_held, held_level: float) -> str | None:
    """Why the leading effect is fitted again together with the calibration (docs/discrepancy.md,
    Naming 3b), from its robust reduced chi^2 on the training points ``chi_train`` and on the
    held-out points ``chi_held`` (None when its held-out run failed) against each set's noise
    level: "training" when it leaves the training points above theirs; "held_out" when it fits
    them but leaves the held-out points above theirs (the calibration without the effect may
    have taken the effect up on the training points at factors that do not carry over to the
    held-out ones: a spring preload read as more friction); None otherwise."""
    if chi_train > train_level:
        return "training"
    if chi_held is not None and chi_held > held_level:
        return "held_out"
    return None


def not_adopted_reason(verdict: str, top: str, posterior: float, chi_top, chi_none, level) -> str | None:
    """Why the most probable model ``top``, an effect or pair, was not adopted (see
    :func:`decide`), in one clause; None when ``top`` is "none", the effect was adopted,
    or it simply leaves the held-out misfit above the noise level like every model."""
    if top in (None, "none") or verdict == "missing_effect" or None in (chi_top, chi_none, level):
        return None
    name = top.replace("+", " and ")
    need = f"{DETECTION_POSTERIOR:.2f} needed"
    if verdict == "no_missing_effect":
        return (f"no missing effect is adopted: {name} is the most probable model but not decisive (posterior "
                f"{posterior:.3f}, {need}), and the calibrated model's held-out misfit is already at the noise level "
                f"(reduced chi^2 {chi_none:.3g} against {level:.3g})")
    if posterior < DETECTION_POSTERIOR and chi_top <= level:
        return (f"{name} (posterior {posterior:.3f}) brings the held-out misfit to the noise level (reduced chi^2 "
                f"{chi_none:.3g} calibrated, {chi_top:.3g} with it, against {level:.3g}) but is not decisive ({need}), "
                "and the calibrated model alone stays above the noise level: not adopted")
    if chi_none <= level < chi_top:
        return (f"{name} is the most probable model (posterior {posterior:.3f}) but leaves the held-out misfit above "
                f"the noise level (reduced chi^2 {chi_top:.3g} against {level:.3g}) where the calibrated model alone "
                f"is within it ({chi_none:.3g}): not adopted")
    return None


def _verdict_message(diag: Diagnosis, left_out: list, level: float) -> str:
    """The verdict of a diagnosed campaign in one sentence (posterior, held-out misfit against
    the noise level ``level`` of reduced chi^2), with the points left out and the candidates
    not ranked because their model runs failed."""
    lk = diag.likelihood
    top = lk.get("model", "none")  # the most probable of the models with a held-out run
    p = diag.posterior.get(top, 0.0)
    chi_cal, chi_top = lk.get("reduced_chi2_held_out_calibrated"), lk.get("reduced_chi2_held_out")
    gaps = f"held-out gap {diag.gap_calibrated_nm:.3g} N m calibrated"
    if diag.verdict == "missing_effect":
        text = (f"{top.replace('+', ' and ')} (posterior {p:.2f}) brings the held-out misfit from reduced chi^2 "
                f"{chi_cal:.3g} to {chi_top:.3g}, within the noise level {level:.3g} ({gaps}, {diag.gap_after_nm:.3g} "
                "N m with the effect)")
    elif why := not_adopted_reason(diag.verdict, top, p, chi_top, chi_cal, level):
        text = f"{why} ({gaps})"
    elif diag.verdict == "no_missing_effect":
        text = (f"no missing effect is the most probable model (posterior {p:.2f}) and the calibrated model's "
                f"held-out misfit is at the noise level (reduced chi^2 {chi_cal:.3g} against {level:.3g}; {gaps})")
    else:
        text = (f"the most probable model ({top}, posterior {p:.2f}) leaves a held-out misfit above the noise level "
                f"(reduced chi^2 {chi_top:.3g} against {level:.3g}; {gaps}): no candidate explains the data")
    if diag.outliers:
        text += f"; outlier point(s), down-weighted: {', '.join(diag.outliers)}"
    excluded = [r["effect"] for r in diag.ranking if r.get("excluded")]
    return (text + (f"; {len(left_out)} point(s) left out because a model run failed there: {', '.join(left_out)} "
                    "(see problems)" if left_out else "")
            + (f"; not ranked because their model runs failed: {', '.join(excluded)} (see ranking)" if excluded else "")
            + ".")


def locate(diag: Diagnosis, system) -> dict:
    """Where the calibrated residual lies above the noise floor, and along which axis it
    collapses (the grouping that explains most of its variance, eta^2)."""
    knee = system.outer.count * system.outer.spring.stiffness * system.outer.hardstop_positive
    rows = []
    for p in diag.points:
        for k, err in enumerate(diag.residuals["calibrated"][p["id"]]):
            rows.append((p["speed_rpm"], p["mean_torque_nm"], k + 1, (k + 1) * p["speed_rpm"] / 60.0, err))
    a = np.array(rows)
    if not len(a):
        return {}
    e2 = a[:, 4] ** 2
    axes = {
        "speed": a[:, 0],
        "mean_torque": a[:, 1],
        "order": a[:, 2],
        "frequency": np.digitize(a[:, 3], [50, 100, 150, 200, 250]),
        "knee_side": (a[:, 1] > knee).astype(float),
    }
    out = {"knee_torque_nm": knee, "axes": {}, "above_floor": {}}
    for name, g in axes.items():
        groups = {}
        for key in np.unique(g):
            groups[float(key)] = float(np.sqrt(np.mean(e2[g == key])))
        # eta^2 of the squared error: variance between groups / total
        tot = np.var(e2)
        between = sum(np.sum(g == key) * (np.mean(e2[g == key]) - np.mean(e2)) ** 2 for key in np.unique(g)) / len(e2)
        out["axes"][name] = {"eta2": float(between / tot) if tot > 0 else 0.0, "rms_by_group_nm": groups}
    out["collapses_on"] = max(out["axes"], key=lambda n: out["axes"][n]["eta2"])
    out["above_floor"] = {p["id"]: _rms(diag.residuals["calibrated"][p["id"]]) > diag.noise_floor_nm for p in diag.points}
    return out


__all__ = ["MIN_TORSIONAL_POINTS", "MIN_SPEEDS", "SAME_SPEED_SHARE", "INSUFFICIENT", "Diagnosis", "decide",
           "not_adopted_reason", "recalibration_trigger", "speeds_of",
           "shortfall", "locate"]
