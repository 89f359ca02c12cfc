"""Result cache of sweeps: keys, stored records, corruption handling, location."""

import math

import numpy as np
import pytest

import dampersim
from dampersim import default_parameters, keys
from dampersim.errors import InputError
from dampersim.parameters import with_updates
from dampersim.sweeps import cache as sc
from dampersim.sweeps.executor import run_sweep
from dampersim.sweeps.grid import TestPoint

SPEED = 1500 * 2 * math.pi / 60  # [rad/s]
# short runs: 1.0 s simulated, the last 0.4 s analysed (the start-up takes 0.6 s)
SHORT = dict(duration=1.0, window=0.4)


@pytest.fixture
def system():
    return default_parameters()


@pytest.fixture
def point():
    return TestPoint(SPEED, 200.0, ((2, 300.0, 0.0), (4, 100.0, 0.0)))


def key(system, point, **kw):
    return sc.cache_key(system, point, duration=kw.pop("duration", 1.0), window=kw.pop("window", 0.4), **kw)


# --------------------------------------------------------------------------- keys
def test_key_is_sha256_hex_and_identical_for_equal_inputs_built_separately(system, point):
    k1 = key(system, point)
    other_system = default_parameters()
    other_point = TestPoint(1500.0 * 2.0 * math.pi / 60.0, 200, [(2.0, 300), (4.0, 100.0, 0)])
    assert other_point == point
    assert len(k1) == 64 and int(k1, 16) >= 0
    assert key(other_system, other_point) == k1
    # a round trip through TOML (another engineer's saved file) keeps the key
    from dampersim.parameters import dumps_toml, loads_toml

    assert key(loads_toml(dumps_toml(system)), point) == k1


@pytest.mark.parametrize(
    "name, factor",
    [
        ("outer.spring.stiffness", 1.01),
        ("inner.nested.mass", 1.01),
        ("inertias.primary", 1.01),
        ("friction.outer.alpha", 1.01),
        ("friction.gamma6", 1.01),
        ("hardstops.stiffness", 1.01),
        ("rig.elements.gearbox.shaft_stiffness", 1.01),
        ("rig.elements.transducer.inertia", 1.01),
        ("solver.time_step", 0.5),
        ("solver.output_sample_rate", 2.0),
    ],
)
def test_key_changes_with_every_parameter(system, point, name, factor):
    obj = system
    for part in name.split("."):
        obj = {e.name: e for e in obj}[part] if isinstance(obj, tuple) else getattr(obj, part)
    changed = with_updates(system, {name: obj * factor})
    assert key(changed, point) != key(system, point)


def test_key_changes_with_boolean_integer_and_string_parameters(system, point):
    base = key(system, point)
    assert key(with_updates(system, {"friction.enabled": False}), point) != base
    assert key(with_updates(system, {"solver.outer_segments": 12}), point) != base
    assert key(with_updates(system, {"motor.mode": "held"}), point) != base


def test_key_floats_are_exact(system, point):
    stiffness = system.outer.spring.stiffness
    nudged = with_updates(system, {"outer.spring.stiffness": math.nextafter(stiffness, math.inf)})
    assert key(nudged, point) != key(system, point)
    doc = keys.canonical(sc.key_document(system, point, 1.0, 0.4))
    assert doc["parts"]["duration_s"] == {"f": (1.0).hex()}


def test_key_ignores_only_the_name_and_source_labels(system, point):
    renamed = with_updates(system, {"name": "copy", "source": "elsewhere"})
    assert key(renamed, point) == key(system, point)


@pytest.mark.parametrize(
    "other",
    [
        TestPoint(SPEED * (1 + 1e-12), 200.0, ((2, 300.0, 0.0), (4, 100.0, 0.0))),
        TestPoint(SPEED, 201.0, ((2, 300.0, 0.0), (4, 100.0, 0.0))),
        TestPoint(SPEED, 200.0, ((2, 301.0, 0.0), (4, 100.0, 0.0))),
        TestPoint(SPEED, 200.0, ((2, 300.0, 0.1), (4, 100.0, 0.0))),
        TestPoint(SPEED, 200.0, ((2, 300.0, 0.0),)),
        TestPoint(SPEED, 200.0, ((2, 300.0, 0.0), (4, 100.0, 0.0), (6, 10.0, 0.0))),
    ],
)
def test_key_changes_with_the_excitation(system, point, other):
    assert key(system, other) != key(system, point)


