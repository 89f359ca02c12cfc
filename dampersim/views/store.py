"""The view cache: computed views stored in diskcache under their keys, looked up by one
decorator (:func:`cached_view`), and the store of parameter sets uploaded to this server.

Views live under ``cache_dir()/"views"`` keyed by :func:`view_key`, the canonical key of
:mod:`dampersim.keys` over the view name, the complete parameter set, the page state, the
package version, the platform and the source of the code behind the view, so a physics
change can never return a stale view.
Every key of this package (page views, single hysteresis loops, the Segments page's
simulation, diagnoses) is made by :func:`view_key`. Sweep test points are cached per
point by :mod:`dampersim.sweeps` as usual, so a cancelled sweep keeps its finished points.

No pickle: whoever could write a pickle into a cache could run code as the server, so both
stores (views, parameter sets) use :class:`SafeDisk`. Keys are text; values are stored as
JSON (numpy arrays inside as tagged base64 with their dtype and shape, so they come back as
the same arrays; NaN kept) or, for a :class:`~dampersim.results.SimulationResult`, as the
Parquet file of :meth:`~dampersim.results.SimulationResult.save`. A pickled row (written by
an older version or planted) is refused and reads as missing. The folders are made by
:func:`dampersim.locations.private_dir` (0700, refused when others may write them).

A damaged database file (``cache.db`` that SQLite cannot read) is moved aside with the
folder (``views.corrupt-<time>``), a fresh store is opened and a warning logged; the page
just computes its view again.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import logging
import os
import re
import sqlite3
import tempfile
import threading
import time

import diskcache
import numpy as np

from dampersim import keys
from dampersim.errors import InputError
from dampersim.parameters import dumps_toml, to_dict
from dampersim.locations import cache_dir, private_dir
from dampersim.safestore import JSON_MAGIC, JsonDisk, decode_json, encode_json

LOGGER = logging.getLogger("dampersim.views.store")

#: Sub-directories of :func:`dampersim.locations.cache_dir` used here.
VIEWS_SUBDIR = "views"
SETS_SUBDIR = "parameter-sets"
#: Size limit of the view cache [bytes].
VIEWS_SIZE_LIMIT = 2 * 2**30
#: Bumped when the content of a cached view changes shape (2: JSON instead of pickle).
VIEW_FORMAT = 2
#: Labels of a parameter set, not physics: never part of a key, never carried as overrides.
LABEL_NAMES = ("name", "source")

_STORES: dict = {}
_LOCK = threading.Lock()
#: Messages of the stores recovered in this process (newest last), for a page to show.
RECOVERIES: list = []

# --------------------------------------------------------------------------- encoding
_RESULT_MAGIC = b"DSV1R\n"


def encode_value(value) -> bytes:
    """The bytes a store keeps for ``value`` (JSON, see :mod:`dampersim.safestore`, or
    Parquet for a SimulationResult). Raises TypeError for a value that is neither."""
    from dampersim.results import SimulationResult

    if isinstance(value, SimulationResult):
        fd, tmp = tempfile.mkstemp(prefix=".result-", suffix=".parquet", dir=private_dir(VIEWS_SUBDIR))
        os.close(fd)
        try:
            value.save(tmp)
            with open(tmp, "rb") as fh:
                return _RESULT_MAGIC + fh.read()
        finally:
            _unlink(tmp)
    return encode_json(value)


def decode_value(data: bytes):
    """Inverse of :func:`encode_value`; raises ValueError for anything else."""
    data = bytes(data)
    if data.startswith(JSON_MAGIC):
        return decode_json(data)
    if data.startswith(_RESULT_MAGIC):
        from dampersim.results import SimulationResult

        fd, tmp = tempfile.mkstemp(prefix=".result-", suffix=".parquet", dir=private_dir(VIEWS_SUBDIR))
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(data[len(_RESULT_MAGIC):])
            return SimulationResult.load(tmp)
        finally:
            _unlink(tmp)
    raise ValueError("stored entry is not a dampersim view (unknown format)")


def _unlink(path):
    try:
        os.unlink(path)
    except OSError:
        pass


class SafeDisk(JsonDisk):
    """diskcache serialisation without pickle (:class:`dampersim.safestore.JsonDisk`),
    values through :func:`encode_value`: JSON, or Parquet for a SimulationResult."""

    def encode(self, value) -> bytes:
        return encode_value(value)

    def decode(self, data: bytes):
        return decode_value(data)


def _is_corruption(exc: BaseException) -> bool:
    """A SQLite error that means the database file is damaged (not locked, not full)."""
    return isinstance(exc, sqlite3.DatabaseError) and not isinstance(exc, sqlite3.OperationalError)


def _move_aside(path: str, exc: BaseException) -> None:
    stamp = time.strftime("%Y%m%d-%H%M%S")
    target = f"{path}.corrupt-{stamp}-{os.getpid()}"
    try:
        os.replace(path, target)
    except OSError:
        target = None
    message = (f"the cache folder {os.path.basename(path)!r} held a damaged database ({exc}); "
               + (f"moved aside as {os.path.basename(target)!r}" if target else "it could not be moved aside")
               + " and a fresh store opened: its views are computed again")
    LOGGER.warning(message)
    RECOVERIES.append(message)


def _open(sub: str, size_limit=VIEWS_SIZE_LIMIT):
    with _LOCK:
        path = str(cache_dir() / sub)
        key = (os.getpid(), path)  # never reuse a SQLite connection across a fork
        store = _STORES.get(key)
        if store is not None:
            return store
        private_dir(sub)  # 0700, refused when another user owns it or others may write
        try:
            try:
                store = diskcache.Cache(path, size_limit=size_limit, disk=SafeDisk)
            except sqlite3.DatabaseError as exc:
                if not _is_corruption(exc):
                    raise
                _move_aside(path, exc)
                private_dir(sub)
                store = diskcache.Cache(path, size_limit=size_limit, disk=SafeDisk)
        except (OSError, sqlite3.Error) as exc:
            raise InputError(f"cache folder {sub!r} cannot be used ({getattr(exc, 'strerror', None) or exc}); "
                             "set DAMPERSIM_CACHE_DIR to a writable folder") from None
        _STORES[key] = store
        return store


def _recover(sub: str, exc: BaseException) -> None:
    """Close the damaged store ``sub`` of this process and move its folder aside."""
    with _LOCK:
        path = str(cache_dir() / sub)
        store = _STORES.pop((os.getpid(), path), None)
        if store is not None:
            try:
                store.close()
            except Exception:
                pass
        _move_aside(path, exc)


def _guarded(sub: str, size_limit, action):
    """Run ``action(store)``; when the database turns out damaged, recover and retry once."""
    try:
        return action(_open(sub, size_limit))
    except sqlite3.DatabaseError as exc:
        if not _is_corruption(exc):
            raise
        _recover(sub, exc)
        return action(_open(sub, size_limit))


def view_store():
    """The diskcache of views (``cache_dir()/"views"``, JSON values, see :class:`SafeDisk`)."""
    return _open(VIEWS_SUBDIR)


def close_stores() -> None:
    """Close the stores this process opened (tests switch cache directories)."""
    for key in list(_STORES):
        if key[0] == os.getpid():
            try:
                _STORES.pop(key).close()
            except Exception:
                pass


# --------------------------------------------------------------------------- keys
def view_key(kind: str, system, state: dict, *, module: str) -> str:
    """SHA-256 key of a view (:func:`dampersim.keys.make_key`): kind, complete parameter set
    (labels excluded), page state (without the parameter state, which ``system`` already
    holds), package version, platform and the source of ``module`` (the view module that
    computes it: pass ``__name__``) with every module it reaches through imports
    (figures, analysis, simulation, diagnosis). Editing one page's view module therefore
    leaves the other pages' cached views, and a cached diagnosis, valid."""
    parts = {
        "format": VIEW_FORMAT,
        "kind": kind,
        "parameters": {k: v for k, v in to_dict(system).items() if k not in LABEL_NAMES},
        # numbers as floats: a state that went through JSON (a browser store) may bring 30 for 30.0
        "state": {k: (float(v) if isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) else v)
                  for k, v in state.items() if k != "params"},
    }
    return keys.make_key("dampersim.view", module, parts)


