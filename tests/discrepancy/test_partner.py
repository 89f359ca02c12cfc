"""The pair's partner (discrepancy.partner): every other candidate screened on what the leading
fit leaves. A linear toy of four effects stands in for the simulations (the diagnosis's runs are
patched), with one candidate that imitates the leading effect and the true partner, whose
signature the leading effect cannot take up."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from dampersim import costs
from dampersim.discrepancy import drive, fitting, naming, partner, selection, shapes
from dampersim.discrepancy.effects import info
from dampersim.discrepancy.fitting import PRIOR_LOG_SD
from dampersim.discrepancy.likelihood import Likelihood

from tests.discrepancy.toy_namer import BASE, log_factors, patch_runs

LEAD, TRUE_PARTNER, IMITATOR, OTHER = "pendulum_absorber", "spring_preload", "turbine_drag", "inner_short_springs"
CANDIDATES = [LEAD, TRUE_PARTNER, IMITATOR, OTHER]
POINTS = [SimpleNamespace(id=f"p{i}") for i in range(4)]
RNG = np.random.default_rng(5)
SHAPE = (len(POINTS), len(drive.ORDERS))
#: each effect's signature at its typical magnitude [N m]; the imitator's is mostly the lead's
SIG = {n: RNG.normal(size=SHAPE) * (1 + 1j) for n in CANDIDATES}
SIG[IMITATOR] = 0.95 * SIG[LEAD] + 0.15 * RNG.normal(size=SHAPE) * (1 + 1j)
SENS = RNG.normal(size=(*SHAPE, 6)) * 0.5 * (1 + 1j)
SD = 0.05  # [N m] each cell's standard deviation


def _toy(system):
    """Coefficients [N m]: linear in the calibration's log factors and in each switched-on
    effect's magnitude over its typical one."""
    y = 10.0 + SENS @ log_factors(system)
    for n in CANDIDATES:
        eff = getattr(system.effects, n)
        if eff.enabled:
            y = y + SIG[n] * getattr(eff, info(n).magnitude) / info(n).magnitudes[1]
    return y


def _namer(monkeypatch, fails=lambda runner, s: False, toy=_toy, partner_values=(TRUE_PARTNER, {"force": 10.0})):
    """A Namer on ``toy``'s runs, measured at the lead (inertia 0.001) plus ``partner_values``
    (effect, its values)."""
    calls = []
    patch_runs(monkeypatch, toy, fails, calls)
    truth = naming.with_effect(naming.with_effect(BASE, LEAD, {"inertia": 0.001}), *partner_values)
    meas = toy(truth)
    lik = Likelihood(meas, np.full(meas.shape, SD), [100.0] * len(POINTS), drive.ORDERS)
    train = list(range(len(POINTS)))
    jac = np.column_stack([lik.vec(SENS[..., k], train) for k in range(6)])
    starts = {"calibrated": (BASE, np.zeros(6), None), "estimated": (BASE, np.zeros(6), None)}
    out = naming.Namer(SimpleNamespace(), lik, train, POINTS, jac, starts, {n: {} for n in CANDIDATES})
    out.calls = calls
    return out


def _lead_fit(namer):
    system = naming.with_effect(BASE, LEAD, {"inertia": 0.001})
    return {"system": system, "x": np.zeros(6), "y": _toy(system)}


def test_the_partner_is_the_effect_the_leading_fit_leaves_not_its_imitator(monkeypatch):
    namer = _namer(monkeypatch)
    gained = partner.gains(namer, LEAD, _lead_fit(namer), CANDIDATES)
    assert set(gained) == {TRUE_PARTNER, IMITATOR, OTHER}  # never the leading effect itself
    assert partner.choose(gained, fallback=IMITATOR) == TRUE_PARTNER
    # the residual is the preload's signature at 2/3 of its typical size, chi^2 about 17 000:
    # its gain is about 8500 nats, the others' at most about 140 (chance alignment of
    # their random parts with that residual); a tenth of it leaves a wide margin on both sides
    assert gained[TRUE_PARTNER].nats > 10.0 * max(gained[IMITATOR].nats, gained[OTHER].nats, 1.0)
    # read alone against the data without any effect, the imitator ranks above the true partner:
    # a choice by the singles' evidence would pick it (the rule this module replaced)
    r = namer.lik.vec(namer.lik.meas - _toy(BASE), namer.train)

    def single(n):
        d = namer.w(_toy(naming.with_effect(BASE, n, {info(n).magnitude: info(n).magnitudes[1]})) - _toy(BASE))
        return selection.linear_screen_evidence(r, namer.jac, d, np.zeros(6), PRIOR_LOG_SD)[0]

    assert single(IMITATOR) > single(TRUE_PARTNER)