def test_key_changes_with_excitation_ramps_duration_and_window(system, point):
    base = key(system, point)
    slow = dampersim.OrderSum(point.speed, point.mean_torque, point.orders, mean_ramp=0.4)
    assert sc.cache_key(system, point.excitation(), duration=1.0, window=0.4) == base
    assert sc.cache_key(system, slow, duration=1.0, window=0.4) != base
    assert key(system, point, duration=1.2) != base
    assert key(system, point, window=0.3) != base
    # None means the solver's duration, which is the same key as giving it explicitly
    assert sc.cache_key(system, point) == sc.cache_key(system, point, duration=system.solver.duration, window=1.25)


def test_key_changes_with_kernel_source_and_version(system, point, monkeypatch):
    base = key(system, point)
    real = sc.kernel_source_hash()
    assert len(real) == 64
    monkeypatch.setattr(sc, "kernel_source_hash", lambda: "0" * 64)
    assert key(system, point) != base
    monkeypatch.undo()
    assert key(system, point) == base
    monkeypatch.setattr(keys, "__version__", "9.9.9")
    assert key(system, point) != base


def test_source_hash_covers_every_module_that_shapes_a_point():
    covered = set(keys.module_closure(sc.RECORD_MODULE))
    # the kernel modules, their layout and driver, the simulation, the result, the signal
    # analysis and the transducer low pass behind effect transducer_bandwidth (in
    # dampersim.signal; a hand-kept file list once missed it), the excitation's order sum
    need = {
        "dampersim.solver.kernels.integrate", "dampersim.solver.kernels.forces", "dampersim.solver.kernels.friction",
        "dampersim.solver.kernels.contacts", "dampersim.solver.kernels.effects", "dampersim.solver.kernels.fastmath",
        "dampersim.solver.layout", "dampersim.solver.driver", "dampersim.simulation.damper", "dampersim.results",
        "dampersim.signal", "dampersim.excitation.orders", "dampersim.parameters.model", "dampersim.sweeps.cache",
    }
    assert need <= covered, sorted(need - covered)
    assert sc.current_source_hash() == sc.kernel_source_hash()


def test_key_changes_with_the_platform(system, point, monkeypatch):
    base = key(system, point)
    other = {**keys.platform(), "cpu": {"name": "another-cpu", "features": ""}}
    monkeypatch.setattr(keys, "platform", lambda: other)
    assert key(system, point) != base


def test_key_rejects_unhashable_values(system):
    with pytest.raises(InputError, match="cache key"):
        sc.cache_key(system, object())


# --------------------------------------------------------------------------- records
def make_record(key="k" * 64):
    return sc.PointRecord(
        key=key,
        orders=np.array(sc.STORED_ORDERS),
        input_amplitude=np.linspace(1, 16, 16),
        output_amplitude=np.linspace(0.5, 8, 16),
        df=2.5,
        input_spectrum=np.arange(401, dtype=np.float32),
        output_spectrum=np.ones(401, dtype=np.float32),
        mean_input_torque=200.0,
        mean_output_torque=199.5,
        wall_time=0.2,
        compute_time=0.21,
        sample_rate=10000.0,
        window=0.4,
    )


def test_record_round_trip():
    rec = make_record()
    back = sc.PointRecord.from_bytes(rec.to_bytes(), key=rec.key)
    for name in ("orders", "input_amplitude", "output_amplitude", "input_spectrum", "output_spectrum"):
        np.testing.assert_array_equal(getattr(back, name), getattr(rec, name))
    assert back.input_spectrum.dtype == np.float32
    assert back.mean_output_torque == 199.5 and back.window == 0.4
    np.testing.assert_allclose(back.frequency_hz[:3], [0.0, 2.5, 5.0])
    a_in, a_out = back.amplitudes([1, 2])
    np.testing.assert_array_equal(a_in, [2.0, 4.0])


