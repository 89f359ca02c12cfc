"""The held-out misfit breakdown of bench/bench_sigma_terms.py, on hand-made arrays (no
diagnosis is run): the figures docs/discrepancy.md quotes from it rest on these functions."""

import numpy as np
import pytest

from dampersim.discrepancy import diagnose as dg
from dampersim.discrepancy import drive, likelihood
from dampersim.discrepancy.fitting import UNCALIBRATED
from dampersim.discrepancy.likelihood import Likelihood
from tests.discrepancy.benches import NullRunner, load_bench

TERMS = ("repeat", "model", "mains", "input", "uncalibrated", "floor")
N, K = 9, 8


@pytest.fixture(scope="module")
def bench():
    return load_bench("bench_sigma_terms")


def cz(rng, *shape):
    return rng.normal(size=shape) + 1j * rng.normal(size=shape)


def case(seed=0, cell=0.1):
    """Terms (each cell's variance of each term about ``cell`` [N m^2]), a likelihood, model
    coefficients y0 and the four maps of the model terms, laid out as bench.compare_maps
    makes them, built from known changes: (maps, {column: change})."""
    rng = np.random.default_rng(seed)
    meas = cz(rng, N, K)
    terms = {t: cell * (0.1 + rng.random((N, K))) for t in TERMS}
    lik = Likelihood(meas, np.sqrt(sum(terms.values())), np.full(N, 150.0), np.arange(1, K + 1))
    y0 = meas + 0.1 * cz(rng, N, K)
    change = {"model": 0.1 * cz(rng, N, K), "input": 0.1 * cz(rng, N, K), "input:even": 0.05 * cz(rng, N, K)}
    unc = []
    for name in UNCALIBRATED:
        odd, even = 0.1 * cz(rng, N, K), 0.05 * cz(rng, N, K)
        change[f"uncalibrated:{name}"], change[f"uncalibrated:{name}:even"] = odd, even
        unc += [y0 + even + odd, y0 + even - odd]  # moved +, then -
    odd, even = change["input"], change["input:even"]
    y_in = np.concatenate([y0 + even + odd, y0 + even - odd])  # the input moved up, then down
    maps = [y0[None], (y0 + change["model"])[None], y_in[None], np.stack(unc)]
    return terms, lik, y0, maps, change


def test_the_changes_are_read_from_the_compare_maps_in_their_order(bench):
    _, _, _, maps, change = case()
    got = bench.systematic_changes(maps, N)
    assert list(got) == list(change)
    for k, v in change.items():  # up to the sign, which u u^T does not see
        assert min(np.max(np.abs(got[k] - v)), np.max(np.abs(got[k] + v))) < 1e-12, k


def test_the_fitted_amplitudes_recover_a_residual_built_from_the_changes(bench):
    # residual = sum of a_c u_c (through the channels' gain and delay) with per-cell terms a
    # millionth of the changes' size: the posterior mean is then the least-squares solution,
    # which recovers every amplitude; a wrong column (layout, sign aside, or transform) cannot
    terms, lik, y0, maps, change = case(seed=1, cell=1e-12)
    rows, nu = [0, 3, 6], np.array([0.03, 2e-4])
    amps = dict(zip(change, np.linspace(-1.5, 2.0, len(change))))
    resid = sum(a * change[c] for c, a in amps.items())  # from the known changes, not the bench's reading
    y = lik.meas - resid  # meas - y = resid, before the transform
    lik.meas = lik.transform(y, list(range(N)), nu) + lik.transform(resid, list(range(N)), nu)
    got = bench.correlated_chi2(terms, maps, lik, y[rows], rows, nu)
    for c, a in amps.items():  # up to the sign of a column, which u u^T does not see
        assert abs(got["amplitudes"][c]) == pytest.approx(abs(a), rel=1e-6, abs=1e-6), c
    # the columns carry the variance of the terms they replace: here the terms are tiny, so
    # their ratio is huge; the algebra of `size` is checked in the next test
    assert got["size"]["model"] > 1e6


