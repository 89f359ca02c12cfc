"""Shorter inner springs in some nested pairs (effect inner_short_springs): a second
representative nested pair with its own masses, friction and clearance (docs/model.md
§4, §11; [thesis] §5.1: 2 of the smaller damper's 5 pairs)."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from dampersim import OrderSum, default_parameters, simulate
from dampersim.excitation import TorqueRamp
from dampersim.parameters import with_updates
from dampersim.solver.layout import build_layout
from dampersim.units import rpm_to_rad_s

P = default_parameters()
SHORT = with_updates(P, {"effects.inner_short_springs.enabled": True})
SS = SHORT.effects.inner_short_springs
N_SHORT = SS.count
K_PO, K_PI = P.inner.spring.stiffness, P.inner.nested.stiffness
# inner-set rate below the clearance: normal pairs with both springs, short pairs with
# their outer spring only; above it the short inner springs add their rate
K_FIRST = (P.inner.count - N_SHORT) * (K_PO + K_PI) + N_SHORT * K_PO
K_THIRD = K_FIRST + N_SHORT * SS.stiffness
# the point where the inner windup swings about the clearance: mean torque = K_FIRST c
CROSSING = OrderSum(speed=rpm_to_rad_s(1500), mean_torque=K_FIRST * SS.clearance, orders=((2, 300.0, 0.0),))


def _spring(res, name):
    return next(s for s in res.springs if s.name == name)


@functools.lru_cache(maxsize=None)
def _ramp(name):
    system = {"base": P, "short": SHORT}[name]
    system = with_updates(system, {"friction.enabled": False, "motor.mode": "held",
                                   "solver.output_sample_rate": 2000})
    # below the outer knee (299 N m), so the inner windup follows the inner set alone
    ex = TorqueRamp(speed=rpm_to_rad_s(500), points=(0.0, 280.0), rate=50.0, hold=0.0, lead=0.2)
    return simulate(system, ex, record_segments=False)


def _fit_rate(res, lo, hi):
    """Inner-set rate [N m/rad] fitted between input torques lo and hi [N m]."""
    t, w = res.input_torque, res.windup_inner
    m = (t > lo) & (t < hi)
    return 1.0 / np.polyfit(t[m], w[m], 1)[0], np.polyfit(t[m], w[m], 1)


def test_static_curve_has_the_third_stage_at_the_clearance():
    res = _ramp("short")
    k1, fit1 = _fit_rate(res, 30.0, 0.85 * K_FIRST * SS.clearance)
    k3, fit3 = _fit_rate(res, 1.15 * K_FIRST * SS.clearance, 270.0)
    # 1 %: as the static curve of the default set (tests/physics/test_static_curve.py);
    # the residual is the undamped low mode the ramp start excites
    assert k1 == pytest.approx(K_FIRST, rel=0.01)
    assert k3 == pytest.approx(K_THIRD, rel=0.01)
    # the two lines meet at the clearance: 1 % of it (0.06 deg), the fits' scatter
    t_knee = (fit3[1] - fit1[1]) / (fit1[0] - fit3[0])
    assert np.polyval(fit1, t_knee) == pytest.approx(SS.clearance, rel=0.01)
    # the set without short springs is one straight line at the full pairs' rate
    k_base, _ = _fit_rate(_ramp("base"), 30.0, 270.0)
    assert k_base == pytest.approx(P.inner.count * (K_PO + K_PI), rel=0.01)


@functools.lru_cache(maxsize=None)
def _crossing_friction_only():
    # friction as the only loss (no viscous rig damping, no hardstop damping, held output
    # motor), as the "friction only" case of tests/physics/test_energy.py
    rig = [e.name for e in P.rig.elements]
    upd = {**{f"rig.elements.{e}.inertia_damping": 0.0 for e in rig},
           **{f"rig.elements.{e}.shaft_damping": 0.0 for e in rig},
           "hardstops.damping": 0.0, "motor.mode": "held"}
    return simulate(with_updates(SHORT, upd), CROSSING)


def test_energy_balance_closes_across_the_clearance():
    res = _crossing_friction_only()
    e = res.energy
    # the run does cross the clearance: the short springs' end segments carry load at
    # some samples and none at others in the steady part (1e-12 rad: the rounding of a
    # free end's slot coordinate, which sits one relaxed segment from its neighbour)
    comp = res.segment_compression("short_pair_inner")
    steady = res.segment_t > 1.0
    ends = np.maximum(comp[steady, 0], comp[steady, -1])
    assert ends.max() > 1e-4 and ends.min() < 1e-12
    assert e["stacking"][-1] == 0.0
    losses = e["friction"][-1] + e["damping"][-1]
    assert e["friction"][-1] > 0.99 * losses  # friction is (nearly) all of the losses
    # 1 % of the friction dissipation, the only loss here (the criterion of
    # tests/physics/test_energy.py, stated against friction rather than viscous losses;
    # measured: 0.011 J against 80 J)
    assert np.max(np.abs(res.energy_residual())) < 0.01 * e["friction"][-1]


def _makkar(v, fr):
    """Friction coefficient at slip speed v [m/s] ([thesis] Eq. 27), numpy's tanh."""
    return (fr.gamma1 * (np.tanh(fr.gamma2 * v) - np.tanh(fr.gamma3 * v)) + fr.gamma4 * np.tanh(fr.gamma5 * v)
            + fr.gamma6 * v)


