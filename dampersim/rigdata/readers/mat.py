"""Reader of MATLAB MAT-files, v5/v7 (scipy.io) and v7.3 (HDF5, h5py), in three layouts.

Accepted layouts (top-level variables; vectors are numeric 1xN or Nx1 arrays; a time
vector is named ``t``, ``time``, ``Time``, ``time_s`` or ``time`` plus a suffix, in
seconds; both layouts of structs may appear side by side in one file):

1. flat: one time vector and numeric vectors of the same length, one per channel,
   all sharing that time base (group id: the time vector's name). Units, optional: a
   struct ``units`` whose fields are channel names holding the unit text.
2. group structs: a struct holding a time vector and numeric vectors of the same length
   (one per channel); optionally a ``units`` struct field as in 1. Group id: the struct's
   name. Several group structs carry several sample rates.
3. channel structs (DEWESoft-style): a struct per channel with the fields ``data`` (the
   vector), ``unit`` or ``units`` (text, optional) and the time base as either a time
   vector field (``time``, ``t``, ...) of the same length or ``sample_rate`` /
   ``sample_rate_hz`` / ``fs`` [Hz] (time ``i / rate`` from 0 s, or from
   ``start_time`` [s] when given). Channel name and group id: the struct's name.

Scalars, text and variables or structs that match no layout are ignored; a vector that
belongs to a layout but has the wrong length, a top-level vector without a top-level
time vector, or several top-level time vectors are InputErrors, as is a file without
any channel.

Memory: v5/v7 files are loaded whole into memory when opened (scipy.io has no partial
read). v7.3 files stay open (h5py) and ``read_window`` reads only the window's samples
of the dataset; time vectors are streamed once in chunks of 2^20 samples when opened.
"""

from __future__ import annotations

import math

import numpy as np

from dampersim.errors import InputError
from dampersim.rigdata.readers import Recording, SampledTime, UniformTime, _one_line, is_time_name

ACCEPTED_LAYOUT = ("accepted MAT layouts: flat vectors with one time vector (t, time, time_s), structs holding "
                   "a time vector and channel vectors, or one struct per channel with data, unit and "
                   "time or sample_rate")
