"""diskcache stores without pickle: whoever could write a pickle into a cache folder could
run code as the program that reads it, so the stores of this package never unpickle.

:class:`JsonDisk` is a :class:`diskcache.Disk` whose keys are text (or numbers) and whose
values are stored as JSON behind a magic prefix (:func:`encode_json`): dicts, lists,
tuples, text, numbers (NaN and infinities kept), booleans, None, numpy scalars and numeric
numpy arrays (tagged base64 with their dtype and shape, so they come back as the same
arrays) and objects with ``to_plotly_json`` (plotly figures). A row in any other form, a
pickled one above all (written by an older version or planted), is refused with a
ValueError instead of being read; callers treat it as missing. Subclasses change the
encoding through :meth:`JsonDisk.encode` / :meth:`JsonDisk.decode` (the view store adds
Parquet for simulation results).

The folders of these stores are made by :func:`dampersim.locations.private_dir` (0700,
refused when others may write them).
"""

from __future__ import annotations

import base64
import json

import diskcache
import numpy as np

#: Prefix of a JSON value (the format's name and version).
JSON_MAGIC = b"DSV1J\n"
_ARRAY_TAG = "__ndarray__"
_TUPLE_TAG = "__tuple__"


def encode_obj(obj):
    """``obj`` as JSON-able data; numpy arrays tagged (base64, dtype, shape), tuples tagged.
    Raises TypeError for a value of another type."""
    if isinstance(obj, dict):
        return {str(k): encode_obj(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [encode_obj(v) for v in obj]
    if isinstance(obj, tuple):
        return {_TUPLE_TAG: [encode_obj(v) for v in obj]}
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind in "biufc":
            arr = np.ascontiguousarray(obj)
            return {_ARRAY_TAG: base64.b64encode(arr.tobytes()).decode("ascii"), "dtype": arr.dtype.str,
                    "shape": list(arr.shape)}
        return encode_obj(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    if obj is None or isinstance(obj, (str, int, float)):
        return obj
    to_plotly = getattr(obj, "to_plotly_json", None)  # plotly figures and graph objects
    if callable(to_plotly):
        return encode_obj(to_plotly())
    raise TypeError(f"a value of type {type(obj).__name__} cannot be stored as JSON: accepted are dicts, lists, "
                    "tuples, text, numbers, booleans, None and numeric numpy arrays")


def decode_obj(obj):
    """Inverse of :func:`encode_obj`; a tagged array of a non-numeric dtype is refused (ValueError)."""
    if isinstance(obj, dict):
        if _ARRAY_TAG in obj and set(obj) == {_ARRAY_TAG, "dtype", "shape"}:
            dtype = np.dtype(obj["dtype"])
            if dtype.kind not in "biufc":
                raise ValueError(f"stored array of dtype {dtype} refused: accepted are numeric arrays")
            raw = base64.b64decode(obj[_ARRAY_TAG])
            return np.frombuffer(raw, dtype=dtype).reshape(obj["shape"]).copy()
        if set(obj) == {_TUPLE_TAG}:
            return tuple(decode_obj(v) for v in obj[_TUPLE_TAG])
        return {k: decode_obj(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [decode_obj(v) for v in obj]
    return obj


def encode_json(value) -> bytes:
    """The bytes stored for ``value``: :data:`JSON_MAGIC` and its JSON (TypeError if it has none)."""
    text = json.dumps(encode_obj(value), separators=(",", ":"), allow_nan=True)
    return JSON_MAGIC + text.encode("ascii")


def decode_json(data: bytes):
    """Inverse of :func:`encode_json`; ValueError for anything else."""
    data = bytes(data)
    if not data.startswith(JSON_MAGIC):
        raise ValueError("stored entry is not a dampersim JSON value (unknown format)")
    return decode_obj(json.loads(data[len(JSON_MAGIC):].decode("ascii")))


class JsonDisk(diskcache.Disk):
    """diskcache serialisation without pickle: text/number keys only, values through
    :meth:`encode` (default :func:`encode_json`); a pickled row is refused instead of
    unpickled, any other unknown row too (ValueError)."""

    def encode(self, value) -> bytes:
        return encode_json(value)

    def decode(self, data: bytes):
        return decode_json(data)

    def put(self, key):
        if type(key) not in (str, bytes, int, float):
            raise TypeError(f"cache key of type {type(key).__name__}: accepted are text keys")
        return super().put(key)

    def get(self, key, raw):
        if not raw:
            raise ValueError("pickled cache key refused")
        return super().get(key, raw)

    def store(self, value, read, key=diskcache.core.UNKNOWN):
        if read:
            raise TypeError("file values are not stored in this cache: accepted are JSON values")
        return super().store(self.encode(value), False, key=key)

    def fetch(self, mode, filename, value, read):
        if mode == diskcache.core.MODE_PICKLE:
            raise ValueError("pickled cache entry refused")
        if read:
            raise TypeError("file values are not read from this cache")
        data = super().fetch(mode, filename, value, False)
        if isinstance(data, str):
            data = data.encode("utf-8")
        if not isinstance(data, (bytes, bytearray)):
            raise ValueError("stored entry is not a dampersim value")
        return self.decode(data)


__all__ = ["JSON_MAGIC", "encode_obj", "decode_obj", "encode_json", "decode_json", "JsonDisk"]