def _normal(x, omega_mid, spring, nseg, count, preload):
    """Normal force [N] on each mass of one representative spring (``count`` springs) over
    each step ([thesis] Eq. 19-24): redirection of the compressed segments averaged over
    the step's two ends (half of each neighbour's to a mass, the end segments' fully to
    their one mass), centrifugal at the mid-step absolute speed omega_mid [rad/s]."""
    def red(xx):
        seg = np.diff(xx, axis=1)
        t = nseg * spring.stiffness * (spring.arc / nseg - seg)
        nw = spring.active_coils / nseg
        f = np.where(t > 0, t / spring.effective_radius * 2 * nw * np.sin(seg / (2 * nw)), 0.0)
        share = np.full(nseg - 1, 0.5)
        left, right = share.copy(), share.copy()
        left[0] = right[-1] = 1.0
        return left * f[:, :-1] + right * f[:, 1:]

    r = 0.5 * (red(x[:-1]) + red(x[1:]))
    return count * (spring.mass / (nseg - 1) * spring.effective_radius * omega_mid ** 2 + r + preload)


def _friction_work(res, system) -> dict:
    """Friction dissipation [J] per contact group, recomputed from a record of every step
    with the exact law (the method of tests/physics/test_friction_energy.py): slips from
    the recorded slot coordinates x = q_A - q_mass differenced over each step, normal
    forces from the recorded nodes, alpha mu F_N r slip dt summed."""
    dt = res.time_step
    fr = system.friction
    ss = system.effects.inner_short_springs
    nodes = {sp.name: res.nodes[:, sp.first_node:sp.first_node + sp.segments + 1] for sp in res.springs}
    dx = {k: np.diff(x[:, 1:-1], axis=0) / dt for k, x in nodes.items()}
    dwo = (np.diff(res.windup_outer) / dt)[:, None]
    dwi = (np.diff(res.windup_inner) / dt)[:, None]
    om_pri, om_sec = res.speed_primary[1:, None], res.speed_secondary[1:, None]
    no, ni = system.solver.outer_segments, system.solver.inner_segments
    n_short = ss.count
    short_spring = ss.spring(system.inner)

    def work(alpha, r, fn, slip):
        return float(dt * np.sum(alpha * _makkar(r * slip, fr) * fn * r * slip))

    out = {"outer": work(fr.outer.alpha, system.outer.spring.friction_radius,
                         _normal(nodes["outer"], om_pri - dx["outer"], system.outer.spring, no, system.outer.count,
                                 fr.outer.preload), dwo - dx["outer"])}
    r_po, r_pi = system.inner.spring.friction_radius, system.inner.nested.friction_radius
    for prefix, inner_spring, count in (("pair", system.inner.nested, system.inner.count - n_short),
                                        ("short_pair", short_spring, n_short)):
        xo, xi = f"{prefix}_outer", f"{prefix}_inner"
        fn_o = _normal(nodes[xo], om_sec - dx[xo], system.inner.spring, ni, count, fr.pair_outer.preload)
        fn_i = _normal(nodes[xi], om_sec - dx[xi], inner_spring, ni, count, fr.pair_inner.preload)
        out[f"{xo} on J_sec"] = work(fr.pair_outer.alpha * fr.alpha_sec, r_po, fn_o, -dx[xo])
        out[f"{xo} on J_ter"] = work(fr.pair_outer.alpha * fr.alpha_ter, r_po, fn_o, dwi - dx[xo])
        out[f"{xi} on its outer"] = work(fr.pair_inner.alpha, r_pi, fn_i, dx[xo] - dx[xi])
    return out


