"""On-disk result cache of sweep test points (diskcache), and what is stored per point.

Location: ``$DAMPERSIM_CACHE_DIR/results`` when that environment variable is set (read on
every call, made absolute), else ``cache/results`` at the repository root.

Key: :func:`dampersim.keys.make_key` of the complete parameter set
(:func:`dampersim.parameters.to_dict`, solver settings included; only the set's ``name``
and ``source`` labels are left out), the excitation (its type and every field), the
simulated duration [s] and the analysis settings, with the package version, the platform
(numpy/numba/llvmlite versions, CPU target) and the hash of every module that
:func:`compute_record` reaches through imports. A physics, analysis or platform change
gives new keys and can never return a stale result.

Value: a :class:`PointRecord` -- order amplitudes of input and output torque for orders
0.5, 1, ..., 8 [N m] ([thesis] §3.4), the amplitude spectra of both over the analysis
window up to 1000 Hz (float32), the mean torques [N m] and the wall times [s]. It is
stored as bytes: a magic tag, a SHA-256 checksum and an ``.npz`` payload (no pickle).
Entries that fail the checksum or the shape/type checks are treated as missing and get
recomputed. Each entry is written in one diskcache transaction, so an interrupted sweep
never leaves a partial entry.

A full disk is not a failure of the sweep: :meth:`ResultCache.put` returns False, the
cache stops writing for the rest of its life (``write_error`` says why) and the sweep goes
on uncached (:attr:`dampersim.sweeps.SweepResult.cache_notice`). The default folder is
made by :func:`dampersim.locations.private_dir` (0700, refused when others may write it).
"""

from __future__ import annotations

import errno
import hashlib
import io
import logging
import math
import sqlite3
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dampersim import keys
from dampersim.errors import InputError
from dampersim.locations import CACHE_DIR_ENV, cache_dir, private_dir, repo_root
from dampersim.parameters import to_dict
from dampersim.results import ANALYSIS_WINDOW
from dampersim.signal import amplitude_spectrum, order_amplitudes
from dampersim.simulation import natural_duration, simulate
from dampersim.sweeps.grid import TestPoint

#: Sub-directory of the cache directory that holds sweep results.
RESULTS_SUBDIR = "results"
#: Engine orders stored per point: 0.5, 1.0, ..., 8.0 ([thesis] §3.4, half orders on request).
STORED_ORDERS = tuple(0.5 * k for k in range(1, 17))
#: Spectra are stored up to this frequency [Hz].
SPECTRUM_MAX_HZ = 1000.0
#: Bumped when the stored layout changes (the source hash covers this file anyway).
RECORD_FORMAT = 1
#: Schema name of a sweep-point key.
KEY_SCHEMA = "dampersim.sweep-point"

LOGGER = logging.getLogger("dampersim.sweeps.cache")

_MAGIC = b"DSPR1\n"
_DIGEST = 32



# --------------------------------------------------------------------------- location
def results_dir() -> Path:
    """Absolute directory of the sweep result cache (``cache_dir() / "results"``)."""
    return cache_dir() / RESULTS_SUBDIR


# --------------------------------------------------------------------------- key
#: The module whose code computes a stored value: its import closure is hashed into the key.
RECORD_MODULE = __name__


def kernel_source_hash() -> str:
    """SHA-256 of the source of every module that shapes a cached point
    (:func:`dampersim.keys.source_hash` of this module's import closure).

    Read once per process, when this module is imported, so that it describes the code
    this process runs even if the files are edited later; sweep workers compare their own
    value with the one the key was built with and refuse to deliver a mismatch.
    """
    return keys.source_hash(RECORD_MODULE)


def current_source_hash() -> str:
    """The same hash read from the files as they are now (not the memo of this process)."""
    return keys.source_hash_at(RECORD_MODULE, keys.PACKAGE_DIR)


try:  # pin the hash to the code loaded now; a failure is reported when a key is needed
    kernel_source_hash()
except Exception:
    pass


def _excitation_of(point_or_excitation):
    if isinstance(point_or_excitation, TestPoint):
        return point_or_excitation.excitation()
    return point_or_excitation


def resolved_duration(system, excitation, duration=None) -> float:
    """Simulated duration [s]: ``duration`` if given, else the excitation's own length or
    the solver's ``duration`` (as :func:`dampersim.simulate` resolves it)."""

    dur = natural_duration(excitation, system.solver) if duration is None else float(duration)
    if not (math.isfinite(dur) and dur > 0):
        raise InputError(f"duration = {duration!r} s: accepted is a positive duration")
    return dur