def test_the_sizes_compare_the_columns_with_the_variances_they_replace(bench):
    terms, lik, y0, maps, change = case(seed=2)
    rows, nu = [1, 4, 7], np.zeros(2)
    u = bench.systematic_changes(maps, N)
    # the diagnosis's own variances of the three systematic terms (likelihood.sigma_variances)
    terms["model"] = np.abs(u["model"]) ** 2
    terms["input"] = np.abs(u["input"]) ** 2 + np.abs(u["input:even"]) ** 2
    terms["uncalibrated"] = sum(np.abs(v) ** 2 for k, v in u.items() if k.startswith("uncalibrated"))
    got = bench.correlated_chi2(terms, maps, lik, y0[rows], rows, nu)
    assert got["size"] == pytest.approx({"model": 1.0, "input": 1.0, "uncalibrated": 1.0}, rel=1e-12)


def test_the_diagonal_variant_reproduces_the_plain_held_out_chi2(bench):
    terms, lik, y0, maps, _ = case(seed=3)
    rows, nu = [1, 4, 7], np.array([0.02, 1e-4])
    plain = lik.reduced_chi2(y0[rows], rows, nu)
    cells = bench.held_out_cells(terms, lik, y0[rows], rows, nu)
    assert cells["reduced_chi2"] == pytest.approx(plain, abs=5e-4)  # printed to three decimals
    assert bench.correlated_chi2(terms, maps, lik, y0[rows], rows, nu)["diagonal"] == pytest.approx(plain, rel=1e-9)
    # the per-order figures average to the whole (each order has as many cells), each rounded
    assert np.mean(list(cells["per_order"].values())) == pytest.approx(plain, abs=5e-4 + 5e-4)


def test_a_misfit_along_one_change_is_discounted_by_its_unit_prior(bench):
    # residual = the input channel's change exactly, the other changes zero: for C = D + u u^T
    # and r = u, r^T C^-1 r = s / (1 + s), s = u^T D^-1 u (D: the per-cell terms, half the cell
    # variance on each of the real and imaginary parts); with one amplitude per point the rows
    # are independent and each discounts its own share
    terms, lik, y0, maps, _ = case(seed=4)
    rows, nu = [0, 3, 6], np.array([-0.02, 3e-4])
    u = bench.systematic_changes(maps, N)["input"]
    maps = [maps[0], maps[0], np.concatenate([y0 + u, y0 - u])[None], np.stack([y0] * maps[3].shape[0])]
    every = list(range(N))
    lik.meas = lik.transform(y0, every, nu) + lik.transform(u, every, nu)  # meas - model = u after the transform
    got = bench.correlated_chi2(terms, maps, lik, y0[rows], rows, nu)
    ut = lik.transform(u[rows], rows, nu)
    d_cell = 0.5 * sum(terms[t][rows] for t in ("repeat", "mains", "floor"))
    s_j = np.sum(np.abs(ut) ** 2 / d_cell, axis=1)
    n_res = 2 * len(rows) * K
    # exact algebra, solved numerically: 1e-9 relative
    assert got["global"] == pytest.approx(s_j.sum() / (1 + s_j.sum()) / n_res, rel=1e-9)
    assert got["per_point"] == pytest.approx(float(np.sum(s_j / (1 + s_j))) / n_res, rel=1e-9)
    assert got["per_cell_terms_only"] == pytest.approx(s_j.sum() / n_res, rel=1e-9)
    assert got["amplitudes"]["input"] == pytest.approx(s_j.sum() / (1 + s_j.sum()), rel=1e-9)
    # one column the data see (posterior variance 1 / (1 + s)), seven zero ones (posterior =
    # prior): standard deviations, not variances; the check on the one seen direction reads
    # a^2 / (1 - C) = s / (1 + s)
    s_all = s_j.sum()
    assert got["amplitude_sd"]["input"] == pytest.approx((1 / (1 + s_all)) ** 0.5, rel=1e-9)
    assert all(v == pytest.approx(1.0) for k, v in got["amplitude_sd"].items() if k != "input")
    check = got["amplitude_check"]
    assert check["dof"] == 1 and check["per_dof"] == pytest.approx(s_all / (1 + s_all), rel=1e-9)
    assert check["expected_rms"] == pytest.approx((s_all / (1 + s_all) / len(got["amplitudes"])) ** 0.5, rel=1e-9)
    # the truth's expected reading is shrunk by 1 - C on the seen column, 0 on the unseen ones
    got = bench.correlated_chi2(terms, maps, lik, y0[rows], rows, nu, truth={"tertiary_inertia": 2.0})
    assert got["truth_expected"]["uncalibrated:tertiary_inertia"] == pytest.approx(0.0, abs=1e-12)