def test_short_pair_masses_move_and_carry_friction():
    lay = build_layout(SHORT, CROSSING.speed)
    assert [s.name for s in lay.springs] == ["outer", "pair_outer", "pair_inner", "short_pair_outer",
                                             "short_pair_inner"]
    # F_COUNT: the number of pairs each representative pair stands for
    assert list(lay.SF[:, 7]) == [P.outer.count] + [P.inner.count - N_SHORT] * 2 + [N_SHORT] * 2
    # a record and a segment sample every step, over a short run
    dt = SHORT.solver.time_step
    fine = with_updates(SHORT, {"solver.output_sample_rate": 1.0 / dt, "solver.segment_sample_rate": 1.0 / dt,
                                "solver.duration": 1.0})
    res = simulate(fine, CROSSING)
    assert res.energy["stacking"][-1] == 0.0  # every position change is a slip
    # the short pair's masses move with the windup as the normal pair's do
    half = res.nodes.shape[0] // 2

    def swing(name):  # peak-to-peak slot coordinate of each mass [rad], second half
        sp = _spring(res, name)
        return np.ptp(res.nodes[half:, sp.first_node + 1:sp.first_node + sp.segments], axis=0)

    for short, normal in (("short_pair_outer", "pair_outer"), ("short_pair_inner", "pair_inner")):
        assert np.all(swing(short) > 0.5 * swing(normal)), short
    # their friction contacts dissipate, and the ledger books them: the recomputed work
    # of all contacts, the short pair's included, equals the ledger
    parts = _friction_work(res, fine)
    short_work = sum(v for k, v in parts.items() if k.startswith("short_pair"))
    normal_work = sum(v for k, v in parts.items() if k.startswith("pair"))
    # the short pair stands for 2 of the 5 pairs: its contacts do a share of the inner
    # set's friction work of that order, far from zero (measured: 0.89 J against the
    # normal pair's 1.21 J; 3.5 % of the ledger's 25.3 J, most of which is the outer set's)
    assert short_work > 0.2 * normal_work, parts
    ledger = res.energy["friction"][-1] - res.energy["friction"][0]
    # 1 %: the criterion of tests/physics/test_friction_energy.py (midpoint quadrature
    # with the exact law against the step's linearised law; measured 0.24 %); dropping
    # the short pair's contacts from the ledger would move it by their share (> 2 %,
    # asserted below)
    assert ledger == pytest.approx(sum(parts.values()), rel=0.01), parts
    assert short_work > 0.02 * ledger, parts


def test_off_or_no_short_pairs_is_the_default_set():
    ex = OrderSum(speed=rpm_to_rad_s(1500), mean_torque=200.0, orders=((2, 300.0, 0.0),))
    base = simulate(with_updates(P, {"solver.duration": 1.0}), ex, record_segments=False)
    changed = {"effects.inner_short_springs.stiffness": 900.0, "effects.inner_short_springs.clearance": 0.0,
               "effects.inner_short_springs.mass": 0.5, "solver.duration": 1.0}
    for upd in ({**changed, "effects.inner_short_springs.enabled": False},
                {**changed, "effects.inner_short_springs.enabled": True, "effects.inner_short_springs.count": 0}):
        system = with_updates(P, upd)
        lay, lay0 = build_layout(system, ex.speed), build_layout(P, ex.speed)
        for f in ("P", "SF", "SI", "J", "contacts_idx", "contacts_f", "singles", "pairs"):
            np.testing.assert_array_equal(getattr(lay, f), getattr(lay0, f))
        res = simulate(system, ex, record_segments=False)
        np.testing.assert_array_equal(res.output_torque, base.output_torque)  # bit-identical


def test_sizes_and_validation_know_the_second_pair():
    from dampersim import costs
    from dampersim.errors import ParameterError
    from dampersim.parameters import validation

    for system in (SHORT, with_updates(SHORT, {"solver.inner_segments": 6, "effects.inner_short_springs.count": 4})):
        lay = build_layout(system, 150.0)
        assert validation.degrees_of_freedom(system) == costs.degrees_of_freedom(system) == lay.ndof
        assert costs.segment_nodes(system) == lay.n_nodes
    for upd, field in (({"effects.inner_short_springs.count": 5}, "count"),  # no normal pair left
                       ({"effects.inner_short_springs.clearance": 0.7}, "clearance")):  # shorter than its block
        with pytest.raises(ParameterError, match=f"effects.inner_short_springs.{field}"):
            validation.validate(with_updates(SHORT, upd))
