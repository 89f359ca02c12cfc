"""Sweeps: grids, run_sweep (serial and processes), cancellation, and the CLI commands."""

import io
import json
import math
import pathlib
import threading

import numpy as np
import pandas as pd
import pytest

from dampersim import default_parameters
from dampersim.cli import build_parser
from dampersim.cli.sweeps import ProgressBar
from dampersim.errors import DampersimError, InputError, SimulationDiverged
from dampersim.sweeps import cache as sc
from dampersim.sweeps.executor import (
    SweepCancelled,
    SweepPointFailed,
    TABLE_COLUMNS,
    run_sweep,
)
from dampersim.sweeps.grid import TestPoint, make_grid, parse_range, parse_torques, parse_values

RPM = 2 * math.pi / 60
SHORT = dict(duration=1.0, window=0.4)  # 1.0 s simulated, last 0.4 s analysed


@pytest.fixture(scope="module")
def system():
    return default_parameters()


def points(n, torque=200.0):
    return make_grid(np.arange(n) * 50 * RPM + 1000 * RPM, [torque], "2:300,4:100")


def cached_keys():
    with sc.ResultCache() as store:
        return set(store.keys())


# --------------------------------------------------------------------------- grid
def test_parse_range_thesis_sweep_is_inclusive_and_in_rad_s():
    w = parse_range("900:2800:10")
    assert w.size == 191  # [thesis] §3.3.2: every 10 rpm
    assert w[0] == pytest.approx(900 * RPM) and w[-1] == pytest.approx(2800 * RPM)
    np.testing.assert_allclose(np.diff(w), 10 * RPM)
    np.testing.assert_allclose(parse_range("1500"), [1500 * RPM])
    np.testing.assert_allclose(parse_range("1200, 1500,1800:2000:100"), np.array([1200, 1500, 1800, 1900, 2000]) * RPM)


def test_parse_values_avoids_accumulated_rounding():
    assert parse_values("0:1:0.1") == tuple(round(0.1 * i, 12) for i in range(11))
    assert parse_torques("50:500:50")[-1] == 500.0
    assert parse_torques("-100,0,100") == (-100.0, 0.0, 100.0)


@pytest.mark.parametrize(
    "text, match",
    [
        ("", "no value"),
        ("900:2800", "malformed"),
        ("900:2800:10:5", "malformed"),
        ("900:abc:10", "'abc' is not a number"),
        ("900:2800:0", "step must be > 0"),
        ("2800:900:10", "below START"),
        ("900,,1000", "empty list item"),
        ("100", "outside the accepted 300 to 6000 rpm"),
        ("900:7000:100", "outside"),
        ("nan", "finite"),
        ("0:6000:0.00001", "at most"),
    ],
)
def test_parse_range_errors(text, match):
    with pytest.raises(InputError, match=match):
        parse_range(text)


def test_make_grid_and_test_points():
    grid = make_grid(parse_range("1000:1100:50"), [100, 200], "2:300,4:100@90")
    assert len(grid) == 6
    assert [p.mean_torque for p in grid] == [100.0] * 3 + [200.0] * 3
    assert grid[0].orders == ((2.0, 300.0, 0.0), (4.0, 100.0, math.pi / 2))
    assert grid[1].speed_rpm == pytest.approx(1050.0)
    ex = grid[0].excitation()
    assert ex.speed == grid[0].speed and ex.orders == grid[0].orders
    assert TestPoint(100, 1, [(2, 3)]) == TestPoint(100.0, 1.0, ((2.0, 3.0, 0.0),))
    with pytest.raises(InputError, match="positive"):
        TestPoint(-1.0, 0.0)
    with pytest.raises(InputError, match="twice"):
        TestPoint(100.0, 0.0, ((2, 1), (2, 3)))
    with pytest.raises(InputError, match="at least one speed"):
        make_grid([], [200.0])


