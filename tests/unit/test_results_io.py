"""SimulationResult.save / load: the simulate --out Parquet file, exact round trip, clear errors."""

import dataclasses
import json
import math

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from dampersim import MeasuredTorque, OrderSum, SimulationResult, TorqueRamp, default_parameters, simulate
from dampersim.errors import InputError
from dampersim.fileio import write_parquet_atomic
from dampersim.results import RESULT_FORMAT_VERSION, ExcitationDescription


@pytest.fixture(scope="module")
def result():
    system = default_parameters()
    ex = OrderSum(speed=1500 * math.pi / 30, mean_torque=200, orders=((2, 300.0), (4, 100.0, 0.5)),
                  mean_ramp=0.05, amplitude_ramp=0.05)
    return simulate(system, ex, duration=0.2, record_segments=True)


def assert_same(a, b):
    """Every field of two results equal: arrays bit for bit with dtype and shape."""
    for f in dataclasses.fields(SimulationResult):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            assert isinstance(y, np.ndarray) and x.dtype == y.dtype and x.shape == y.shape, f.name
            assert x.tobytes() == y.tobytes(), f.name
        elif isinstance(x, dict):
            assert list(x) == list(y), f.name
            for k in x:
                assert x[k].dtype == y[k].dtype and x[k].tobytes() == y[k].tobytes(), f"{f.name}[{k}]"
        elif isinstance(x, float) and math.isnan(x):
            assert isinstance(y, float) and math.isnan(y), f.name
        elif isinstance(x, MeasuredTorque):
            assert type(y) is MeasuredTorque and x.speed == y.speed, f.name
            assert (x.mean_ramp, x.amplitude_ramp) == (y.mean_ramp, y.amplitude_ramp)
            assert x.time.tobytes() == y.time.tobytes() and x.torque_samples.tobytes() == y.torque_samples.tobytes()
        else:
            assert type(x) is type(y) and x == y, f.name


def test_round_trip_is_exact(result, tmp_path):
    assert result.nodes.shape[0] > 0 and result.wall_time > 0
    path = tmp_path / "run.parquet"
    assert result.save(path) == str(path)
    back = SimulationResult.load(path)
    assert_same(result, back)
    assert back.parameters == default_parameters() and back.excitation == result.excitation
    # what the helpers compute from the loaded result is what they computed before
    np.testing.assert_array_equal(back.segment_compression("pair_inner"), result.segment_compression("pair_inner"))
    np.testing.assert_array_equal(back.energy_residual(), result.energy_residual())
    for a, b in zip(back.order_amplitudes(), result.order_amplitudes()):
        np.testing.assert_array_equal(a, b)
    assert [p.name for p in tmp_path.iterdir()] == ["run.parquet"]  # no temporary file left


def test_file_is_the_simulate_out_table_plus_series(result, tmp_path):
    """The result's time series table (the one simulate --out wrote before it called save),
    column for column, then the remaining series."""
    cli = tmp_path / "cli.parquet"
    write_parquet_atomic(result.to_frame(), cli)
    saved = tmp_path / "saved.parquet"
    result.save(saved)
    a, b = pd.read_parquet(cli), pd.read_parquet(saved)
    assert list(b.columns[: a.shape[1]]) == list(a.columns) and len(b) == len(a)
    pd.testing.assert_frame_equal(b[a.columns], a, check_exact=True)
    assert list(b.columns[a.shape[1]:]) == ["spring_torque_outer_nm", "spring_torque_inner_nm"] + [
        f"energy_{k}_j" for k in result.energy
    ]
    header = json.loads(pq.read_schema(saved).metadata[b"dampersim.result"])
    assert header["format"] == "dampersim.result" and header["version"] == RESULT_FORMAT_VERSION


@pytest.mark.parametrize(
    "excitation",
    [
        TorqueRamp(speed=120.0, points=(0.0, 450.0, -180.0, 0.0), rate=50.0, hold=2.0, lead=0.5),
        MeasuredTorque(speed=150.0, time=np.linspace(0.0, 0.1, 64), torque_samples=np.sin(np.arange(64)) * 1 / 3 + 200.0),
    ],
    ids=["ramp", "measured"],
)
def test_other_thesis_excitations_are_rebuilt(result, tmp_path, excitation):
    res = dataclasses.replace(result, excitation=excitation)
    res.save(tmp_path / "r.parquet")
    assert_same(res, SimulationResult.load(tmp_path / "r.parquet"))