def key_parts(system, point_or_excitation, duration=None, window=None) -> dict:
    """What one test point's key is made of, besides version, platform and source.

    system: :class:`DamperSystem`; point_or_excitation: a TestPoint or an excitation
    object; duration [s] (None: natural duration); window: analysis window [s] (None:
    1.25 s, [thesis] §3.4).
    """

    excitation = _excitation_of(point_or_excitation)
    window = ANALYSIS_WINDOW if window is None else float(window)
    return {
        "record_format": RECORD_FORMAT,
        # the set's name and source text are labels, not physics: renaming keeps the hits
        "parameters": {k: v for k, v in to_dict(system).items() if k not in ("name", "source")},
        "solver": to_dict(system.solver),
        "excitation": {"type": type(excitation).__qualname__, "value": excitation},
        "duration_s": resolved_duration(system, excitation, duration),
        "analysis": {
            "window_s": window,
            "orders": STORED_ORDERS,
            "spectrum_max_hz": SPECTRUM_MAX_HZ,
        },
    }


def key_document(system, point_or_excitation, duration=None, window=None, source_hash=None) -> dict:
    """The document hashed into the key (for inspection and tests)."""
    parts = key_parts(system, point_or_excitation, duration, window)
    source = kernel_source_hash() if source_hash is None else source_hash
    return keys.key_document(KEY_SCHEMA, RECORD_MODULE, parts, source)


def cache_key(system, point_or_excitation, duration=None, window=None, source_hash=None) -> str:
    """Stable SHA-256 hex key of one test point's result (see the module docstring).

    Equal inputs built separately give the same key; any change of a parameter, the
    solver settings, the excitation, the duration [s], the analysis window [s], the
    package version, the platform or the source of the code behind a point gives a
    different key. source_hash: pin the source hash (workers use the parent's).
    """
    return keys.digest(key_document(system, point_or_excitation, duration, window, source_hash))


# --------------------------------------------------------------------------- record
@dataclass(frozen=True, eq=False)
class PointRecord:
    """What the cache keeps of one simulated test point (all SI).

    orders [-]; input_amplitude, output_amplitude [N m] per order (NaN for an order at
    or above the Nyquist frequency); frequency step ``df`` [Hz] and float32 amplitude
    spectra [N m] of input and output torque over the analysis window from 0 Hz up to
    1000 Hz; mean_input_torque, mean_output_torque [N m] over the window; wall_time [s]
    of the kernel, compute_time [s] of simulation plus analysis; sample_rate [Hz] and
    window [s] used; key: the cache key it belongs to.
    """

    key: str
    orders: np.ndarray
    input_amplitude: np.ndarray
    output_amplitude: np.ndarray
    df: float
    input_spectrum: np.ndarray
    output_spectrum: np.ndarray
    mean_input_torque: float
    mean_output_torque: float
    wall_time: float
    compute_time: float
    sample_rate: float
    window: float

    @property
    def frequency_hz(self) -> np.ndarray:
        """Bin frequencies [Hz] of the stored spectra."""
        return self.df * np.arange(self.input_spectrum.size)

    def amplitudes(self, orders):
        """(input, output) amplitudes [N m] of the requested stored orders."""
        idx = [_order_index(self.orders, k) for k in orders]
        return self.input_amplitude[idx], self.output_amplitude[idx]

    # ---- serialisation
    def to_bytes(self) -> bytes:
        """Magic tag + SHA-256 + npz payload (arrays only, loadable without pickle)."""
        buf = io.BytesIO()
        scalars = np.array(
            [self.df, self.mean_input_torque, self.mean_output_torque, self.wall_time,
             self.compute_time, self.sample_rate, self.window],
            dtype=np.float64,
        )
        np.savez(
            buf,
            key=np.frombuffer(self.key.encode("ascii"), dtype=np.uint8),
            orders=np.asarray(self.orders, dtype=np.float64),
            input_amplitude=np.asarray(self.input_amplitude, dtype=np.float64),
            output_amplitude=np.asarray(self.output_amplitude, dtype=np.float64),
            input_spectrum=np.asarray(self.input_spectrum, dtype=np.float32),
            output_spectrum=np.asarray(self.output_spectrum, dtype=np.float32),
            scalars=scalars,
        )
        payload = buf.getvalue()
        return _MAGIC + hashlib.sha256(payload).digest() + payload

    @classmethod
    def from_bytes(cls, data, key=None) -> "PointRecord":
        """Decode and validate; raises ValueError for anything that is not an intact
        record (wrong type, bad checksum, missing arrays, wrong dtype/shape, other key)."""
        if not isinstance(data, (bytes, bytearray, memoryview)):
            raise ValueError(f"entry is a {type(data).__name__}, not a record")
        data = bytes(data)
        head = len(_MAGIC) + _DIGEST
        if len(data) <= head or not data.startswith(_MAGIC):
            raise ValueError("entry does not start with the record tag")
        digest, payload = data[len(_MAGIC):head], data[head:]
        if hashlib.sha256(payload).digest() != digest:
            raise ValueError("entry checksum mismatch")
        with np.load(io.BytesIO(payload), allow_pickle=False) as z:
            arrays = {name: z[name] for name in z.files}
        need = {
            "key": np.uint8, "orders": np.float64, "input_amplitude": np.float64,
            "output_amplitude": np.float64, "input_spectrum": np.float32,
            "output_spectrum": np.float32, "scalars": np.float64,
        }
        for name, dtype in need.items():
            arr = arrays.get(name)
            if arr is None or arr.dtype != dtype or arr.ndim != 1:
                raise ValueError(f"entry array {name!r} missing or of the wrong type")
        stored_key = arrays["key"].tobytes().decode("ascii", errors="replace")
        if key is not None and stored_key != key:
            raise ValueError("entry belongs to another key")
        n = arrays["orders"].size
        if n == 0 or arrays["input_amplitude"].size != n or arrays["output_amplitude"].size != n:
            raise ValueError("entry order arrays disagree in length")
        m = arrays["input_spectrum"].size
        if m == 0 or arrays["output_spectrum"].size != m or arrays["scalars"].size != 7:
            raise ValueError("entry spectra/scalars have the wrong size")
        sc = arrays["scalars"]
        if not (np.isfinite(sc).all() and sc[0] > 0):
            raise ValueError("entry scalars are not finite")
        return cls(
            key=stored_key,
            orders=arrays["orders"],
            input_amplitude=arrays["input_amplitude"],
            output_amplitude=arrays["output_amplitude"],
            df=float(sc[0]),
            input_spectrum=arrays["input_spectrum"],
            output_spectrum=arrays["output_spectrum"],
            mean_input_torque=float(sc[1]),
            mean_output_torque=float(sc[2]),
            wall_time=float(sc[3]),
            compute_time=float(sc[4]),
            sample_rate=float(sc[5]),
            window=float(sc[6]),
        )