# --------------------------------------------------------------------------- run_sweep
def test_table_layout_and_second_sweep_from_cache(cache_dir, system):
    pts = points(2)
    calls = []
    first = run_sweep(system, pts, executor="serial", progress=lambda *a: calls.append(a), **SHORT)
    assert calls[0] == (0, 2, 0) and calls[-1] == (2, 2, 0)
    assert (first.computed, first.from_cache) == (2, 0)
    t = first.table
    assert tuple(t.columns) == TABLE_COLUMNS and len(t) == 2 * 8
    np.testing.assert_allclose(t["frequency_hz"], t["order"] * t["speed_rad_s"] / (2 * math.pi))
    np.testing.assert_allclose(t["speed_rpm"].unique(), [1000.0, 1050.0])
    # magnification: output / input, NaN where the input is below 1e-3 of the point's largest
    for _, grp in t.groupby("point"):
        small = grp["input_amplitude_nm"] < 1e-3 * grp["input_amplitude_nm"].max()
        assert grp.loc[small, "magnification"].isna().all()
        ok = ~small
        np.testing.assert_allclose(
            grp.loc[ok, "magnification"], grp.loc[ok, "output_amplitude_nm"] / grp.loc[ok, "input_amplitude_nm"]
        )
    order2 = t[t["order"] == 2.0]
    assert order2["input_amplitude_nm"].to_numpy() == pytest.approx([300.0, 300.0], rel=1e-3)
    assert first.input_spectra.shape == (2, first.frequency_hz.size)
    speeds, freq, amp = first.colourmap("output")
    assert amp.shape == (2, freq.size) and list(speeds) == pytest.approx([1000.0, 1050.0])
    assert len(first.spectra("input")) == 2

    calls.clear()
    second = run_sweep(system, pts, executor="serial", progress=lambda *a: calls.append(a), **SHORT)
    assert (second.computed, second.from_cache) == (0, 2)
    assert calls == [(2, 2, 2)]
    pd.testing.assert_frame_equal(second.table, first.table)
    np.testing.assert_array_equal(second.output_spectra, first.output_spectra)
    assert second.points["from_cache"].all()


def test_duplicate_points_are_computed_once(cache_dir, system):
    p = points(1)[0]
    result = run_sweep(system, [p, p], executor="serial", **SHORT)
    assert result.n_points == 2 and len(cached_keys()) == 1
    assert (result.computed, result.from_cache) == (2, 0)


@pytest.mark.parametrize("use_event", [True, False])
def test_cancel_after_k_points_keeps_exactly_those(cache_dir, system, use_event):
    pts = points(4)
    k = 2
    event = threading.Event()
    flag = {"stop": False}

    def progress(done, total, from_cache):
        if done >= k:
            event.set()
            flag["stop"] = True

    cancel = event if use_event else (lambda: flag["stop"])
    with pytest.raises(SweepCancelled) as info:
        run_sweep(system, pts, executor="serial", progress=progress, cancel=cancel, **SHORT)
    exc = info.value
    assert isinstance(exc, DampersimError)
    assert (exc.completed, exc.total, exc.computed, exc.from_cache) == (k, 4, k, 0)
    assert "2 of 4" in str(exc)
    expected = {sc.cache_key(system, p, **SHORT) for p in pts[:k]}
    assert cached_keys() == expected  # exactly the finished points, no partial entries
    rest = run_sweep(system, pts, executor="serial", **SHORT)
    assert (rest.computed, rest.from_cache) == (2, 2)


def test_cancel_with_processes_keeps_the_finished_points(cache_dir, system):
    pts = points(5)
    event = threading.Event()

    def progress(done, total, from_cache):
        if done >= 1:
            event.set()

    with pytest.raises(SweepCancelled) as info:
        run_sweep(system, pts, executor="processes", workers=2, progress=progress, cancel=event, **SHORT)
    assert 1 <= info.value.completed < 5
    assert len(cached_keys()) == info.value.completed


def test_serial_and_processes_give_identical_numbers(system):
    pts = points(3)
    serial = run_sweep(system, pts, executor="serial", cache=False, **SHORT)
    procs = run_sweep(system, pts, executor="processes", workers=2, cache=False, **SHORT)
    assert procs.executor == "processes"
    pd.testing.assert_frame_equal(serial.table, procs.table, check_exact=True)
    np.testing.assert_array_equal(serial.output_spectra, procs.output_spectra)