def test_the_partner_screen_stays_inside_the_counted_runs(monkeypatch):
    # one run per training point for each other candidate, the short springs at their 4 screened
    # clearances and the absorber at its 3 tuning orders: the cost model's bound, reached when
    # neither leads; with the absorber leading, its 2 extra orders are not run
    grid = shapes.partner_grid()
    own = {n: getattr(BASE.effects, n) for n in CANDIDATES}
    assert costs.DIAGNOSIS_PARTNER_EXTRA == sum(len(shapes.variants(n, own[n], grid)) - 1 for n in CANDIDATES)
    bound = (len(CANDIDATES) - 1 + costs.DIAGNOSIS_PARTNER_EXTRA) * len(POINTS)
    orders = []

    def toy(system):
        if system.effects.pendulum_absorber.enabled:
            orders.append(round(system.effects.pendulum_absorber.order, 6))
        return _toy(system)

    namer = _namer(monkeypatch, toy=toy)
    lead = naming.with_effect(BASE, TRUE_PARTNER, {"force": 10.0})
    fit = {"system": lead, "x": np.zeros(6), "y": _toy(lead)}
    partner.gains(namer, TRUE_PARTNER, fit, CANDIDATES)
    assert len(namer.calls) == bound
    assert sorted(set(orders)) == [1.92, 2.0, 2.08]  # both sides of the excited order 2, and at it
    # the absorber leading: the others only, the short springs' 3 extra clearances among them
    del namer.calls[:]
    partner.gains(namer, LEAD, _lead_fit(namer), CANDIDATES)
    assert len(namer.calls) == bound - (len(shapes.variants(LEAD, own[LEAD], grid)) - 1) * len(POINTS)
    assert len(namer.calls) == (len(CANDIDATES) - 1 + 3) * len(POINTS)


def test_a_candidate_whose_runs_fail_on_top_of_the_lead_gains_nothing_and_is_recorded(monkeypatch):
    namer = _namer(monkeypatch, fails=lambda runner, s: s.effects.spring_preload.enabled)
    gained = partner.gains(namer, LEAD, _lead_fit(namer), CANDIDATES)
    assert gained[TRUE_PARTNER].nats == -math.inf
    assert partner.choose(gained, fallback=IMITATOR) != TRUE_PARTNER
    assert gained[TRUE_PARTNER].shape == {}  # no shape read: the set's own
    # recorded against the effect that made the model fail, as its own screen's failures are
    # (listed in its ranking entry's failed_points), and against nothing else
    assert set(namer.failures[TRUE_PARTNER]) == {p.id for p in POINTS}
    assert all(not v for k, v in namer.failures.items() if k != TRUE_PARTNER)


def test_the_tempered_screen_reads_the_likelihood_at_the_learning_rate(monkeypatch):
    # eta tempers the likelihood: residual, Jacobian and signature all scaled by sqrt(eta), as the
    # single screen does (Namer._screen_z). Recomputed here from those scaled inputs, the gain must
    # agree to rounding (1e-6 relative: both sides do the same arithmetic on the same arrays)
    namer = _namer(monkeypatch)
    fit, eta = _lead_fit(namer), 0.3
    got = partner.gains(namer, LEAD, fit, CANDIDATES, eta=eta)[TRUE_PARTNER].nats
    k = math.sqrt(eta)
    nu = namer.lik.profile(fit["y"], namer.train)[1]  # the channels' gain and delay fitted to the lead
    with namer.lik.using(nu):
        r = namer.lik.mvec(namer.train) - namer.lik.vec(fit["y"], namer.train)
        d = namer.w(_toy(naming.with_effect(fit["system"], TRUE_PARTNER, {"force": 15.0})) - fit["y"])
    z = selection.linear_screen_evidence(k * r, k * namer.jac, k * d, fit["x"], PRIOR_LOG_SD, min_scale=0.05)[0]
    z0 = selection.linear_screen_evidence(k * r, k * namer.jac, None, fit["x"], PRIOR_LOG_SD)[0]
    assert got == pytest.approx(z - z0, rel=1e-6)
    assert got != pytest.approx(partner.gains(namer, LEAD, fit, CANDIDATES)[TRUE_PARTNER].nats, rel=0.1)