def _order_index(stored, k) -> int:
    hits = np.flatnonzero(np.abs(np.asarray(stored) - float(k)) < 1e-12)
    if hits.size == 0:
        raise InputError(
            f"order {k!r} is not stored per test point; accepted are "
            f"{', '.join(f'{o:g}' for o in STORED_ORDERS)}"
        )
    return int(hits[0])


def _amplitudes_below_nyquist(x, fs, speed, orders):
    """Order amplitudes [N m]; NaN for orders at or above the Nyquist frequency."""

    orders = np.asarray(orders, dtype=float)
    out = np.full(orders.size, np.nan)
    ok = orders * speed / (2.0 * np.pi) < 0.5 * fs
    if ok.any():
        out[ok] = order_amplitudes(x, fs, speed, orders[ok])
    return out


def compute_record(system, point, duration=None, window=None, key="") -> PointRecord:
    """Simulate one test point and reduce it to a :class:`PointRecord` ([thesis] §3.4).

    system: DamperSystem; point: TestPoint (speed [rad/s], mean torque [N m], orders);
    duration: simulated time [s] (None: the solver's); window: analysis window [s] at the
    end of the record (None: 1.25 s). Integer orders 1-8 are read in one call of
    :func:`order_amplitudes` (exactly as ``SimulationResult.order_amplitudes``) and the
    half orders 0.5-7.5 in a second call.
    """

    t0 = time.perf_counter()
    window = ANALYSIS_WINDOW if window is None else float(window)
    res = simulate(system, point.excitation(), duration=duration, record_segments=False)
    w = res.window(window)
    fs = res.sample_rate
    x_in = res.input_torque[w]
    x_out = res.output_torque[w]
    whole = [k for k in STORED_ORDERS if float(k).is_integer()]
    half = [k for k in STORED_ORDERS if not float(k).is_integer()]
    amp_in = dict(zip(whole, _amplitudes_below_nyquist(x_in, fs, res.speed, whole)))
    amp_out = dict(zip(whole, _amplitudes_below_nyquist(x_out, fs, res.speed, whole)))
    amp_in.update(zip(half, _amplitudes_below_nyquist(x_in, fs, res.speed, half)))
    amp_out.update(zip(half, _amplitudes_below_nyquist(x_out, fs, res.speed, half)))
    freq, spec_in = amplitude_spectrum(x_in, fs)
    _, spec_out = amplitude_spectrum(x_out, fs)
    keep = freq <= SPECTRUM_MAX_HZ
    return PointRecord(
        key=key,
        orders=np.array(STORED_ORDERS, dtype=np.float64),
        input_amplitude=np.array([amp_in[k] for k in STORED_ORDERS]),
        output_amplitude=np.array([amp_out[k] for k in STORED_ORDERS]),
        df=float(freq[1] - freq[0]),
        input_spectrum=spec_in[keep].astype(np.float32),
        output_spectrum=spec_out[keep].astype(np.float32),
        mean_input_torque=float(np.mean(x_in)),
        mean_output_torque=float(np.mean(x_out)),
        wall_time=float(res.wall_time),
        compute_time=time.perf_counter() - t0,
        sample_rate=float(fs),
        window=float(x_in.size / fs),
    )


