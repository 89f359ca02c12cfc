"""The held-out misfit breakdown of bench/bench_sigma_terms.py, on hand-made arrays (no
diagnosis is run): the figures docs/discrepancy.md quotes from it rest on these two functions."""

import math

import numpy as np
import pytest

from dampersim.discrepancy.likelihood import Likelihood
from tests.discrepancy.benches import load_bench

TERMS = ("repeat", "model", "mains", "input", "uncalibrated", "floor")


@pytest.fixture(scope="module")
def bench():
    return load_bench("bench_sigma_terms")


def case(seed=0, n=9, k=8):
    """Terms, a likelihood, model coefficients and the compare step's four maps."""
    rng = np.random.default_rng(seed)

    def cz(*shape):
        return rng.normal(size=shape) + 1j * rng.normal(size=shape)

    meas = cz(n, k)
    terms = {t: 0.01 + 0.1 * rng.random((n, k)) for t in TERMS}
    lik = Likelihood(meas, np.sqrt(sum(terms.values())), np.full(n, 150.0), np.arange(1, k + 1))
    y0 = meas + 0.1 * cz(n, k)
    compare = [y0[None], (y0 + 0.1 * cz(n, k))[None], np.concatenate([y0 - 0.1 * cz(n, k), y0 + 0.1 * cz(n, k)])[None],
               np.stack([y0 + 0.1 * cz(n, k) for _ in range(6)])]
    return terms, lik, y0, compare


def test_the_diagonal_variant_reproduces_the_plain_held_out_chi2(bench):
    terms, lik, y0, compare = case()
    rows, nu = [1, 4, 7], np.array([0.02, 1e-4])
    plain = lik.reduced_chi2(y0[rows], rows, nu)
    cells = bench.held_out_cells(terms, lik, y0[rows], rows, nu)
    # the breakdown is printed to three decimals
    assert cells["reduced_chi2"] == pytest.approx(plain, abs=1e-3)
    assert bench.correlated_chi2(terms, compare, lik, y0[rows], rows, nu)["diagonal"] == pytest.approx(plain, rel=1e-9)
    # the per-order figures average to the whole (each order has the same number of cells)
    assert np.mean(list(cells["per_order"].values())) == pytest.approx(plain, abs=2e-3)


def test_a_misfit_along_a_systematic_direction_is_discounted_by_its_prior(bench):
    # residual = the discretisation check's change exactly (amplitude 1); the other systematic
    # changes are zero. For C = D + u u^T and r = u: r^T C^-1 r = s / (1 + s), s = u^T D^-1 u
    # (D: the measured terms, half the cell variance on each of the real and imaginary parts)
    terms, lik, y0, compare = case(seed=1)
    rows = [0, 3, 6]
    u = compare[1][0] - y0
    y = lik.meas - u  # meas - y = u at every row
    compare = [compare[0], compare[1], np.concatenate([y0, y0])[None], np.stack([y0] * 6)]
    nu = np.zeros(2)
    d_meas = 0.5 * sum(terms[t][rows] for t in ("repeat", "mains", "floor"))
    s = float(np.sum(np.abs(u[rows]) ** 2 / d_meas))
    got = bench.correlated_chi2(terms, compare, lik, y[rows], rows, nu)
    n_res = 2 * len(rows) * lik.meas.shape[1]
    # exact algebra, solved numerically: 1e-9 relative
    assert got["global"] == pytest.approx(s / (1 + s) / n_res, rel=1e-9)
    assert got["measured_terms_only"] == pytest.approx(s / n_res, rel=1e-9)
    # one amplitude per point: the rows are independent, each discounts its own share s_j
    s_j = np.sum(np.abs(u[rows]) ** 2 / d_meas, axis=1)
    assert got["per_point"] == pytest.approx(float(np.sum(s_j / (1 + s_j))) / n_res, rel=1e-9)


def test_with_one_held_out_point_both_correlated_variants_agree(bench):
    terms, lik, y0, compare = case(seed=2)
    rows, nu = [5], np.array([-0.01, 2e-4])
    got = bench.correlated_chi2(terms, compare, lik, y0[rows] + 0.05, rows, nu)
    assert got["global"] == pytest.approx(got["per_point"], rel=1e-9)
    assert math.isfinite(got["measured_terms_only"]) and got["measured_terms_only"] >= got["global"]