@pytest.mark.parametrize("gained, fallback, expected", [
    ({"a": (1.0, {}), "b": (3.0, {}), "c": (2.0, {})}, "z", "b"),
    ({"a": (2.0, {}), "b": (2.0, {})}, "z", "a"),  # ties: the first listed
    ({"a": (-math.inf, {}), "b": (-5.0, {})}, "z", "b"),  # a negative gain still beats a failed screen
    ({"a": (-math.inf, {}), "b": (-math.inf, {})}, "z", "z"),  # every screen failed: the fallback
    ({}, None, None),
])
def test_choose(gained, fallback, expected):
    assert partner.choose(gained, fallback) == expected


def test_the_pair_label_is_order_free():
    assert partner.pair_label("b_effect", "a_effect") == "a_effect+b_effect"
    assert partner.pair_label("a_effect", "b_effect") == "a_effect+b_effect"


def test_the_diagnosis_tries_the_lead_with_the_partner_the_screen_chose(monkeypatch):
    """The pair step's wiring, on the stand-in model of tests.discrepancy.fake_rig (six points,
    two held out): the noise level is set below every model's held-out misfit so that the pair
    step runs, and the partner is taken from the screen's gains even when it was never fitted
    alone (the preload: not among the three the first screen shortlisted)."""
    from dampersim.discrepancy import diagnose as dg
    from tests.discrepancy import fake_rig as F

    seen = {}
    real_gains = partner.gains

    def gains(namer, lead, fit, candidates, eta=1.0):
        seen["lead"], seen["eta"] = lead, eta
        seen["gains"] = real_gains(namer, lead, fit, candidates, eta)
        return seen["gains"]

    monkeypatch.setattr(partner, "gains", gains)
    monkeypatch.setattr(partner, "choose", lambda gained, fallback: "spring_preload")
    monkeypatch.setattr(dg, "noise_level", lambda dof: 0.1)  # every held-out misfit lies above it
    monkeypatch.setattr(drive, "simulate_point", F.fake_model(None))
    cands = ["clutch_slip", "turbine_drag", "pendulum_absorber", "spring_preload"]
    d = dg.diagnose(F.campaign([F.point(*p) for p in F.POINTS]), workers=1, candidates=cands)
    assert set(seen["gains"]) == set(cands) - {seen["lead"]}
    # the gains are reported, a failed screen as null
    reported = {n: (g if math.isfinite(g) else None) for n, (g, *_) in seen["gains"].items()}
    assert d.likelihood["pair_partners"] == reported
    assert 0.0 < seen["eta"] <= 1.0
    label = partner.pair_label(seen["lead"], "spring_preload")
    assert label in d.posterior
    row = next(r for r in d.ranking if r["effect"] == label)
    assert "force" in row["parameters"] and row["fitted_from"] == "pair"
    # both effects' held shapes are listed with the pair: the first at its single fit's values
    lead_row = next(r for r in d.ranking if r["effect"] == seen["lead"])
    for q in naming.SHAPES.get(seen["lead"], ()):
        assert row["parameters"][q] == lead_row["parameters"][q]
    assert set(naming.SHAPES.get(seen["lead"], ())), "the test needs a leading effect with shape parameters"
    # the preload was only screened: no single fit of it, so its shape is the screen's
    assert next(r for r in d.ranking if r["effect"] == "spring_preload")["parameters"] == {}
    # the partner screen is inside the runs the cost model bounds
    assert d.simulations <= costs.diagnosis_runs(len(F.POINTS), len(cands))


#: the short springs' count seen apart from count x stiffness: what only real runs at each count
#: tell (the linear screen scales a signature as a whole)
SIG_COUNT = RNG.normal(size=SHAPE) * (1 + 1j)


def _toy_counted(seen):
    """The linear toy with the short springs' signature split into the engaged rate
    (count x stiffness, what the screen reads) and a part that follows the count alone;
    ``seen`` gets, for every system run, whether the leading effect was switched on."""

    def toy(system):
        seen.append(getattr(system.effects, LEAD).enabled)
        y = 10.0 + SENS @ log_factors(system)
        for n in CANDIDATES:
            eff = getattr(system.effects, n)
            if not eff.enabled:
                continue
            scale = getattr(eff, info(n).magnitude) / info(n).magnitudes[1]
            if n == OTHER:
                y = y + SIG[n] * scale * eff.count / 2.0 + 0.5 * SIG_COUNT * (eff.count - 2)
            else:
                y = y + SIG[n] * scale
        return y

    return toy