class _OwnDrive:
    speed = 140.0
    steady_start = 0.25

    def torque(self, t):
        return np.zeros_like(t)

    def __repr__(self):
        return "_OwnDrive(speed=140.0)"


def test_foreign_excitation_is_described_and_non_finite_scalars_survive(result, tmp_path):
    res = dataclasses.replace(result, excitation=_OwnDrive(), wall_time=float("nan"), steady_start=float("inf"))
    res.save(tmp_path / "r.parquet")
    back = SimulationResult.load(tmp_path / "r.parquet")
    assert back.excitation == ExcitationDescription(
        kind=f"{__name__}._OwnDrive", speed=140.0, steady_start=0.25, duration=None, text="_OwnDrive(speed=140.0)"
    )
    assert math.isnan(back.wall_time) and back.steady_start == math.inf
    # a loaded description saves and loads unchanged
    back.save(tmp_path / "again.parquet")
    assert_same(back, SimulationResult.load(tmp_path / "again.parquet"))


def test_result_without_parameters_or_excitation(result, tmp_path):
    res = dataclasses.replace(result, parameters=None, excitation=None)
    res.save(tmp_path / "r.parquet")
    assert_same(res, SimulationResult.load(tmp_path / "r.parquet"))


def test_result_without_segment_frames(result, tmp_path):
    """simulate --out runs with record_segments=False: no frames, nodes of shape (0, n)."""
    res = dataclasses.replace(result, nodes=result.nodes[:0], segment_t=result.segment_t[:0])
    res.save(tmp_path / "r.parquet")
    back = SimulationResult.load(tmp_path / "r.parquet")
    assert back.nodes.shape == (0, result.nodes.shape[1])
    assert_same(res, back)


def test_missing_folder_is_named(result, tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        result.save(tmp_path / "nowhere" / "r.parquet")


def _rewrite_header(src, dst, edit):
    table = pq.read_table(src)
    meta = dict(table.schema.metadata)
    meta[b"dampersim.result"] = edit(meta[b"dampersim.result"])
    pq.write_table(table.replace_schema_metadata(meta), dst)


@pytest.mark.parametrize(
    "make, fragment",
    [
        (lambda p, good: None, "no such file"),
        (lambda p, good: p.write_text("time_s,input_torque_nm\n0,1\n"), "is not a Parquet file"),
        (lambda p, good: p.write_bytes(good.read_bytes()[:-200]), "is not a Parquet file"),
        (lambda p, good: pd.DataFrame({"time_s": [0.0, 1e-4]}).to_parquet(p, index=False), "no dampersim.result metadata"),
        (lambda p, good: _rewrite_header(good, p, lambda b: b[:-10]), "not valid JSON"),
        (lambda p, good: _rewrite_header(good, p, lambda b: b.replace(b'"version":1', b'"version":99')), "format version 99"),
        (lambda p, good: _rewrite_header(good, p, lambda b: b.replace(b'"t":"time_s"', b'"t":"time"')), "is damaged"),
        (lambda p, good: _rewrite_header(good, p, lambda b: b.replace(b'"base64":"', b'"base64":"!', 1)), "is damaged"),
        (lambda p, good: _rewrite_header(good, p, lambda b: b.replace(b'"count":3', b'"count":-3')), "parameter set is not valid"),
    ],
    ids=["missing", "csv", "truncated", "plain-table", "bad-json", "version", "column", "array", "parameters"],
)
def test_bad_file_is_a_clear_error(result, tmp_path, make, fragment):
    good = tmp_path / "good.parquet"
    result.save(good)
    bad = tmp_path / "bad.parquet"
    make(bad, good)
    with pytest.raises(InputError) as info:
        SimulationResult.load(bad)
    msg = str(info.value)
    assert fragment in msg and str(bad) in msg and "accepted is a Parquet file written by SimulationResult.save" in msg
    assert len(msg.splitlines()) == 1