# --------------------------------------------------------------------------- entries
def load_entry(key: str):
    """The value stored under ``key`` in the view store, or None (missing, unreadable,
    not ours, or the store damaged: then it is recovered, see the module docstring)."""
    try:
        return _guarded(VIEWS_SUBDIR, VIEWS_SIZE_LIMIT, lambda store: store.get(key, default=None, retry=True))
    except Exception:
        return None


def save_entry(key: str, value) -> None:
    """Store ``value`` under ``key``; a value that cannot be stored (not JSON, disk full,
    folder refused) is not an error: the view is shown uncached."""
    try:
        _guarded(VIEWS_SUBDIR, VIEWS_SIZE_LIMIT, lambda store: store.set(key, value, retry=True))
    except Exception as exc:
        LOGGER.debug("view %s not cached: %s", key[:12], exc)


def load_view(key: str):
    """A cached view by key, or None."""
    view = load_entry(key)
    if not isinstance(view, dict):
        return None
    return {**view, "from_cache": True}


def save_view(key: str, view: dict) -> dict:
    """Store a computed view under ``key``; returns it with ``key`` and ``from_cache`` False
    (a view that cannot be cached is still shown)."""
    view = {**view, "key": key, "from_cache": False}
    save_entry(key, view)
    return view


def cached_view(key_of):
    """Decorator of a view function: look the view up in the cache first.

    ``key_of`` receives the view function's arguments by name (defaults filled in) and
    returns the view's key (made with :func:`view_key`). A cached view under that key is
    returned at once (marked ``from_cache``); otherwise the function computes the view,
    which is stored and returned with ``key`` and ``from_cache`` False. A function that
    returns None (nothing to show without computing, e.g. ``cache_only``) stores nothing.
    When the function has a ``use_cache`` argument and it is False, the lookup is skipped
    (the result is still stored).
    """
    def decorate(compute):
        signature = inspect.signature(compute)

        @functools.wraps(compute)
        def view(*args, **kwargs):
            bound = signature.bind(*args, **kwargs)
            bound.apply_defaults()
            key = key_of(**bound.arguments)
            if bound.arguments.get("use_cache", True):
                hit = load_view(key)
                if hit is not None:
                    return hit
            computed = compute(*args, **kwargs)
            return None if computed is None else save_view(key, computed)

        return view

    return decorate