def test_the_short_springs_as_partner_take_their_count_from_runs_on_top_of_the_lead(monkeypatch):
    # the truth: the lead plus one short spring at twice the typical stiffness (the set's count
    # is 2, at the same engaged rate); the count is read by runs on top of the lead's fit, so the
    # truth's count wins, and each of those runs carries the lead. A choice left at the set's
    # count, or read without the lead, fails one of the two assertions
    seen = []
    toy = _toy_counted(seen)
    namer = _namer(monkeypatch, toy=toy, partner_values=(OTHER, {"stiffness": 480.0, "count": 1}))
    lead = naming.with_effect(BASE, LEAD, {"inertia": 0.001})
    fit = {"system": lead, "x": np.zeros(6), "y": toy(lead)}
    gained = partner.gains(namer, LEAD, fit, CANDIDATES)
    assert partner.choose(gained, fallback=None) == OTHER
    del seen[:]
    label = partner.pair_label(LEAD, OTHER)
    got, mass = partner.shape(namer, OTHER, fit, gained, {}, label, 0.0)
    assert got["count"] == 1
    assert got["clearance"] == gained[OTHER].shape["clearance"]  # the screen's best clearance on top of the lead
    assert len(seen) == len(shapes.choices(OTHER)) * len(POINTS) and all(seen)  # one run per count and point
    # the other counts explain far less: the mass is the equal share, -log 3, to rounding
    assert mass == pytest.approx(-math.log(3.0), abs=1e-6)


def test_a_partner_without_a_shape_grid_keeps_its_single_fit_s_shape(monkeypatch):
    namer = _namer(monkeypatch)
    fit = _lead_fit(namer)
    clutch = naming.with_effect(BASE, "clutch_slip", {"capacity": 600.0, "slip_speed": 0.2, "viscous": 40.0})
    models = {"clutch_slip": {"system": clutch, "log_mass": 0.0}}
    gained = {"clutch_slip": (3.0, {}, 1.2)}
    got, mass = partner.shape(namer, "clutch_slip", fit, gained, models, "x", 0.0)
    assert got == {"slip_speed": 0.2, "viscous": 40.0} and mass == 0.0
    # not fitted alone: the screen's shape, passed through without runs
    screened = {"clutch_slip": (3.0, {"slip_speed": 0.3}, 1.2)}
    assert partner.shape(namer, "clutch_slip", fit, screened, {}, "x", 0.0) == ({"slip_speed": 0.3}, 0.0)
    assert not namer.calls


def test_an_absorber_partner_takes_its_screened_order_and_keeps_its_single_fit_s_damping(monkeypatch):
    # the absorber's tuning order is screened (on both sides of the excited order 2), its damping
    # is not: as a partner it takes the order read on top of the lead and the damping its own
    # single fit reached; no runs, since it has no discrete choice
    namer = _namer(monkeypatch)
    fit = _lead_fit(namer)
    alone = naming.with_effect(BASE, "pendulum_absorber", {"inertia": 0.0008, "order": 2.05, "damping": 0.06})
    models = {"pendulum_absorber": {"system": alone, "log_mass": 0.0}}
    gained = {"pendulum_absorber": partner.Gain(4.0, {"order": 1.92}, 0.9)}
    got, mass = partner.shape(namer, "pendulum_absorber", fit, gained, models, "x", 0.0)
    assert got == {"order": 1.92, "damping": 0.06} and mass == 0.0
    # not fitted alone: the screened order and the set's own damping (held by the fit as the set has it)
    assert partner.shape(namer, "pendulum_absorber", fit, gained, {}, "x", 0.0) == ({"order": 1.92}, 0.0)
    assert not namer.calls


def test_the_short_springs_hold_the_set_s_count_when_every_count_run_fails_on_top_of_the_lead(monkeypatch):
    # the count runs all fail: the pair holds the screened clearance and the parameter set's own
    # count (Namer.choose), not the count the springs' single fit reached
    namer = _namer(monkeypatch, fails=lambda runner, s: s.effects.inner_short_springs.enabled
                   and s.effects.pendulum_absorber.enabled)
    fit = _lead_fit(namer)
    alone = naming.with_effect(BASE, OTHER, {"stiffness": 300.0, "count": 3, "clearance": 0.08})
    assert alone.effects.inner_short_springs.count != BASE.effects.inner_short_springs.count
    models = {OTHER: {"system": alone, "log_mass": -0.4}}
    gained = {OTHER: partner.Gain(5.0, {"clearance": 0.0707}, 1.0)}
    got, _ = partner.shape(namer, OTHER, fit, gained, models, "x", 0.0)
    assert got.get("count", BASE.effects.inner_short_springs.count) == BASE.effects.inner_short_springs.count
    assert got["clearance"] == 0.0707