def test_the_cell_breakdown_by_order_and_by_term_left_out(bench):
    # two held-out points, residual 0.3 N m in every cell of order 1 and 0 elsewhere; terms:
    # floor 0.04, input 0.05 N m^2 at order 1 only, the others zero
    rng = np.random.default_rng(5)
    meas = cz(rng, 4, 3)
    terms = {t: np.zeros((4, 3)) for t in TERMS}
    terms["floor"][:] = 0.04
    terms["input"][:, 0] = 0.05
    sigma = np.sqrt(sum(terms.values()))
    lik = Likelihood(meas, sigma, np.full(4, 150.0), np.arange(1, 4))
    rows, nu = [1, 3], np.zeros(2)
    y = meas[rows].copy()
    y[:, 0] -= 0.3
    cells = bench.held_out_cells(terms, lik, y, rows, nu)
    assert cells["per_order"] == {1: pytest.approx(0.09 / 0.09, abs=5e-4), 2: 0.0, 3: 0.0}
    assert cells["reduced_chi2"] == pytest.approx(1.0 / 3, abs=5e-4)
    assert cells["rms_residual_nm"] == {1: pytest.approx(0.3, abs=5e-5), 2: 0.0, 3: 0.0}
    assert cells["rms_term_nm"]["input"] == {1: pytest.approx(0.05 ** 0.5, abs=5e-5), 2: 0.0, 3: 0.0}
    assert cells["rms_term_nm"]["floor"] == {k: pytest.approx(0.2, abs=5e-5) for k in (1, 2, 3)}
    # without the input channel order 1 reads 0.09 / 0.04; a zero term changes nothing
    assert cells["without"]["input"] == pytest.approx((0.09 / 0.04) / 3, abs=5e-4)
    assert cells["without"]["repeat"] == pytest.approx(cells["reduced_chi2"], abs=5e-4)
    assert cells["median_share"]["floor"] == pytest.approx(1.0)


def test_the_whole_diagnosis_reading_picks_the_verdicts_call_and_restores_what_it_patched(bench, monkeypatch):
    # a stand-in diagnosis makes the calls the real one makes (diagnose.diagnose): the model
    # terms at the set as given (for the kept rows), then at the calibrated set, each through
    # diagnose.uncertainty, then the held-out chi^2 of two fitted models, the verdict's last; the
    # bench must read the last terms and that call, and undo its spies
    from dampersim.discrepancy import model_terms
    from dampersim.discrepancy.model_terms import ModelTerms

    terms, lik, y0, maps, _ = case(seed=6)
    rows, nu = [1, 4, 7], np.array([0.01, 1e-4])
    other = y0[rows] + 0.3
    up, down = maps[2][0][:N], maps[2][0][N:]
    last = ModelTerms(y0, maps[1][0], up, down, maps[3], [1.0] * N)
    first = ModelTerms(*(np.concatenate([a, a[:1]]) for a in (y0 + 1, y0 + 1, y0, y0)),
                       np.concatenate([maps[3], maps[3][:, :1]], axis=1), [1.0] * (N + 1))
    monkeypatch.setattr(likelihood, "sigma_variances", lambda *a, **k: terms)
    patched = (likelihood.sigma_variances, likelihood.Likelihood.robust_reduced_chi2, dg.uncertainty,
               model_terms.measure)
    seen = {}

    class Doc:
        def __init__(self, value):
            self.value = value

        def to_json(self):
            return {"likelihood": {"reduced_chi2_held_out": self.value}}

    def stand_in(camp, workers, recommend):
        seen["floor"] = likelihood.SIGMA_FLOOR_SHARE
        z = np.zeros((N, K))
        dg.uncertainty(z, lik.meas, z, first, list(range(N)))  # one point left out of N + 1
        dg.uncertainty(z, lik.meas, z, last)
        lik.robust_reduced_chi2(other, rows, nu)
        return Doc(lik.robust_reduced_chi2(y0[rows], rows, nu))

    monkeypatch.setattr(dg, "diagnose", stand_in)
    floor = likelihood.SIGMA_FLOOR_SHARE
    _, cells = bench.whole_diagnosis(None, 1, 0.123)
    assert seen["floor"] == 0.123 and likelihood.SIGMA_FLOOR_SHARE == floor
    assert (likelihood.sigma_variances, likelihood.Likelihood.robust_reduced_chi2, dg.uncertainty,
            model_terms.measure) == patched
    plain = lik.reduced_chi2(y0[rows], rows, nu)
    assert cells["reduced_chi2"] == pytest.approx(plain, abs=5e-4)  # the verdict's model, not the other
    assert cells["correlated"]["diagonal"] == pytest.approx(plain, abs=5e-4)
    # read from the last terms, not the first's (whose input moves alike up and down); printed
    # to three decimals
    expected = bench.correlated_chi2(terms, maps, lik, y0[rows], rows, nu)
    assert cells["correlated"]["size"]["input"] == pytest.approx(expected["size"]["input"], abs=5e-4)
    assert cells["correlated"]["size"]["input"] > 0


