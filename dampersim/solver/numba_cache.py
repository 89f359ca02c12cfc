"""Key numba's on-disk cache of a kernel package by the source the package is compiled from.

numba's ``cache=True`` checks only the source file of the function it loads. A change in
a jitted helper imported from another module, or in a module-level constant imported from
a layout module (numba freezes global constants into the machine code), leaves the cached
machine code in use: stale results with no error. Nor does it tell numba's code generation
settings apart: code compiled at one optimisation level is loaded at another.
:func:`guard` registers a package directory with a key, the SHA-256 of every ``.py`` file
of the package plus the given extra files (the layout modules whose constants the kernels
freeze in). Every function defined in a file of that directory is then cached in a
sub-folder named after the key and the settings, ``src-<key>-<settings>``, inside the
folder numba would have picked itself (``NUMBA_CACHE_DIR`` when set, else ``__pycache__``
beside the source, else numba's user-wide cache). A changed source therefore compiles
afresh, and two source versions never share cache entries; nor do two settings of
NUMBA_OPT, NUMBA_LOOP_VECTORIZE or NUMBA_SLP_VECTORIZE (:func:`settings_tag`). Folders of
earlier sources or settings are left in place, not cleaned up.

The locator is found by numba when a function is decorated, so :func:`guard` must run
before the package's modules are imported: call it in the package's ``__init__``. A
locator list forced through ``NUMBA_CACHE_LOCATOR_CLASSES`` bypasses the guard.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

from numba.core import caching

from dampersim.keys import numba_codegen

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


def settings_tag() -> str:
    """The code generation settings of :func:`dampersim.keys.numba_codegen` that compiled code
    depends on, as a folder name suffix: ``O3-loop`` is numba's default (optimisation level
    3, loop vectoriser on, SLP vectoriser off), ``O1-loop`` NUMBA_OPT=1 alone, ``Omax-loop``
    NUMBA_OPT=max, ``O3-loop-slp`` the SLP vectoriser added to the default."""
    s = numba_codegen()
    if "error" in s:
        return "unknown"
    return f"O{s['opt']}" + ("-loop" if s["loop_vectorize"] else "") + ("-slp" if s["slp_vectorize"] else "")


class KeyedCacheLocator(caching._CacheLocator):
    """Cache locator for functions of a guarded package: the folder numba's own locators
    would choose, plus a ``src-<key>-<settings>`` sub-folder (:func:`settings_tag`); the
    index is stamped with the key."""

    def __init__(self, inner, key: str, py_file: str):
        self._inner = inner
        self._key = key
        self._py_file = py_file  # numba names it in its warning of a function it cannot cache
        self._cache_path = os.path.join(inner.get_cache_path(), f"src-{key[:20]}-{settings_tag()}")

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
            self = cls(inner, key, py_file)
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


__all__ = ["guard", "source_key", "settings_tag", "KeyedCacheLocator"]