def test_failed_point_keeps_finished_points(cache_dir, system, monkeypatch):
    pts = points(3)
    real = sc.compute_record

    def flaky(system, point, **kw):
        if point is pts[1]:
            raise SimulationDiverged(0.5, "NaN in the state", 2e-5)
        return real(system, point, **kw)

    monkeypatch.setattr(sc, "compute_record", flaky)
    with pytest.raises(SweepPointFailed, match="1050 rpm, 200 N m failed .*diverged"):
        run_sweep(system, pts, executor="serial", **SHORT)
    assert cached_keys() == {sc.cache_key(system, pts[0], **SHORT)}


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(executor="threads"), "accepted is one of processes, serial, dask"),
        (dict(executor="serial", scheduler="tcp://127.0.0.1:8786"), "executor 'dask'"),
        (dict(workers=0), "whole number >= 1"),
        (dict(orders=(1, 9)), "not stored"),
        (dict(duration=1.0, window=1.25), r"does not fit after the start-up \(0.6 s\)"),
        (dict(duration=1.0, window=0.1), "too short to separate half orders"),
        (dict(cancel="yes"), "threading.Event"),
    ],
)
def test_run_sweep_rejects_bad_arguments(system, kwargs, match):
    kw = dict(SHORT)
    kw.update(kwargs)
    with pytest.raises(InputError, match=match):
        run_sweep(system, points(1), cache=False, **kw)


def test_run_sweep_rejects_non_points(system):
    with pytest.raises(InputError, match="at least one test point"):
        run_sweep(system, [], cache=False)
    with pytest.raises(InputError, match="TestPoint"):
        run_sweep(system, [(100.0, 200.0)], cache=False)


# --------------------------------------------------------------------------- CLI
def cli(argv):
    args = build_parser().parse_args(argv)
    return args.func(args)


def test_sweep_command_json_and_cache(cache_dir, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["sweep", "--speeds", "1000:1050:50", "--torque", "200", "--orders", "2:300",
            "--executor", "serial", "--duration", "1.0", "--window", "0.4",
            "--set", "friction.outer.alpha=0.5", "--out", str(out), "--json"]
    assert cli(argv) == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out)
    assert summary["points"] == 2 and summary["computed"] == 2 and summary["from_cache"] == 0
    assert summary["table"] == str(out / "sweep.parquet")
    assert "2/2 points" in captured.err  # the progress bar
    table = pd.read_parquet(summary["table"])
    assert tuple(table.columns) == TABLE_COLUMNS and len(table) == 16
    assert [p.name for p in out.iterdir() if p.name.endswith(".tmp")] == []
    # figures come from the plotting module when it is there; otherwise a note says why not
    if summary["figures"]:
        assert all(pathlib.Path(f).is_file() and f.endswith(".html") for f in summary["figures"])
    else:
        assert "figures skipped" in captured.err

    assert cli(argv) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["computed"] == 0 and summary["from_cache"] == 2


