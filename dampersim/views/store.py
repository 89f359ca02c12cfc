"""The view cache: computed views stored in diskcache under their keys, looked up by one
decorator (:func:`cached_view`), and the store of parameter sets uploaded to this server.

Views live under ``cache_dir()/"views"`` keyed by :func:`view_key`, the canonical key of
:mod:`dampersim.keys` over the view name, the complete parameter set, the page state, the
package version, the platform and the source of the code behind the view, so a physics
change can never return a stale view.
Every key of this package (page views, single hysteresis loops, the Segments page's
simulation, diagnoses) is made by :func:`view_key`. Sweep test points are cached per
point by :mod:`dampersim.sweeps` as usual, so a cancelled sweep keeps its finished points.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import os
import re

import diskcache
import numpy as np

from dampersim import keys
from dampersim.errors import InputError
from dampersim.parameters import dumps_toml, to_dict
from dampersim.locations import cache_dir

#: Sub-directories of :func:`dampersim.locations.cache_dir` used here.
VIEWS_SUBDIR = "views"
SETS_SUBDIR = "parameter-sets"
#: Size limit of the view cache [bytes].
VIEWS_SIZE_LIMIT = 2 * 2**30
#: Bumped when the content of a cached view changes shape.
VIEW_FORMAT = 1
#: Labels of a parameter set, not physics: never part of a key, never carried as overrides.
LABEL_NAMES = ("name", "source")

_STORES: dict = {}


def _open(sub: str, size_limit=VIEWS_SIZE_LIMIT):
    path = str(cache_dir() / sub)
    key = (os.getpid(), path)  # never reuse a SQLite connection across a fork
    store = _STORES.get(key)
    if store is None:
        try:
            os.makedirs(path, exist_ok=True)
            store = diskcache.Cache(path, size_limit=size_limit)
        except OSError as exc:
            raise InputError(f"cache directory {path!r} cannot be used ({exc.strerror or exc}); set DAMPERSIM_CACHE_DIR to a writable folder") from None
        _STORES[key] = store
    return store


def view_store():
    """The diskcache of views (``cache_dir()/"views"``)."""
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
    """The value stored under ``key`` in the view store, or None (missing or unreadable)."""
    try:
        return view_store().get(key, default=None, retry=True)
    except Exception:
        return None


def save_entry(key: str, value) -> None:
    """Store ``value`` under ``key``; a value that cannot be stored is not an error."""
    try:
        view_store().set(key, value, retry=True)
    except Exception:
        pass


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
def _sets_store():
    return _open(SETS_SUBDIR, size_limit=2**28)


def valid_set_id(set_id) -> bool:
    """Whether ``set_id`` has the form of a stored set's id (16 hex digits)."""
    return isinstance(set_id, str) and re.fullmatch(r"[0-9a-f]{16}", set_id) is not None


def store_parameter_set(system) -> str:
    """Store a parameter set on this server; returns its id (16 hex digits)."""
    text = dumps_toml(system)
    set_id = hashlib.sha256(text.encode()).hexdigest()[:16]
    _sets_store().set(set_id, text, retry=True)
    return set_id


def load_parameter_set(set_id: str):
    """TOML text of a stored parameter set, or None."""
    if not valid_set_id(set_id):
        return None
    try:
        return _sets_store().get(set_id, default=None, retry=True)
    except Exception:
        return None


__all__ = [
    "VIEWS_SUBDIR",
    "SETS_SUBDIR",
    "VIEW_FORMAT",
    "LABEL_NAMES",
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