def test_truth_coordinates_by_hand(bench):
    # log changes +0.03 / -0.03 of the inner and nested springs: split coordinate
    # (0.03 + 0.03) / (0.06 / sqrt(2) * 2) = 0.707; the tertiary inertia at +0.12 is 2 standard
    # uncertainties; a pair friction scaled together (a calibration factor) has no split; a
    # rig shaft at -0.15 is -1.5 at a rig uncertainty of 0.1
    import math

    from dampersim.discrepancy.fitting import ESTIMATE_LOG_SD
    from dampersim.parameters import default_parameters
    from dampersim.parameters.io import named_values

    base = default_parameters()
    v = named_values(base)
    up = {"inner.spring.stiffness": 0.03, "inner.nested.stiffness": -0.03, "inertias.tertiary": 0.12,
          "friction.pair_outer.alpha": 0.2, "friction.pair_inner.alpha": 0.2,
          "rig.elements.transducer.shaft_stiffness": -0.15}
    applied = {n: v[n] * math.exp(t) for n, t in up.items()}
    got = bench.truth_coordinates(applied, base, UNCALIBRATED, ESTIMATE_LOG_SD)
    assert got == pytest.approx({"inner_spring_split": 0.06 / (math.sqrt(2) * 0.06), "pair_friction_split": 0.0,
                                 "tertiary_inertia": 2.0}, abs=1e-12)
    rig = bench.rig_directions(base)
    got = bench.truth_coordinates(applied, base, rig, 0.1)
    assert got["rig:transducer_stiffness"] == pytest.approx(-1.5, rel=1e-12)
    assert {k: x for k, x in got.items() if k != "rig:transducer_stiffness"} == dict.fromkeys(
        [k for k in rig if k != "rig:transducer_stiffness"], 0.0)


def test_rig_directions_name_parameters_the_set_has(bench):
    from dampersim.parameters import default_parameters
    from dampersim.parameters.io import named_values

    base = default_parameters()
    rig = bench.rig_directions(base)
    names = named_values(base)
    assert len(rig) == len(base.rig.elements) + 1  # every shaft but the motor's, and two inertias: gearbox, motor
    assert all(set(w) <= set(names) and list(w.values()) == [1.0] for w in rig.values())


def test_posterior_amplitudes_minimise_the_regularised_misfit(bench):
    # the posterior mean is argmin |r - U a|^2_D + |a|^2: the stacked least-squares problem
    rng = np.random.default_rng(7)
    cols, diag, r = rng.normal(size=(40, 5)), 0.5 + rng.random(40), rng.normal(size=40)
    amp, cov = bench.posterior_amplitudes(cols, diag, r)
    w = 1.0 / np.sqrt(diag)
    stacked = np.vstack([cols * w[:, None], np.eye(5)])
    ref = np.linalg.lstsq(stacked, np.concatenate([r * w, np.zeros(5)]), rcond=None)[0]
    assert amp == pytest.approx(ref, rel=1e-9)
    assert cov == pytest.approx(np.linalg.inv(stacked.T @ stacked), rel=1e-9)


