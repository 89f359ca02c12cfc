"""Cache keys: one canonical, content-addressed key for every cached result in dampersim.

A key is the SHA-256 of a canonical JSON document (:func:`canonical`) that holds

* what was asked for (parameter set, excitation, page state, options: the caller's parts);
* the package version;
* the platform: Python, numpy, scipy, numba and llvmlite versions, the CPU that numba
  compiles for and numba's code generation settings. Fast-math rounding differs between CPU
  targets, optimisation levels and compiler versions, and in a chaotic regime a last-bit
  difference moves an order amplitude by several per cent, so a result computed elsewhere
  is not served as if it were this machine's;
* a hash of the source of every dampersim module the result's code can reach
  (:func:`source_hash`). The set of modules is found by reading the import statements of
  the package's own files (imports inside functions included), starting from the module
  that computes the result, so no file list is kept by hand: a new module that shapes a
  result is covered the moment something imports it.

Floats enter the document as ``float.hex`` strings: two values that differ in the last
bit give different keys. Arrays enter as dtype, shape and the SHA-256 of their bytes.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib.metadata
import json
import os
import platform as _platform
import re
from pathlib import Path

import numpy as np

from dampersim.errors import DampersimError, InputError
from dampersim.version import __version__

#: The package folder (``dampersim/``) whose sources are hashed.
PACKAGE_DIR = Path(__file__).resolve().parent
PACKAGE = "dampersim"


# --------------------------------------------------------------------------- canonical form
def canonical(obj):
    """A JSON-ready structure of ``obj`` in which every float is exact (``float.hex``).

    Accepts None, bool, str, int, float (and numpy scalars), numpy arrays, dicts, lists,
    tuples and dataclass instances (as their type name and fields). Anything else raises
    InputError naming the type: a key must never depend on ``repr`` or object identity.
    """
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return {"f": float(obj).hex()}
    if isinstance(obj, np.ndarray):
        arr = np.ascontiguousarray(obj)
        return {"array": str(arr.dtype), "shape": list(arr.shape), "sha256": hashlib.sha256(arr.tobytes()).hexdigest()}
    if isinstance(obj, dict):
        return {str(k): canonical(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [canonical(v) for v in obj]
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {
            "type": f"{type(obj).__module__}.{type(obj).__qualname__}",
            "fields": {f.name: canonical(getattr(obj, f.name)) for f in dataclasses.fields(obj)},
        }
    raise InputError(f"cannot build a cache key from a {type(obj).__name__} value ({obj!r:.60})")


def digest(document) -> str:
    """SHA-256 hex digest of the canonical JSON of ``document``."""
    text = json.dumps(canonical(document), sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)
    return hashlib.sha256(text.encode("ascii")).hexdigest()


# --------------------------------------------------------------------------- sources
def _module_file(name: str, root: Path) -> Path | None:
    """File of dotted module ``name`` (``dampersim.x.y``) under ``root``, or None."""
    rel = name.split(".")[1:]
    base = root.joinpath(*rel) if rel else root
    if (base / "__init__.py").is_file():
        return base / "__init__.py"
    py = base.with_suffix(".py") if rel else None
    return py if py is not None and py.is_file() else None


_IMPORT = re.compile(r"^[ \t]*import[ \t]+([\w., \t]+)", re.M)
_FROM = re.compile(r"^[ \t]*from[ \t]+(\.*[\w.]*)[ \t]+import[ \t]+(\([^)]*\)|[^\n]*)", re.M)


def _imports(name: str, path: Path) -> set:
    """Dotted dampersim module names imported anywhere in the file of module ``name``.

    Import statements are found line by line (a regular expression, ten times faster
    than parsing the file); an import-like line inside a docstring can add a module that
    is not really imported, which only makes a key depend on more source than it must.
    """
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise DampersimError(
            f"cannot read {path} ({exc}); results are keyed by the package's source, so install "
            "dampersim with its .py files"
        ) from None
    is_pkg = path.name == "__init__.py"
    here = name.split(".") if is_pkg else name.split(".")[:-1]
    found = set()
    for match in _IMPORT.finditer(text):
        for item in match.group(1).split(","):
            mod = item.split()[0] if item.split() else ""
            if mod.split(".")[0] == PACKAGE:
                found.add(mod)
    for match in _FROM.finditer(text):
        source, names = match.group(1), match.group(2)
        level = len(source) - len(source.lstrip("."))
        if level:
            base = here[: len(here) - level + 1]
            rest = source[level:]
            mod = ".".join(base + ([rest] if rest else []))
        else:
            mod = source
        if mod.split(".")[0] != PACKAGE:
            continue
        found.add(mod)
        for line in names.strip("()").splitlines():
            for item in line.split("#")[0].split(","):
                words = item.split()
                if words and words[0].isidentifier():
                    found.add(f"{mod}.{words[0]}")  # `from package import module`
    return found


def module_closure(module: str, root: Path = PACKAGE_DIR) -> tuple:
    """Sorted names of the dampersim modules whose source can shape what ``module`` computes.

    That is ``module`` and every module it reaches through import statements (imports
    inside functions included), followed transitively, plus the parent packages of each
    (Python runs a package's ``__init__`` before any of its modules). A parent package's
    own source is included, but its imports are followed only where a reached module
    imports the package itself: a package that merely collects its modules does not pull
    all of them into every key. ``root`` is the package folder to read (tests point it at
    a copy).
    """
    seen: set = set()
    todo = [module]
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        path = _module_file(name, root)
        if path is None:  # a name imported from a module, not a module: nothing to read
            continue
        seen.add(name)
        todo.extend(_imports(name, path) - seen)
    parents = {".".join(n.split(".")[:i]) for n in seen for i in range(1, len(n.split(".")))}
    return tuple(sorted(seen | {p for p in parents if _module_file(p, root) is not None}))


def _hash_sources(module: str, root: Path) -> str:
    h = hashlib.sha256()
    for name in module_closure(module, root):
        path = _module_file(name, root)
        h.update(name.encode())
        h.update(b"\0")
        h.update(path.read_bytes())
        h.update(b"\0")
    return h.hexdigest()


@functools.lru_cache(maxsize=None)
def source_hash(module: str) -> str:
    """SHA-256 of the source of ``module`` and of every dampersim module it reaches through
    imports (:func:`module_closure`), read once per process: the hash describes the code this
    process loaded, even when the files are edited while it runs."""
    return _hash_sources(module, PACKAGE_DIR)


def source_hash_at(module: str, root) -> str:
    """:func:`source_hash` of the package copy in folder ``root`` (not memoised)."""
    return _hash_sources(module, Path(root))


# --------------------------------------------------------------------------- platform
def _version(dist: str) -> str:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return "absent"


@functools.lru_cache(maxsize=1)
def platform() -> dict:
    """What besides our source can change a computed number: the Python, numpy, scipy
    (filters), numba and llvmlite versions, numba's code generation settings
    (:func:`numba_codegen`), the CPU features numpy dispatches on, the
    OpenBLAS kernels (:func:`blas_kernels`) and the CPU numba compiles for (name and
    feature string: the host's unless NUMBA_CPU_NAME or NUMBA_CPU_FEATURES choose another
    target, as numba's own code generator reads them; a kernel built for a generic x86-64
    moves a chaotic campaign's orders by up to 1.4 repeatabilities, docs/discrepancy.md,
    Known limits)."""
    try:
        from llvmlite import binding as llvm
        from numba.core import codegen, config as numba_config

        # as numba.core.codegen.JITCPUCodegen chooses its target (its _get_host_cpu_name and
        # _get_host_cpu_features): the configured name and features if set, else the host's,
        # whose features lose AVX where numba's config disables it (NUMBA_ENABLE_AVX)
        name = llvm.get_host_cpu_name() if numba_config.CPU_NAME is None else numba_config.CPU_NAME
        features = numba_config.CPU_FEATURES
        cpu = {"name": name, "features": codegen.get_host_cpu_features() if features is None else features}
    except Exception as exc:  # llvmlite missing or unable to tell: say so in the key
        cpu = {"name": "unknown", "error": type(exc).__name__}
    try:  # numpy's runtime dispatch (NPY_DISABLE_CPU_FEATURES switches groups such as X86_V3 off)
        from numpy._core._multiarray_umath import __cpu_features__ as feats
        numpy_cpu = sorted(k for k, on in feats.items() if on)
    except ImportError:  # numpy's internal layout moved: say so in the key
        numpy_cpu = ["unknown"]
    return {
        "python": _platform.python_version(),
        "numba_codegen": numba_codegen(),
        "machine": _platform.machine(),
        "numpy": np.__version__,
        "scipy": _version("scipy"),
        "numba": _version("numba"),
        "llvmlite": _version("llvmlite"),
        "cpu": cpu,
        "numpy_cpu": numpy_cpu,
        "blas": blas_kernels(),
    }


#: The environment variables of numba's code generation settings (:func:`numba_codegen`).
NUMBA_CODEGEN_ENV = ("NUMBA_OPT", "NUMBA_LOOP_VECTORIZE", "NUMBA_SLP_VECTORIZE", "NUMBA_DISABLE_JIT")


def numba_codegen() -> dict:
    """numba's settings that change the machine code of a kernel on a given CPU
    (:data:`NUMBA_CODEGEN_ENV`): the optimisation level (NUMBA_OPT: 0 to 3, or ``"max"``, level
    3 with an extra pass), the loop and SLP vectorisers (NUMBA_LOOP_VECTORIZE,
    NUMBA_SLP_VECTORIZE) and whether the kernels run as Python instead (NUMBA_DISABLE_JIT).
    With the kernels' reassociating fast-math (:data:`dampersim.solver.kernels.JIT`) each can
    change the order of the sums, so the last bits of every step, and a chaotic run's orders
    with them. Read from numba's config as it stands; numba reads the environment again at
    each compilation, but a key (:func:`platform`, read once per process) and the kernels'
    on-disk cache folder (:mod:`dampersim.solver.numba_cache`, fixed when a kernel is
    decorated) follow the settings the process started with, so set them before it starts."""
    try:
        from numba.core import config as numba_config

        opt = numba_config.OPT
        return {"opt": "max" if getattr(opt, "is_opt_max", False) else int(opt),
                "disable_jit": bool(numba_config.DISABLE_JIT),
                "loop_vectorize": bool(numba_config.LOOP_VECTORIZE),
                "slp_vectorize": bool(numba_config.SLP_VECTORIZE)}
    except Exception as exc:  # numba missing or its config moved: say so in the key
        return {"error": type(exc).__name__}


def blas_kernels() -> dict:
    """The kernel each OpenBLAS that numpy and scipy bundle runs in this process
    (OPENBLAS_CORETYPE or another CPU picks another), by library file name: {} where none can
    be asked (not Linux, another BLAS, or a build that links a system OpenBLAS), and
    ``{"error": ...}`` if asking failed, so that a key can always be made. The diagnosis's
    linear algebra runs on these kernels, and its path, in a chaotic campaign, moves with
    their rounding (docs/discrepancy.md, Known limits)."""
    try:
        import ctypes

        import scipy
        import scipy.linalg  # noqa: F401 - loads scipy's own OpenBLAS

        # only the wheels' own library folders: another package's OpenBLAS in this process
        # must not change the key (a worker that did not import it would disagree)
        own = tuple(str(Path(m.__file__).resolve().parent.parent / f"{m.__name__}.libs") + os.sep
                    for m in (np, scipy))
        paths = set()
        with open("/proc/self/maps", "rb") as fh:
            for ln in fh:
                fields = ln.rstrip(b"\n").split(maxsplit=5)  # the path may hold spaces
                path = os.fsdecode(fields[5]).removesuffix(" (deleted)") if len(fields) == 6 else ""
                if path.startswith(own) and "openblas" in Path(path).name.lower():
                    paths.add(path)
        out = {}
        for path in sorted(paths):
            lib = ctypes.CDLL(path)
            for name in ("scipy_openblas_get_corename64_", "scipy_openblas_get_corename", "openblas_get_corename64_",
                         "openblas_get_corename"):
                fn = getattr(lib, name, None)
                if fn is not None:
                    fn.restype = ctypes.c_char_p
                    out[Path(path).name] = fn().decode(errors="replace")
                    break
        return out
    except FileNotFoundError:  # no /proc: not Linux
        return {}
    except Exception as exc:  # never let the probe stop a key from being made; say so in it
        return {"error": type(exc).__name__}


# --------------------------------------------------------------------------- keys
def make_key(schema: str, module: str, parts: dict, source: str | None = None) -> str:
    """The cache key of one result.

    schema: what kind of entry (e.g. ``"dampersim.sweep-point"``); module: the dotted name
    of the module whose code computes the result (its import closure is hashed); parts: the
    inputs (parameter set, excitation, state, options), anything :func:`canonical` accepts;
    source: a source hash to use instead of ``source_hash(module)`` (a worker pins the one
    the parent used).
    """
    return digest(key_document(schema, module, parts, source))


def key_document(schema: str, module: str, parts: dict, source: str | None = None) -> dict:
    """The document :func:`make_key` hashes (for inspection and tests)."""
    return {
        "schema": schema,
        "version": __version__,
        "platform": platform(),
        "source": source_hash(module) if source is None else source,
        "parts": parts,
    }


__all__ = [
    "canonical",
    "digest",
    "key_document",
    "make_key",
    "module_closure",
    "NUMBA_CODEGEN_ENV",
    "numba_codegen",
    "platform",
    "source_hash",
    "source_hash_at",
]