# --------------------------------------------------------------------------- parameter sets
#: Size limit of the parameter-set store [bytes].
SETS_SIZE_LIMIT = 2**28


def valid_set_id(set_id) -> bool:
    """Whether ``set_id`` has the form of a stored set's id (16 hex digits)."""
    return isinstance(set_id, str) and re.fullmatch(r"[0-9a-f]{16}", set_id) is not None


def store_parameter_set(system) -> str:
    """Store a parameter set on this server; returns its id (16 hex digits)."""
    text = dumps_toml(system)
    set_id = hashlib.sha256(text.encode()).hexdigest()[:16]
    _guarded(SETS_SUBDIR, SETS_SIZE_LIMIT, lambda store: store.set(set_id, text, retry=True))
    return set_id


def load_parameter_set(set_id: str):
    """TOML text of a stored parameter set, or None."""
    if not valid_set_id(set_id):
        return None
    try:
        text = _guarded(SETS_SUBDIR, SETS_SIZE_LIMIT, lambda store: store.get(set_id, default=None, retry=True))
    except Exception:
        return None
    return text if isinstance(text, str) else None


__all__ = [
    "VIEWS_SUBDIR",
    "SETS_SUBDIR",
    "VIEW_FORMAT",
    "LABEL_NAMES",
    "RECOVERIES",
    "SafeDisk",
    "encode_value",
    "decode_value",
    "view_store",
    "close_stores",
    "view_key",
    "load_entry",
    "save_entry",
    "load_view",
    "save_view",
    "cached_view",
    "valid_set_id",
    "store_parameter_set",
    "load_parameter_set",
]