def test_sweep_command_text_summary_and_errors(cache_dir, tmp_path, capsys):
    assert cli(["sweep", "--speeds", "1000", "--executor", "serial", "--duration", "1.0",
                "--window", "0.4", "--out", str(tmp_path / "o"), "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "1 test points" in text and "computed:   1" in text and "from cache: 0" in text
    with pytest.raises(InputError, match="does not fit"):
        cli(["sweep", "--speeds", "1000", "--duration", "1.0", "--out", str(tmp_path / "o")])
    with pytest.raises(DampersimError, match="did you mean"):
        cli(["sweep", "--speeds", "1000", "--set", "solver.time_stp=1e-5", "--out", str(tmp_path / "o")])
    (tmp_path / "afile").write_text("x")
    with pytest.raises(InputError, match="not a folder"):
        cli(["sweep", "--speeds", "1000", "--out", str(tmp_path / "afile")])


def test_progress_bar_without_terminal():
    stream = io.StringIO()
    bar = ProgressBar(stream)
    for done in range(0, 21):
        bar(done, 20, 0)
    lines = stream.getvalue().splitlines()
    assert 2 <= len(lines) <= 12 and lines[-1].startswith("[" + "#" * 30 + "] 20/20")


# --------------------------------------------------------------------------- orders command
FS = 10_000.0
RPM_FILE = 1500.0
AMPS = {1: 5.0, 2: 300.0, 4: 100.0, 6: 20.0}


def signal(n=12_500, fs=FS):
    t = np.arange(n) / fs
    f1 = RPM_FILE / 60.0
    x = 200.0 + sum(a * np.cos(2 * np.pi * k * f1 * t + 0.3 * k) for k, a in AMPS.items())
    return t, x


def expected():
    return [AMPS.get(k, 0.0) for k in range(1, 9)]


def test_orders_command_on_csv(tmp_path, capsys):
    t, x = signal()
    path = tmp_path / "rec.csv"
    pd.DataFrame({"time_s": t, "input_torque_nm": x * 2, "output_torque_nm": x}).to_csv(path, index=False)
    assert cli(["orders", str(path), "--rpm", str(RPM_FILE), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["orders"] == [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]
    # 31.25 periods of order 1 in the record: Hann leakage stays below 1e-4 of the largest order
    np.testing.assert_allclose(out["amplitude_nm"], expected(), atol=1e-4 * 300)
    assert out["column"] == "output_torque_nm"
    assert cli(["orders", str(path), "--rpm", "1500", "--column", "input_torque_nm", "--orders", "2,4", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    np.testing.assert_allclose(out["amplitude_nm"], [600.0, 200.0], rtol=1e-4)


def test_orders_command_on_parquet_with_fs_and_first_numeric_column(tmp_path, capsys):
    _, x = signal()
    path = tmp_path / "rec.parquet"
    pd.DataFrame({"label": ["a"] * x.size, "torque": x}).to_parquet(path)
    assert cli(["orders", str(path), "--rpm", "1500", "--fs", str(FS), "--window", "1.0", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["column"] == "torque" and out["samples"] == 10_000
    # whole periods in the 1.0 s window: exact up to rounding
    np.testing.assert_allclose(out["amplitude_nm"], expected(), atol=1e-6 * 300)
    assert cli(["orders", str(path), "--rpm", "1500", "--fs", str(FS)]) == 0
    assert "amplitude [N m]" in capsys.readouterr().out


def write_csv(path, **cols):
    pd.DataFrame(cols).to_csv(path, index=False)
    return str(path)


@pytest.mark.parametrize(
    "case, argv_extra, match",
    [
        ("missing_column", ["--column", "nope"], "column 'nope' is not in .*available columns: time_s, output_torque_nm"),
        ("nan", [], "1 NaN/inf samples .*data row 100"),
        ("inf", [], "NaN/inf"),
        ("nonuniform", [], "non-uniform"),
        ("decreasing", [], "strictly increasing"),
        ("short", [], "'output_torque_nm' .* has 8 samples; at least 16"),
        ("short_resolution", [], "too short to resolve the orders"),
        ("nyquist", ["--fs", "200"], "Nyquist"),
        ("no_time", [], "no time column .*--fs.*available columns: torque"),
        ("text_column", ["--column", "label"], "not numeric"),
        ("bad_rpm", ["--rpm", "-5"], "positive shaft speed"),
        ("long_window", ["--window", "5"], "needs 50000 samples"),
    ],
)
def test_orders_command_bad_input(tmp_path, case, argv_extra, match):
    t, x = signal()
    csv = tmp_path / "rec.csv"
    if case == "nan":
        x[100] = np.nan
    if case == "inf":
        x[5] = np.inf
    if case == "nonuniform":
        t = t.copy()
        t[500:] += 0.01
    if case == "decreasing":
        t = t.copy()
        t[10] = t[8]
    if case in ("short", "short_resolution"):
        n = 8 if case == "short" else 200
        t, x = t[:n], x[:n]
    if case == "no_time":
        path = write_csv(csv, torque=x)
    elif case == "text_column":
        path = write_csv(csv, time_s=t, label=["a"] * t.size, output_torque_nm=x)
    else:
        path = write_csv(csv, time_s=t, output_torque_nm=x)
    argv = ["orders", path, "--rpm", "1500", "--json"]
    if "--rpm" in argv_extra:
        argv = ["orders", path, "--json"]
    with pytest.raises(InputError, match=match):
        cli(argv + argv_extra)


def test_orders_command_bad_files(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        cli(["orders", str(tmp_path / "missing.csv"), "--rpm", "1500"])
    xlsx = tmp_path / "rec.xlsx"
    xlsx.write_bytes(b"PK\x03\x04")
    with pytest.raises(InputError, match="unknown file type '.xlsx'.*accepted are .csv and .parquet"):
        cli(["orders", str(xlsx), "--rpm", "1500"])
    empty = tmp_path / "empty.csv"
    empty.write_text("")
    with pytest.raises(InputError, match="empty"):
        cli(["orders", str(empty), "--rpm", "1500"])
    header_only = tmp_path / "header.csv"
    header_only.write_text("time_s,output_torque_nm\n")
    with pytest.raises(InputError, match="no data rows"):
        cli(["orders", str(header_only), "--rpm", "1500"])
    broken = tmp_path / "broken.parquet"
    broken.write_bytes(b"not parquet at all")
    with pytest.raises(InputError, match="cannot be read"):
        cli(["orders", str(broken), "--rpm", "1500"])