def test_the_short_springs_fall_back_to_their_single_fit_when_their_screen_failed(monkeypatch):
    namer = _namer(monkeypatch)
    fit = _lead_fit(namer)
    own = naming.with_effect(BASE, OTHER, {"stiffness": 300.0, "count": 3, "clearance": 0.08})
    models = {OTHER: {"system": own, "log_mass": -0.4}}
    got, mass = partner.shape(namer, OTHER, fit, {OTHER: (-math.inf, {}, 1.0)}, models, "x", 0.0)
    assert got == {"clearance": 0.08, "count": 3} and mass == -0.4
    assert not namer.calls  # no count runs


def test_the_diagnosis_holds_a_short_spring_partner_at_the_shape_read_on_top_of_the_lead(monkeypatch):
    """The pair step's wiring with the short springs as the partner, on the stand-in model of
    tests.discrepancy.fake_rig: the pair holds the clearance and count partner.shape returned
    (listed with the pair), and the runs stay inside the cost model's bound, which counts the
    count choice."""
    from dampersim.discrepancy import diagnose as dg
    from tests.discrepancy import fake_rig as F

    seen = {}
    real_shape = partner.shape

    def shape(*args):
        seen["shape"] = real_shape(*args)
        return seen["shape"]

    monkeypatch.setattr(partner, "shape", shape)
    monkeypatch.setattr(partner, "choose", lambda gained, fallback: OTHER)
    monkeypatch.setattr(dg, "noise_level", lambda dof: 0.1)  # every held-out misfit lies above it
    monkeypatch.setattr(drive, "simulate_point", F.fake_model(None))
    cands = ["clutch_slip", "turbine_drag", "pendulum_absorber", OTHER]
    d = dg.diagnose(F.campaign([F.point(*p) for p in F.POINTS]), workers=1, candidates=cands)
    held, mass = seen["shape"]
    assert set(held) == {"clearance", "count"} and -math.log(3.0) - 1e-9 <= mass <= 0.0
    row = next(r for r in d.ranking if "+" in r["effect"] and OTHER in r["effect"])
    assert row["parameters"]["count"] == held["count"]
    assert row["parameters"]["clearance"] == pytest.approx(held["clearance"], rel=1e-12)
    assert d.simulations <= costs.diagnosis_runs(len(F.POINTS), len(cands))


def test_a_fit_on_top_of_another_effect_verifies_with_its_own_search_run(monkeypatch):
    # on top of another effect only the start's factors are verified, and that run is the
    # search's own at the best magnitude: one run per point per magnitude tried and one for the
    # derivative, none repeated
    namer = _namer(monkeypatch)
    trials = []
    real = namer._trial
    monkeypatch.setattr(namer, "_trial", lambda *a: trials.append(a) or real(*a))
    # the lead's single fit at 0.0013 (the truth's 0.001) and factors 2 % off the truth's, the
    # preload fitted on top of it with the lead's prior terms, as diagnose's pair step fits it
    x = 0.02 * np.array([1.0, -1.0, 1.0, -1.0, 1.0, -1.0])
    lead = fitting.calibrated_system(naming.with_effect(BASE, LEAD, {"inertia": 0.0013}), x)
    del namer.calls[:]
    pair = namer.fit(TRUE_PARTNER, (lead, x, _toy(lead)), label=partner.pair_label(LEAD, TRUE_PARTNER),
                     jac=namer.jac, extra_prior=namer._magnitude_prior(LEAD, 0.0013))
    assert len(namer.calls) == (len(trials) + 1) * len(POINTS)
    # the run kept is the reported set's own: coefficients and objective at its magnitude and factors
    # (1e-12 and 1e-9: the same toy evaluated twice, and the same arithmetic)
    assert np.allclose(pair["y"], _toy(pair["system"]), rtol=1e-12, atol=1e-12)
    extra = namer._magnitude_prior(LEAD, 0.0013) + namer._magnitude_prior(TRUE_PARTNER, pair["m"])
    assert pair["cost"] == pytest.approx(namer.cost(_toy(pair["system"]), pair["x"], extra), rel=1e-9)