RATE_FIELDS = ("sample_rate", "sample_rate_hz", "fs")
UNIT_FIELDS = ("unit", "units")
CHUNK = 1 << 20
_NUMERIC_CLASSES = {"double", "single", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64"}


class _Vector:
    """A numeric vector of a MAT-file; ``read(lo, hi)`` returns float64 samples."""

    def __init__(self, length: int, read):
        self.length = int(length)
        self.read = read


def _is_vector_shape(shape) -> bool:
    return len(shape) == 1 or (len(shape) == 2 and min(shape) == 1)


# -- MAT v5/v7 (scipy.io) -------------------------------------------------------------

def _node5(value):
    """A loaded scipy.io value as _Vector, float (scalar), str, dict (struct) or None."""
    if isinstance(value, dict):
        return {k: _node5(v) for k, v in value.items()}
    if isinstance(value, str):
        return value
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "US":
            return "".join(str(s) for s in value.reshape(-1))
        if value.dtype.kind in "iuf" and _is_vector_shape(value.shape):
            flat = np.ascontiguousarray(value.reshape(-1))
            if flat.size == 1:
                return float(flat[0])
            return _Vector(flat.size, lambda lo, hi, a=flat: a[lo:hi])
    if isinstance(value, np.generic) and np.asarray(value).dtype.kind in "iuf":
        return float(value)
    return None


def _load5(path):
    import scipy.io

    try:
        raw = scipy.io.loadmat(path, squeeze_me=False, simplify_cells=True)
    except Exception as exc:  # noqa: BLE001 - any failure to parse is bad input
        raise InputError(f"{path}: not a readable MAT v5/v7 file ({_one_line(exc)}); truncated or damaged") from None
    return {k: _node5(v) for k, v in raw.items() if not k.startswith("__")}


# -- MAT v7.3 (HDF5) ------------------------------------------------------------------

def _matlab_class(obj) -> str:
    value = obj.attrs.get("MATLAB_class", b"")
    return value.decode("ascii", "replace") if isinstance(value, bytes) else str(value)


def _node73(obj):
    import h5py

    if isinstance(obj, h5py.Group):
        return {k: _node73(obj[k]) for k in obj.keys() if not k.startswith("#")}
    if not isinstance(obj, h5py.Dataset):
        return None
    cls = _matlab_class(obj)
    if obj.attrs.get("MATLAB_empty", 0):
        return "" if cls == "char" else None
    if cls == "char":
        return "".join(chr(int(c)) for c in np.asarray(obj[()]).reshape(-1))
    if cls not in _NUMERIC_CLASSES or not _is_vector_shape(obj.shape) or obj.size == 0:
        return None
    if obj.size == 1:
        return float(np.asarray(obj[()]).reshape(-1)[0])
    shape = obj.shape
    if len(shape) == 1:
        def read(lo, hi, ds=obj):
            return ds[lo:hi]
    elif shape[0] == 1:
        def read(lo, hi, ds=obj):
            return ds[0, lo:hi]
    else:
        def read(lo, hi, ds=obj):
            return ds[lo:hi, 0]
    return _Vector(obj.size, read)


# -- layouts ----------------------------------------------------------------------------

def _units(node) -> dict:
    return {k: v for k, v in node.items() if isinstance(v, str)} if isinstance(node, dict) else {}


def _time_key(node: dict, where: str):
    keys = [k for k, v in node.items() if is_time_name(k) and isinstance(v, _Vector)]
    if len(keys) > 1:
        raise InputError(f"{where}: several time vectors ({', '.join(keys)}); {ACCEPTED_LAYOUT}")
    return keys[0] if keys else None


class MatRecording(Recording):
    """A MAT-file, v5/v7 (``fmt`` "mat5") or v7.3 ("mat73"); module doc: layouts, memory."""

    accepted = ACCEPTED_LAYOUT

    def __init__(self, path, fmt: str):
        super().__init__(path)
        if fmt not in ("mat5", "mat73"):
            raise InputError(f"{self.path}: format {fmt!r}; accepted are mat5 and mat73")
        self.format = fmt
        self._h5 = None
        self._times: dict[int, object] = {}
        if fmt == "mat5":
            tree = _load5(self.path)
        else:
            import h5py

            try:
                self._h5 = h5py.File(self.path, "r")
                tree = _node73(self._h5)
            except Exception as exc:  # noqa: BLE001 - any failure to parse is bad input
                self._close()
                raise InputError(f"{self.path}: not a readable MAT v7.3 (HDF5) file ({_one_line(exc)}); "
                                 "truncated or damaged") from None
        self._parse(lambda: self._layouts(tree), "MAT", ACCEPTED_LAYOUT)

    def _sampled(self, vector: _Vector, where: str):
        key = id(vector)
        if key not in self._times:
            self._times[key] = SampledTime(vector.read, vector.length, where, chunk=CHUNK)
        return self._times[key]

    def _layouts(self, tree: dict):
        where = self.path
        # 1. flat
        flat_time = _time_key(tree, where)
        flat_units = _units(tree.get("units"))
        loose = [k for k, v in tree.items() if isinstance(v, _Vector) and k != flat_time]
        if loose and flat_time is None:
            raise InputError(f"{where}: vectors {', '.join(loose[:5])} without a time vector; {ACCEPTED_LAYOUT}")
        if flat_time is not None:
            tb = self._sampled(tree[flat_time], f"{where} time vector {flat_time!r}")
            for k in loose:
                self._check_length(tree[k], tb.samples, f"{where} variable {k!r}", flat_time)
                self._add(k, flat_units.get(k, ""), flat_time, tb, tree[k])
        # 2. group structs and 3. channel structs
        for name, node in tree.items():
            if not isinstance(node, dict) or name == "units":
                continue
            if isinstance(node.get("data"), _Vector):
                self._channel_struct(name, node)
                continue
            tkey = _time_key(node, f"{where} struct {name!r}")
            if tkey is None:
                continue
            tb = self._sampled(node[tkey], f"{where} struct {name!r} time vector {tkey!r}")
            units = _units(node.get("units"))
            for k, v in node.items():
                if k != tkey and isinstance(v, _Vector):
                    self._check_length(v, tb.samples, f"{where} struct {name!r} field {k!r}", tkey)
                    self._add(k, units.get(k, ""), name, tb, v)
        self._finish()

    def _channel_struct(self, name: str, node: dict):
        where = f"{self.path} struct {name!r}"
        data = node["data"]
        unit = next((node[k] for k in UNIT_FIELDS if isinstance(node.get(k), str)), "")
        tkey = _time_key(node, where)
        rkey = next((k for k in RATE_FIELDS if k in node), None)
        if tkey is not None:
            tb = self._sampled(node[tkey], f"{where} time vector {tkey!r}")
            self._check_length(data, tb.samples, f"{where} field 'data'", tkey)
        elif rkey is not None:
            rate = node[rkey]
            if not isinstance(rate, float) or not math.isfinite(rate) or rate <= 0:
                raise InputError(f"{where}: {rkey} = {rate!r}; accepted is a positive sample rate [Hz]")
            start = node.get("start_time", 0.0)
            if not isinstance(start, float):
                raise InputError(f"{where}: start_time = {start!r}; accepted is a number of seconds")
            tb = UniformTime(start, 1.0 / rate, data.length, rate_hz=rate, where=where)
        else:
            raise InputError(f"{where}: channel struct without a time base; accepted is a time vector field "
                             f"(time, t, time_s) or a sample rate field ({', '.join(RATE_FIELDS)}) [Hz]")
        self._add(name, unit, name, tb, data)

    @staticmethod
    def _check_length(vector: _Vector, samples: int, where: str, time_name: str):
        if vector.length != samples:
            raise InputError(f"{where}: {vector.length} samples, time vector {time_name!r} has {samples}; "
                             "accepted are channel vectors as long as their time vector")

    def _values(self, handle, lo, hi):
        if hi <= lo:
            return np.empty(0)
        return handle.read(lo, hi)

    def _close(self):
        if self._h5 is not None:
            self._h5.close()
            self._h5 = None