@pytest.mark.parametrize(
    "mangle",
    [
        lambda b: b"garbage",
        lambda b: b[:-10],
        lambda b: b[:50] + bytes([b[50] ^ 0xFF]) + b[51:],
        lambda b: b[: len(b) // 2],
        lambda b: "text",
        lambda b: {"orders": [1, 2]},
        lambda b: None if False else 12345,
    ],
)
def test_damaged_records_are_rejected(mangle):
    with pytest.raises(ValueError):
        sc.PointRecord.from_bytes(mangle(make_record().to_bytes()), key="k" * 64)


def test_record_of_another_key_is_rejected():
    with pytest.raises(ValueError, match="another key"):
        sc.PointRecord.from_bytes(make_record("a" * 64).to_bytes(), key="b" * 64)


def test_store_get_put_and_garbage(cache_dir):
    with sc.ResultCache() as store:
        assert store.directory == cache_dir / "results"
        rec = make_record()
        assert store.get(rec.key) is None
        store.put(rec.key, rec)
        assert rec.key in store and len(store) == 1
        store.diskcache.set(rec.key, b"garbage")
        assert store.get(rec.key) is None and store.corrupted == 1
        store.diskcache.set(rec.key, {"not": "a record"})
        assert store.get(rec.key) is None and store.corrupted == 2


# --------------------------------------------------------------------------- location
def test_cache_dir_is_read_at_call_time_and_absolute(tmp_path, monkeypatch):
    monkeypatch.setenv("DAMPERSIM_CACHE_DIR", str(tmp_path / "a"))
    assert sc.cache_dir() == tmp_path / "a"
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("DAMPERSIM_CACHE_DIR", "relative")
    assert sc.cache_dir() == tmp_path / "relative" and sc.cache_dir().is_absolute()
    monkeypatch.delenv("DAMPERSIM_CACHE_DIR")
    assert sc.cache_dir() == sc.repo_root() / "cache"
    assert sc.results_dir() == sc.repo_root() / "cache" / "results"


def test_unusable_cache_dir_is_a_clear_error(tmp_path, monkeypatch, system, point):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("DAMPERSIM_CACHE_DIR", str(blocker))
    with pytest.raises(InputError, match="DAMPERSIM_CACHE_DIR"):
        run_sweep(system, [point], executor="serial", **SHORT)


# --------------------------------------------------------------------------- with the solver
def test_corrupted_entry_is_recomputed(cache_dir, system, point):
    first = run_sweep(system, [point], executor="serial", **SHORT)
    assert first.computed == 1
    k = first.keys[0]
    with sc.ResultCache() as store:
        good = store.diskcache.get(k)
        store.diskcache.set(k, b"garbage" + good[7:])  # same length, broken tag and checksum
    again = run_sweep(system, [point], executor="serial", **SHORT)
    assert again.computed == 1 and again.from_cache == 0
    assert again.table.equals(first.table)
    with sc.ResultCache() as store:
        assert store.get(k) is not None  # repaired
    third = run_sweep(system, [point], executor="serial", **SHORT)
    assert third.from_cache == 1 and third.computed == 0


def test_stored_record_matches_the_simulation(cache_dir, system, point):
    result = run_sweep(system, [point], executor="serial", **SHORT)
    sim = dampersim.simulate(system, point.excitation(), duration=1.0, record_segments=False)
    a_in, a_out = sim.order_amplitudes(tuple(range(1, 9)), seconds=0.4)
    np.testing.assert_array_equal(result.table["input_amplitude_nm"].to_numpy(), a_in)
    np.testing.assert_array_equal(result.table["output_amplitude_nm"].to_numpy(), a_out)
    assert result.frequency_hz[-1] <= sc.SPECTRUM_MAX_HZ
    assert result.input_spectra.dtype == np.float32
    w = sim.window(0.4)
    assert result.points["mean_output_torque_nm"].iloc[0] == pytest.approx(np.mean(sim.output_torque[w]))


def test_an_explicit_empty_cache_is_used(tmp_path, system, point):
    with sc.ResultCache(tmp_path / "explicit") as store:
        assert len(store) == 0
        first = run_sweep(system, [point], executor="serial", cache=store, **SHORT)
        assert first.computed == 1 and len(store) == 1
        second = run_sweep(system, [point], executor="serial", cache=store, **SHORT)
        assert second.from_cache == 1
    with pytest.raises(InputError, match="ResultCache"):
        run_sweep(system, [point], executor="serial", cache="yes", **SHORT)
