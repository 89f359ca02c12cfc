"""Modal analysis of the linear model, Campbell data and the campbell command."""

import argparse
import json
import math

import numpy as np
import pytest

import dampersim
from dampersim.analysis import modal
from dampersim.cli.analysis import add_parsers
from dampersim.errors import InputError
from dampersim.solver.linear import linearise
from dampersim.units import rpm_to_rad_s


@pytest.mark.parametrize("motor", ["free", "held"])
def test_natural_frequencies_match_numpy_on_the_exported_matrices(motor):
    system = dampersim.default_parameters()
    lm = linearise(system, motor=motor)
    res = modal.modal_analysis(system, motor=motor)
    lam = np.linalg.eigvals(np.linalg.solve(lm.M, lm.K))
    ref = np.sort(np.sqrt(np.abs(lam.real)) / (2 * np.pi))
    elastic = ref > 1e-3
    # two eigen-solvers on the same well-conditioned matrices: 1e-7 relative
    assert np.allclose(res.frequencies_hz[elastic], ref[elastic], rtol=1e-7)
    # rigid-body mode (free motor only) at 0 Hz; round-off leaves < 1e-3 Hz
    assert res.rigid.sum() == (1 if motor == "free" else 0)
    assert np.all(res.frequencies_hz[res.rigid] < 1e-3)
    assert res.dof_names == lm.dof_names


def test_mode_shapes_solve_the_eigenproblem_and_energy_shares_sum_to_one():
    system = dampersim.default_parameters()
    lm = linearise(system, motor="held")
    res = modal.modal_analysis(system, motor="held")
    for i in range(5):
        w2 = (2 * np.pi * res.frequencies_hz[i]) ** 2
        phi = res.shapes[:, i]
        resid = lm.K @ phi - w2 * (lm.M @ phi)
        # residual relative to the size of the terms: eigh is accurate to ~1e-12 here
        assert np.linalg.norm(resid) <= 1e-8 * np.linalg.norm(lm.K @ phi)
        assert np.max(np.abs(phi)) == pytest.approx(1.0) and phi[np.argmax(np.abs(phi))] > 0
    assert np.allclose(res.kinetic_fraction.sum(axis=0), 1.0)
    groups = res.group_fractions(0)
    assert sum(groups.values()) == pytest.approx(1.0)
    assert "outer" in groups  # the 17 outer spring masses are summed into one body


def test_two_dof_system_against_the_analytic_solution():
    # fixed-fixed chain ground-k-J-k-J-k-ground: w^2 = k/J (in phase) and 3k/J (opposed)
    J, k = 0.5, 2.0e4
    M = np.diag([J, J])
    K = np.array([[2 * k, -k], [-k, 2 * k]])
    res = modal.modes_from_matrices(M, K, ("a", "b"))
    expect = np.sqrt([k / J, 3 * k / J]) / (2 * np.pi)
    assert np.allclose(res.frequencies_hz, expect, rtol=1e-12)  # 2x2 symmetric eigh: round-off only
    assert np.allclose(res.shapes[:, 0], [1, 1]) and np.allclose(np.abs(res.shapes[:, 1]), [1, 1])
    assert res.dominant_dofs(0, 2)[0][1] == pytest.approx(0.5)  # both move equally
    s = res.summary()
    assert list(s["mode"]) == [1, 2] and "a (50 %)" in s["dominant"].iloc[0]
    with pytest.raises(InputError, match="symmetric"):
        modal.modes_from_matrices(M, np.array([[1.0, 2.0], [0.0, 1.0]]))
    with pytest.raises(InputError, match="mode"):
        res.dominant_dofs(5)


def test_campbell_crossing_of_order_k_with_a_mode():
    f_n, k = 50.0, 2.0
    data = modal.campbell([f_n, 175.0], orders=(1, 2, 4), speed_range_rad_s=(rpm_to_rad_s(500), rpm_to_rad_s(3000)))
    row = data.crossings[(data.crossings["order"] == k) & (data.crossings["mode"] == 1)]
    assert len(row) == 1
    # order k meets f_n where k * rpm / 60 = f_n: 1500 rpm (exact arithmetic, 1e-12)
    assert row["speed_rpm"].iloc[0] == pytest.approx(60 * f_n / k, rel=1e-12)
    assert k * row["speed_rad_s"].iloc[0] / (2 * math.pi) == pytest.approx(f_n, rel=1e-12)
    # order 1 at 50 Hz would need 3000 rpm: on the range edge, included; 175 Hz / order 1 out of range
    pairs = set(zip(data.crossings["order"], data.crossings["mode"]))
    assert (1.0, 1) in pairs and (1.0, 2) not in pairs and (4.0, 2) in pairs
    assert list(data.crossings["speed_rad_s"]) == sorted(data.crossings["speed_rad_s"])
    lines = data.order_lines
    sub = lines[lines["order"] == 4]
    assert np.allclose(sub["frequency_hz"], 4 * sub["speed_rpm"] / 60, rtol=1e-12)
    with pytest.raises(InputError, match="speed range"):
        modal.campbell([50.0], speed_range_rad_s=(300.0, 100.0))


def test_campbell_from_modal_result_skips_rigid_modes():
    res = modal.modal_analysis(dampersim.default_parameters(), motor="free")
    data = modal.campbell(res)
    assert data.modes[0] == 2  # mode 1 is the rigid-body mode
    assert np.all(data.natural_frequencies_hz > 1e-3)


def test_campbell_command_json(capsys, tmp_path):
    p = argparse.ArgumentParser()
    add_parsers(p.add_subparsers(dest="command"))
    out_html = tmp_path / "campbell.html"
    args = p.parse_args(["campbell", "--json", "--out", str(out_html), "--set", "inertias.primary=0.25"])
    assert args.func(args) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["rigid"][0] is True and d["modes"][0]["mode"] == 2
    assert all(c["speed_rpm"] >= 500 and c["speed_rpm"] <= 3000 for c in d["crossings"])
    assert out_html.exists()
    args = p.parse_args(["campbell"])
    assert args.func(args) == 0
    text = capsys.readouterr().out
    assert "mode  2" in text and "order crossings" in text
    bad = p.parse_args(["campbell", "--speed-range", "3000,500"])
    with pytest.raises(InputError, match="speed-range"):
        bad.func(bad)
