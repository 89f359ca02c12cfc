"""Key numba's on-disk cache of a kernel package by the source the package is compiled from.

numba's ``cache=True`` checks only the source file of the function it loads. A change in
a jitted helper imported from another module, or in a module-level constant imported from
a layout module (numba freezes global constants into the machine code), leaves the cached
machine code in use: stale results with no error. :func:`guard` registers a package
directory with a key, the SHA-256 of every ``.py`` file of the package plus the given
extra files (the layout modules whose constants the kernels freeze in). Every function
defined in a file of that directory is then cached in a sub-folder named after the key,
``src-<key>``, inside the folder numba would have picked itself (``NUMBA_CACHE_DIR`` when
set, else ``__pycache__`` beside the source, else numba's user-wide cache). A changed
source therefore compiles afresh, and two source versions never share cache entries.

The locator is found by numba when a function is decorated, so :func:`guard` must run
before the package's modules are imported: call it in the package's ``__init__``. A
locator list forced through ``NUMBA_CACHE_LOCATOR_CLASSES`` bypasses the guard.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

from numba.core import caching

#: real path of a guarded package directory -> its source key
_KEYS: dict[str, str] = {}


def source_key(package_dir, extra_files=()) -> str:
    """SHA-256 (hex) of the ``.py`` files directly in ``package_dir`` and of ``extra_files``."""
    files = sorted(Path(package_dir).glob("*.py")) + [Path(f) for f in extra_files]
    h = hashlib.sha256()
    for f in files:
        h.update(f.name.encode())
        h.update(b"\0")
        h.update(f.read_bytes())
        h.update(b"\0")
    return h.hexdigest()


class KeyedCacheLocator(caching._CacheLocator):
    """Cache locator for functions of a guarded package: the folder numba's own locators
    would choose, plus a ``src-<key>`` sub-folder; the index is stamped with the key."""

    def __init__(self, inner, key: str):
        self._inner = inner
        self._key = key
        self._cache_path = os.path.join(inner.get_cache_path(), "src-" + key[:20])

    def get_cache_path(self):
        return self._cache_path

    def get_source_stamp(self):
        return self._key

    def get_disambiguator(self):
        return self._inner.get_disambiguator()

    @classmethod
    def from_function(cls, py_func, py_file):
        key = _KEYS.get(os.path.dirname(os.path.realpath(py_file)))
        if key is None:
            return None  # not a guarded package: numba's own locators decide
        for base in caching.CacheImpl._locator_classes:
            if base is cls:
                continue
            inner = base.from_function(py_func, py_file)
            if inner is None:
                continue
            self = cls(inner, key)
            try:
                self.ensure_cache_path()
            except OSError:
                continue
            return self
        return None


def guard(package_dir, extra_files=()) -> str:
    """Key the numba cache of every function defined in ``package_dir`` by
    :func:`source_key` (``package_dir``, ``extra_files``); returns the key."""
    key = source_key(package_dir, extra_files)
    _KEYS[os.path.realpath(package_dir)] = key
    if KeyedCacheLocator not in caching.CacheImpl._locator_classes:
        caching.CacheImpl._locator_classes.insert(0, KeyedCacheLocator)
    return key


__all__ = ["guard", "source_key", "KeyedCacheLocator"]