# --------------------------------------------------------------------------- store
def _disk_full(exc: BaseException) -> bool:
    """Whether ``exc`` says the disk (or the user's quota) is full."""
    if isinstance(exc, OSError):
        return exc.errno in (errno.ENOSPC, errno.EDQUOT)
    return isinstance(exc, sqlite3.OperationalError) and "full" in str(exc).lower()


class ResultCache:
    """Sweep result cache on disk (diskcache; safe to share between processes).

    directory: cache folder; None means :func:`results_dir` evaluated now. Use as a
    context manager or call :meth:`close`. ``corrupted`` counts entries found damaged
    (and therefore treated as missing) by :meth:`get`.
    """

    #: size limit of the cache [bytes]; least recently stored entries are culled beyond it
    SIZE_LIMIT = 4 * 2**30

    def __init__(self, directory=None):
        self._default = directory is None
        self.directory = Path(os.path.abspath(directory)) if directory is not None else results_dir()
        self._cache = None
        self.corrupted = 0
        #: why this cache stopped storing (a full disk), or None while it stores
        self.write_error = None
        #: points that could not be stored
        self.unstored = 0

    @property
    def diskcache(self):
        """The underlying :class:`diskcache.Cache` (opened on first use)."""
        if self._cache is None:
            import diskcache

            try:
                if self._default:
                    private_dir(RESULTS_SUBDIR)  # 0700; refused when others may write it
                else:
                    self.directory.mkdir(parents=True, exist_ok=True)
                # keep entries (tens of kB) inside SQLite: one row, one atomic transaction
                self._cache = diskcache.Cache(
                    str(self.directory), size_limit=self.SIZE_LIMIT, disk_min_file_size=2**22
                )
            except OSError as exc:
                raise InputError(
                    f"cache directory {str(self.directory)!r} cannot be used ({exc.strerror or exc}); "
                    f"set {CACHE_DIR_ENV} to a writable folder"
                ) from None
        return self._cache

    def get(self, key) -> PointRecord | None:
        """The intact record stored under ``key``, or None (missing, unreadable or corrupt)."""
        try:
            raw = self.diskcache.get(key, default=None, retry=True)
        except InputError:
            raise
        except Exception:  # unreadable row or value file: same as missing
            self.corrupted += 1
            return None
        if raw is None:
            return None
        try:
            return PointRecord.from_bytes(raw, key=key)
        except Exception:
            self.corrupted += 1
            return None

    @property
    def writable(self) -> bool:
        """False once a write failed for lack of space (see :meth:`put`)."""
        return self.write_error is None

    def put(self, key, record) -> bool:
        """Store ``record`` (a PointRecord or its bytes) under ``key`` in one transaction.

        Returns True when stored. A full disk (ENOSPC/EDQUOT, or SQLite's "database or disk
        is full") returns False, sets :attr:`write_error` and makes every later ``put`` a
        no-op returning False: the caller goes on without the cache. Other errors raise.
        """
        if self.write_error is not None:
            self.unstored += 1
            return False
        data = record if isinstance(record, (bytes, bytearray)) else record.to_bytes()
        cache = self.diskcache
        try:
            with cache.transact(retry=True):
                cache.set(key, bytes(data), retry=True)
        except (OSError, sqlite3.OperationalError) as exc:
            if not _disk_full(exc):
                raise
            self.write_error = (f"the result cache is out of disk space "
                                f"({getattr(exc, 'strerror', None) or exc}); points are computed but not stored")
            self.unstored += 1
            LOGGER.warning("sweep cache: %s", self.write_error)
            return False
        return True

    def __contains__(self, key) -> bool:
        return self.get(key) is not None

    def __len__(self) -> int:
        return len(self.diskcache)

    def keys(self) -> list:
        """All keys currently stored (intact or not)."""
        return list(self.diskcache.iterkeys())

    def delete(self, key) -> bool:
        return bool(self.diskcache.delete(key, retry=True))

    def clear(self) -> int:
        """Remove every entry; returns how many."""
        return self.diskcache.clear(retry=True)

    def close(self) -> None:
        if self._cache is not None:
            self._cache.close()
            self._cache = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


__all__ = [
    "CACHE_DIR_ENV",
    "STORED_ORDERS",
    "SPECTRUM_MAX_HZ",
    "PointRecord",
    "ResultCache",
    "cache_dir",
    "repo_root",
    "results_dir",
    "cache_key",
    "key_document",
    "key_parts",
    "kernel_source_hash",
    "current_source_hash",
    "compute_record",
    "resolved_duration",
]