@pytest.mark.parametrize("seed", [8, 1, 2])
def test_the_prior_check_reads_one_for_amplitudes_drawn_from_their_prior(bench, seed):
    # residuals r = U a + e with a ~ N(0, s^2 I) and e ~ N(0, D). On an eigen-direction of
    # A = U^T D^-1 U with eigenvalue mu, the check's term has mean (s^2 mu + 1) / (1 + mu):
    # 1 for s = 1, and towards s^2 only where the data see the direction well. The mean over
    # 4000 draws must be within 4 of its standard errors (estimated from the draws) of that
    rng = np.random.default_rng(seed)
    cols, diag = rng.normal(size=(30, 4)) * [1.0, 0.5, 0.2, 0.05], 1.0 + rng.random(30)
    mu = np.linalg.eigvalsh(cols.T @ (cols / diag[:, None]))
    kept = mu / (1 + mu) > 0.05  # prior_check's cut-off on the eigenvalues of I - C
    for scale in (1.0, 0.3):
        per_dof, rms2, expected2 = [], [], []
        for _ in range(4000):
            r = cols @ (scale * rng.normal(size=4)) + np.sqrt(diag) * rng.normal(size=30)
            check = bench.prior_check(*bench.posterior_amplitudes(cols, diag, r))
            assert check["dof"] == kept.sum()
            per_dof.append(check["per_dof"])
            rms2.append(check["rms"] ** 2)
            expected2.append(check["expected_rms"] ** 2)
        expected = float(np.mean((scale ** 2 * mu[kept] + 1) / (1 + mu[kept])))
        assert abs(np.mean(per_dof) - expected) < 4 * np.std(per_dof) / np.sqrt(len(per_dof)), scale
        if scale == 1.0:  # the mean square of the posterior means is the expected one
            assert abs(np.mean(rms2) - np.mean(expected2)) < 4 * np.std(rms2) / np.sqrt(len(rms2))


def test_direction_changes_and_the_extra_columns(bench, monkeypatch):
    # a stand-in runner returns known maps for the moved sets: the columns are their odd and
    # even parts, in the directions' order; a failed run is counted; an extra column's
    # amplitude is recovered beside the systematic ones
    terms, lik, y0, maps, change = case(seed=9, cell=1e-12)
    odd, even = 0.1 * cz(np.random.default_rng(10), N, K), 0.02 * cz(np.random.default_rng(11), N, K)
    moved = np.stack([y0 + even + odd, y0 + even - odd, y0, y0])
    moved[3, 2, :] = np.nan  # two failed runs: the sets' rows are NaN where a run failed
    moved[2, 4, :] = np.nan

    monkeypatch.setattr(drive, "Runner", NullRunner)
    monkeypatch.setattr(drive, "coefficients_of_sets", lambda runner, sets, points: moved[:len(sets)])

    dirs = {"a": {"inertias.tertiary": 1.0}, "b": {"rig.elements.gearbox.inertia": 1.0}}
    cols, failed = bench.direction_changes(list(range(N)), y0, dirs, 0.1, 1)
    assert list(cols) == ["a", "a:even", "b", "b:even"] and failed == 2
    assert np.max(np.abs(cols["a"] - odd)) < 1e-12 and np.max(np.abs(cols["a:even"] - even)) < 1e-12
    rows, nu = [0, 3, 6], np.array([0.01, 1e-4])
    every = list(range(N))
    resid = 0.7 * change["input"] - 1.3 * odd
    lik.meas = lik.transform(y0, every, nu) + lik.transform(resid, every, nu)
    extra = {"a": odd, "a:even": even}
    got = bench.correlated_chi2(terms, maps, lik, y0[rows], rows, nu, extra)
    assert got["amplitudes_with_extra"]["a"] == pytest.approx(-1.3, abs=1e-6)
    assert got["amplitudes_with_extra"]["input"] == pytest.approx(0.7, abs=1e-6)
    assert got["amplitudes_with_extra"]["a:even"] == pytest.approx(0.0, abs=1e-6)
    assert got["global_with_extra"] < got["global"]  # the extra column explains what the others cannot
    # the truth's expected reading: with a well-seen column the posterior barely shrinks it
    got = bench.correlated_chi2(terms, maps, lik, y0[rows], rows, nu, extra, truth={"a": -1.3, "inner_spring_split": 0.5})
    assert got["truth_expected_with_extra"]["a"] == pytest.approx(-1.3, abs=1e-3)
    assert got["truth_expected_with_extra"]["uncalibrated:inner_spring_split"] == pytest.approx(0.5, abs=1e-3)
    assert got["truth_expected_with_extra"]["a:even"] == pytest.approx(0.0, abs=1e-3)
