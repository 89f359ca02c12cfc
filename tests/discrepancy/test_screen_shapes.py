"""The screen's shapes: an effect whose signature is far from linear in a shape parameter (the
short springs act only beyond their clearance) is read over a grid of shapes and discrete
choices before any fit, and the fit starts from the best of them. Checked on a toy whose
points sit at known inner windups (the diagnosis's runs are patched), so the right shape is
known, and on the prior weights and choice masses by hand."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from dampersim.discrepancy import drive, naming, shapes
from dampersim.discrepancy.effects import NAMES
from dampersim.discrepancy.fitting import CALIBRATION
from dampersim.discrepancy.likelihood import Likelihood
from dampersim.discrepancy.selection import SHAPE_PRIOR_SD
from dampersim.parameters import with_updates

from tests.discrepancy.toy_namer import BASE, log_factors, patch_runs

NAME = "inner_short_springs"
OWN = getattr(BASE.effects, NAME)  # the library's short springs: 2 of them, clearance 0.1 rad
#: the toy's points: inner-set windup [rad] at each; the short springs act beyond their clearance
WINDUP = np.array([0.03, 0.055, 0.08, 0.11, 0.14, 0.18, 0.22])
POINTS = [SimpleNamespace(id=f"p{i}") for i in range(len(WINDUP))]
RNG = np.random.default_rng(3)
SENS = RNG.normal(size=(len(POINTS), len(drive.ORDERS), len(CALIBRATION))) * (1 + 1j)
#: how a point's coefficients move per (N m/rad x rad) of short-spring torque, and per missing
#: full-length inner spring below the clearance (a short pair lacks it there)
LOAD = RNG.normal(size=(len(POINTS), len(drive.ORDERS))) * (1 + 1j)
SOFT = RNG.normal(size=(len(POINTS), len(drive.ORDERS))) * (1 - 1j)
TRUTH = {"stiffness": 240.0, "clearance": 0.064, "count": 3}


def _toy(system):
    """Coefficients [N m] (points x orders) of a parameter set: the six factors act linearly; the
    short springs add count x stiffness x (windup - clearance) beyond their clearance and take
    0.5 N m per short pair off every point below it."""
    y = 10.0 + SENS @ log_factors(system)
    s = getattr(system.effects, NAME)
    if s.enabled:
        engaged = np.maximum(WINDUP - s.clearance, 0.0)[:, None]
        below = (WINDUP < s.clearance)[:, None]
        y = y + LOAD * s.count * s.stiffness * engaged * 0.05 - 0.5 * SOFT * s.count * below
    return y


@pytest.fixture()
def namer(monkeypatch):
    patch_runs(monkeypatch, _toy, lambda runner, s: False)
    meas = _toy(naming.with_effect(BASE, NAME, TRUTH))
    lik = Likelihood(meas, np.full(meas.shape, 0.05), [100.0] * len(POINTS), drive.ORDERS)
    zeros = np.zeros(len(CALIBRATION))
    y0 = _toy(BASE)
    starts = {"calibrated": (BASE, zeros, y0), "estimated": (BASE, zeros, y0)}
    jac = np.column_stack([lik.vec(SENS[:, :, k], list(range(len(POINTS)))) for k in range(len(CALIBRATION))])
    return naming.Namer(SimpleNamespace(), lik, list(range(len(POINTS))), POINTS, jac, starts, {NAME: {}})


def test_the_variants_carry_the_prior_and_the_library_shape():
    vs = shapes.variants(NAME, OWN)
    # 4 clearances (0.05, 0.0707, 0.1, 0.1414 rad), weights summing to one; the count is not screened
    assert len(vs) == 4 and shapes.logsumexp(lw for _, lw in vs) == pytest.approx(0.0, abs=1e-12)
    assert [round(v["clearance"], 4) for v, _ in vs] == [0.05, 0.0707, 0.1, 0.1414]
    # the library's own shape is one of them, exactly (so its typical run serves the detectability)
    assert any(v == {"clearance": OWN.clearance} for v, _ in vs)
    # the weights are the log-normal prior's (spread SHAPE_PRIOR_SD) at the grid: half the library's
    # clearance against the library's own, log ratio -(ln 2 / 0.5)^2 / 2 = -0.961
    w = {round(v["clearance"], 4): lw for v, lw in vs}
    assert w[0.05] - w[0.1] == pytest.approx(-0.5 * (math.log(2.0) / SHAPE_PRIOR_SD) ** 2, rel=1e-12)
    # every other effect is read at the parameter set's own shape only: one variant, weight 1
    for name in NAMES:
        if name != NAME:
            assert shapes.variants(name, getattr(BASE.effects, name)) == [({}, 0.0)]
            assert shapes.choices(name) == []


def test_a_partner_absorber_is_screened_on_both_sides_of_the_excited_order_it_is_tuned_to():
    # the library tunes the pendulum to order 2.0, which the drive excites: its effective inertia
    # there, J_a / (1 - (2 / n_t)^2), changes sign with the tuning, so the partner screen reads one
    # order below 2 and one above it besides the library's own; the single screen does not
    own = BASE.effects.pendulum_absorber
    assert own.order == 2.0
    assert shapes.variants("pendulum_absorber", own) == [({}, 0.0)]
    vs = shapes.variants("pendulum_absorber", own, shapes.partner_grid())
    orders = sorted(v["order"] for v, _ in vs)
    assert orders == pytest.approx([1.92, 2.0, 2.08], rel=1e-12)
    assert shapes.logsumexp(lw for _, lw in vs) == pytest.approx(0.0, abs=1e-12)
    # the prior hardly prefers the library's tuning over 4 % either side: (ln 1.04 / 0.5)^2 / 2 = 0.003
    w = {round(v["order"], 2): lw for v, lw in vs}
    assert w[2.0] - w[2.08] == pytest.approx(0.5 * (math.log(1.04) / SHAPE_PRIOR_SD) ** 2, rel=1e-12)


def test_the_count_choices_keep_the_engaged_rate():
    assert shapes.choices(NAME) == [{"count": 1}, {"count": 2}, {"count": 3}]
    # two springs at 360 N m/rad engage as three at 240 and one at 720
    assert shapes.magnitude_at_choice(NAME, 360.0, {"count": 2}, {"count": 3}) == pytest.approx(240.0)
    assert shapes.magnitude_at_choice(NAME, 360.0, {"count": 2}, {"count": 1}) == pytest.approx(720.0)
    assert shapes.magnitude_at_choice("turbine_drag", 3.0, {}, {}) == 3.0


def test_the_choice_mass_is_the_share_of_the_other_choices():
    scored = [({"clearance": 0.1, "count": 1}, -5.0), ({"clearance": 0.05, "count": 1}, -2.0),
              ({"clearance": 0.1, "count": 2}, -2.0), ({"clearance": 0.1, "count": 3}, -math.inf)]
    # best of count 1: -2, of count 2: -2, count 3: none; at count 2: log(1 + 1 + 0) - log 3
    assert shapes.choice_log_mass(NAME, {"count": 2}, scored) == pytest.approx(math.log(2.0 / 3.0), rel=1e-12)
    # the others explain nothing: the whole prior price of the choice, -log 3
    lone = [({"count": 3}, 0.0), ({"count": 1}, -math.inf), ({"count": 2}, -math.inf)]
    assert shapes.choice_log_mass(NAME, {"count": 3}, lone) == pytest.approx(-math.log(3.0), rel=1e-12)
    assert shapes.choice_log_mass("turbine_drag", {}, []) == 0.0


def test_the_screen_finds_the_clearance_and_the_choice_the_count(namer, monkeypatch):
    screened = namer.screen(NAME)
    # the truth engages at 0.064 rad: of the grid, 0.0707 rad is the only clearance whose points
    # engage as the truth's do (0.08 rad and beyond); the screen reads the library's two springs
    assert screened["shape"] == {"clearance": pytest.approx(0.05 * math.sqrt(2.0), rel=1e-12)}
    wide = screened["rel_log_evidence"]
    # read at the library's shape alone, the screen sees much less of the effect (the toy's
    # misfit is 0.05 N m per cell: the shapes' evidence exceeds it by thousands of nats)
    with monkeypatch.context() as m:
        m.setattr(shapes, "SCREEN_FACTORS", {})
        narrow = namer.screen(NAME)
    assert narrow["shape"] == {} and wide > narrow["rel_log_evidence"] + 1000.0
    assert narrow["y_library"] is not None and screened["y_library"] is not None
    # the screen scales a signature as a whole, so two springs at 1.5 x 240 N m/rad look to it as the
    # truth's three at 240 do; the runs at equal count x stiffness tell them apart, since below the
    # clearance each short pair lacks its full-length spring whatever the stiffness
    assert screened["scale"] == pytest.approx(1.5, rel=0.05)
    shape, log_mass = namer.choose(NAME, screened)
    assert shape["count"] == TRUTH["count"] and shape["clearance"] == screened["shape"]["clearance"]
    # the chosen count's prior mass: a third, the others' objectives thousands above (no share)
    assert log_mass == pytest.approx(-math.log(3.0), abs=1e-6)
    fits = namer.fit_candidate(NAME, screened)
    assert all(namer.shape_values(NAME, f["system"])["count"] == 3 for f in fits)
    assert all(f["log_mass"] == log_mass for f in fits)
    # the shape step moves the clearance towards the truth's 0.064 rad
    fit = namer.fit_shapes(NAME, fits[0])
    held = namer.shape_values(NAME, fit["system"])
    assert held["count"] == 3
    # the objective counts the clearance's prior term against the library's 0.1 rad
    term = namer.shape_prior(NAME, {"clearance": held["clearance"]})
    assert term == pytest.approx((math.log(held["clearance"] / OWN.clearance) / SHAPE_PRIOR_SD) ** 2, rel=1e-12)
    assert fit["cost"] >= term
    # noise-free toy: one step lands at 0.0647 rad and 240.9 N m/rad (the truth: 0.064, 240), 11 % of
    # the screened clearance's offset short; the bounds (15 % of that offset, 2 % in stiffness) leave
    # room for the step's linearisation across the kink, not for a count or grid value that is off
    start = 0.05 * math.sqrt(2.0)
    assert abs(held["clearance"] - TRUTH["clearance"]) < 0.15 * abs(start - TRUTH["clearance"])
    assert fit["m"] == pytest.approx(TRUTH["stiffness"], rel=0.02)


def test_the_screen_sums_the_grid_under_its_prior_weights(namer):
    # a start's screen evidence is the log-sum over its shapes of (linear evidence + log prior
    # weight), against "none": two shapes with the same signature at weights 0.3 and 0.7 give the
    # evidence of one (a max would give log 0.7 less); a shape whose run failed adds nothing
    n = len(namer.lik.mvec(namer.train))
    r = np.random.default_rng(2).normal(size=n)
    d = np.random.default_rng(4).normal(size=n)
    x0 = np.zeros(len(CALIBRATION))

    def rel(ds):
        return namer.screen_evidence({"parts": [(r, ds, x0)]}, 1.0)

    one = rel([(d, 0.0)])
    assert math.isfinite(one)
    assert rel([(d, math.log(0.3)), (d, math.log(0.7))]) == pytest.approx(one, abs=1e-12)
    assert rel([(d, math.log(0.3)), (None, math.log(0.7))]) == pytest.approx(one + math.log(0.3), abs=1e-12)
    assert rel([(None, 0.0)]) == -math.inf
    # tempered (eta < 1), the weights stay as they are: only the likelihood is scaled
    half = namer.screen_evidence({"parts": [(r, [(d, 0.0)], x0)]}, 0.5)
    assert namer.screen_evidence({"parts": [(r, [(d, math.log(0.3)), (None, 0.0)], x0)]}, 0.5) == \
        pytest.approx(half + math.log(0.3), abs=1e-12)


def test_the_count_choice_mass_enters_the_evidence_once(namer):
    fit = namer.fit_shapes(NAME, namer.fit_candidate(NAME, namer.screen(NAME))[0])
    fit["effects"], fit["columns"] = [NAME], [fit["column"], *fit.get("shape_columns", [])]
    fit["nuisance"] = namer.lik.profile(fit["y"], namer.train)[1]
    with_mass, _ = namer.evidence(fit, [NAME])
    without, _ = namer.evidence({**fit, "log_mass": 0.0}, [NAME])
    assert with_mass - without == pytest.approx(fit["log_mass"], abs=1e-9) and fit["log_mass"] < 0.0
    # the offsets read the clearance against the parameter set's 0.1 rad, not the grid value it
    # started from
    offset = namer._offset(fit, [NAME])
    k = len(CALIBRATION) + 1 + list(fit["shape_start"]).index("clearance")
    held = namer.shape_values(NAME, fit["system"])["clearance"]
    assert offset[k] == pytest.approx(math.log(held / OWN.clearance), rel=1e-12)


def test_shapes_and_counts_the_set_refuses_are_not_run(namer):
    # an inner set of three pairs takes at most two short springs: the count of three is left out,
    # not run (the set's check would stop the diagnosis), and the choice is between one and two
    namer.base = with_updates(BASE, {"inner.count": 3})
    options = namer.admissible(NAME, [({"count": c}, 0.0) for c in (1, 2, 3)])
    assert [v["count"] for v, _ in options] == [1, 2]
    shape, log_mass = namer.choose(NAME, {"start": "calibrated", "shape": {"clearance": 0.07}, "scale": 1.5})
    assert shape["count"] in (1, 2) and log_mass <= 0.0 and log_mass >= -math.log(2.0) - 1e-12
    # a clearance that leaves the short spring no longer than its block arc is left out of the grid
    slot = BASE.inner.slot_arc
    grid = [({"clearance": c}, 0.0) for c in (0.05, slot - 1e-6)]
    assert [v["clearance"] for v, _ in namer.admissible(NAME, grid)] == [0.05]


def test_a_single_effect_reports_its_shapes_and_its_count():
    from dampersim.discrepancy import intervals

    n_cal = len(CALIBRATION)
    system = naming.with_effect(BASE, NAME, {"stiffness": 250.0, "clearance": 0.0707, "count": 3})
    cov = np.diag(np.r_[np.full(n_cal, 0.01), 0.04, 0.09, 0.01, 0.01])  # factors, stiffness, clearance, channels
    fit = {"effects": [NAME], "m": 250.0, "cov": cov, "system": system, "shape_start": {"clearance": 0.0707},
           "shapes": {}}  # the shape step refused: the clearance where the fit started
    (entry,) = intervals.effects_of(NAME, fit)
    assert entry["parameters"] == {"stiffness": 250.0, "clearance": 0.0707, "count": 3}
    assert set(entry["intervals"]) == {"stiffness", "clearance"}  # the count is chosen, not fitted: no interval
    low, high = entry["intervals"]["clearance"]
    assert math.log(high / low) == pytest.approx(2 * 1.6448536 * 0.3, rel=1e-6)  # its own variance, 0.09
    fit["shapes"] = {"clearance": 0.066}  # the step moved it
    assert intervals.effects_of(NAME, fit)[0]["parameters"]["clearance"] == 0.066
